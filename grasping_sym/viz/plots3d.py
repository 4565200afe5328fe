"""Figures of a 3D grasping simulation (``model.grasp3d``): snapshots, contact traces,
multipliers, arclengths and residuals.

Frames as in ``model.grasp3d``: a point ``P`` of the object's surface (object frame) is at
``pos + R P`` in the world; a point of finger ``i``'s fingertip surface (fingertip frame
``Pi_i``, origin at the fingertip centre ``r_i``) at ``r_i + Pi_i P``. World positions come
from the scene's geometry function (``derive.grasp3d``, evaluated uncompiled by CasADi), the
traces from the contact coordinates ``(u_f, v_f, u_o, v_o)`` in the states. Figures are
``matplotlib.figure.Figure`` on the Agg canvas (no pyplot state), as in ``grasping_sym.viz.plots``.
Lengths in m (traces in mm), times in s, forces in N.
"""
from __future__ import annotations

import logging
import math
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from matplotlib.axes import Axes
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure

from grasping_sym.derive.grasp3d import derive_grasp3d
from grasping_sym.geometry.surfaces import ParametricSurface
from grasping_sym.model.grasp3d import GraspScene3D
from grasping_sym.runtime.result import SimulationResult

log = logging.getLogger(__name__)

#: Samples per parameter direction of a surface mesh.
MESH_SAMPLES = 36
#: Samples of the world paths of the contact points drawn in the snapshots.
PATH_SAMPLES = 400
FINGER_COLORS = ("tab:blue", "tab:green", "tab:purple", "tab:olive", "tab:cyan")
OBJECT_COLOR = "tab:red"
ZERO_STYLE = {"color": "0.4", "linestyle": "--", "linewidth": 1.0}
#: Outputs drawn in the orthonormality panel, with their labels.
CHECK_LABELS = {"orthonormality": "object: max |R^T R - I|", "quat_norm_error": "object: |quat| - 1",
                "frame_orthonormality": "frames: max |Psi^T Psi - I|"}


def _new_figure(width: float, height: float) -> Figure:
    fig = Figure(figsize=(width, height), layout="constrained")
    FigureCanvasAgg(fig)
    return fig


def _color(i: int) -> str:
    return FINGER_COLORS[(i - 1) % len(FINGER_COLORS)]


# ---------------------------------------------------------------------------- geometry
def geometry_function(scene: GraspScene3D):
    """The scene's uncompiled ``geometry`` CasADi Function ``(x, p) -> R, pos, joints{i}, ...``.

    Derives the scene with SymPy (``derive.grasp3d``, 1-3 s). The geometry does not depend on
    ``p``: pass the model's ``default_params``, or zeros.
    """

    return derive_grasp3d(scene).function("geometry", "geometry")


