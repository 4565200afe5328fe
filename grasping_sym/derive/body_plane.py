"""A free rigid body on a plane of the world, in its three contact modes (``model.body``;
``docs/conventions.md`` section 7, MODELS.md section 5), as CasADi SX.

With the contact force ``F`` (world, on the body at its support point ``r_c = p + R S(u, v)``):

    v' = g + F / m,   H omega' + omega x H omega = S x R^T F,   quat' = N(quat) omega

and the support point's coordinates kept where the body's normal is ``-n``
(``d/dt (R N(u, v)) = -gain (R N + n)``, solved on the tangent plane through the Weingarten map).
The contact point's velocity is ``v_c = v + R (omega x S)``, relative to the plane's material
point there (a turntable, ``plane_spin``: minus ``Omega n x (r_c - w0)``); the gap
``g = n . (r_c - w0)`` has ``g' = n . v_c``. Along the motion ``d/dt v_c = K F + b`` with ``K`` the contact's inverse
effective mass (``1/m I - R [S]x H^-1 [S]x R^T``, from CasADi's Jacobian of the expression) and
``b`` the rest. The modes choose ``F``:

- rolling (mode 0): ``d/dt v_c = -2 gain v_c - gain^2 g n`` (three rows), ``F = K^-1 (...)``;
- sliding (mode 1): ``F = f (n - mu d)``, ``d = v_t / |v_t|`` while ``v_t . slip > 0``, else
  the parameter ``slip`` (a slide from rest of the slip; past its stop, the continuation whose
  ``v_t . slip`` crosses 0), ``f`` from the normal row; its coefficient
  ``n . K (n - mu d)`` (``painleve``) must stay > 0. At the onset of a slide from rest of
  the slip in a radau run (the parameter ``slip_onset = s > 0``), ``d`` is the onset's instead
  (``derive.slip_onset``); the run sets ``s`` back to 0 where the output ``onset_left``
  reaches 0;
- separated (mode 2): ``F = 0``.

The rolling solution's forces are outputs in every mode (the rolling-consistency test of a
stop).
"""
from __future__ import annotations

import casadi as ca
import numpy as np
import sympy as sp

from grasping_sym import rotations
from grasping_sym.derive import slip_onset
from grasping_sym.derive.bodies3d import object_rotation, surface_sx
from grasping_sym.errors import InvalidSceneError
from grasping_sym.geometry.atlas import LAT as ATLAS_LAT
from grasping_sym.model.body import TIME
from grasping_sym.symbolic.translate import SympyToCasadi

#: Floor of ``|v_t|`` (m/s) in the slip's direction ``v_t / |v_t|`` (used only where
#: ``v_t . slip > 0``).
SLIP_ZERO = 1e-300


def translation_sx(motion, t: ca.SX) -> tuple[ca.SX, ca.SX, ca.SX]:
    """``(d, d', d'')``: a surface's translation ``motion`` (SymPy expressions of ``TIME``, as
    ``model.body.translation_of_time`` gives them) and its velocity and acceleration, as SX of
    ``t``."""
    d = SympyToCasadi({TIME: t})(sp.Matrix(motion))
    d_dot = ca.jacobian(d, t)
    return d, d_dot, ca.jacobian(d_dot, t)


