"""A run as a moving picture: ``gs.viz.animate(res, "motion.gif")`` (or ``.mp4``).

2D scenes are drawn as ``plots.draw_scene`` draws them, 3D scenes as ``plots3d.draw_scene3d``
(the geometry derived once with SymPy, 1-3 s), at evenly spaced times of the run, with the
same axis limits in every frame. GIFs are written with Pillow (matplotlib's dependency);
``.mp4`` needs ``ffmpeg`` on the PATH.

The options are checked before anything is drawn, each against its bounds (``check_options``):
``fps`` in (0, 100] (a GIF counts time in hundredths of a second), ``seconds`` in (0, 600],
``dpi`` in [10, 600], and the frames times their pixels at most ``MAX_PIXELS`` (the frames of
a GIF are held in memory until it is written).
"""
from __future__ import annotations

import dataclasses
import math
import shutil
from pathlib import Path

import numpy as np
import sympy as sp
from matplotlib import animation
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure

from grasping_sym.errors import ViewOptionError
from grasping_sym.geometry.values import as_real
from grasping_sym.model import kinds
from grasping_sym.model.body import TIME
from grasping_sym.viz.body import frames as body_frames
from grasping_sym.viz.body import frames2d as body_frames2d
from grasping_sym.viz.options import check_scene
from grasping_sym.viz.plots import draw_scene, motion_limits
from grasping_sym.viz.plots3d import (
    _equal_box,
    draw_scene3d,
    geometry_at,
    geometry_function,
    parts_points,
    scene_parts3d,
)

#: Frames per second of the animation, by default.
FPS = 20
#: At most this many seconds of animation by default (a longer run plays faster).
MAX_SECONDS = 8.0
#: Bounds of the options: frames per second, seconds of animation, dots per inch.
FPS_RANGE = (0.0, 100.0)
SECONDS_RANGE = (0.0, 600.0)
DPI_RANGE = (10.0, 600.0)
#: At most this many pixels in all frames together (2e8: 870 frames of the 3D figure at the
#: default dpi, about 0.8 GB held by the GIF writer).
MAX_PIXELS = 2e8
#: The figure's size (inches), 2D and 3D.
FIGSIZE = {2: (6.4, 5.2), 3: (6.4, 5.6)}


def frame_rows(t: np.ndarray, fps: float, seconds: float | None) -> np.ndarray:
    """The result's rows shown: evenly spaced in time, ``fps`` per second of animation, the
    run played in ``seconds`` (default: real time, at most ``MAX_SECONDS``)."""
    span = float(t[-1] - t[0])
    seconds = min(span, MAX_SECONDS) if seconds is None else float(seconds)
    n = max(2, int(round(seconds * fps)) + 1)
    times = np.linspace(t[0], t[-1], n)
    return np.unique(np.clip(np.searchsorted(t, times), 0, len(t) - 1))


def check_options(n_samples: int, *, fps: float = FPS, seconds: float | None = None, dpi: float = 80,
                  dimension: int = 2) -> None:
    """Refuse, by name and with its bounds, an option ``animate`` cannot honour for a result
    of ``n_samples`` times: ``fps`` in ``FPS_RANGE`` (0, 100], ``seconds`` in
    ``SECONDS_RANGE`` (0, 600] (or None), ``dpi`` in ``DPI_RANGE`` [10, 600], and the frames
    (at most one per sample) times their pixels at most ``MAX_PIXELS``."""
    def real(v) -> bool:
        return (x := as_real(v)) is not None and math.isfinite(x)

    if not real(fps) or not FPS_RANGE[0] < fps <= FPS_RANGE[1]:
        raise ViewOptionError(f"fps = {fps!r}: give frames per second in ({FPS_RANGE[0]:g}, "
                              f"{FPS_RANGE[1]:g}] (default {FPS})")
    if seconds is not None and (not real(seconds) or not SECONDS_RANGE[0] < seconds <= SECONDS_RANGE[1]):
        raise ViewOptionError(f"seconds = {seconds!r}: give the animation's length in "
                              f"({SECONDS_RANGE[0]:g}, {SECONDS_RANGE[1]:g}] s, or None (the run's "
                              f"own length, at most {MAX_SECONDS:g} s)")
    if not real(dpi) or not DPI_RANGE[0] <= dpi <= DPI_RANGE[1]:
        raise ViewOptionError(f"dpi = {dpi!r}: give dots per inch in [{DPI_RANGE[0]:g}, "
                              f"{DPI_RANGE[1]:g}] (default 80)")
    length = MAX_SECONDS if seconds is None else float(seconds)
    frames = min(max(2, int(round(length * fps)) + 1), max(int(n_samples), 2))
    w, h = FIGSIZE[dimension]
    pixels = frames * round(w * dpi) * round(h * dpi)
    if pixels > MAX_PIXELS:
        raise ViewOptionError(f"{frames} frames of {round(w * dpi)} x {round(h * dpi)} pixels (fps = {fps!r}, "
                              f"seconds = {seconds!r}, dpi = {dpi!r}) make {pixels:.3g} pixels, more "
                              f"than {MAX_PIXELS:.3g}: lower fps, seconds or dpi")


