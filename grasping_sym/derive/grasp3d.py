"""Closed-loop equations of a 3D grasping scene (``model.grasp3d``) as CasADi SX.

Division of labour: SymPy derives every formula from the definitions -- the fingers'
kinematics and Lagrangian dynamics (``derive.spatial``), the surfaces' fundamental forms and
Montana forms (``geometry.surfaces``), the contact update law on generic forms
(``derive.contact3d``) -- and ``codegen.translate`` turns them into SX with shared
subexpressions kept shared. The constraint Jacobians and the second time derivatives of the
constraints are then taken by CasADi's algorithmic differentiation on that SX graph (exact,
and linear in the graph's size, where SymPy's would swell).

Equations (the design is in ``docs/design-3d.md``), state ``x = (z, V, eta)``::

    z = (q_1..q_N, [p], quat),  V = (q_1'..q_N', [v], omega),  eta = contact states
    M a + h + A^T mu = tau,          M = diag(G_1..G_N, [m I], H)
    h = (h_i + dP_i/dq_i, [-m g], omega x H omega),  tau = (u_i, 0)
    C'' + 2 g C' + g^2 C = 0,        C = (Qn_i, Qb_i, Qe_i)_i   (total derivatives)

``C_i`` is the gap between the fingertip's and the object's contact points in finger i's
contact frame; with the contact coordinates held fixed its gradient is the relative velocity
of the two material points, so ``A^T mu`` are the contact forces (``f_i`` normal, > 0 presses;
``lam_i``, ``eta_i`` tangential). The object's rotation is ``R(quat)`` in the homogeneous form
(an exact rotation for any non-zero quaternion, so R is orthonormal to rounding whatever the
quaternion's norm drift), and the quaternion follows ``spatial.quaternion_rate``.

Contact tracking, by ``scene.formulation``:

* ``'regular'`` (default): ``eta_i = (u_f, v_f, u_o, v_o, psi)``, rates from Montana's
  equations for rolling (``contact3d``): linear in the relative angular velocity, zero at rest.
* ``'paper'``: ``eta_i = (u_f, v_f, u_o, v_o, s, Psi0 (9), Psi1 (9))``, the paper's (Es),
  (Efs) with the geodesic curvatures of (31)-(32) (and the geodesic torsion the printed (Efs)
  omits, see the oracle ``tests/oracles/reference3d_paper.py``). The bodies' accelerations come from the same
  Lagrangian pieces, evaluated at the contact points carried by the paper's states and the
  frame angle read from the two surfaces' frames there. It divides by
  ``D_i = omega0.e0 + omega1.e1`` (output ``frame_denominator{i}``), 0/0 at rest.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from functools import lru_cache

import casadi as ca
import numpy as np
import sympy as sp

from grasping_sym.derive import contact3d as c3
from grasping_sym.derive.spatial import (
    finger_dynamics,
    finger_kinematics,
    quaternion_rate,
    quaternion_rate_matrix,
    quaternion_to_matrix,
)
from grasping_sym.derive.system import assemble
from grasping_sym.geometry.surfaces import ParametricSurface, U, V
from grasping_sym.model.grasp3d import GraspScene3D
from grasping_sym.symbolic.translate import SympyToCasadi

#: 1/s, damping of the paper formulation's frames' orthonormality drift (zero on SO(3)).
FRAME_GAIN = 50.0


@dataclass
class Grasp3DSystem:
    """SX of one scene: ``xdot(x, p)``, every output, and the pieces for tests and plots."""

    x: ca.SX
    p: ca.SX
    xdot: ca.SX
    outputs: dict[str, ca.SX]
    pieces: dict[str, ca.SX]
    geometry: dict[str, ca.SX]
    param_names: tuple[str, ...]
    timings: dict[str, float] = field(default_factory=dict)
    #: every condition of a consistent contact, by name (regular formulation): the gaps C,
    #: the normals opposed, the frame angle psi read from the surfaces' frames, a unit
    #: quaternion; zero at a consistent start (``runtime.start``)
    start_conditions: dict[str, ca.SX] = field(default_factory=dict)
    #: the time (the controller's), and whether the law reads it itself
    t: ca.SX | None = None
    reads_time: bool = False

    def function(self, name: str, which: str) -> ca.Function:
        """An (uncompiled) ``Function(x, p) -> dict`` of ``pieces``/``geometry``/``outputs``."""
        d = {"pieces": self.pieces, "geometry": self.geometry, "outputs": self.outputs}[which]
        values = list(d.values())
        if self.t is not None:  # the law's time at 0 (a law that reads it: at the start)
            values = ca.substitute(values, [self.t], [ca.SX(0)])
        return ca.Function(name, [self.x, self.p], values, ["x", "p"], list(d))


# ------------------------------------------------------------------ symbolic building blocks
@lru_cache(maxsize=None)
def _finger_symbolic(chain, gravity):
    kin = finger_kinematics(chain)
    dyn = finger_dynamics(kin, gravity)
    return kin, dyn


def finger_function(chain, gravity) -> ca.Function:
    """``(q, dq) -> r, Pi, J, W, G, h, joints[, dP, P]``: the finger's kinematics and
    dynamics, derived with SymPy (``derive.spatial``) and translated to SX."""
    kin, dyn = _finger_symbolic(chain, gravity)
    q, dq = ca.SX.sym("q", chain.n), ca.SX.sym("dq", chain.n)
    tr = SympyToCasadi({**{kin.q[k]: q[k] for k in range(chain.n)},
                        **{kin.dq[k]: dq[k] for k in range(chain.n)}})
    out = {"r": tr(kin.r), "Pi": tr(kin.Pi), "J": tr(kin.J), "W": tr(kin.W), "G": tr(dyn.G),
           "h": tr(dyn.h), "joints": ca.horzcat(*[tr(p) for p in kin.joint_positions], tr(kin.r))}
    if gravity is not None:
        out["dP"] = tr(dyn.gravity_gradient)
        out["P"] = tr(dyn.potential_energy)
    return ca.Function(f"finger_{chain.name}", [q, dq], list(out.values()), ["q", "dq"], list(out))


def finger_sx(chain, gravity, q: ca.SX, dq: ca.SX) -> dict[str, ca.SX]:
    """The finger's kinematics and dynamics as SX in ``q, dq``: its template (derived with
    SymPy once per chain and gravity, and stored, ``codegen.templates.finger_template``)
    evaluated on ``q, dq``."""
    from grasping_sym.assemble.templates import finger_template  # noqa: PLC0415

    g = None if gravity is None else tuple(float(v) for v in gravity)
    fn, _ = finger_template(chain, g, lambda: finger_function(chain, g))
    outs = fn.call([q, dq])
    return {fn.name_out(i): outs[i] for i in range(fn.n_out())}


def surface_sx(surface: ParametricSurface, u, v, extra: bool = False) -> dict[str, ca.SX]:
    """Point, Montana frame and forms of ``surface`` at ``(u, v)`` as SX."""
    tr = SympyToCasadi({U: u, V: v})
    x, y, n = surface.frame
    out = {"S": tr(surface.S), "x": tr(x), "y": tr(y), "n": tr(n),
           "M": tr(surface.montana_metric), "K": tr(surface.curvature_form),
           "T": tr(surface.torsion_form)}
    if extra:
        out["Tm"] = ca.horzcat(tr(surface.S_u), tr(surface.S_v))
        out["II"] = tr(surface.second_fundamental_form)
    return out


@lru_cache(maxsize=1)
def _generic_rates():
    ff, fo = c3.MontanaForms.generic("f"), c3.MontanaForms.generic("o")
    psi = sp.Symbol("psi", real=True)
    w = sp.symbols("w_x w_y w_z", real=True)
    return ff, fo, psi, w, c3.contact_rates_symbolic(ff, fo, psi, w).vector


def contact_rates_sx(sf: dict, so: dict, psi, w_rel) -> ca.SX:
    """Montana's rolling rates ``(u_f, v_f, u_o, v_o, psi)'`` with the surfaces' forms."""
    ff, fo, psi_s, w_s, rates = _generic_rates()

    def entries(d):
        M, K, T = d["M"], d["K"], d["T"]
        return [M[0, 0], M[0, 1], M[1, 1], K[0, 0], K[0, 1], K[1, 1], T[0, 0], T[0, 1]]

    sym = {**dict(zip(ff.entries(), entries(sf))), **dict(zip(fo.entries(), entries(so))),
           psi_s: psi, **{w_s[i]: w_rel[i] for i in range(3)}}
    return SympyToCasadi({k: v for k, v in sym.items() if isinstance(k, sp.Symbol)})(rates)


