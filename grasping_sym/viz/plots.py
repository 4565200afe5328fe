"""Figures of a 2D simulation: the scene drawn at a state, and the paper's time plots.

Reproduces Yoshida, Arimoto, Tahara 2009, Fig. 5 (snapshots) and Figs 6-14 (time
histories). Frames as in ``grasping_sym.model.planar`` (``docs/conventions.md`` section 1):

- finger joint 1 at the origin, joint 2 at ``l11 (sin q1, cos q1)``, fingertip centre
  ``O01 = joint2 + l12 (sin(q1+q2), cos(q1+q2))``;
- fingertip contour point ``O01 + Rot(pi/2 - q1 - q2) c0(u0)``;
- object contour point ``Om + Rot(-theta) c1(u1)``.

Figures are made with ``matplotlib.figure.Figure`` on the Agg canvas: no pyplot state, no
window, safe in tests and on headless machines. All lengths are metres, angles radians.
"""
from __future__ import annotations

import logging
import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from matplotlib.axes import Axes
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure

from grasping_sym.model.planar import PlanarFingerScene
from grasping_sym.runtime.result import SimulationResult

log = logging.getLogger(__name__)

#: Samples per contour when drawing it over its whole domain.
CONTOUR_SAMPLES = 400

FINGER_COLOR = "tab:blue"
OBJECT_COLOR = "tab:red"
CONTACT_COLOR = "black"
ZERO_STYLE = {"color": "0.4", "linestyle": "--", "linewidth": 1.0}


# ---------------------------------------------------------------------------- geometry
def _rot(a: float) -> np.ndarray:
    """``Rot(a) = [[cos a, -sin a], [sin a, cos a]]``."""
    c, s = math.cos(a), math.sin(a)
    return np.array([[c, -s], [s, c]])


@dataclass(frozen=True)
class Pose:
    """Inertial positions (m) of the drawable parts of a scene at one state."""

    joint1: np.ndarray       # (2,)
    joint2: np.ndarray       # (2,)
    o01: np.ndarray          # fingertip centre, (2,)
    pivot: np.ndarray        # Om, (2,)
    fingertip: np.ndarray    # whole fingertip contour, (n, 2)
    object: np.ndarray       # whole object contour, (n, 2)
    contact_finger: np.ndarray  # contact point on the fingertip, (2,)
    contact_object: np.ndarray  # contact point on the object, (2,)


@dataclass(frozen=True)
class Finger:
    """What draws one finger of a scene: its joint states, base, link lengths, fingertip
    contour and the states of its contact parameters (fingertip, object)."""

    joints: tuple[str, str]
    base: tuple[float, float]
    lengths: tuple[float, float]
    fingertip: object
    contact: tuple[str, str]


def fingers(scene: PlanarFingerScene) -> list[Finger]:
    """Finger 1 (joints at the origin) and the scene's extra fingers, in order."""
    if not scene.extra_fingers:
        contact = ("s", "s") if scene.shared_parameter else ("u0", "u1")
        return [Finger(("q1", "q2"), (0.0, 0.0), (scene.params["l11"], scene.params["l12"]),
                       scene.fingertip, contact)]
    out = [Finger(("q11", "q12"), (0.0, 0.0), (scene.params["l11"], scene.params["l12"]),
                  scene.fingertip, ("u0_1", "u1_1"))]
    for i, f in enumerate(scene.extra_fingers, start=2):
        out.append(Finger((f"q{i}1", f"q{i}2"), tuple(f.base), tuple(f.lengths), f.fingertip,
                          (f"u0_{i}", f"u1_{i}")))
    return out


def contact_parameters(scene: PlanarFingerScene, x: Sequence[float], finger: int = 0) -> tuple[float, float]:
    """``(u0, u1)``: the contact parameters on the fingertip and object contours at ``x`` (of
    finger ``finger``, 0 the first)."""
    names = scene.state_names
    a, b = fingers(scene)[finger].contact
    return float(x[names.index(a)]), float(x[names.index(b)])


