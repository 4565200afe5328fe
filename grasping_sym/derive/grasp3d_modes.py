"""A 3D grasp whose finger contacts each roll, slide or separate (``model.grasp3d_modes``;
``docs/conventions.md`` section 9, MODELS.md section 5), as CasADi SX.

The regular formulation's pieces (``derive.loop3d``: bodies, contacts, ``C = (Qn, Qb, Qe)``
per contact in the fingertip's contact frame, ``A = dC/dV`` with the contact coordinates held,
Montana's rolling rates) with every contact's mode a run-time parameter (``mode{i}``: 0
rolling, 1 sliding, 2 separated), its slip direction at the start of a slide (``slip_x{i}``,
``slip_y{i}``, in the fingertip's contact frame) and its friction coefficient (``mu{i}``).
The contact force on the system is ``-A^T lam``, ``lam = (f, lam_x, lam_y)`` per contact
(``f > 0`` presses); the slip velocity is ``v_t = A_t V`` (the rate of ``(Qb, Qe)`` with the
contact coordinates held: the fingertip's material point relative to the object's).

- rolling: the contact's three rows, ``C'' + 2 g C' + g^2 C = 0``, Montana's rolling rates;
- sliding: the normal row only; ``(lam_x, lam_y) = mu f d``, ``d = v_t/|v_t|`` once
  ``v_t . slip >= SLIP_FULL``, ``slip`` below ``SLIP_START``, blended between; at a slide's
  onset from rest of the slip (``slip_onset{i} > 0``), the onset's (``derive.slip_onset``); the contact
  coordinates move so that the two points stay on a common normal: ``G = (Qb, Qe, x_f . n_o, y_f . n_o) = 0`` held by
  ``G_alpha alpha' = -G_z z' - TRACK_GAIN G`` (``alpha = (u_f, v_f, u_o, v_o)``) and ``psi``
  following the frames' angle;
- separated: no force; the coordinates as in sliding, so ``-Qn`` is the gap.

Every row's ``C'`` and ``C''`` are taken along the coordinates' motion of its contact's mode.
"""
from __future__ import annotations

import casadi as ca
import numpy as np
import sympy as sp

from grasping_sym.derive import slip_onset
from grasping_sym.derive.bodies3d import bodies, surface_sx
from grasping_sym.derive.grasp3d import REGULAR
from grasping_sym.derive.loop3d import applied_forces, contacts, dynamics, split_torques
from grasping_sym.derive.loop3d import outputs as loop_outputs
from grasping_sym.model.body import TIME
from grasping_sym.symbolic.translate import SympyToCasadi

#: 1/s: the rate at which sliding and separated contact coordinates return to the common
#: normal (its conditions are invariants of their law; this only damps round-off).
TRACK_GAIN = 200.0
#: Floors (m/s, N) of the slip speed and the normal force where they divide.
SLIP_ZERO = 1e-300
#: m/s: a slide follows its own velocity's direction ``v_t/|v_t|`` once ``v_t . slip`` reaches
#: ``SLIP_FULL``; below ``SLIP_START``, the direction ``slip`` (the fixed point of the slip's
#: acceleration, where a slip from rest starts: the round-off of a slip starting from rest has
#: no direction); between, a C1 blend of the two, normalised. A switch at one threshold made the
#: direction jump by the round-off's angle (1e-13 m/s of the rolling's residual slip against
#: 1e-10): radau crossed it in ~1400 steps of 1e-13 s (a 0.25 s drop of the grasp: 17 310 steps,
#: 2.8 s; 465 000 steps, 191 s at rtol 1e-8). The blend lasts ~1e-8 s of a slide (|a_t| ~ 5 m/s^2):
#: the same drop takes 2 465 steps, 0.16 s, its states within 1.1e-9 of the switch's and its
#: events within 1e-12 s.
SLIP_START = 1e-10
SLIP_FULL = 1e-7
FORCE_FLOOR = 1e-300