def relative_curvature_min(sf: dict, so: dict, psi) -> ca.SX:
    """Smaller eigenvalue of ``K_f + R_psi K_o R_psi`` (1/m)."""
    c, s = ca.cos(psi), ca.sin(psi)
    Rp = ca.vertcat(ca.horzcat(c, -s), ca.horzcat(-s, -c))
    K = sf["K"] + Rp @ so["K"] @ Rp
    half_tr = 0.5 * (K[0, 0] + K[1, 1])
    det = K[0, 0] * K[1, 1] - K[0, 1] * K[1, 0]
    return half_tr - ca.sqrt(ca.fmax(half_tr * half_tr - det, 0))


def _quat_pieces(quat: ca.SX, om: ca.SX):
    qs, ws = sp.Matrix(sp.symbols("qw qx qy qz", real=True)), sp.Matrix(sp.symbols("wX wY wZ", real=True))
    tr = SympyToCasadi({**{qs[i]: quat[i] for i in range(4)}, **{ws[i]: om[i] for i in range(3)}})
    return tr(quaternion_to_matrix(qs, unit=False)), tr(quaternion_rate(qs, ws)), tr(quaternion_rate_matrix(qs))


def _darboux(kg, tg, kn):
    return ca.vertcat(ca.horzcat(0, -kn, tg), ca.horzcat(kn, 0, -kg), ca.horzcat(-tg, kg, 0))