def pose(scene: PlanarFingerScene, x: Sequence[float]) -> Pose:
    """Inertial positions of links, contours, pivot and contact at the state ``x`` (finger 1;
    ``poses`` gives every finger's).

    ``x`` is ordered as ``scene.state_names``.
    """
    return poses(scene, x)[0]


def poses(scene: PlanarFingerScene, x: Sequence[float]) -> list[Pose]:
    """``pose`` of every finger (each with the same object and pivot)."""
    return [_finger_pose(scene, x, k) for k in range(len(fingers(scene)))]


def _finger_pose(scene: PlanarFingerScene, x: Sequence[float], k: int) -> Pose:
    names = scene.state_names
    fg = fingers(scene)[k]
    theta = float(x[names.index("theta")])
    q1, q2 = (float(x[names.index(j)]) for j in fg.joints)
    l11, l12 = fg.lengths
    joint1 = np.asarray(fg.base, dtype=float)
    joint2 = joint1 + l11 * np.array([math.sin(q1), math.cos(q1)])
    o01 = joint2 + l12 * np.array([math.sin(q1 + q2), math.cos(q1 + q2)])
    om = (np.array([float(x[names.index("x")]), float(x[names.index("y")])]) if scene.free
          else np.asarray(scene.pivot, dtype=float))
    r_finger = _rot(math.pi / 2 - q1 - q2)
    r_object = _rot(-theta)

    def local(curve, t) -> np.ndarray:
        t = np.atleast_1d(np.asarray(t, dtype=float))
        ev = curve.evaluate(t)
        return np.column_stack([np.broadcast_to(ev["x"], t.shape),
                                np.broadcast_to(ev["y"], t.shape)])

    t0 = np.linspace(*fg.fingertip.domain, CONTOUR_SAMPLES)
    t1 = np.linspace(*scene.object.domain, CONTOUR_SAMPLES)
    u0, u1 = contact_parameters(scene, x, k)
    fingertip = o01 + local(fg.fingertip, t0) @ r_finger.T
    obj = om + local(scene.object, t1) @ r_object.T
    c_f = o01 + local(fg.fingertip, u0)[0] @ r_finger.T
    c_o = om + local(scene.object, u1)[0] @ r_object.T
    return Pose(joint1, joint2, o01, om, fingertip, obj, c_f, c_o)


def draw_scene(ax: Axes, scene: PlanarFingerScene, x: Sequence[float]) -> Pose:
    """Draw the finger, fingertip, object, pivot and contact at the state ``x`` on ``ax``.

    Links are thick lines with joint markers; both contours are drawn over their whole
    domains in the inertial frame; ``Om``, ``O01`` and the contact point are marked. The
    axes get equal aspect and labels in metres. Returns the computed ``Pose``.
    """
    every = poses(scene, x)
    many = len(every) > 1
    for k, (p, fg) in enumerate(zip(every, fingers(scene))):
        first = k == 0
        links = np.vstack([p.joint1, p.joint2, p.o01])
        ax.plot(links[:, 0], links[:, 1], "-", color="0.35", linewidth=5, solid_capstyle="round",
                zorder=2, label="finger links" if first else None)
        ax.plot(links[:2, 0], links[:2, 1], "o", color="0.1", markersize=7, zorder=3)
        ax.plot(*p.fingertip.T, "-", color=FINGER_COLOR, linewidth=2, zorder=4,
                label=(f"fingertip{'s' if many else ''} ({fg.fingertip.name}"
                       + (", ..." if many else "") + ")") if first else None)
        ax.plot(*p.o01, "s", color=FINGER_COLOR, markersize=6, zorder=5)
        ax.annotate(f"$O_{{0{k + 1}}}$" if many else "$O_{01}$", p.o01, textcoords="offset points",
                    xytext=(-18, 6))
        ax.plot(*p.contact_object, "o", markerfacecolor="none", markeredgecolor=CONTACT_COLOR,
                markersize=10, markeredgewidth=1.5, zorder=6,
                label=("contact points" if many else "contact point") if first else None)
        ax.plot(*p.contact_finger, ".", color=CONTACT_COLOR, markersize=5, zorder=7)
    p = every[0]
    ax.plot(*p.object.T, "-", color=OBJECT_COLOR, linewidth=2, zorder=4,
            label=f"object ({scene.object.name})")
    ax.plot(*p.pivot, "o" if scene.free else "P", color=OBJECT_COLOR, markersize=9 - 3 * scene.free,
            zorder=5)
    ax.annotate("$O_m$", p.pivot, textcoords="offset points", xytext=(6, 6))
    ax.set_aspect("equal", adjustable="datalim")
    ax.set_xlabel("x [m]")
    ax.set_ylabel("y [m]")
    ax.grid(True, linewidth=0.3)
    return p


