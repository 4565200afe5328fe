"""The 2D finger-object model in its three contact modes (``model.planar_modes``;
``docs/conventions.md`` section 8, MODELS.md section 5), as CasADi SX.

The rolling model's pieces (``derive.planar.derive_template`` with separate contact
parameters ``u0``, ``u1``; M, h, the joint torques, ``C = (Q, R)``, the update law
``sigma`` and the tangency defect ``delta``) are translated with the scene's concrete contours;
the modes differ in which rows hold and how the contact parameters move. With
``gQ = dQ/dq``, ``gR = dR/dq`` (``u`` fixed), the contact force on the system is
``-(f gQ + lam gR)`` and the slip velocity (finger's material point relative to the
object's, along the object's tangent) is ``v_t = gR . v``.

- rolling (mode 0): the rolling model (both rows, ``u' = sigma``, Baumgarte gains ``gf, wf,
  gl, wl``): bit for bit the equations of ``derive.planar``;
- sliding (mode 1): the ``Q`` row only, ``lam = mu f d`` with ``d = sign(v_t)`` while
  ``v_t slip > 0``, else the parameter ``slip`` (+-1: a slide from rest of the slip);
  ``f`` from ``Q'' = -2 gf Q' - wf Q`` with coefficient ``painleve = Qa . M^-1 (gQ + mu d gR)``
  (``Qa = dQ'/dv``), which must stay > 0;
- separated (mode 2): no force.

Sliding and separated move the contact parameters so that they stay the pair of points on a
common normal (``R = 0``, ``delta = 0``): ``[dR/du; ddelta/du] u' = -[gR; ddelta/dq] v -
TRACK_GAIN [R; delta]``; then ``-Q`` is the gap between the contours (m, > 0 apart). Rolling
with the same state keeps both too, so a switch maps no state.
"""
from __future__ import annotations

import casadi as ca

from grasping_sym.derive.body_line import contour_sx
from grasping_sym.derive.body_plane import translation_sx
from grasping_sym.derive.planar import derive_template, has_gravity, parameter_values, torque_names
from grasping_sym.errors import InvalidSceneError
from grasping_sym.symbolic.contour_functions import OBJECT, fingertip_functions, leaf_expressions
from grasping_sym.symbolic.translate import SympyToCasadi

#: 1/s: the rate at which sliding and separated contact parameters return to the common
#: normal (``R = delta = 0`` are invariants of their law; this only damps round-off).
TRACK_GAIN = 200.0
#: Floor of ``f`` (N) in the cone ratio's denominator.
FORCE_FLOOR = 1e-300


def _setup(scene, torques):
    """The pieces both derivations share: the template of the scene's fingers, the symbols
    ``x``, ``p``, ``t``, the controller's torques ``tau`` (refused where they read the contact
    parameters) and whether it reads the time, the translator of the template's SymPy into
    CasADi with the scene's contours, and the stabilisation's gains ``(gf, gl, wf, wl)``."""
    base, k = scene.base, scene.n_fingers
    system = derive_template(False, has_gravity(base), k, base.free)
    names = scene.p_names
    x = ca.SX.sym("x", len(scene.state_names))
    p = ca.SX.sym("p", len(names))
    t = ca.SX.sym("t")
    nq = scene.n_speeds
    tau, _, timed = torques(scene, t, x, p)
    if ca.depends_on(tau, x[2 * nq:2 * nq + 2 * k]):
        raise InvalidSceneError(["the controller reads the contact parameters (u0, u1): with contact "
                                 "modes they are not one point while a contact slides or is open; "
                                 "write the law on the joints and the object (m.q, m.dq, m.tip, ...)"])
    values = parameter_values(base)
    symbols = {s: x[i] for i, s in enumerate(system.state)}
    taus = torque_names(k)
    for s in system.params:
        key = str(s)
        symbols[s] = tau[taus.index(key)] if key in taus else p[names.index(key)] if key in names \
            else ca.SX(values[key])
    leaves = dict(leaf_expressions(OBJECT, base.object))
    for i, tip in enumerate(base.fingertips, start=1):
        leaves.update(leaf_expressions(fingertip_functions(i), tip))
    by_name = {str(s): symbols[s] for s in system.params}
    gains = tuple(by_name[key] for key in ("gf", "gl", "wf", "wl"))
    return system, x, p, t, tau, timed, SympyToCasadi(symbols, leaves), gains