def derive_body_plane(scene) -> dict:
    """``{"x", "p", "xdot", "outputs", "constraint"}`` of a ``model.body.BodyScene``."""
    x = ca.SX.sym("x", 15)
    p = ca.SX.sym("p", len(scene.p_names))
    t = ca.SX.sym("t")
    mode, mu, slip, onset = p[0], p[1], p[2:5], p[5]
    pos, quat, vel, om, uv = x[0:3], x[3:7], x[7:10], x[10:13], x[13:15]
    m = float(scene.mass)
    H = ca.DM(np.asarray(scene.inertia))
    Hinv = ca.DM(np.linalg.inv(np.asarray(scene.inertia)))
    n = ca.DM(scene.plane_normal)
    w0 = ca.DM(scene.plane_point)
    g_vec = ca.DM(scene.gravity)
    gain = float(scene.gain)

    R, quat_dot, _ = object_rotation(quat, om)
    chart = p[scene.p_names.index("chart")] if "chart" in scene.p_names else None
    s = surface_sx(scene.surface, uv[0], uv[1], extra=True, chart=chart)
    S, N, Tm = s["S"], s["n"], s["Tm"]
    N_uv = ca.jacobian(N, uv)
    # the support point: d/dt (R N) = R (om x N + N_uv uv') = -gain (R N + n)
    rhs_uv = -ca.cross(om, N) - gain * (N + R.T @ n)
    uv_dot = ca.solve(Tm.T @ N_uv, Tm.T @ rhs_uv)

    r_c = pos + R @ S
    v_c = vel + R @ ca.cross(om, S)
    spin = float(scene.plane_spin)
    if spin:  # a turntable: the plane turns about its normal through w0 at spin rad/s
        W = spin * n
        v_c = v_c - ca.cross(W, r_c - w0)   # relative to the plane's material point
    moving = scene.plane_motion is not None
    if moving:  # a translating plane: its point, velocity and acceleration at t
        d, d_dot, d_ddot = translation_sx(scene.plane_motion, t)
        w0 = w0 + d
        v_c = v_c - d_dot   # relative to the plane's material point
    gap = ca.dot(n, r_c - w0)
    vn = ca.dot(n, v_c)
    v_t = v_c - vn * n

    F = ca.SX.sym("F", 3)
    om_dot_F = Hinv @ (ca.cross(S, R.T @ F) - ca.cross(om, H @ om))
    vel_dot_F = g_vec + F / m
    acc = vel_dot_F + R @ (ca.cross(om_dot_F, S) + ca.cross(om, ca.cross(om, S))) \
        + R @ ca.cross(om, Tm @ uv_dot)
    if spin:  # minus the plane's velocity's rate along the moving contact point
        acc = acc - ca.cross(W, vel + R @ ca.cross(om, S) + R @ (Tm @ uv_dot))
    if moving:  # minus the plane's acceleration (a translation: the same at every point)
        acc = acc - d_ddot
    K = ca.jacobian(acc, F)
    b = ca.substitute(acc, F, ca.DM.zeros(3))

    # rolling: all three rows
    target = -2 * gain * v_c - gain**2 * gap * n
    F_roll = ca.solve(K, target - b)
    # sliding: the normal row, Coulomb's force along the slip
    speed = ca.norm_2(v_t)
    # the slip's direction; past a stop (v_t . slip <= 0) and from rest of the slip, the
    # parameter's: the slide's continuation along it, where the stop's witness v_t . slip
    # crosses 0 with the slope it had (what locating the stop integrates)
    d = ca.if_else(ca.dot(v_t, slip) > 0, v_t / ca.fmax(speed, SLIP_ZERO), slip)
    # at a slide's onset from rest of the slip, a direction continuous in v_t (derive.slip_onset)
    d = slip_onset.direction(v_t, slip, onset, d)
    dirn = n - mu * d
    painleve = ca.dot(n, K @ dirn)
    f_slide = (-2 * gain * vn - gain**2 * gap - ca.dot(n, b)) / painleve
    F_slide = f_slide * dirn
    F_act = ca.if_else(mode < 0.5, F_roll, ca.if_else(mode < 1.5, F_slide, ca.DM.zeros(3)))

    vel_dot = ca.substitute(vel_dot_F, F, F_act)
    om_dot = ca.substitute(om_dot_F, F, F_act)
    xdot = ca.vertcat(vel, quat_dot, vel_dot, om_dot, uv_dot)

    f_act = ca.dot(n, F_act)
    Ft = F_act - f_act * n
    f_roll = ca.dot(n, F_roll)
    Ft_roll = F_roll - f_roll * n
    ft = ca.norm_2(Ft)
    kinetic = 0.5 * m * ca.dot(vel, vel) + 0.5 * ca.dot(om, H @ om)
    potential = -m * ca.dot(g_vec, pos)
    out = {"gap": gap, "normal_speed": vn, "normal_force": f_act, "tangential_force": ft,
           "cone_ratio": ft / ca.fmax(f_act, 1e-300),
           "slip_speed": speed, "onset_left": slip_onset.left(v_t, slip, onset),
           "rolling_normal_force": f_roll, "rolling_tangential_force": ca.norm_2(Ft_roll),
           "painleve": painleve, "kinetic_energy": kinetic, "potential_energy": potential,
           "energy": kinetic + potential,
           # |R N + n|: 0 where the support point (u, v) faces the plane (its rate keeps it so)
           "support_facing": ca.norm_2(R @ N + n)}
    for k, c in enumerate("xyz"):
        out[f"vt_{c}"] = v_t[k]
        out[f"Ft_{c}"] = Ft[k]
        out[f"rolling_Ft_{c}"] = Ft_roll[k]
        out[f"rc_{c}"] = (R @ S)[k]
        out[f"vc_{c}"] = v_c[k]
    for i in range(3):
        for j in range(3):
            out[f"K_{i}{j}"] = K[i, j]
    return {"x": x, "p": p, "t": t, "xdot": xdot, "outputs": out, "reads_time": moving}