def derive_grasp3d_modes(scene, torques) -> dict:
    """``{"x", "p", "t", "xdot", "outputs", "reads_time"}`` of a ``model.grasp3d_modes`` scene;
    ``torques(base, t, x, p_base)`` gives the joint torques of the base scene's controller."""
    base = scene.base
    kf = base.n_contacts
    k = scene.n_contacts
    names = scene.p_names
    x = ca.SX.sym("x", len(scene.state_names))
    p = ca.SX.sym("p", len(names))
    t = ca.SX.sym("t")
    p_base = ca.vertcat(*[p[names.index(n)] for n in base.p_names]) if base.p_names else ca.SX(0, 1)
    tau_joints, _, timed = torques(base, t, x[:len(base.state_names)], p_base)
    b = bodies(base, x, REGULAR.n_eta)
    # a surface with an atlas is written in its chart, a run-time parameter (runtime.atlas)
    charts = {slot: p[names.index(name)] for slot, name, _ in base.chart_slots()}
    cs = contacts(base, b, REGULAR, lambda slot, s, u, v, extra: surface_sx(s, u, v, extra, chart=charts.get(slot)))
    C_f = ca.vertcat(*[c.gap for c in cs])
    M, h = dynamics(base, b)
    modes = [p[names.index(f"mode{i}")] for i in range(1, k + 1)]
    mus = [p[names.index(f"mu{i}")] for i in range(1, k + 1)]
    slips = [ca.vertcat(p[names.index(f"slip_x{i}")], p[names.index(f"slip_y{i}")]) for i in range(1, k + 1)]
    onsets = [p[names.index(f"slip_onset{i}")] for i in range(1, k + 1)]
    u = split_torques(base, tau_joints)
    # a soft finger's twist friction acts where the contact touches (rolling or sliding)
    tau, dissipation = applied_forces(base, b, cs, u, touching=[ca.if_else(m < 1.5, 1, 0) for m in modes[:kf]])
    gain = p[names.index("gain")] if "gain" in names else ca.SX(base.params["gain"])
    V = b.Vs

    # the fingers' contact coordinates' rates in each mode
    eta_rates = []
    for c, eta, mode in zip(cs, b.etas, modes):
        alpha = eta[0:4]
        xf, yf = c.frame[:, 0], c.frame[:, 1]
        n_o, x_o = b.R @ c.object["n"], b.R @ c.object["x"]
        G = ca.vertcat(c.gap[1], c.gap[2], ca.dot(xf, n_o), ca.dot(yf, n_o))
        alpha_dot = ca.solve(ca.jacobian(G, alpha), -ca.jtimes(G, b.zb, b.zb_dot) - TRACK_GAIN * G)
        psi_frames = ca.atan2(-ca.dot(x_o, yf), ca.dot(x_o, xf))
        za, za_dot = ca.vertcat(b.zb, alpha), ca.vertcat(b.zb_dot, alpha_dot)
        psi_dot = ca.jtimes(psi_frames, za, za_dot) - TRACK_GAIN * ca.sin(eta[4] - psi_frames)
        eta_rates.append(ca.if_else(mode < 0.5, c.rates, ca.vertcat(alpha_dot, psi_dot)))
    # the planes': the support point where the object's normal is -n, its rows in (n, t1, t2)
    nb = len(base.state_names)
    uvs, uv_rates, plane_rows = [], [], []
    for m, w in enumerate(scene.planes):
        uv = x[nb + 2 * m:nb + 2 * m + 2]
        chart = p[names.index(f"chart_w{m + 1}")] if f"chart_w{m + 1}" in names else None
        sd = surface_sx(base.object_surface, uv[0], uv[1], extra=True, chart=chart)
        n = ca.DM(w.normal)
        N_uv = ca.jacobian(sd["n"], uv)
        rhs_uv = -ca.cross(b.om, sd["n"]) - TRACK_GAIN * (sd["n"] + b.R.T @ n)
        uvs.append(uv)
        uv_rates.append(ca.solve(sd["Tm"].T @ N_uv, sd["Tm"].T @ rhs_uv))
        r_c = b.pos + b.R @ sd["S"]
        v_c = (b.vel if base.free else 0) + b.R @ ca.cross(b.om, sd["S"])
        J = ca.jacobian(v_c, V)
        t1, t2 = _tangents(np.asarray(w.normal))
        # a driven plane: its point w0 + d(t); its material's velocity at the contact point
        # d'(t) + w(t) n x (r_c - w0 - d(t)) (turning at w(t) about its normal)
        d = ca.SX.zeros(3) if w.motion is None else SympyToCasadi({TIME: t})(sp.Matrix(w.motion))
        arm = r_c - ca.DM(w.point) - d
        v_plane = ca.jacobian(d, t)
        if w.spin is not None:
            v_plane = v_plane + SympyToCasadi({TIME: t})(sp.Matrix([w.spin]))[0] * ca.cross(n, arm)
        plane_rows.append((-ca.dot(n, arm), -(n.T @ J), -(ca.DM(t1).T @ J), -(ca.DM(t2).T @ J),
                           ca.vertcat(n.T @ v_plane, ca.DM(t1).T @ v_plane, ca.DM(t2).T @ v_plane)))
    z = ca.vertcat(b.zb, *b.etas, *uvs)
    zdot = ca.vertcat(b.zb_dot, *eta_rates, *uv_rates)
    # every row: its position value (0: a velocity-level row), its rate, its Jacobian A
    A_f = ca.jacobian(ca.jtimes(C_f, b.zb, b.zb_dot_lin), V)
    C_rows = [C_f[r] for r in range(3 * kf)]
    Cdot_rows = [ca.jtimes(C_f[r], z, zdot) for r in range(3 * kf)]
    A_rows = [A_f[r, :] for r in range(3 * kf)]
    #: each row's velocity relative to a driven plane is ``A_r V + drift_r(t)``
    drift_rows = [ca.SX(0)] * (3 * kf)
    for gap_c, An, At1, At2, drift in plane_rows:
        C_rows += [gap_c, ca.SX(0), ca.SX(0)]
        Cdot_rows += [ca.jtimes(gap_c, z, zdot) + ca.jacobian(gap_c, t), At1 @ V + drift[1], At2 @ V + drift[2]]
        A_rows += [An, At1, At2]
        drift_rows += [drift[0], drift[1], drift[2]]
    C = ca.vertcat(*C_rows)
    Cdot = ca.vertcat(*Cdot_rows)
    A = ca.vertcat(*A_rows)
    drift_v = ca.vertcat(*drift_rows)
    Ahat = ca.jacobian(Cdot, V)
    bhat = ca.jtimes(Cdot, z, zdot) + ca.jacobian(Cdot, t)

    free = ca.solve(M, tau - h)
    MinvAT = ca.solve(M, A.T)
    n3 = 3 * k
    eye = ca.DM.eye(n3)
    rows, rhs, vts, ds = [], [], [], []
    for i in range(k):
        r = 3 * i
        vt = A[r + 1:r + 3, :] @ V + drift_v[r + 1:r + 3]
        speed = ca.norm_2(vt)
        along = ca.dot(vt, slips[i])
        ramp = ca.fmin(ca.fmax((along - SLIP_START) / (SLIP_FULL - SLIP_START), 0), 1)
        w = ramp * ramp * (3 - 2 * ramp)  # C1 from slip (v_t . slip <= SLIP_START) to v_t / |v_t|
        d = (1 - w) * slips[i] + w * vt / ca.fmax(speed, SLIP_ZERO)
        d = slip_onset.direction(vt, slips[i], onsets[i], d / ca.fmax(ca.norm_2(d), SLIP_ZERO))
        vts.append(vt)
        ds.append(d)
        rolling, sliding = modes[i] < 0.5, modes[i] < 1.5
        for j in range(3):
            dyn = Ahat[r + j, :] @ MinvAT
            dyn_rhs = Ahat[r + j, :] @ free + bhat[r + j] + 2 * gain * Cdot[r + j] + gain * gain * C[r + j]
            if j == 0:
                slide_row, slide_rhs = dyn, dyn_rhs
            else:  # Coulomb's law: lam_t = mu f d
                slide_row, slide_rhs = eye[r + j, :] - mus[i] * d[j - 1] * eye[r, :], ca.SX(0)
            rows.append(ca.if_else(rolling, dyn, ca.if_else(sliding, slide_row, eye[r + j, :])))
            rhs.append(ca.if_else(rolling, dyn_rhs, ca.if_else(sliding, slide_rhs, 0)))
    S = ca.vertcat(*rows)
    # an open contact's multipliers are 0 exactly (not the solve's round-off)
    closed = ca.vertcat(*[ca.if_else(m < 1.5, 1, 0) for m in modes for _ in range(3)])
    lam = closed * ca.solve(S, ca.vertcat(*rhs))
    a = free - MinvAT @ lam
    xdot = ca.vertcat(b.zb_dot, a, *eta_rates, *uv_rates)
    acc_C = Ahat @ a + bhat  # C'' along the motion

    out = loop_outputs(base, b, cs, C_f, lam, u, dissipation)
    W = A @ MinvAT
    for i in range(k):
        r, tag = 3 * i, i + 1
        f, Ft = lam[r], lam[r + 1:r + 3]
        ft = ca.norm_2(Ft)
        own = MinvAT[:, r] + mus[i] * (MinvAT[:, r + 1:r + 3] @ ds[i])
        out.update({
            f"f{tag}": f, f"lam{tag}": Ft[0], f"eta{tag}": Ft[1],
            f"gap{tag}": -C[r], f"normal_speed{tag}": -Cdot[r], f"normal_acceleration{tag}": -acc_C[r],
            f"normal_force{tag}": f, f"tangential_force{tag}": ft,
            f"cone_ratio{tag}": ft / ca.fmax(f, FORCE_FLOOR),
            f"vt_x{tag}": vts[i][0], f"vt_y{tag}": vts[i][1], f"slip_speed{tag}": ca.norm_2(vts[i]),
            f"onset_left{tag}": slip_onset.left(vts[i], slips[i], onsets[i]),
            f"painleve{tag}": Ahat[r, :] @ own,
            f"at_x{tag}": ca.jtimes(vts[i][0], x, xdot), f"at_y{tag}": ca.jtimes(vts[i][1], x, xdot),
            f"vn_fixed{tag}": A[r, :] @ V + drift_v[r],
        })
    for r in range(n3):
        for c_ in range(r, n3):
            out[f"W_{r}_{c_}"] = W[r, c_]
        for j in range(V.numel()):
            out[f"MinvAT_{j}_{r}"] = MinvAT[j, r]
    moving = any(w.motion is not None or w.spin is not None for w in scene.planes)
    return {"x": x, "p": p, "t": t, "xdot": xdot, "outputs": out, "reads_time": timed or moving}


def _tangents(n: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Two unit tangents of the unit normal ``n`` with ``(t1, t2, n)`` right-handed."""
    helper = np.eye(3)[int(np.argmin(np.abs(n)))]
    t1 = np.cross(helper, n)
    t1 /= np.linalg.norm(t1)
    return t1, np.cross(n, t1)
