"""A run as a moving picture: ``SimulationResult.animate("motion.gif")`` (or ``.mp4``).

2D scenes are drawn as ``plots.draw_scene`` draws them, 3D scenes as ``plots3d.draw_scene3d``
(the geometry derived once with SymPy, 1-3 s), at evenly spaced times of the run, with the
same axis limits in every frame. GIFs are written with Pillow (matplotlib's dependency);
``.mp4`` needs ``ffmpeg`` on the PATH.
"""
from __future__ import annotations

import shutil
from pathlib import Path

import numpy as np

#: Frames per second of the animation, by default.
FPS = 20
#: At most this many seconds of animation by default (a longer run plays faster).
MAX_SECONDS = 8.0


def frame_rows(t: np.ndarray, fps: float, seconds: float | None) -> np.ndarray:
    """The result's rows shown: evenly spaced in time, ``fps`` per second of animation, the
    run played in ``seconds`` (default: real time, at most ``MAX_SECONDS``)."""
    span = float(t[-1] - t[0])
    seconds = min(span, MAX_SECONDS) if seconds is None else float(seconds)
    n = max(2, int(round(seconds * fps)) + 1)
    times = np.linspace(t[0], t[-1], n)
    return np.unique(np.clip(np.searchsorted(t, times), 0, len(t) - 1))


def animate(result, path: str | Path, scene=None, *, fps: float = FPS, seconds: float | None = None,
            dpi: int = 80) -> Path:
    """Write ``result``'s motion to ``path`` (``.gif`` or ``.mp4``) and return the path.

    ``scene``: the scene of the run (default ``result.scene``: set by the model that ran it when
    that model came from ``gs.build``)."""
    import matplotlib  # noqa: PLC0415

    matplotlib.use("Agg")
    from matplotlib import animation  # noqa: PLC0415
    from matplotlib.backends.backend_agg import FigureCanvasAgg  # noqa: PLC0415
    from matplotlib.figure import Figure  # noqa: PLC0415

    scene = scene if scene is not None else getattr(result, "scene", None)
    if scene is None:
        raise ValueError("animate needs the run's scene: pass scene=..., or run a model made by "
                         "gs.build(scene) (a model from gs.load, or a loaded result, has none)")
    path = Path(path)
    if path.suffix not in (".gif", ".mp4"):
        raise ValueError(f"{path.name}: write a .gif (Pillow) or an .mp4 (ffmpeg)")
    if path.suffix == ".mp4" and shutil.which("ffmpeg") is None:
        raise ValueError("an .mp4 needs ffmpeg on the PATH (e.g. apt install ffmpeg); or write a .gif")
    if not (np.isfinite(fps) and fps > 0):
        raise ValueError(f"fps = {fps!r} must be > 0")
    if len(result.t) < 2:
        raise ValueError("a result of one sample does not move: simulate with more output times")
    rows = frame_rows(result.t, fps, seconds)
    three_d = getattr(scene, "dimension", 2) == 3
    fig = Figure(figsize=(6.4, 5.6) if three_d else (6.4, 5.2), layout="constrained")
    FigureCanvasAgg(fig)
    draw = _frames_3d(fig, scene, result, rows) if three_d else _frames_2d(fig, scene, result, rows)
    writer = animation.PillowWriter(fps=fps) if path.suffix == ".gif" else animation.FFMpegWriter(fps=fps)
    path.parent.mkdir(parents=True, exist_ok=True)
    # one drawing per frame (FuncAnimation.save draws each frame three times), and the layout
    # computed on the first frame only: the panels then stay put from frame to frame
    with writer.saving(fig, str(path), dpi):
        for k in range(len(rows)):
            draw(k)
            writer.grab_frame()
            if k == 0:
                fig.set_layout_engine("none")
    return path


def _frames_2d(fig, scene, result, rows):
    from grasping_sym.plots import draw_scene, motion_limits  # noqa: PLC0415

    ax = fig.add_subplot()
    lo, hi = motion_limits(scene, result.x[rows[:: max(1, len(rows) // 20)]])

    def draw(k):
        ax.clear()
        draw_scene(ax, scene, result.x[rows[k]])
        ax.set_xlim(lo[0], hi[0])
        ax.set_ylim(lo[1], hi[1])
        ax.set_aspect("equal", adjustable="box")
        ax.set_title(f"{scene.name}: t = {result.t[rows[k]]:.3f} s")
        ax.legend(loc="lower right", fontsize=7)
    return draw


def _frames_3d(fig, scene, result, rows):
    from grasping_sym.plots3d import (  # noqa: PLC0415
        _equal_box,
        draw_scene3d,
        geometry_at,
        geometry_function,
        parts_points,
        scene_parts3d,
    )

    geos = geometry_at(geometry_function(scene), scene, result, rows)
    ax = fig.add_subplot(projection="3d")
    g = scene.gravity if scene.gravity and any(scene.gravity) else (0.0, -1.0, 0.0)
    vertical = "xyz"[int(np.argmax(np.abs(g)))]
    # the limits of the whole motion, from the parts at a few frames
    box = np.vstack([parts_points(scene_parts3d(scene, geo))[0] for geo in geos[:: max(1, len(geos) // 6)]])

    def draw(k):
        ax.clear()
        ax.view_init(elev=25, azim=-60 if vertical == "z" else 35, vertical_axis=vertical)
        draw_scene3d(ax, scene, geos[k])
        _equal_box(ax, box, "m", pad=0.02)
        ax.set_title(f"{scene.name}: t = {result.t[rows[k]]:.3f} s", fontsize=10)
    return draw