def geometry_at(geo, scene: GraspScene3D, result: SimulationResult,
                rows: Sequence[int]) -> list[dict[str, np.ndarray]]:
    """``geo`` at the samples ``rows`` of ``result``: one dict of arrays per row (vectors
    ``(3,)``, matrices ``(3, k)``)."""
    rows = list(rows)
    # the start's parameters (the centre spring's rest point) do not enter the geometry
    p = np.array([result.params.get(k, scene.params[k]) for k in scene.runtime]
                 + [0.0] * (len(scene.p_names) - len(scene.runtime)), dtype=float)
    P = np.tile(p[:, None], (1, len(rows)))
    for name, col in getattr(result, "charts", {}).items():  # each row's charts (surfaces with atlases)
        if name in scene.p_names:
            P[scene.p_names.index(name)] = np.asarray(col)[rows]
    out = geo.map(len(rows))(x=result.x[rows].T, p=P)
    out = {k: np.asarray(v) for k, v in out.items()}
    width = {name: a.shape[1] // len(rows) for name, a in out.items()}
    return [{name: a[:, k * w] if w == 1 else a[:, k * w:(k + 1) * w]
             for (name, a), w in zip(out.items(), width.values())} for k in range(len(rows))]


def surface_mesh(surface: ParametricSurface, box=None, n: int = MESH_SAMPLES) -> np.ndarray:
    """Points ``(n, n, 3)`` of ``surface`` (own frame, m) on a grid over ``box``
    ``((u0, u1), (v0, v1))``, default the whole domain, closed over the poles of a
    latitude-longitude chart (``drawing_box``)."""
    (u0, u1), (v0, v1) = drawing_box(surface) if box is None else box
    uu, vv = np.meshgrid(np.linspace(u0, u1, n), np.linspace(v0, v1, n))
    return surface.evaluate(uu, vv)["point"]


def drawing_box(surface: ParametricSurface):
    """The box a drawing covers: the domain, except that a latitude-longitude chart (sphere,
    ellipsoid, superquadric: its chart stops short of the poles, where it is singular) is drawn
    up to latitudes +-pi/2 when the surface closes there (one point for every longitude), so
    the drawn body has no holes at its poles."""
    (u0, u1), (v0, v1) = surface.domain
    if u1 - u0 < 2 * math.pi - 1e-9 or not (-math.pi / 2 < v0 and v1 < math.pi / 2):
        return surface.domain
    lon = np.linspace(u0, u1, 7)
    size = float(np.ptp(surface.evaluate(*np.meshgrid(lon, np.linspace(v0, v1, 5)))["point"]
                        .reshape(-1, 3), axis=0).max())
    box = [v0, v1]
    for k, pole in ((0, -math.pi / 2), (1, math.pi / 2)):
        with np.errstate(all="ignore"):
            pts = surface.evaluate(lon, np.full_like(lon, pole))["point"].reshape(-1, 3)
        if np.all(np.isfinite(pts)) and float(np.ptp(pts, axis=0).max()) <= 1e-9 * size:
            box[k] = pole
    return (u0, u1), tuple(box)


def _to_world(points: np.ndarray, rot: np.ndarray, origin: np.ndarray) -> np.ndarray:
    return np.asarray(origin).reshape(3) + points @ np.asarray(rot).T


# ---------------------------------------------------------------------------- traces
def trace_arclength(points: np.ndarray) -> np.ndarray:
    """Cumulative length (m) of the polyline through ``points`` ``(n, 3)``: 0 at the first.

    On a sampled contact trace it is the distance travelled by the contact point on that
    surface; in rolling without slip it is the same on the object and on the fingertip.
    """
    steps = np.linalg.norm(np.diff(np.asarray(points, dtype=float), axis=0), axis=1)
    return np.concatenate([[0.0], np.cumsum(steps)])


@dataclass(frozen=True)
class ContactTrace:
    """The path of contact ``i`` on the object (object frame) and on its fingertip (tip frame):
    surface coordinates ``(n, 2)`` and points ``(n, 3)`` (m) at the samples of a result."""

    i: int
    uv_object: np.ndarray
    uv_tip: np.ndarray
    object_points: np.ndarray
    tip_points: np.ndarray

    @property
    def s_object(self) -> np.ndarray:  # m, travelled on the object
        return trace_arclength(self.object_points)

    @property
    def s_tip(self) -> np.ndarray:  # m, travelled on the fingertip
        return trace_arclength(self.tip_points)


def contact_traces(scene: GraspScene3D, result: SimulationResult) -> list[ContactTrace]:
    """The trace of every contact over the samples of ``result`` (states ``u_f{i}`` ...)."""
    traces = []
    for i, finger in enumerate(scene.fingers, start=1):
        uv_o = np.column_stack([result[f"u_o{i}"], result[f"v_o{i}"]])
        uv_f = np.column_stack([result[f"u_f{i}"], result[f"v_f{i}"]])
        charts = getattr(result, "charts", {})  # each row's chart (surfaces with atlases)
        traces.append(ContactTrace(
            i, uv_o, uv_f,
            scene.object_surface.evaluate(uv_o[:, 0], uv_o[:, 1], chart=charts.get(f"chart_o{i}"))["point"],
            finger.tip.evaluate(uv_f[:, 0], uv_f[:, 1], chart=charts.get(f"chart_f{i}"))["point"]))
    return traces


# ---------------------------------------------------------------------------- 3D axes
def _equal_box(ax, points: np.ndarray, unit: str, pad: float = 0.0, flat: float = 0.25) -> None:
    """Limits around ``points`` with equal scales on x, y, z (a box, not a cube; every side
    at least ``flat`` times the longest so that a flat scene keeps some depth), labels."""
    lo, hi = points.min(axis=0), points.max(axis=0)
    span = np.maximum(hi - lo, flat * float(np.max(hi - lo)) or 1e-3) * (1 + 2 * pad)
    for name, m, h in zip("xyz", 0.5 * (lo + hi), 0.5 * span):
        getattr(ax, f"set_{name}lim")(m - h, m + h)
        getattr(ax, f"set_{name}label")(f"{name} [{unit}]", fontsize=8)
    ax.set_box_aspect(tuple(span), zoom=0.9)  # below 1: the axis labels stay inside the panel
    ax.locator_params(nbins=4)
    ax.tick_params(labelsize=6)


def _view_from(ax, direction: np.ndarray, tilt: float) -> np.ndarray:
    """Look from ``direction`` raised by ``tilt`` degrees (z up); returns the unit vector to
    the eye."""
    d = np.asarray(direction, dtype=float) / (np.linalg.norm(direction) or 1.0)
    elev = float(np.clip(math.degrees(math.asin(float(np.clip(d[2], -1, 1)))) + tilt, -89, 89))
    azim = math.degrees(math.atan2(d[1], d[0]))
    ax.view_init(elev=elev, azim=azim)
    e, a = math.radians(elev), math.radians(azim)
    return np.array([math.cos(e) * math.cos(a), math.cos(e) * math.sin(a), math.sin(e)])


# ---------------------------------------------------------------------------- figures
def scene_parts3d(scene: GraspScene3D, g: dict[str, np.ndarray]) -> dict:
    """The scene's parts in the world at the geometry ``g`` (one ``geometry_at`` dict): the
    object's mesh ``(n, n, 3)``, each fingertip's mesh and each finger's joints ``(3, k)``."""
    return {"object": _to_world(surface_mesh(scene.object_surface), g["R"], g["pos"]),
            "joints": [g[f"joints{i}"].reshape(3, -1) for i in range(1, len(scene.fingers) + 1)],
            "tips": [_to_world(surface_mesh(f.tip, n=18), g[f"Pi{i}"], g[f"joints{i}"].reshape(3, -1)[:, -1])
                     for i, f in enumerate(scene.fingers, start=1)]}


def parts_points(parts: dict) -> tuple[np.ndarray, np.ndarray]:
    """Points ``(n, 3)`` of ``scene_parts3d``'s parts: all, and those of the object and
    fingertips only (for the axes' limits)."""
    near = [parts["object"].reshape(-1, 3), *(t.reshape(-1, 3) for t in parts["tips"])]
    return np.vstack(near + [j.T for j in parts["joints"]]), np.vstack(near)


def draw_scene3d(ax, scene: GraspScene3D, g: dict[str, np.ndarray], clip: bool = False) -> tuple[np.ndarray, ...]:
    """Draw links, fingertips (wireframes), object (mesh, body axes) and contact points at the
    geometry ``g`` (one ``geometry_at`` dict). Returns the drawn points ``(n, 3)``: all, and
    those of the object and fingertips only (``parts_points``, for the axes' limits). ``clip``:
    nothing drawn outside the axes' limits (a zoomed view)."""
    c = {"axlim_clip": True} if clip else {}
    ax.computed_zorder = False  # draw in call order: lines stay on top of the meshes
    parts = scene_parts3d(scene, g)
    obj = parts["object"]
    ax.plot_surface(*obj.transpose(2, 0, 1), color=OBJECT_COLOR, alpha=0.35, linewidth=0, **c)
    size = 0.6 * float(np.max(np.ptp(obj.reshape(-1, 3), axis=0)))
    for k, style in enumerate(("-", "--", ":")):  # the object's body axes X, Y, Z
        ax.plot(*np.column_stack([g["pos"], g["pos"] + size * g["R"][:, k]]),
                color=OBJECT_COLOR, linewidth=1.2, linestyle=style, **c)
    for i, (joints, tip) in enumerate(zip(parts["joints"], parts["tips"]), start=1):
        ax.plot_wireframe(*tip.transpose(2, 0, 1), color=_color(i), linewidth=0.4, alpha=0.7, **c)
        ax.plot(*joints, "-", color="0.3", linewidth=3, solid_capstyle="round", **c)
        ax.plot(*joints[:, :-1], "o", color="0.1", markersize=4, **c)
        ax.plot(*g[f"p_o{i}"].reshape(3, 1), "o", color="black", markersize=4, **c)
    return parts_points(parts)


def snapshot_figure3d(scene: GraspScene3D, result: SimulationResult, geo,
                      times: Sequence[float] | None = None) -> Figure:
    """The scene in 3D at ``times`` (s; default 0, T/10, T/3, T): whole (top row) and the
    object with the fingertips (bottom row), with the world paths of the contact points up to
    each time. Equal scales on x, y, z; the same limits along a row; the vertical axis
    is the one gravity is along (y without gravity)."""
    t = result.t
    if times is None:
        times = [t[0] + f * (t[-1] - t[0]) for f in (0.0, 0.1, 1 / 3, 1.0)]
    rows = [int(np.argmin(np.abs(t - ti))) for ti in times]
    path_rows = np.unique(np.linspace(0, len(t) - 1, min(PATH_SAMPLES, len(t))).astype(int))
    path = geometry_at(geo, scene, result, path_rows)
    geos = geometry_at(geo, scene, result, rows)
    g = scene.gravity if scene.gravity and any(scene.gravity) else (0.0, -1.0, 0.0)
    vertical = "xyz"[int(np.argmax(np.abs(g)))]  # no gravity: y up
    n = len(rows)
    fig = _new_figure(5.2 * n, 14.0)
    grid, axes, pts = fig.add_gridspec(3, n, height_ratios=(1.0, 1.5, 1.5)), [[], [], []], [[], [], []]
    # the third row: around contact 1, over where its contact point travels in the whole run
    travel = np.array([g["p_o1"] for g in path]).reshape(-1, 3)
    reach = 1.5 * float(np.max(np.ptp(travel, axis=0))) + 2e-3
    near = np.vstack([travel.min(axis=0) - reach, travel.max(axis=0) + reach])
    for k, row in enumerate(rows):
        for r in range(3):
            ax = fig.add_subplot(grid[r, k], projection="3d")
            ax.view_init(elev=25, azim=-60 if vertical == "z" else 35, vertical_axis=vertical)
            for p, drawn in zip(pts, draw_scene3d(ax, scene, geos[k], clip=r == 2)):
                p.append(drawn)
            upto = [j for j, pr in enumerate(path_rows) if pr <= row]
            for i in range(1, scene.n_contacts + 1 if len(upto) > 1 else 1):
                ax.plot(*np.array([path[j][f"p_o{i}"] for j in upto]).T, color=_color(i),
                        linewidth=1.5, label=f"path of contact {i}")
            where = ("whole scene", "object and fingertips", "around contact 1")[r]
            ax.set_title(f"({chr(ord('a') + k)}) t = {t[row]:.3g} s, {where}", fontsize=9)
            axes[r].append(ax)
    for r in range(3):
        for ax in axes[r]:
            box = near if r == 2 else np.vstack(pts[r])
            _equal_box(ax, box, "m", pad=0.02 if r == 0 else 0.0, flat=1.0 if r == 2 else 0.25)
    if axes[1][-1].get_legend_handles_labels()[0]:
        axes[1][-1].legend(fontsize=7, loc="upper left")
    fig.suptitle(f"{scene.name}: fingers (links, tip wireframes), object (mesh; body axes "
                 f"X solid, Y dashed, Z dotted), contact points (black)")
    return fig


def _outward_normals(surface: ParametricSurface, uv: np.ndarray) -> np.ndarray:
    """Unit normals at ``uv`` ``(n, 2)``, turned away from the surface's centroid."""
    grid = surface.evaluate(*np.meshgrid(*[np.linspace(a, b, 9) for a, b in surface.domain]))
    sign = np.sign(np.sum(grid["normal"] * (grid["point"] - grid["point"].mean(axis=(0, 1)))))
    return (sign or 1.0) * surface.evaluate(uv[:, 0], uv[:, 1])["normal"]


def _zoom_box(surface: ParametricSurface, uv: np.ndarray) -> tuple:
    """A parameter box around the trace ``uv``, about square on the surface (its sides 1.4
    times the trace's extent), inside the domain."""
    e = surface.evaluate(*uv.mean(axis=0))
    scale = np.sqrt([float(e["E"]), float(e["G"])])  # m per unit of u, v
    ext = np.array([b - a for a, b in surface.domain])
    lo, hi = uv.min(axis=0), uv.max(axis=0)
    side = max(float(np.max((hi - lo) * scale)), 0.01 * float(np.max(ext * scale)))
    half = np.maximum(0.5 * (hi - lo), 0.5 * side / scale) * 1.4
    return tuple((max(a, m - h), min(b, m + h))
                 for (a, b), m, h in zip(surface.domain, 0.5 * (lo + hi), half))


def _trace_panel(ax, surface: ParametricSurface, traces, color: str, zoom: bool, title: str) -> None:
    """A surface (own frame, mm) with ``traces`` ``[(uv, points, label, colour), ...]`` seen
    from the first one's side; parts on the far side (outward normal away from the eye) are
    dotted. Circle: start, square: end."""
    uv0 = traces[0][0]
    mesh = 1e3 * surface_mesh(surface, _zoom_box(surface, uv0) if zoom else None, n=24 if zoom else MESH_SAMPLES)
    ax.computed_zorder = False
    ax.plot_surface(*mesh.transpose(2, 0, 1), color=color, alpha=0.3, linewidth=0.2, edgecolor="0.5")
    eye = _view_from(ax, _outward_normals(surface, uv0.mean(axis=0)[None])[0], tilt=10.0 if zoom else 25.0)
    for uv, pts, label, c in traces:
        p = 1e3 * pts
        back = (_outward_normals(surface, uv) @ eye < 0)[:, None]
        ax.plot(*np.where(back, np.nan, p).T, color=c, linewidth=2.0, label=label)
        if back.any():
            ax.plot(*np.where(back, p, np.nan).T, ":", color=c, alpha=0.6, label=f"{label} (far side)")
        for k, marker in ((0, "o"), (-1, "s")):  # start and end, where visible
            ax.plot(*np.where(back[k], np.nan, p[k]), marker, markersize=4, color=c)
    _equal_box(ax, mesh.reshape(-1, 3), "mm")
    ax.set_title(title, fontsize=9)
    ax.legend(fontsize=7, loc="upper left")


def traces_figure(scene: GraspScene3D, traces: list[ContactTrace]) -> Figure:
    """The contact traces, a row per contact: the object (whole, and near the trace; object
    frame, with every contact's trace on the whole one) and the fingertip (whole, and near the
    trace; its own frame)."""
    n = len(traces)
    fig = _new_figure(16.0, 5.0 * n)
    on_object = [(tr.uv_object, tr.object_points, f"contact {tr.i}", _color(tr.i)) for tr in traces]
    for r, tr in enumerate(traces):
        mine = [on_object[r], *on_object[:r], *on_object[r + 1:]]
        on_tip = [(tr.uv_tip, tr.tip_points, f"contact {tr.i}", _color(tr.i))]
        obj, tip, col = scene.object_surface, scene.fingers[tr.i - 1].tip, _color(tr.i)
        for c, panel in enumerate(((obj, mine, OBJECT_COLOR, False, "object, object frame"),
                                   (obj, mine[:1], OBJECT_COLOR, True, f"object near contact {tr.i}"),
                                   (tip, on_tip, col, False, f"fingertip {tr.i}, its frame"),
                                   (tip, on_tip, col, True, f"fingertip {tr.i} near the contact"))):
            _trace_panel(fig.add_subplot(n, 4, 4 * r + c + 1, projection="3d"), *panel)
    fig.suptitle(f"{scene.name}: contact traces (circle: start, square: end; dotted: far side), lengths in mm")
    return fig


def _time_axes(ax: Axes, result: SimulationResult, ylabel: str, title: str) -> None:
    ax.set_xlim(result.t[0], result.t[-1])
    ax.set_xlabel("time [s]")
    ax.set_ylabel(ylabel)
    ax.set_title(title, fontsize=10)
    ax.grid(True, linewidth=0.3)
    ax.legend(fontsize=8, loc="best")


def multipliers_figure(scene: GraspScene3D, result: SimulationResult) -> Figure | None:
    """Per contact: the normal multiplier ``f_i`` (> 0 presses) and the tangential ones
    ``lam_i``, ``eta_i`` (N). ``None`` when the model generated none of them."""
    n = scene.n_contacts
    if not any(f"{k}{i}" in result.outputs for k in ("f", "lam", "eta") for i in range(1, n + 1)):
        log.warning("skipping the multipliers figure: the model generated no f{i}, lam{i}, eta{i}")
        return None
    fig = _new_figure(11.0, 3.0 * n)
    axes = fig.subplots(n, 2, squeeze=False, sharex=True)
    for i in range(1, n + 1):
        for ax, keys, title in ((axes[i - 1, 0], [("f", "$f")], "normal"),
                                (axes[i - 1, 1], [("lam", r"$\lambda"), ("eta", r"$\eta")], "tangential")):
            for key, tex in keys:
                if f"{key}{i}" in result.outputs:
                    ax.plot(result.t, result.outputs[f"{key}{i}"], linewidth=1.5, label=f"{tex}_{i}$")
            ax.axhline(0.0, **ZERO_STYLE)
            _time_axes(ax, result, "multiplier [N]", f"contact {i}: {title}")
    fig.suptitle(f"{scene.name}: contact multipliers")
    return fig


def _log_safe(y) -> np.ndarray:
    y = np.abs(np.asarray(y, dtype=float))
    return np.where(y > 0, y, np.nan)  # exact zeros have no place on a log axis


def arclength_figure(scene: GraspScene3D, result: SimulationResult, traces: list[ContactTrace]) -> Figure:
    """Arclengths of the traces on the object and on the fingertip (equal in rolling); the
    constraint residual and the arclengths' mismatch (log); the rotation's orthonormality
    error (log) when generated."""
    checks = {k: v for k, v in CHECK_LABELS.items() if k in result.outputs}
    fig = _new_figure(5.2 * (2 + bool(checks)), 4.0)
    axes = fig.subplots(1, 2 + bool(checks), squeeze=False)[0]
    for tr in traces:
        axes[0].plot(result.t, 1e3 * tr.s_object, color=_color(tr.i), linewidth=2.0,
                     label=f"contact {tr.i}, on the object")
        axes[0].plot(result.t, 1e3 * tr.s_tip, color="black", linestyle="--", linewidth=1.0,
                     label=f"contact {tr.i}, on fingertip {tr.i}")
        axes[1].semilogy(result.t, _log_safe(tr.s_object - tr.s_tip), color=_color(tr.i),
                         linewidth=1.0, label=f"|arclength mismatch|, contact {tr.i}")
    _time_axes(axes[0], result, "arclength [mm]", "arclengths of the contact traces")
    if "constraint_residual" in result.outputs:
        axes[1].semilogy(result.t, _log_safe(result.outputs["constraint_residual"]), color="black", linewidth=1.0,
                         label="constraint residual")
    _time_axes(axes[1], result, "residual [m]", "residuals (log; exact zeros not drawn)")
    for key, label in checks.items():
        axes[2].semilogy(result.t, _log_safe(result.outputs[key]), linewidth=0.6, label=label)
    if checks:
        _time_axes(axes[2], result, "error [-]", "orthonormality (log)")
    fig.suptitle(f"{scene.name}: {result.method}, t = 0 .. {result.t[-1]:g} s")
    return fig


def pose_figure(scene: GraspScene3D, result: SimulationResult) -> Figure | None:
    """The object's pose and the fingers' joint angles against time: the centre's displacement
    from its start (mm, a free object), the angle the object has turned since the start (from
    the quaternion), and every joint angle."""
    names = result.state_names
    joints = [k for k in names if k.startswith("q") and k[1:].isdigit()]
    has_quat = all(k in names for k in ("qw", "qx", "qy", "qz"))
    free = all(k in names for k in ("x", "y", "z"))
    if not joints:
        return None
    panels = 1 + int(has_quat) + int(free)
    fig = _new_figure(6.4, 2.6 * panels)
    axes = fig.subplots(panels, 1, sharex=True, squeeze=False)[:, 0]
    k = 0
    if free:
        for c in ("x", "y", "z"):
            axes[k].plot(result.t, (result[c] - result[c][0]) * 1e3, linewidth=1.2, label=c)
        _time_axes(axes[k], result, "displacement [mm]", "object centre, from its start")
        k += 1
    if has_quat:
        q = np.column_stack([result[c] for c in ("qw", "qx", "qy", "qz")])
        q = q / np.linalg.norm(q, axis=1, keepdims=True)
        dot = np.clip(np.abs(q @ q[0]), 0.0, 1.0)
        axes[k].plot(result.t, 2 * np.arccos(dot), color=OBJECT_COLOR, linewidth=1.2,
                     label="angle turned")
        _time_axes(axes[k], result, "angle [rad]", "object: rotation since the start")
        k += 1
    for j in joints:
        axes[k].plot(result.t, result[j], linewidth=1.0, label=j)
    _time_axes(axes[k], result, "joint angle [rad]", "finger joints")
    axes[k].legend(fontsize=7, loc="center left", bbox_to_anchor=(1.0, 0.5))
    for ax in axes[:-1]:
        ax.set_xlabel("")
    return fig


def write_figures3d(scene: GraspScene3D, result: SimulationResult, out_dir: Path | str, *,
                    geo=None) -> list[Path]:
    """Write ``snapshots.png``, ``contact_traces.png``, ``multipliers.png`` (when the model
    generated multipliers), ``arclengths_residuals.png`` and ``pose_joints.png`` into
    ``out_dir``.

    ``geo``: the scene's geometry function (default: ``geometry_function(scene)``).
    """
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    geo = geometry_function(scene) if geo is None else geo
    traces = contact_traces(scene, result)
    figures = {"snapshots": snapshot_figure3d(scene, result, geo),
               "contact_traces": traces_figure(scene, traces),
               "multipliers": multipliers_figure(scene, result),
               "arclengths_residuals": arclength_figure(scene, result, traces),
               "pose_joints": pose_figure(scene, result)}
    for name, fig in figures.items():
        if fig is not None:
            fig.savefig(out_dir / f"{name}.png", dpi=110)
    return [out_dir / f"{name}.png" for name, fig in figures.items() if fig is not None]


def summary_lines(scene: GraspScene3D, result: SimulationResult) -> list[str]:
    """What ``grasping-sym simulate`` prints of a 3D run: residual, normal forces, traces."""
    lines = []
    if "constraint_residual" in result.outputs:
        lines.append(f"max residual     {float(result.outputs['constraint_residual'].max()):.3e} m")
    for i in range(1, scene.n_contacts + 1):
        if f"f{i}" in result.outputs:
            lines.append(f"{f'min f{i}':<17}{float(result.outputs[f'f{i}'].min()):.6e} N")
    for tr in contact_traces(scene, result):
        lines.append(f"{f'trace {tr.i}':<17}{1e3 * tr.s_object[-1]:.6f} mm on the object, "
                     f"{1e3 * tr.s_tip[-1]:.6f} mm on fingertip {tr.i}")
    return lines