# ------------------------------------------------------------------ the closed loop
def state_slices(scene: GraspScene3D) -> dict[str, slice]:
    """Where the state's parts lie: ``q``, ``pos`` (free objects), ``quat``, ``dq``, ``vel``
    (free objects), ``om``, then the contacts' states."""
    nQ = sum(f.chain.n for f in scene.fingers)
    sizes = [("q", nQ), ("pos", 3 if scene.free else 0), ("quat", 4), ("dq", nQ),
             ("vel", 3 if scene.free else 0), ("om", 3)]
    out, k = {}, 0
    for key, n in sizes:
        out[key] = slice(k, k + n)
        k += n
    return out


def derive_grasp3d(scene: GraspScene3D, surface_fn=None, torque_inputs: bool = False) -> Grasp3DSystem:
    """The scene's closed loop as SX.

    ``surface_fn(slot, surface, u, v, extra)`` gives a contour slot's point, frame and forms
    (the dict of :func:`surface_sx`; slot ``2 i`` is contact ``i``'s fingertip, ``2 i + 1``
    the object there); default :func:`surface_sx` itself. A structure passes the surfaces'
    values as inputs instead (``codegen.structure3d``).

    ``p`` holds the run-time parameters ``scene.runtime``, then ``scene.start_param_names``:
    ``r_bar0`` (m), the mean of the fingertip centres at the start, where the centre spring
    of the controller is at rest (``initial3d`` computes it; absent when ``k_center = 0``),
    then the inputs' coefficients (``scene.p_names``). The joint torques are the controller
    layer's (``codegen.controller``); with ``torque_inputs`` they are the last entries of
    ``p`` instead, which then holds no inputs' coefficients (a structure's, whose model
    computes the torques).
    """
    from grasping_sym.assemble.controller import controller_torques  # noqa: PLC0415

    paper = scene.formulation == "paper"
    N = scene.n_contacts
    nq = [f.chain.n for f in scene.fingers]
    nQ = sum(nq)
    free = scene.free
    n_eta = 23 if paper else 5
    nx = len(scene.state_names)
    x = ca.SX.sym("x", nx)
    t = ca.SX.sym("t")
    if torque_inputs:
        p_names = (*scene.runtime, *scene.start_param_names, *(f"tau_{k}" for k in scene.joint_names))
    else:
        p_names = scene.p_names
    p = ca.SX.sym("p", len(p_names))
    prm = {k: (p[scene.runtime.index(k)] if k in scene.runtime else ca.SX(v))
           for k, v in scene.params.items()}
    sl = state_slices(scene)
    q, quat, dq, om = x[sl["q"]], x[sl["quat"]], x[sl["dq"]], x[sl["om"]]
    pos = x[sl["pos"]] if free else ca.DM(scene.position)
    vel = x[sl["vel"]] if free else None
    k = sl["om"].stop
    etas = [x[k + i * n_eta:k + (i + 1) * n_eta] for i in range(N)]
    g = None if scene.gravity is None else tuple(float(v) for v in scene.gravity)
    R, quat_dot, Eq = _quat_pieces(quat, om)

    fingers, off = [], 0
    for f, n in zip(scene.fingers, nq):
        fingers.append(finger_sx(f.chain, g, q[off:off + n], dq[off:off + n]))
        fingers[-1]["dq"] = dq[off:off + n]
        off += n

    # contact geometry at the contact coordinates
    contacts = []
    surface_fn = surface_fn or (lambda slot, s, u, v, extra: surface_sx(s, u, v, extra))
    for i, (f, fin, eta) in enumerate(zip(scene.fingers, fingers, etas)):
        sf = surface_fn(2 * i, f.tip, eta[0], eta[1], paper)
        so = surface_fn(2 * i + 1, scene.object_surface, eta[2], eta[3], paper)
        Cf = fin["Pi"] @ ca.horzcat(sf["x"], sf["y"], sf["n"])
        if paper:  # psi read from the two surfaces' frames at the carried points
            xo = R @ so["x"]
            psi = ca.atan2(-ca.dot(xo, Cf[:, 1]), ca.dot(xo, Cf[:, 0]))
        else:
            psi = eta[4]
        pf = fin["r"] + fin["Pi"] @ sf["S"]
        po = pos + R @ so["S"]
        gap = Cf.T @ (pf - po)
        w_rel = Cf.T @ (R @ om - fin["W"] @ fin["dq"])
        contacts.append({"sf": sf, "so": so, "Cf": Cf, "psi": psi, "pf": pf, "po": po,
                         "C": ca.vertcat(gap[2], gap[0], gap[1]), "w_rel": w_rel,
                         "sigma": contact_rates_sx(sf, so, psi, w_rel)})

    # Lagrangian pieces with regular contact coordinates (u_f, v_f, u_o, v_o, psi) per contact
    eta_reg = ca.vertcat(*[ca.vertcat(e[:4], c["psi"]) for e, c in zip(etas, contacts)])
    sigma = ca.vertcat(*[c["sigma"] for c in contacts])
    C = ca.vertcat(*[c["C"] for c in contacts])
    zb = ca.vertcat(q, pos, quat) if free else ca.vertcat(q, quat)
    zb_dot_lin = ca.vertcat(dq, vel, Eq @ om) if free else ca.vertcat(dq, Eq @ om)
    zb_dot = ca.vertcat(dq, vel, quat_dot) if free else ca.vertcat(dq, quat_dot)
    Vs = ca.vertcat(dq, vel, om) if free else ca.vertcat(dq, om)
    if paper:
        # C depends on eta_reg only through the carried (u, v): psi does not enter C
        eta_vars = ca.vertcat(*[e[:4] for e in etas])
        eta_rates = ca.vertcat(*[c["sigma"][:4] for c in contacts])
    else:
        eta_vars, eta_rates = eta_reg, sigma
    z = ca.vertcat(zb, eta_vars)
    zdot = ca.vertcat(zb_dot, eta_rates)
    # C' and C'' along the motion as forward directional derivatives (jtimes), not through
    # the full Jacobians dC/dz and dC'/dz: paper3d's closed loop has 7146 instructions this
    # way against 11448 (bhat alone 3263 against 8472)
    A = ca.jacobian(ca.jtimes(C, zb, zb_dot_lin), Vs)
    Cdot = ca.jtimes(C, z, zdot)
    Ahat = ca.jacobian(Cdot, Vs)
    bhat = ca.jtimes(Cdot, z, zdot)
    H = ca.DM(np.asarray(scene.inertia))
    m = float(scene.mass)
    blocks = [fin["G"] for fin in fingers] + ([m * ca.DM.eye(3)] if free else []) + [H]
    Mm = ca.diagcat(*blocks)
    h_f = [fin["h"] + (fin["dP"] if g is not None else 0) for fin in fingers]
    h_obj = ([-m * ca.DM(g) if g is not None else ca.DM.zeros(3)] if free else [])
    h = ca.vertcat(*h_f, *h_obj, ca.cross(om, H @ om))

    # the joint torques: the controller layer's, or inputs of a structure
    reads_time = False
    if torque_inputs:
        torques = p[len(p_names) - nQ:]
    else:
        torques, _, reads_time = controller_torques(scene, t, x, p)
    u, off = [], 0
    for n in nq:
        u.append(torques[off:off + n])
        off += n
    rs = [fin["r"] for fin in fingers]
    r_bar = sum(rs[1:], rs[0]) / N
    # torsional (spin) friction at the contacts: a soft finger's viscous twist torque
    spin_f = [ca.DM.zeros(n) for n in nq]
    spin_o = ca.DM.zeros(3)
    dissipation = ca.SX(0)
    if scene.spin_damping > 0:
        for i, (fin, c) in enumerate(zip(fingers, contacts)):
            n_w = c["Cf"][:, 2]
            spin = ca.dot(n_w, R @ om - fin["W"] @ fin["dq"])
            torque = scene.spin_damping * spin * n_w          # on the finger, world; -torque on the object
            spin_f[i] = fin["W"].T @ torque
            spin_o = spin_o - R.T @ torque
            dissipation = dissipation - scene.spin_damping * spin * spin
    tau = ca.vertcat(*[ui + sf_ for ui, sf_ in zip(u, spin_f)], ca.DM.zeros(3) if free else ca.SX(0, 1), spin_o)
    gain = prm["gain"]
    m_c = 3 * N
    xdot_b, mu = assemble(Vs.numel(), Vs,
                          [Mm, h, tau, A, Ahat, bhat, Cdot, C, ca.repmat(2 * gain, m_c, 1),
                           ca.repmat(gain * gain, m_c, 1), sigma],
                          ca.solve, lambda parts: ca.vertcat(*parts), lambda a, b: a * b,
                          lambda a: a.T, qdot=zb_dot)
    nb = zb.numel() + Vs.numel()
    acc = xdot_b[zb.numel():nb]
    outputs: dict[str, ca.SX] = {}
    if paper:
        eta_dot, extra = _paper_tracking(scene, x, xdot_b[:nb], etas, contacts, fingers, R, om)
        xdot = ca.vertcat(xdot_b[:nb], eta_dot)
        outputs.update(extra)
    else:
        xdot = xdot_b
    # outputs
    outputs["constraint_residual"] = ca.mmax(ca.fabs(C))
    for i, c in enumerate(contacts, start=1):
        outputs[f"f{i}"] = mu[3 * (i - 1)]
        outputs[f"lam{i}"] = mu[3 * (i - 1) + 1]
        outputs[f"eta{i}"] = mu[3 * (i - 1) + 2]
        outputs[f"krel_min{i}"] = relative_curvature_min(c["sf"], c["so"], c["psi"])
    outputs["orthonormality"] = ca.mmax(ca.fabs(R.T @ R - ca.DM.eye(3)))
    outputs["quat_norm_error"] = ca.norm_2(quat) - 1
    ke = sum((0.5 * fin["dq"].T @ fin["G"] @ fin["dq"] for fin in fingers), 0.5 * om.T @ H @ om)
    pe = ca.SX(0)
    if free:
        ke = ke + 0.5 * m * ca.dot(vel, vel)
    if g is not None:
        pe = sum((fin["P"] for fin in fingers), pe)
        if free:
            pe = pe - m * ca.dot(ca.DM(g), pos)
    outputs["kinetic_energy"] = ke
    outputs["potential_energy"] = pe
    outputs["power"] = sum((ca.dot(fin["dq"], ui) for fin, ui in zip(fingers, u)), dissipation)
    outputs["object_speed"] = ca.norm_2(vel) if free else ca.SX(0)
    outputs["object_angular_speed"] = ca.norm_2(om)
    geometry = {"R": R, "pos": pos if free else ca.SX(ca.DM(scene.position)), "r_bar": r_bar}
    start_conditions: dict[str, ca.SX] = {}
    if not paper:
        for i, (c, eta) in enumerate(zip(contacts, etas), start=1):
            xf, yf = c["Cf"][:, 0], c["Cf"][:, 1]
            n_o, x_o = R @ c["so"]["n"], R @ c["so"]["x"]
            psi = eta[4]
            start_conditions.update({
                f"Qn{i}": c["C"][0], f"Qb{i}": c["C"][1], f"Qe{i}": c["C"][2],
                f"normal_x{i}": ca.dot(xf, n_o), f"normal_y{i}": ca.dot(yf, n_o),
                # psi = atan2(-x_o.y_f, x_o.x_f), as sin/cos: no branch cut in the condition
                f"frame_angle{i}": ca.sin(psi) * ca.dot(x_o, xf) + ca.cos(psi) * ca.dot(x_o, yf),
            })
        start_conditions["quaternion_norm"] = ca.dot(quat, quat) - 1
    for i, (fin, c) in enumerate(zip(fingers, contacts), start=1):
        geometry.update({f"joints{i}": fin["joints"], f"Pi{i}": fin["Pi"], f"p_f{i}": c["pf"],
                         f"p_o{i}": c["po"], f"psi{i}": c["psi"]})
    pieces = {"M": Mm, "h": h, "tau": tau, "A": A, "Ahat": Ahat, "bhat": bhat, "Cdot": Cdot,
              "C": C, "sigma": sigma, "mu": mu, "acc": acc, "eta_reg": eta_reg}
    return Grasp3DSystem(x=x, p=p, xdot=xdot, outputs=outputs, pieces=pieces, geometry=geometry,
                         param_names=p_names, start_conditions=start_conditions, t=t,
                         reads_time=reads_time)