def animate(result, path: str | Path, scene=None, *, fps: float = FPS, seconds: float | None = None,
            dpi: int = 80) -> Path:
    """Write ``result``'s motion to ``path`` (``.gif`` or ``.mp4``) and return the path.

    Parameters
    ----------
    scene
        The scene of the run (default ``result.scene``: set by the model that ran it when that
        model came from ``gs.build``).
    fps
        Frames per second, in (0, 100].
    seconds
        Length of the animation (s), in (0, 600]; default the run's own, at most
        ``MAX_SECONDS``.
    dpi
        Dots per inch of the frames, in [10, 600] (the figure is 6.4 inches wide).

    Raises
    ------
    ViewOptionError
        An option out of its bounds (``check_options``), too many pixels in all, no scene,
        another suffix than ``.gif``/``.mp4``, no ffmpeg for an ``.mp4``, or a result of one
        sample.
    """
    scene = scene if scene is not None else getattr(result, "scene", None)
    if scene is None:
        raise ViewOptionError("animate needs the run's scene: pass scene=..., or run a model made by "
                              "gs.build(scene) (a model from gs.load, or a loaded result, has none)")
    check_scene(result, scene, "animate")
    check_options(len(result.t), fps=fps, seconds=seconds, dpi=dpi,
                  dimension=scene.dimension)
    path = Path(path)
    if path.suffix not in (".gif", ".mp4"):
        raise ViewOptionError(f"{path.name}: write a .gif (Pillow) or an .mp4 (ffmpeg)")
    if path.suffix == ".mp4" and shutil.which("ffmpeg") is None:
        raise ViewOptionError("an .mp4 needs ffmpeg on the PATH (e.g. apt install ffmpeg); or write a .gif")
    if len(result.t) < 2:
        raise ViewOptionError("a result of one sample does not move: simulate with more output times")
    rows = frame_rows(result.t, fps, seconds)
    fig = Figure(figsize=FIGSIZE[scene.dimension], layout="constrained")
    FigureCanvasAgg(fig)
    draw = kinds.of(scene, _FRAMES, "an animation")(fig, scene, result, rows)
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

    ax = fig.add_subplot()
    lo, hi = motion_limits(scene, result.x[rows[:: max(1, len(rows) // 20)]])
    lines = getattr(scene, "lines", ())
    if lines:   # the lines of the world under the motion's box (a driven one rises with it)
        points = np.array([w.point for w in lines], dtype=float)
        lo, hi = np.minimum(lo, points.min(axis=0)), np.maximum(hi, points.max(axis=0))
    moved = [np.zeros((len(rows), 2)) if w.motion is None else np.array(
        [np.asarray(sp.lambdify(TIME, list(w.motion), "numpy")(result.t[i]), dtype=float) for i in rows])
        for w in lines]

    def draw(k):
        ax.clear()
        draw_scene(ax, scene, result.x[rows[k]])
        for w, d in zip(lines, moved):
            n = np.asarray(w.normal)
            base = np.asarray(w.point) + np.dot(d[k], n) * n
            ends = base + np.outer([-1.0, 1.0], [-n[1], n[0]]) * (np.max(hi - lo) + 1.0)
            ax.plot(*ends.T, "-", color="0.4", linewidth=2)
        ax.set_xlim(lo[0], hi[0])
        ax.set_ylim(lo[1], hi[1])
        ax.set_aspect("equal", adjustable="box")
        mode = "" if result.modes is None else \
            ", " + ", ".join(str(m) for m in np.atleast_1d(result.modes[rows[k]]))
        ax.set_title(f"{scene.name}: t = {result.t[rows[k]]:.3f} s{mode}", fontsize=10)
        ax.legend(loc="lower right", fontsize=7)
    return draw


def _frames_3d(fig, scene, result, rows):

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


def _frames_grasp_modes(fig, scene, result, rows):
    """A grasp with modes: its base grasp drawn from the base's states, each plane of the world
    as a square under the object, and the contacts' modes in the title."""
    nb = len(scene.base.state_names)
    base_run = dataclasses.replace(result, x=result.x[:, :nb], state_names=scene.base.state_names)
    draw_base = _frames_3d(fig, scene.base, base_run, rows)
    ax = fig.axes[-1]
    names = scene.base.state_names
    centre = result.x[:, [names.index(k) for k in "xyz"]] if scene.base.free else \
        np.tile(np.asarray(scene.base.position, float), (len(result.t), 1))

    def draw(k):
        draw_base(k)
        for w in scene.planes:
            n, w0 = np.asarray(w.normal), np.asarray(w.point)
            foot = centre[rows[k]] - np.dot(n, centre[rows[k]] - w0) * n
            helper = np.eye(3)[int(np.argmin(np.abs(n)))]
            t1 = np.cross(helper, n) / np.linalg.norm(np.cross(helper, n))
            t2 = np.cross(n, t1)
            s = np.linspace(-PLANE_HALF_WIDTH, PLANE_HALF_WIDTH, 2)
            a, b = np.meshgrid(s, s)
            pts = foot[:, None, None] + t1[:, None, None] * a + t2[:, None, None] * b
            ax.plot_surface(*pts, color="0.55", alpha=0.3, linewidth=0)
        if result.modes is not None:
            ax.set_title(f"{scene.name}: t = {result.t[rows[k]]:.3f} s\n"
                         + ", ".join(str(m) for m in np.atleast_1d(result.modes[rows[k]])), fontsize=9)
    return draw


#: m: half the side of the square that draws a plane of the world
PLANE_HALF_WIDTH = 0.05

#: kind of scene (``model.kinds``) -> how its frames are drawn
_FRAMES = {"planar": _frames_2d, "planar_modes": _frames_2d, "grasp3d": _frames_3d,
           "grasp3d_modes": _frames_grasp_modes, "body": body_frames, "body2d": body_frames2d}