def derive_planar_modes(scene, torques) -> dict:
    """``{"x", "p", "t", "xdot", "outputs", "reads_time"}`` of a ``model.planar_modes`` scene;
    ``torques(scene, t, x, p) -> (tau, reads the object, reads the time)`` gives the joint
    torques of its controller (``assemble.controller.controller_torques``). Several fingers:
    ``derive_planar_fingers_modes``."""
    if scene.numbered:
        return derive_planar_fingers_modes(scene, torques)
    names = scene.p_names
    system, x, p, t, tau, timed, tr, (gf, gl, wf, wl) = _setup(scene, torques)
    mode, slip, mu = (p[names.index(k)] for k in ("mode", "slip", "mu"))

    M, h, F = tr(system.mass_matrix), tr(system.bias), tr(system.force)
    C = tr(system.constraint)
    sigma = tr(system.contact_rates)
    delta = tr(system.outputs["tangency_defect"])
    q, v, u = x[0:3], x[3:6], x[6:8]
    Q, R = C[0], C[1]
    gQ, gR = ca.jacobian(Q, q), ca.jacobian(R, q)
    A = ca.vertcat(gQ, gR)
    zero3 = ca.SX.zeros(3)

    # contact parameters on the common normal (sliding, separated)
    G = ca.vertcat(R, delta)
    u_geo = ca.solve(ca.jacobian(G, u), -ca.jacobian(G, q) @ v - TRACK_GAIN * G)

    free = ca.solve(M, F - h)
    MinvA = ca.solve(M, A.T)
    # rolling: the rolling model's rows (derive.system.assemble)
    Cdot = ca.jtimes(C, x, ca.vertcat(v, zero3, sigma))
    Ahat = ca.jacobian(Cdot, v)
    bhat = ca.jtimes(Cdot, x, ca.vertcat(v, zero3, sigma))
    lam_roll = ca.solve(Ahat @ MinvA, Ahat @ free + bhat + ca.vertcat(2 * gf, 2 * gl) * Cdot
                        + ca.vertcat(wf, wl) * C)
    a_roll = free - MinvA @ lam_roll
    # sliding: the normal row along the common normal's motion, Coulomb's lam = mu f d
    Qdot = ca.jtimes(Q, x, ca.vertcat(v, zero3, u_geo))
    Qa = ca.jacobian(Qdot, v)
    Qb = ca.jtimes(Qdot, x, ca.vertcat(v, zero3, u_geo))
    vt = ca.mtimes(gR, v)
    d = ca.if_else(vt * slip > 0, ca.sign(vt), slip)
    w = MinvA @ ca.vertcat(1, mu * d)
    painleve = ca.mtimes(Qa, w)
    f_slide = (ca.mtimes(Qa, free) + Qb + 2 * gf * Qdot + wf * Q) / painleve
    a_slide = free - f_slide * w

    rolling, sliding = mode < 0.5, mode < 1.5
    a = ca.if_else(rolling, a_roll, ca.if_else(sliding, a_slide, free))
    udot = ca.if_else(rolling, sigma, u_geo)
    f = ca.if_else(rolling, lam_roll[0], ca.if_else(sliding, f_slide, 0))
    lam = ca.if_else(rolling, lam_roll[1], ca.if_else(sliding, mu * d * f_slide, 0))
    xdot = ca.vertcat(v, a, udot)

    W = A @ MinvA
    kinetic = tr(system.outputs["kinetic_energy"])
    potential = tr(system.outputs["potential_energy"])
    outputs = {
        "gap": -Q, "normal_speed": -Qdot, "normal_force": f, "lam": lam,
        "tangential_force": ca.fabs(lam), "cone_ratio": ca.fabs(lam) / ca.fmax(f, FORCE_FLOOR),
        "vt": vt, "slip_speed": ca.fabs(vt), "vt_rate": ca.jtimes(vt, x, xdot),
        "rolling_normal_force": lam_roll[0], "rolling_lam": lam_roll[1],
        "rolling_tangential_force": ca.fabs(lam_roll[1]), "painleve": painleve,
        "free_normal_acceleration": -(ca.mtimes(Qa, free) + Qb),
        "Q": Q, "R": R, "tangency_defect": delta,
        "kinetic_energy": kinetic, "potential_energy": potential,
        "power": ca.dot(v[1:3], tau),
        "vn_fixed": ca.mtimes(gQ, v),
        "W_nn": W[0, 0], "W_nt": W[0, 1], "W_tt": W[1, 1],
    }
    for i in range(3):
        outputs[f"Minv_gQ_{i}"] = MinvA[i, 0]
        outputs[f"Minv_gR_{i}"] = MinvA[i, 1]
    return {"x": x, "p": p, "t": t, "xdot": xdot, "outputs": outputs, "reads_time": timed}