def _paper_tracking(scene, x, xdot_body, etas, contacts, fingers, R, om):
    """Rates of ``(u_f, v_f, u_o, v_o, s, Psi0, Psi1)`` per contact: (Es), (Efs), (31)-(32)."""
    kg = ca.SX.sym("kg", 2 * len(etas))
    rates, r25s, extra = [], [], {}
    I3 = ca.DM.eye(3)
    worst = []
    for i, (eta, c, fin) in enumerate(zip(etas, contacts, fingers)):
        P0 = ca.reshape(eta[5:14], 3, 3)
        P1 = ca.reshape(eta[14:23], 3, 3)
        w0 = R @ om
        w1 = fin["W"] @ fin["dq"]
        F0, F1 = R @ P0, fin["Pi"] @ P1

        def curv(s, P):
            Tp = ca.pinv(s["Tm"])
            a, cc = Tp @ P[:, 1], Tp @ P[:, 2]
            return -(a.T @ s["II"] @ a), cc.T @ s["II"] @ a, a

        kn0, tg0, a0 = curv(c["so"], P0)
        kn1, tg1, a1 = curv(c["sf"], P1)
        D = ca.dot(w0, F0[:, 2]) + ca.dot(w1, F1[:, 2])
        sdot = -D / (kn0 + kn1)
        Dn = ca.dot(w0, F0[:, 0]) + ca.dot(w1, F1[:, 0])
        r25s.append(ca.dot(w0, F0[:, 1]) - ca.dot(w1, F1[:, 1]) - (tg1 - tg0) * sdot)
        k0, k1 = kg[2 * i], kg[2 * i + 1]
        P0dot = P0 @ _darboux(k0, tg0, kn0) * sdot - 0.5 * FRAME_GAIN * P0 @ (P0.T @ P0 - I3)
        P1dot = P1 @ _darboux(k1, tg1, kn1) * sdot - 0.5 * FRAME_GAIN * P1 @ (P1.T @ P1 - I3)
        rates.append(ca.vertcat(a1 * sdot, a0 * sdot, sdot, ca.reshape(P0dot, 9, 1), ca.reshape(P1dot, 9, 1)))
        extra[f"frame_denominator{i + 1}"] = D
        extra[f"_Dn{i + 1}"] = Dn
        extra[f"_sdot{i + 1}"] = sdot
        worst.append(ca.fmax(ca.mmax(ca.fabs(P0.T @ P0 - I3)), ca.mmax(ca.fabs(P1.T @ P1 - I3))))
    eta_dot = ca.vertcat(*rates)
    xdot_all = ca.vertcat(xdot_body, eta_dot)
    # d/dt (25) = 0 is affine in each contact's kg; (27): kg0 + kg1 = -Dn / s'
    sol = []
    for i, r25 in enumerate(r25s):
        d25 = ca.jtimes(r25, x, xdot_all)
        kk = kg[2 * i:2 * i + 2]
        c0 = ca.substitute(d25, kg, ca.DM.zeros(kg.numel()))
        c12 = ca.jacobian(d25, kk)
        Amat = ca.vertcat(ca.horzcat(1, 1), c12)
        rhs = ca.vertcat(-extra[f"_Dn{i + 1}"] / extra[f"_sdot{i + 1}"], -c0)
        sol.append(ca.solve(Amat, rhs))
    eta_dot = ca.substitute(eta_dot, kg, ca.vertcat(*sol))
    for i in range(len(etas)):
        extra.pop(f"_Dn{i + 1}")
        extra.pop(f"_sdot{i + 1}")
    extra["frame_orthonormality"] = ca.mmax(ca.vertcat(*worst))
    return eta_dot, extra
