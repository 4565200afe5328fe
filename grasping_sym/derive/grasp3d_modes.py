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
- sliding: the normal row only; ``(lam_x, lam_y) = mu f d``, ``d = v_t/|v_t|`` while
  ``v_t . slip > 0``, else ``slip``; the contact coordinates move so that the two points stay
  on a common normal: ``G = (Qb, Qe, x_f . n_o, y_f . n_o) = 0`` held by
  ``G_alpha alpha' = -G_z z' - TRACK_GAIN G`` (``alpha = (u_f, v_f, u_o, v_o)``) and ``psi``
  following the frames' angle;
- separated: no force; the coordinates as in sliding, so ``-Qn`` is the gap.

Every row's ``C'`` and ``C''`` are taken along the coordinates' motion of its contact's mode.
"""
from __future__ import annotations

import casadi as ca

from grasping_sym.derive.bodies3d import bodies, surface_sx
from grasping_sym.derive.grasp3d import REGULAR
from grasping_sym.derive.loop3d import applied_forces, contacts, dynamics, split_torques
from grasping_sym.derive.loop3d import outputs as loop_outputs

#: 1/s: the rate at which sliding and separated contact coordinates return to the common
#: normal (its conditions are invariants of their law; this only damps round-off).
TRACK_GAIN = 200.0
#: Floors (m/s, N) of the slip speed and the normal force where they divide.
SLIP_ZERO = 1e-300
#: m/s: a slide follows its own velocity's direction once ``v_t . slip`` exceeds this; below,
#: the direction ``slip`` (the round-off of a slip starting from rest has no direction).
SLIP_START = 1e-10
FORCE_FLOOR = 1e-300


def derive_grasp3d_modes(scene, torques) -> dict:
    """``{"x", "p", "t", "xdot", "outputs", "reads_time"}`` of a ``model.grasp3d_modes`` scene;
    ``torques(base, t, x, p_base)`` gives the joint torques of the base scene's controller."""
    base = scene.base
    k = base.n_contacts
    names = scene.p_names
    x = ca.SX.sym("x", len(scene.state_names))
    p = ca.SX.sym("p", len(names))
    t = ca.SX.sym("t")
    p_base = ca.vertcat(*[p[names.index(n)] for n in base.p_names]) if base.p_names else ca.SX(0, 1)
    tau_joints, _, timed = torques(base, t, x, p_base)
    b = bodies(base, x, REGULAR.n_eta)
    cs = contacts(base, b, REGULAR, lambda slot, s, u, v, extra: surface_sx(s, u, v, extra))
    C = ca.vertcat(*[c.gap for c in cs])
    M, h = dynamics(base, b)
    modes = [p[names.index(f"mode{i}")] for i in range(1, k + 1)]
    u = split_torques(base, tau_joints)
    # a soft finger's twist friction acts where the contact touches (rolling or sliding)
    tau, dissipation = applied_forces(base, b, cs, u, touching=[ca.if_else(m < 1.5, 1, 0) for m in modes])
    gain = p[names.index("gain")] if "gain" in names else ca.SX(base.params["gain"])
    A = ca.jacobian(ca.jtimes(C, b.zb, b.zb_dot_lin), b.Vs)
    V = b.Vs

    mus = [p[names.index(f"mu{i}")] for i in range(1, k + 1)]
    slips = [ca.vertcat(p[names.index(f"slip_x{i}")], p[names.index(f"slip_y{i}")]) for i in range(1, k + 1)]

    # the contact coordinates' rates in each mode
    eta_rates, geo = [], []
    for c, eta, mode in zip(cs, b.etas, modes):
        alpha = eta[0:4]
        xf, yf = c.frame[:, 0], c.frame[:, 1]
        n_o, x_o = b.R @ c.object["n"], b.R @ c.object["x"]
        G = ca.vertcat(c.gap[1], c.gap[2], ca.dot(xf, n_o), ca.dot(yf, n_o))
        alpha_dot = ca.solve(ca.jacobian(G, alpha), -ca.jtimes(G, b.zb, b.zb_dot) - TRACK_GAIN * G)
        psi_frames = ca.atan2(-ca.dot(x_o, yf), ca.dot(x_o, xf))
        za, za_dot = ca.vertcat(b.zb, alpha), ca.vertcat(b.zb_dot, alpha_dot)
        psi_dot = ca.jtimes(psi_frames, za, za_dot) - TRACK_GAIN * ca.sin(eta[4] - psi_frames)
        common = ca.vertcat(alpha_dot, psi_dot)
        geo.append(common)
        eta_rates.append(ca.if_else(mode < 0.5, c.rates, common))
    eta_all = ca.vertcat(*b.etas)
    z = ca.vertcat(b.zb, eta_all)
    zdot = ca.vertcat(b.zb_dot, *eta_rates)
    Cdot = ca.jtimes(C, z, zdot)
    Ahat = ca.jacobian(Cdot, V)
    bhat = ca.jtimes(Cdot, z, zdot)

    free = ca.solve(M, tau - h)
    MinvAT = ca.solve(M, A.T)
    n3 = 3 * k
    eye = ca.DM.eye(n3)
    rows, rhs, vts, ds = [], [], [], []
    for i in range(k):
        r = 3 * i
        vt = A[r + 1:r + 3, :] @ V
        speed = ca.norm_2(vt)
        d = ca.if_else(ca.dot(vt, slips[i]) > SLIP_START, vt / ca.fmax(speed, SLIP_ZERO), slips[i])
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
    lam = ca.solve(S, ca.vertcat(*rhs))
    a = free - MinvAT @ lam
    xdot = ca.vertcat(b.zb_dot, a, *eta_rates)
    acc_C = Ahat @ a + bhat  # C'' along the motion

    out = loop_outputs(base, b, cs, C, lam, u, dissipation)
    W = A @ MinvAT
    for i in range(k):
        r, tag = 3 * i, i + 1
        f, Ft = lam[r], lam[r + 1:r + 3]
        ft = ca.norm_2(Ft)
        own = MinvAT[:, r] + mus[i] * (MinvAT[:, r + 1:r + 3] @ ds[i])
        out.update({
            f"gap{tag}": -C[r], f"normal_speed{tag}": -Cdot[r], f"normal_acceleration{tag}": -acc_C[r],
            f"normal_force{tag}": f, f"tangential_force{tag}": ft,
            f"cone_ratio{tag}": ft / ca.fmax(f, FORCE_FLOOR),
            f"vt_x{tag}": vts[i][0], f"vt_y{tag}": vts[i][1], f"slip_speed{tag}": ca.norm_2(vts[i]),
            f"painleve{tag}": Ahat[r, :] @ own,
            f"at_x{tag}": ca.jtimes(vts[i][0], x, xdot), f"at_y{tag}": ca.jtimes(vts[i][1], x, xdot),
            f"vn_fixed{tag}": A[r, :] @ V,
        })
    for r in range(n3):
        for c_ in range(r, n3):
            out[f"W_{r}_{c_}"] = W[r, c_]
        for j in range(V.numel()):
            out[f"MinvAT_{j}_{r}"] = MinvAT[j, r]
    return {"x": x, "p": p, "t": t, "xdot": xdot, "outputs": out, "reads_time": timed}
