"""Drawings of a free body on a plane of the world (``model.body``): its frames for an
animation, its figures (the modes over time, ``viz.modes``) and its summary lines."""
from __future__ import annotations

from pathlib import Path

import numpy as np

from grasping_sym.runtime.modes import rotation
from grasping_sym.viz.modes import modes_figure
from grasping_sym.viz.plots3d import _equal_box, surface_mesh

#: Samples per side of the body's drawn mesh.
MESH = 24


def frames(fig, scene, result, rows):
    """``draw(k)`` of frame ``k``: the body (its surface, turned and moved) over a patch of its
    plane, the contact's mode in the title."""
    mesh = surface_mesh(scene.surface, n=MESH).reshape(-1, 3)
    n = np.asarray(scene.plane_normal)
    w0 = np.asarray(scene.plane_point)
    centres = result.x[rows, 0:3]
    e1 = np.cross(n, [1.0, 0.0, 0.0] if abs(n[0]) < 0.9 else [0.0, 1.0, 0.0])
    e1 /= np.linalg.norm(e1)
    e2 = np.cross(n, e1)
    size = float(np.ptp(mesh, axis=0).max())
    foot = centres - np.outer((centres - w0) @ n, n)
    lo1, hi1 = (foot - w0) @ e1, (foot - w0) @ e1
    lo2, hi2 = (foot - w0) @ e2, (foot - w0) @ e2
    a = np.linspace(lo1.min() - size, hi1.max() + size, 2)
    b = np.linspace(lo2.min() - size, hi2.max() + size, 2)
    A, B = np.meshgrid(a, b)
    plane = w0 + A[..., None] * e1 + B[..., None] * e2
    box = np.vstack([plane.reshape(-1, 3), *[c + mesh for c in centres[:: max(1, len(rows) // 8)]]])
    ax = fig.add_subplot(projection="3d")
    g = np.asarray(scene.gravity)
    vertical = "xyz"[int(np.argmax(np.abs(g)))] if np.any(g) else "z"
    modes = result.modes

    def draw(k):
        ax.clear()
        ax.view_init(elev=20, azim=-60, vertical_axis=vertical)
        ax.plot_surface(plane[..., 0], plane[..., 1], plane[..., 2], color="0.8", alpha=0.5, lw=0)
        x = result.x[rows[k]]
        pts = x[0:3] + mesh @ rotation(x[3:7]).T
        P = pts.reshape(MESH, MESH, 3)
        ax.plot_surface(P[..., 0], P[..., 1], P[..., 2], color="tab:blue", alpha=0.8, lw=0.2,
                        edgecolor="k")
        _equal_box(ax, box, "m", pad=0.02)
        mode = f", {modes[rows[k]]}" if modes is not None else ""
        ax.set_title(f"{scene.name}: t = {result.t[rows[k]]:.3f} s{mode}", fontsize=10)
    return draw


def write_figures(scene, result, out_dir: Path | str) -> list:
    """The modes over time (``viz.modes``) in ``out_dir``."""
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    return [modes_figure(result, out / f"{scene.name}_modes.png")] if result.modes is not None else []


def summary_lines(scene, result) -> list[str]:
    """The run's switches of contact modes."""
    return [f"{len(result.events)} switches of contact modes; ends {result.modes[-1]}"] \
        if result.modes is not None and len(result.modes) else []
