"""A free 2D body on a line of the world, in its three contact modes (``model.body_line``;
``docs/conventions.md`` section 14, MODELS.md section 5), as CasADi SX: the 2D counterpart of
``derive.body_plane``.

With ``R = Rot(-theta)`` (section 1: a body point is ``Om + R c(u)``), the body's angular
velocity (counterclockwise) is ``w = -theta'``, and with the contact force ``F`` (world, on
the body at its support point ``r_c = Om + R S``, ``S = c(u)``):

    M Om'' = M g + F,    I w' = (R S) x F    (the scalar cross product a_x b_y - a_y b_x)

The support point is kept where the body's outward normal is ``-n``: with ``phi = (R T(u)).n``
(``T`` the contour's unit tangent; ``phi = 0`` there), ``phi' = -gain phi``. The contact
point's velocity is ``v_c = Om' + w perp(R S)`` (``perp(a) = (-a_y, a_x)``), the gap
``g = n.(r_c - w0)`` has ``g' = n.v_c``, and along the motion ``d/dt v_c = K F + b``, ``K``
the contact's inverse effective mass ``1/M I + perp(R S) perp(R S)^T / I`` (from CasADi's
Jacobian of the expression), ``b`` the rest. The modes choose ``F``:

- rolling (mode 0): ``d/dt v_c = -2 gain v_c - gain^2 g n`` (both rows), ``F = K^-1 (...)``;
- sliding (mode 1): ``F = f (n - mu d t)``, ``t = (-n_y, n_x)``, ``d = sign(v_t)`` while
  ``v_t slip > 0``, else the parameter ``slip`` (+1 or -1), ``f`` from the normal row; its
  coefficient ``n.K(n - mu d t)`` (``painleve``) must stay > 0;
- separated (mode 2): ``F = 0``.

The rolling solution's forces are outputs in every mode (the rolling-consistency test of a
stop).
"""
from __future__ import annotations

import casadi as ca
import numpy as np
import sympy as sp

from grasping_sym.derive.body_plane import translation_sx
from grasping_sym.errors import InvalidSceneError
from grasping_sym.model.body import TIME
from grasping_sym.symbolic.translate import SympyToCasadi


def _perp(a):
    return ca.vertcat(-a[1], a[0])


def _cross(a, b):
    return a[0] * b[1] - a[1] * b[0]


def contour_sx(contour, u) -> tuple[ca.SX, ca.SX]:
    """``(c(u), T(u))``: the contour's point and unit tangent (body frame) as SX."""
    tr = SympyToCasadi({contour.param: u})
    S = ca.vertcat(tr(contour.x), tr(contour.y))
    T = ca.vertcat(tr(contour.tangent[0]), tr(contour.tangent[1]))
    return S, T