def start_state(scene) -> tuple[np.ndarray, dict]:
    """The body's start and what was solved: the support point ``(u, v)`` where its normal is
    ``-n`` (Newton from ``scene.support``), the body put on the plane (``start="contact"``:
    moved along ``n``, the contact point's normal speed removed)."""
    R0 = np.asarray(scene.rotation, float)
    n = np.asarray(scene.plane_normal, float)
    uv0, S0, chart = support_in_a_chart(scene.surface, R0, n, scene.support)
    pos = np.asarray(scene.position, float)
    om = np.asarray(scene.omega, float)
    vel = np.asarray(scene.velocity, float)
    if scene.start == "contact":
        v_plane = np.zeros(3) if scene.plane_motion is None else np.array(
            [float(sp.diff(e, TIME).subs(TIME, 0)) for e in scene.plane_motion])
        pos = pos - np.dot(n, pos + R0 @ S0 - np.asarray(scene.plane_point)) * n
        vel = vel - np.dot(n, vel + R0 @ np.cross(om, S0) - v_plane) * n
    x0 = np.concatenate([pos, rotations.quaternion(R0), vel, om, uv0])
    charts = {"charts": {"chart": chart}} if getattr(scene.surface, "atlas", None) is not None else {}
    return x0, {"support": [float(v) for v in uv0], **charts}


def support_point(surface, R: np.ndarray, n: np.ndarray, guess) -> tuple[np.ndarray, np.ndarray]:
    """``((u, v), S)``: the point of ``surface`` (body frame, turned by ``R``) whose outward
    normal is ``-n`` (Newton's method from ``guess``); a named error where there is none near."""
    found = _support_in(surface, R, n, guess)
    if found is None:
        raise InvalidSceneError([f"no support point near support = {tuple(guess)}: Newton's method from it "
                                 "finds no point whose normal faces -plane_normal; give a guess "
                                 "(support=(u, v)) where the surface faces the plane"])
    return found


def _support_in(surface, R: np.ndarray, n: np.ndarray, guess):
    """``support_point`` on ``surface`` from ``guess``, or None where Newton's method ends
    elsewhere (a point facing the plane's side, or not finite)."""
    uv = ca.SX.sym("uv", 2)
    s = surface_sx(surface, uv[0], uv[1], extra=True)
    resid = s["Tm"].T @ (s["n"] + ca.DM(R.T @ n))
    solver = ca.rootfinder("support", "newton", ca.Function("r", [uv], [resid]),
                           {"abstol": 1e-15, "max_iter": 100, "error_on_fail": False,
                            "show_eval_warnings": False})  # a chart's pole: NaN, refused below
    uv0 = np.ravel(solver(ca.DM(guess)).full())
    if not np.isfinite(uv0).all():
        return None
    S0, N0 = (np.ravel(v.full()) for v in ca.Function("geo", [uv], [s["S"], s["n"]])(uv0))
    if not (np.isfinite(S0).all() and np.dot(R @ N0, n) < -1 + 1e-12):
        return None
    return uv0, S0


#: Longitudes from which the support point of a surface with an atlas is looked for in a
#: chart, after the user's guess (each at latitude 0: its chart's equator)
_LONGITUDES = (0.0, 0.5 * np.pi, np.pi, -0.5 * np.pi)


def support_in_a_chart(surface, R: np.ndarray, n: np.ndarray, guess) -> tuple[np.ndarray, np.ndarray, int]:
    """``((u, v), S, chart)``: ``support_point``, on a surface with an atlas
    (``geometry.atlas``) in chart 0 where it lies inside it (``guess`` in chart 0, then from
    its equator), else in chart 1 (from its equator): a start at chart 0's pole (a ball with
    ``atlas=True`` on a table below it) starts in chart 1. A surface without one: chart 0
    (``support_point``)."""
    if getattr(surface, "atlas", None) is None:
        return (*support_point(surface, R, n, guess), 0)
    for chart, shape in ((0, surface), (1, surface.atlas.second)):
        for start in ((tuple(guess),) if chart == 0 else ()) + tuple((u, 0.0) for u in _LONGITUDES):
            found = _support_in(shape, R, n, start)
            if found is not None and abs(found[0][1]) < ATLAS_LAT[1]:
                return found[0], found[1], chart
    raise InvalidSceneError([f"no support point of {surface.name!r} faces -plane_normal inside either chart "
                             f"of its atlas (from support = {tuple(guess)} and each chart's equator)"])