def derive_planar_fingers_modes(scene, torques) -> dict:
    """``derive_planar_modes`` of a scene of several contacts (``k`` fingers, then the lines of
    the world of a free object): each contact ``i`` in its own mode (``mode{i}``, ``slip{i}``,
    ``mu{i}``), the multipliers of every contact ``z = (f_1, lam_1, ..., f_n, lam_n)`` (the
    force on the system ``-A^T z``, ``A`` the rows ``(gQ_i, gR_i)``) solved together from two
    rows per contact: rolling, its two constraint rows along the motion (as the rolling model;
    a line's tangential row at the speed level, ``vt' = -2 gl vt``); sliding, its normal row
    along the common normal's motion and Coulomb's ``lam_i = mu_i d_i f_i``; separated,
    ``f_i = lam_i = 0``. ``painleve{i}`` is contact ``i``'s own coefficient of its sliding
    normal row. A line acts as a fixed finger (``_line_rows``)."""
    k = scene.n_fingers
    n_lines = len(scene.lines)
    n = k + n_lines
    names = scene.p_names
    system, x, p, t, tau, timed, tr, (gf, gl, wf, wl) = _setup(scene, torques)
    nq = scene.n_speeds
    q, v, u = x[0:nq], x[nq:2 * nq], x[2 * nq:2 * nq + 2 * k]
    u_w = x[2 * nq + 2 * k:2 * nq + 2 * k + n_lines]
    defect = [tr(system.outputs["tangency_defect" if k == 1 else f"tangency_defect{i}"])
              for i in range(1, k + 1)]

    M, h, F = tr(system.mass_matrix), tr(system.bias), tr(system.force)
    C = tr(system.constraint)
    sigma = tr(system.contact_rates)
    lines = [_line_rows(scene.base, w, q, v, u_w[m], t) for m, w in enumerate(scene.lines)]
    u_w_dot = ca.vertcat(*[ln["u_dot"] for ln in lines])
    zq = ca.SX.zeros(nq)
    A = ca.vertcat(ca.jacobian(C, q), *[ca.vertcat(ln["gQ"], ln["gR"]) for ln in lines])
    free = ca.solve(M, F - h)
    MinvA = ca.solve(M, A.T)
    # sliding and separated contacts' parameters on the common normal
    u_geo = []
    for i in range(1, k + 1):
        ui = u[2 * i - 2:2 * i]
        G = ca.vertcat(C[2 * i - 1], defect[i - 1])
        u_geo.append(ca.solve(ca.jacobian(G, ui), -ca.jacobian(G, q) @ v - TRACK_GAIN * G))
    u_geo = ca.vertcat(*u_geo)
    # the rolling rows along the motion (each contact's parameters carried by sigma)
    rolled = ca.vertcat(v, zq, sigma, u_w_dot)
    Cdot = ca.jtimes(C, x, rolled)
    Ahat = ca.jacobian(Cdot, v)
    bhat = ca.jtimes(Cdot, x, rolled)
    along = ca.vertcat(v, zq, u_geo, u_w_dot)
    # each row's velocity relative to a driven line is ``A_r v + drift_r(t)``
    drift = ca.vertcat(ca.SX.zeros(2 * k), *[ln["drift"] for ln in lines])
    rows, rhs, per = [], [], []
    unit = ca.SX.eye(2 * n)
    for i in range(1, n + 1):
        a_, b_ = 2 * i - 2, 2 * i - 1
        mode, slip, mu = (p[names.index(f"{key}{i}")] for key in ("mode", "slip", "mu"))
        Q = C[a_] if i <= k else lines[i - k - 1]["Q"]
        Qdot = ca.jtimes(Q, x, along) + ca.jacobian(Q, t)
        Qa = ca.jacobian(Qdot, v)
        Qb = ca.jtimes(Qdot, x, along) + ca.jacobian(Qdot, t)
        vt = ca.mtimes(A[b_, :], v) + drift[b_]
        d = ca.if_else(vt * slip > 0, ca.sign(vt), slip)
        rolling, sliding = mode < 0.5, mode < 1.5
        if i <= k:
            roll_a = (Ahat[a_, :] @ MinvA, Ahat[a_, :] @ free + bhat[a_] + 2 * gf * Cdot[a_] + wf * C[a_])
            roll_b = (Ahat[b_, :] @ MinvA, Ahat[b_, :] @ free + bhat[b_] + 2 * gl * Cdot[b_] + wl * C[b_])
        else:
            roll_a = (Qa @ MinvA, Qa @ free + Qb + 2 * gf * Qdot + wf * Q)
            tb = ca.jtimes(vt, x, along) + ca.jacobian(vt, t)
            roll_b = (A[b_, :] @ MinvA, A[b_, :] @ free + tb + 2 * gl * vt)
        slide_a = (Qa @ MinvA, Qa @ free + Qb + 2 * gf * Qdot + wf * Q)
        slide_b = (unit[b_, :] - mu * d * unit[a_, :], ca.SX(0))
        for (ra, fa), (rs, fs), ro in ((roll_a, slide_a, unit[a_, :]), (roll_b, slide_b, unit[b_, :])):
            rows.append(ca.if_else(rolling, ra, ca.if_else(sliding, rs, ro)))
            rhs.append(ca.if_else(rolling, fa, ca.if_else(sliding, fs, 0)))
        per.append({"Q": Q, "Qdot": Qdot, "Qa": Qa, "Qb": Qb, "vt": vt, "d": d, "mu": mu,
                    "rolling": rolling, "R": C[b_] if i <= k else ca.SX(0),
                    "defect": defect[i - 1] if i <= k else lines[i - k - 1]["phi"]})
    z = ca.solve(ca.vertcat(*rows), ca.vertcat(*rhs))
    a = free - MinvA @ z
    udot = ca.vertcat(*[ca.if_else(c["rolling"], sigma[2 * i:2 * i + 2], u_geo[2 * i:2 * i + 2])
                        for i, c in enumerate(per[:k])], u_w_dot)
    xdot = ca.vertcat(v, a, udot)

    outputs = {}
    for i, c in enumerate(per, start=1):
        f, lam = z[2 * i - 2], z[2 * i - 1]
        w = MinvA @ (unit[:, 2 * i - 2] + c["mu"] * c["d"] * unit[:, 2 * i - 1])
        outputs.update({
            f"gap{i}": -c["Q"], f"normal_speed{i}": -c["Qdot"], f"normal_force{i}": f, f"lam{i}": lam,
            f"tangential_force{i}": ca.fabs(lam), f"cone_ratio{i}": ca.fabs(lam) / ca.fmax(f, FORCE_FLOOR),
            f"vt{i}": c["vt"], f"slip_speed{i}": ca.fabs(c["vt"]), f"painleve{i}": ca.mtimes(c["Qa"], w),
            f"normal_acceleration{i}": -(ca.mtimes(c["Qa"], a) + c["Qb"]),
            f"Q{i}": c["Q"], f"R{i}": c["R"], f"tangency_defect{i}": c["defect"],
            f"vn_fixed{i}": ca.mtimes(A[2 * i - 2, :], v) + drift[2 * i - 2],
        })
    W = A @ MinvA
    outputs.update({
        "kinetic_energy": tr(system.outputs["kinetic_energy"]),
        "potential_energy": tr(system.outputs["potential_energy"]),
        "power": ca.dot(v[nq - 2 * k:], tau),
    })
    for r in range(2 * n):
        for c in range(r, 2 * n):
            outputs[f"W_{r}_{c}"] = W[r, c]
    for s_ in range(nq):
        for r in range(2 * n):
            outputs[f"MinvAT_{s_}_{r}"] = MinvA[s_, r]
    moving = any(w.motion is not None for w in scene.lines)
    return {"x": x, "p": p, "t": t, "xdot": xdot, "outputs": outputs, "reads_time": timed or moving}