def derive_body_line(scene) -> dict:
    """``{"x", "p", "t", "xdot", "outputs", "reads_time"}`` of a ``model.body_line.LineBodyScene``."""
    x = ca.SX.sym("x", 7)
    p = ca.SX.sym("p", len(scene.p_names))
    t = ca.SX.sym("t")
    mode, mu, slip = p[0], p[1], p[2]
    pos, th, vel, dth, u = x[0:2], x[2], x[3:5], x[5], x[6]
    m, inertia = float(scene.mass), float(scene.inertia)
    n = ca.DM(scene.line_normal)
    tan = ca.DM(scene.tangent)
    w0 = ca.DM(scene.line_point)
    g_vec = ca.DM(scene.gravity)
    gain = float(scene.gain)

    c, s = ca.cos(th), ca.sin(th)
    R = ca.vertcat(ca.horzcat(c, s), ca.horzcat(-s, c))      # Rot(-theta)
    S, T = contour_sx(scene.contour, u)
    phi = ca.dot(R @ T, n)
    u_dot = (-gain * phi - ca.jacobian(phi, th) * dth) / ca.jacobian(phi, u)

    w = -dth
    rS = R @ S
    r_c = pos + rS
    v_c = vel + w * _perp(rS)
    moving = scene.line_motion is not None
    if moving:  # a translating line: its point, velocity and acceleration at t
        d, d_dot, d_ddot = translation_sx(scene.line_motion, t)
        w0 = w0 + d
        v_c = v_c - d_dot   # relative to the line's material point
    gap = ca.dot(n, r_c - w0)
    vn = ca.dot(n, v_c)
    vt = ca.dot(tan, v_c)

    F = ca.SX.sym("F", 2)
    vel_dot_F = g_vec + F / m
    w_dot_F = _cross(rS, F) / inertia
    # d/dt (R S) = w perp(R S) + R S_u u'
    rS_dot = w * _perp(rS) + R @ ca.jacobian(S, u) * u_dot
    acc = vel_dot_F + w_dot_F * _perp(rS) + w * _perp(rS_dot)
    if moving:  # minus the line's acceleration (a translation: the same at every point)
        acc = acc - d_ddot
    K = ca.jacobian(acc, F)
    b = ca.substitute(acc, F, ca.DM.zeros(2))

    target = -2 * gain * v_c - gain**2 * gap * n
    F_roll = ca.solve(K, target - b)
    d = ca.if_else(vt * slip > 0, ca.sign(vt), slip)
    dirn = n - mu * d * tan
    painleve = ca.dot(n, K @ dirn)
    f_slide = (-2 * gain * vn - gain**2 * gap - ca.dot(n, b)) / painleve
    F_act = ca.if_else(mode < 0.5, F_roll, ca.if_else(mode < 1.5, f_slide * dirn, ca.DM.zeros(2)))

    vel_dot = ca.substitute(vel_dot_F, F, F_act)
    dth_dot = -ca.substitute(w_dot_F, F, F_act)
    xdot = ca.vertcat(vel, dth, vel_dot, dth_dot, u_dot)

    f_act, ft_act = ca.dot(n, F_act), ca.dot(tan, F_act)
    kinetic = 0.5 * m * ca.dot(vel, vel) + 0.5 * inertia * dth**2
    potential = -m * ca.dot(g_vec, pos)
    out = {"gap": gap, "normal_speed": vn, "normal_force": f_act, "tangential_force": ca.fabs(ft_act),
           "Ft": ft_act, "cone_ratio": ca.fabs(ft_act) / ca.fmax(f_act, 1e-300),
           "slip_speed": ca.fabs(vt), "vt": vt,
           "rolling_normal_force": ca.dot(n, F_roll),
           "rolling_tangential_force": ca.fabs(ca.dot(tan, F_roll)), "rolling_Ft": ca.dot(tan, F_roll),
           "painleve": painleve, "kinetic_energy": kinetic, "potential_energy": potential,
           "energy": kinetic + potential,
           "rc_x": rS[0], "rc_y": rS[1], "vc_x": v_c[0], "vc_y": v_c[1]}
    for i in range(2):
        for j in range(2):
            out[f"K_{i}{j}"] = K[i, j]
    return {"x": x, "p": p, "t": t, "xdot": xdot, "outputs": out, "reads_time": moving}


def start_state(scene) -> tuple[np.ndarray, dict]:
    """The body's start and what was solved: the support point ``u`` where its outward normal
    is ``-n`` (Newton from ``scene.support``), the body put on the line (``start="contact"``:
    moved along ``n``, the contact point's normal speed removed)."""
    n = np.asarray(scene.line_normal, float)
    th = float(scene.theta)
    u0, S0 = support_point(scene.contour, th, n, scene.support)
    c, s = np.cos(th), np.sin(th)
    rS = np.array([c * S0[0] + s * S0[1], -s * S0[0] + c * S0[1]])
    pos = np.asarray(scene.position, float)
    vel = np.asarray(scene.velocity, float)
    dth = float(scene.dtheta)
    if scene.start == "contact":
        v_line = np.zeros(2) if scene.line_motion is None else np.array(
            [float(sp.diff(e, TIME).subs(TIME, 0)) for e in scene.line_motion])
        pos = pos - np.dot(n, pos + rS - np.asarray(scene.line_point)) * n
        vel = vel - np.dot(n, vel - dth * np.array([-rS[1], rS[0]]) - v_line) * n
    x0 = np.array([*pos, th, *vel, dth, u0])
    return x0, {"support": float(u0)}


def support_point(contour, theta: float, n: np.ndarray, guess: float) -> tuple[float, np.ndarray]:
    """``(u, S)``: the contour's point whose outward normal, the body turned by ``theta``, is
    ``-n`` (Newton's method from ``guess``); a named error where there is none near."""
    u = ca.SX.sym("u")
    S, T = contour_sx(contour, u)
    c, s = np.cos(theta), np.sin(theta)
    R = ca.DM([[c, s], [-s, c]])
    resid = ca.dot(R @ T, ca.DM(n))
    solver = ca.rootfinder("support", "newton", ca.Function("r", [u], [resid]),
                           {"abstol": 1e-15, "max_iter": 100})
    u0 = float(solver(guess))
    S0, T0 = (np.ravel(v.full()) for v in ca.Function("geo", [u], [S, T])(u0))
    normal = R.full() @ np.array([-T0[1], T0[0]])        # outward: left of a clockwise contour
    if not (np.dot(normal, n) < -1 + 1e-12 and contour.in_domain(u0)):
        raise InvalidSceneError([f"no support point near support = {guess}: the contour's normal at "
                                 f"u = {u0:.6g} faces {normal}, not -line_normal (or lies outside its "
                                 f"domain {contour.domain}); give a guess (support=u) where the contour "
                                 "faces the line"])
    return u0, S0