# ---------------------------------------------------------------------------- figures
def _new_figure(width: float, height: float) -> Figure:
    fig = Figure(figsize=(width, height), layout="constrained")
    FigureCanvasAgg(fig)
    return fig


def _state_at(result: SimulationResult, t: float) -> tuple[float, np.ndarray]:
    i = int(np.argmin(np.abs(result.t - t)))
    return float(result.t[i]), result.x[i]


def _fmt_time(t: float) -> str:
    return f"{t:g}"


def snapshot_figure(scene: PlanarFingerScene, result: SimulationResult,
                    times: Sequence[float] | None = None) -> Figure:
    """Side-by-side drawings of the scene at ``times`` (s), like the paper's Fig. 5.

    Default ``times`` are the first and last sample: "(a) initial pose", "(b) after T s".
    Every panel gets the same axis limits so motion is comparable.
    """
    if times is None:
        times = (float(result.t[0]), float(result.t[-1]))
    fig = _new_figure(5.0 * len(times), 5.0)
    axes = fig.subplots(1, len(times), squeeze=False)[0]
    states = []
    for k, (ax, t) in enumerate(zip(axes, times)):
        t_i, x = _state_at(result, t)
        draw_scene(ax, scene, x)
        states.append(x)
        label = "initial pose" if t_i == result.t[0] else f"after {_fmt_time(t_i)} s"
        ax.set_title(f"({chr(ord('a') + k)}) {label}")
    lo, hi = motion_limits(scene, states)
    for ax in axes:
        ax.set_xlim(lo[0], hi[0])
        ax.set_ylim(lo[1], hi[1])
        ax.set_aspect("equal", adjustable="box")
    # the legend below the panels, where it covers no finger
    handles, labels = axes[0].get_legend_handles_labels()
    fig.legend(handles, labels, loc="outside lower center", ncols=min(len(labels), 4), fontsize=8)
    fig.suptitle(f"{scene.name}: motion of pinching a 2-D object")
    return fig


def motion_limits(scene: PlanarFingerScene, states) -> tuple[np.ndarray, np.ndarray]:
    """Axis limits ``(lo, hi)`` (m) that hold every finger, contour and the pivot at each of
    ``states``, with a margin of 5 %: the same in every panel or frame."""
    pts = np.vstack([np.vstack([p.joint1[None], p.fingertip, p.object, p.pivot[None]])
                     for x in states for p in poses(scene, x)])
    lo, hi = pts.min(axis=0), pts.max(axis=0)
    pad = 0.05 * float(np.max(hi - lo))
    return lo - pad, hi + pad


@dataclass(frozen=True)
class TimePlot:
    """One of the paper's time figures: which quantity, its label and unit."""

    key: str
    paper_fig: int
    title: str
    ylabel: str
    curves: Callable[[PlanarFingerScene, SimulationResult], list[tuple[str, np.ndarray]] | None]


def _per_finger(names, name: str, n: int) -> list[tuple[int, str]]:
    """``[(finger, key)]``: ``name`` itself, or its per-finger keys ``name1`` / ``name_1`` ..."""
    if name in names:
        return [(0, name)]
    return [(i, k) for i in range(1, n + 1) for k in (f"{name}{i}", f"{name}_{i}") if k in names]


