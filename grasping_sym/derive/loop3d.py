"""The stages of a 3D scene's closed loop, shared by its formulations (``derive.grasp3d``).

Bodies (``derive.bodies3d``) -> contacts (:func:`contacts`: points, frames, gaps, Montana's
rolling rates) -> constraint derivatives by CasADi's AD (:func:`constraint_derivatives`) ->
Lagrangian dynamics (:func:`dynamics`) and applied forces (:func:`applied_forces`) ->
accelerations and multipliers (:func:`close`, ``derive.system.assemble``) -> outputs and
geometry. What a formulation decides (how it tracks the contacts) is a :class:`Formulation`.
"""
from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from functools import lru_cache

import casadi as ca
import sympy as sp

from grasping_sym.derive import contact3d as c3
from grasping_sym.derive.bodies3d import Bodies, Finger
from grasping_sym.derive.system import assemble
from grasping_sym.model.grasp3d import GraspScene3D
from grasping_sym.symbolic.translate import SympyToCasadi


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


@dataclass
class Contact:
    """One contact (world frame, m): the fingertip's and the object's surface quantities
    there (``surface_sx`` dicts), the fingertip's contact frame ``frame`` (columns ``x_f,
    y_f, n_f``), the frame angle ``psi``, the two contact points, the constraint ``gap``
    ``(Qn, Qb, Qe)`` in that frame, the relative angular velocity ``w_rel`` (contact frame)
    and Montana's rolling rates ``rates`` of ``(u_f, v_f, u_o, v_o, psi)``."""

    tip: dict[str, ca.SX]
    object: dict[str, ca.SX]
    frame: ca.SX
    psi: ca.SX
    p_f: ca.SX
    p_o: ca.SX
    gap: ca.SX
    w_rel: ca.SX
    rates: ca.SX


#: ``surface_fn(slot, surface, u, v, extra)``: a contour slot's ``surface_sx`` dict
SurfaceFn = Callable[..., dict]


@dataclass(frozen=True)
class Formulation:
    """How a formulation tracks its contacts.

    ``n_eta``: states per contact; ``extra``: it reads the surfaces' tangent maps and second
    forms; ``frame_angle(eta, frame, object_surface, R)``: the frame angle psi;
    ``constraint_coordinates(bodies, contacts)``: the contact coordinates ``C`` depends on and
    their rates, ``(eta, eta')``; ``state_rates(scene, bodies, contacts, xdot_bodies)``: the
    contact states' rates and extra outputs, or ``(None, {})`` when they are the rolling
    rates; ``start_conditions(bodies, contacts)``: the conditions of a consistent start.
    """

    name: str
    n_eta: int
    extra: bool
    frame_angle: Callable
    constraint_coordinates: Callable
    state_rates: Callable
    start_conditions: Callable


def contacts(scene: GraspScene3D, b: Bodies, formulation: Formulation, surface_fn: SurfaceFn) -> list[Contact]:
    """Every contact at the contact coordinates the state carries."""
    out = []
    for i, (f, fin, eta) in enumerate(zip(scene.fingers, b.fingers, b.etas)):
        sf = surface_fn(2 * i, f.tip, eta[0], eta[1], formulation.extra)
        so = surface_fn(2 * i + 1, scene.object_surface, eta[2], eta[3], formulation.extra)
        Cf = fin.Pi @ ca.horzcat(sf["x"], sf["y"], sf["n"])
        psi = formulation.frame_angle(eta, Cf, so, b.R)
        pf = fin.r + fin.Pi @ sf["S"]
        po = b.pos + b.R @ so["S"]
        gap = Cf.T @ (pf - po)
        w_rel = Cf.T @ (b.R @ b.om - fin.W @ fin.dq)
        out.append(Contact(tip=sf, object=so, frame=Cf, psi=psi, p_f=pf, p_o=po,
                           gap=ca.vertcat(gap[2], gap[0], gap[1]), w_rel=w_rel,
                           rates=contact_rates_sx(sf, so, psi, w_rel)))
    return out


def constraint_derivatives(C: ca.SX, b: Bodies, eta: ca.SX, eta_rates: ca.SX):
    """``(A, C', Ahat, bhat)``: ``A = dC/dV`` with the contact coordinates held, the total
    ``C'`` along the motion, and ``C'' = Ahat a + bhat``.

    Forward directional derivatives (jtimes), not the full Jacobians dC/dz and dC'/dz:
    paper3d's closed loop has 7146 instructions this way against 11448 (bhat alone 3263
    against 8472)."""
    z = ca.vertcat(b.zb, eta)
    zdot = ca.vertcat(b.zb_dot, eta_rates)
    A = ca.jacobian(ca.jtimes(C, b.zb, b.zb_dot_lin), b.Vs)
    Cdot = ca.jtimes(C, z, zdot)
    Ahat = ca.jacobian(Cdot, b.Vs)
    bhat = ca.jtimes(Cdot, z, zdot)
    return A, Cdot, Ahat, bhat


def dynamics(scene: GraspScene3D, b: Bodies) -> tuple[ca.SX, ca.SX]:
    """``(M, h)``: ``M = diag(G_1..G_N, [m I], H)``, ``h = (h_i + dP_i/dq_i, [-m g], omega x H omega)``."""
    H, m = b.inertia, b.mass
    g = b.gravity
    blocks = [fin.G for fin in b.fingers] + ([m * ca.SX.eye(3)] if scene.free else []) + [H]
    M = ca.diagcat(*blocks)
    h_f = [fin.h + (fin.dP if g is not None else 0) for fin in b.fingers]
    h_obj = ([-m * ca.DM(g) if g is not None else ca.DM.zeros(3)] if scene.free else [])
    return M, ca.vertcat(*h_f, *h_obj, ca.cross(b.om, H @ b.om))