def _line_rows(base, line, q, v, u, t) -> dict:
    """A line of the world touching the free object of ``base`` (``docs/conventions.md``
    section 14), as a fixed finger: with ``R = Rot(-theta)``, the support point
    ``r_c = R c(u)``, the gap ``g = n.(Om + r_c - w0)``, ``Q = -g``; the line's velocity
    relative to the object's material point there, ``-v_c``, ``v_c = Om' - theta' perp(r_c)``,
    gives the rows ``gQ = dQ/dq = -n.J``, ``gR = -t.J`` (``t = (-n_y, n_x)``, ``J v = v_c``), so
    that the force on the object is ``f n + lam t`` (``-(f gQ + lam gR)``); the support point
    keeps ``phi = (R T(u)).n`` at 0 with ``phi' = -TRACK_GAIN phi``. A driven line (its
    point ``w0 + d(t)``) adds ``n.d'(t)`` and ``t.d'(t)`` to the rows' velocities (``drift``:
    the line's material moves)."""
    n = ca.DM(line.normal)
    tan = ca.DM([-line.normal[1], line.normal[0]])
    pos, th, dth = q[0:2], q[2], v[2]
    c, s = ca.cos(th), ca.sin(th)
    R = ca.vertcat(ca.horzcat(c, s), ca.horzcat(-s, c))
    S, T = contour_sx(base.object, u)
    rS = R @ S
    d, d_dot = (ca.SX.zeros(2), ca.SX.zeros(2)) if line.motion is None else translation_sx(line.motion, t)[:2]
    Q = -ca.dot(n, pos + rS - ca.DM(line.point) - d)
    phi = ca.dot(R @ T, n)
    u_dot = (-TRACK_GAIN * phi - ca.jacobian(phi, th) * dth) / ca.jacobian(phi, u)
    v_c = v[0:2] - dth * ca.vertcat(-rS[1], rS[0])
    gQ = ca.jacobian(Q, q)
    gR = -ca.jacobian(ca.dot(tan, v_c), v)
    return {"Q": Q, "gQ": gQ, "gR": gR, "phi": phi, "u_dot": u_dot,
            "drift": ca.vertcat(ca.dot(n, d_dot), ca.dot(tan, d_dot))}