def _output(name: str, label: str, scale: Callable | None = None):
    def get(scene, result):
        keys = _per_finger(result.outputs, name, len(fingers(scene)))
        if not keys:
            return None
        k = scale(scene, result) if scale else 1.0
        return [(label if i == 0 else f"{label}, finger {i}", np.asarray(result.outputs[key], float) * k)
                for i, key in keys]
    return get


def _state(name: str, label: str):
    """A joint speed ``dq1`` / ``dq2``: finger 1's, or each finger's (``dq11``, ``dq21``, ...)."""
    def get(scene, result):
        if name in result.state_names:
            return [(label, result[name])]
        if not name.startswith("dq"):
            return None
        j = name[2:]
        keys = [(i, f"dq{i}{j}") for i in range(1, len(fingers(scene)) + 1)]
        curves = [(f"{label}, finger {i}", result[k]) for i, k in keys if k in result.state_names]
        return curves or None
    return get


def _contact_params(scene, result):
    if "s" in result.state_names:
        return [("$s$", result["s"])]
    curves = []
    for i, fg in enumerate(fingers(scene), start=1):
        for k in dict.fromkeys(fg.contact):
            if k in result.state_names:
                tag = f"${k[0]}_{k[1]}$" + (f", finger {i}" if len(fingers(scene)) > 1 else "")
                curves.append((tag, result[k]))
    return curves or None


def _fd_over_r(scene: PlanarFingerScene, result: SimulationResult) -> float:
    fd = result.params.get("fd", scene.params["fd"])
    r = result.params.get("r", scene.params["r"])
    return fd / r


#: The paper's Figs 6-14, in order.
TIME_PLOTS: tuple[TimePlot, ...] = (
    TimePlot("delta_f", 6, r"$\Delta f$", r"$\Delta f$ [N]", _output("delta_f", r"$\Delta f$")),
    TimePlot("delta_lam", 7, r"$\Delta\lambda$", r"$\Delta\lambda$ [N]",
             _output("delta_lam", r"$\Delta\lambda$")),
    TimePlot("N1", 8, r"$(f_d/r)\,N_1$", r"$(f_d/r)\,N_1$ [N m]",
             _output("N1", r"$(f_d/r)\,N_1$", _fd_over_r)),
    TimePlot("s", 9, "contact parameter", "$s$ [m]", _contact_params),
    TimePlot("dq1", 10, r"$\dot q_1$", r"$\dot q_1$ [rad/s]", _state("dq1", r"$\dot q_1$")),
    TimePlot("dq2", 11, r"$\dot q_2$", r"$\dot q_2$ [rad/s]", _state("dq2", r"$\dot q_2$")),
    TimePlot("dtheta", 12, r"$\dot\theta$", r"$\dot\theta$ [rad/s]",
             _state("dtheta", r"$\dot\theta$")),
    TimePlot("R", 13, "$R$ (rolling constraint)", "$R$ [m]", _output("R", "$R$")),
    TimePlot("Q", 14, "$Q$ (contact constraint)", "$Q$ [m]", _output("Q", "$Q$")),
)


def _param_unit(curve) -> str:
    return "m" if curve.unit_speed else "curve parameter"


def _draw_time_plot(ax: Axes, plot: TimePlot, curves, scene, result) -> None:
    ax.set_xlabel("time [s]")
    ax.set_title(f"Fig. {plot.paper_fig}: {plot.title}")
    ax.set_xlim(result.t[0], result.t[-1])
    ax.grid(True, linewidth=0.3)
    if plot.key == "s" and len(curves) == 2 and not scene.extra_fingers:
        # two-parameter scene: u0 (fingertip) and u1 (object) may differ in unit and scale
        (l0, y0), (l1, y1) = curves
        h0 = ax.plot(result.t, y0, linewidth=1.5, color="tab:blue", label=l0)
        ax.set_ylabel(f"$u_0$ [{_param_unit(scene.fingertip)}]", color="tab:blue")
        ax.axhline(0.0, **ZERO_STYLE)
        twin = ax.twinx()
        h1 = twin.plot(result.t, y1, linewidth=1.5, color="tab:orange", label=l1)
        twin.set_ylabel(f"$u_1$ [{_param_unit(scene.object)}]", color="tab:orange")
        zero = ax.plot([], [], label="The value of zero ($u_0$)", **ZERO_STYLE)
        ax.legend(handles=h0 + h1 + zero, fontsize=8, loc="best")
        return
    for label, y in curves:
        ax.plot(result.t, y, linewidth=1.5, label=label)
    ax.axhline(0.0, label="The value of zero", **ZERO_STYLE)
    ax.set_ylabel(plot.ylabel)
    ax.legend(fontsize=8, loc="best")


