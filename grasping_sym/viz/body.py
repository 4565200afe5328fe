"""Drawings of a free body on a plane of the world (``model.body``) or on a line of the world
(``model.body_line``): its frames for an animation, its figures (the modes over time,
``viz.modes``) and its summary lines."""
from __future__ import annotations

from pathlib import Path

import numpy as np
import sympy as sp

from grasping_sym.model.body import TIME
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


def frames2d(fig, scene, result, rows):
    """``draw(k)`` of frame ``k`` of a body on a line: its contour, turned and moved, a mark
    of its turning (the segment from the centre to its contour's parameter 0), the line under
    the whole motion (moved by its ``line_motion``), the contact's mode in the title."""
    u = np.linspace(*scene.contour.domain, 400)
    ev = scene.contour.evaluate(u)
    pts = np.column_stack([np.broadcast_to(ev["x"], u.shape), np.broadcast_to(ev["y"], u.shape)])
    ref = scene.contour.evaluate(0.0) if scene.contour.in_domain(0.0) else scene.contour.evaluate(u[0])
    mark = np.array([float(ref["x"]), float(ref["y"])])
    n, w0 = np.asarray(scene.line_normal), np.asarray(scene.line_point)
    tan = np.array([-n[1], n[0]])
    centres = result.x[rows, 0:2]
    size = float(np.ptp(pts, axis=0).max())
    along = (centres - w0) @ tan
    ends = w0 + np.outer([along.min() - size, along.max() + size], tan)
    box = np.vstack([ends, *[c + pts for c in centres[:: max(1, len(rows) // 8)]]])
    if scene.line_motion is None:
        moved = np.zeros((len(rows), 2))
    else:
        shift = sp.lambdify(TIME, list(scene.line_motion), "numpy")
        # along itself the line looks the same: only its rise along n is drawn
        moved = np.array([np.dot(np.asarray(shift(result.t[i]), dtype=float), n) * n for i in rows])
    box = np.vstack([box, ends[0] + moved, ends[1] + moved])
    lo, hi = box.min(axis=0) - 0.1 * size, box.max(axis=0) + 0.1 * size
    ax = fig.add_subplot()
    modes = result.modes

    def draw(k):
        ax.clear()
        x = result.x[rows[k]]
        c, s = np.cos(x[2]), np.sin(x[2])
        turn = np.array([[c, s], [-s, c]])          # Rot(-theta)
        ax.plot(*(ends + moved[k]).T, "-", color="0.4", linewidth=2)
        body = x[0:2] + pts @ turn.T
        ax.fill(*body.T, color="tab:blue", alpha=0.6)
        ax.plot(*np.vstack([x[0:2], x[0:2] + turn @ mark]).T, "-", color="k", linewidth=1)
        ax.set_xlim(lo[0], hi[0])
        ax.set_ylim(lo[1], hi[1])
        ax.set_aspect("equal", adjustable="box")
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