def split_torques(scene: GraspScene3D, torques: ca.SX) -> list[ca.SX]:
    """The joint torques (all fingers', in order) per finger."""
    u, off = [], 0
    for f in scene.fingers:
        u.append(torques[off:off + f.chain.n])
        off += f.chain.n
    return u


def applied_forces(scene: GraspScene3D, b: Bodies, cs: list[Contact], u: list[ca.SX],
                   touching: list | None = None) -> tuple[ca.SX, ca.SX]:
    """``(tau, dissipation)``: the generalised applied force (joint torques, and torsional
    (spin) friction at the contacts: a soft finger's viscous twist torque) and the power
    the friction dissipates (W, <= 0). ``touching``: per contact, 1 where it touches and 0
    where it is open (contact modes); default every contact touches."""
    spin_f = [ca.DM.zeros(f.chain.n) for f in scene.fingers]
    spin_o = ca.DM.zeros(3)
    dissipation = ca.SX(0)
    if scene.spin_damping > 0:
        for i, (fin, c) in enumerate(zip(b.fingers, cs)):
            n_w = c.frame[:, 2]
            spin = ca.dot(n_w, b.R @ b.om - fin.W @ fin.dq)
            if touching is not None:
                spin = spin * touching[i]
            torque = scene.spin_damping * spin * n_w          # on the finger, world; -torque on the object
            spin_f[i] = fin.W.T @ torque
            spin_o = spin_o - b.R.T @ torque
            dissipation = dissipation - scene.spin_damping * spin * spin
    tau = ca.vertcat(*[ui + sf_ for ui, sf_ in zip(u, spin_f)],
                     ca.DM.zeros(3) if scene.free else ca.SX(0, 1), spin_o)
    return tau, dissipation


def close(b: Bodies, pieces: list) -> tuple[ca.SX, ca.SX]:
    """``(xdot of the bodies and the rolling contact coordinates, mu)`` from the canonical
    pieces (``ConstrainedSystem.pieces`` order)."""
    return assemble(b.Vs.numel(), b.Vs, pieces, ca.solve, lambda parts: ca.vertcat(*parts),
                    lambda a, c: a * c, lambda a: a.T, qdot=b.zb_dot)


def outputs(scene: GraspScene3D, b: Bodies, cs: list[Contact], C: ca.SX, mu: ca.SX,
            u: list[ca.SX], dissipation: ca.SX) -> dict[str, ca.SX]:
    """The outputs every formulation has: residuals, contact forces, energies, power, speeds."""
    out: dict[str, ca.SX] = {"constraint_residual": ca.mmax(ca.fabs(C))}
    for i, c in enumerate(cs, start=1):
        out[f"f{i}"] = mu[3 * (i - 1)]
        out[f"lam{i}"] = mu[3 * (i - 1) + 1]
        out[f"eta{i}"] = mu[3 * (i - 1) + 2]
        out[f"krel_min{i}"] = relative_curvature_min(c.tip, c.object, c.psi)
    out["orthonormality"] = ca.mmax(ca.fabs(b.R.T @ b.R - ca.DM.eye(3)))
    out["quat_norm_error"] = ca.norm_2(b.quat) - 1
    out.update(_energies(scene, b))
    out["power"] = sum((ca.dot(fin.dq, ui) for fin, ui in zip(b.fingers, u)), dissipation)
    out["object_speed"] = ca.norm_2(b.vel) if scene.free else ca.SX(0)
    out["object_angular_speed"] = ca.norm_2(b.om)
    return out


def _energies(scene: GraspScene3D, b: Bodies) -> dict[str, ca.SX]:
    H, m = b.inertia, b.mass
    ke = sum((0.5 * fin.dq.T @ fin.G @ fin.dq for fin in b.fingers), 0.5 * b.om.T @ H @ b.om)
    pe = ca.SX(0)
    if scene.free:
        ke = ke + 0.5 * m * ca.dot(b.vel, b.vel)
    if b.gravity is not None:
        pe = sum((fin.P for fin in b.fingers), pe)
        if scene.free:
            pe = pe - m * ca.dot(ca.DM(b.gravity), b.pos)
    return {"kinetic_energy": ke, "potential_energy": pe}


def fingertip_centre(fingers: list[Finger]) -> ca.SX:
    """``r_bar`` (m, world): the mean of the fingertip centres."""
    rs = [fin.r for fin in fingers]
    return sum(rs[1:], rs[0]) / len(rs)


def geometry(scene: GraspScene3D, b: Bodies, cs: list[Contact]) -> dict[str, ca.SX]:
    """What drawings read (world frame, m): the object's ``R`` and ``pos``, and per finger
    ``joints{i}``, ``Pi{i}``, ``p_f{i}``, ``p_o{i}``, ``psi{i}``."""
    out = {"R": b.R, "pos": b.pos if scene.free else ca.SX(ca.DM(scene.position))}
    for i, (fin, c) in enumerate(zip(b.fingers, cs), start=1):
        out.update({f"joints{i}": fin.joints, f"Pi{i}": fin.Pi, f"p_f{i}": c.p_f,
                    f"p_o{i}": c.p_o, f"psi{i}": c.psi})
    return out