def time_figures(scene: PlanarFingerScene, result: SimulationResult,
                 out_dir: Path | str) -> list[Path]:
    """Write one PNG per paper figure 6-14 and an overview grid into ``out_dir``.

    Files: ``fig06_delta_f.png`` ... ``fig14_Q.png`` and ``overview.png``. A quantity
    whose output the model did not generate is skipped with a log message.
    """
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    paths: list[Path] = []
    available: list[tuple[TimePlot, list]] = []
    for plot in TIME_PLOTS:
        curves = plot.curves(scene, result)
        if not curves:
            log.warning("skipping Fig. %d (%s): the model did not generate it (build the scene "
                        "with outputs=(...) including %r)", plot.paper_fig, plot.key, plot.key)
            continue
        available.append((plot, curves))
        fig = _new_figure(6.0, 4.0)
        _draw_time_plot(fig.add_subplot(), plot, curves, scene, result)
        path = out_dir / f"fig{plot.paper_fig:02d}_{plot.key}.png"
        fig.savefig(path, dpi=120)
        paths.append(path)
    path = constraints_log_figure(scene, result, out_dir)
    if path is not None:
        paths.append(path)
    if available:
        ncols = 3
        nrows = math.ceil(len(available) / ncols)
        fig = _new_figure(5.0 * ncols, 3.4 * nrows)
        axes = fig.subplots(nrows, ncols, squeeze=False).ravel()
        for ax, (plot, curves) in zip(axes, available):
            _draw_time_plot(ax, plot, curves, scene, result)
        for ax in axes[len(available):]:
            ax.set_visible(False)
        fig.suptitle(f"{scene.name}: {result.method}, t = 0 .. {_fmt_time(result.t[-1])} s")
        path = out_dir / "overview.png"
        fig.savefig(path, dpi=100)
        paths.append(path)
    return paths


def constraints_log_figure(scene: PlanarFingerScene, result: SimulationResult,
                           out_dir: Path) -> Path | None:
    """``constraints_log.png``: |Q| and |R| of every contact on a log scale (the paper's Figs 13
    and 14 are linear, where rounding-level residuals are a flat line); None without them."""
    curves = [(f"|{c[0].strip('$')}|" + c[0][len(c[0].split(',')[0]):], y)
              for key in ("Q", "R") for c, y in ((c, c[1]) for c in (_output(key, key)(scene, result) or []))]
    if not curves:
        return None
    fig = _new_figure(6.4, 4.0)
    ax = fig.add_subplot()
    for label, y in curves:
        ax.semilogy(result.t, np.maximum(np.abs(y), 1e-20), linewidth=1.0, label=label)
    ax.set_xlabel("time [s]")
    ax.set_ylabel("contact constraint [m] (log)")
    ax.set_xlim(result.t[0], result.t[-1])
    ax.grid(True, which="both", linewidth=0.3)
    ax.set_title("|Q|, |R| on a log scale")
    ax.legend(fontsize=8, loc="best")
    path = out_dir / "constraints_log.png"
    fig.savefig(path, dpi=120)
    return path


def write_figures(scene: PlanarFingerScene, result: SimulationResult,
                  out_dir: Path | str) -> list[Path]:
    """Write the snapshot figure (``fig05_snapshots.png``) and all time figures."""
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    fig = snapshot_figure(scene, result)
    path = out_dir / "fig05_snapshots.png"
    fig.savefig(path, dpi=120)
    return [path, *time_figures(scene, result, out_dir)]
