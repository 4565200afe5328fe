"""SymPy derivation of the 2D finger-object model (Yoshida-Arimoto-Tahara 2009).

Conventions: ``grasping_sym.model.planar`` and MODELS.md section 1. With unit tangents
``T0 = c0'/|c0'|`` (fingertip) and ``T1 = c1'/|c1'|`` (object), the paper's angles are
``sin psi0 = T0x, cos psi0 = T0y`` and ``sin theta1 = T1x, cos theta1 = T1y``, so no arctangent
is needed except in the tangency defect. In the inertial frame

    b1 = Rot(-theta) T1,  n1 = (b1y, -b1x),  b0 = Rot(pi/2 - q1 - q2) T0 (= b1 at contact)
    lb0 = X0 T0x + Y0 T0y,   ln0 = X0 T0y - Y0 T0x                      (paper 7, 9)
    lb1 = -X T1x - Y T1y,    ln1 = -X T1y + Y T1x                       (paper 8, 10)
    Q1 = (O01 - Om).n1,  R1 = (O01 - Om).b1
    delta = signed angle from b1 to b0   (= phi1 - psi0 - pi/2, zero on the manifold)
    Q = Q1 + ln0 + ln1 - lb0 delta                                      (paper 14)
    R = R1 + lb0 + lb1 + ln0 delta                                      (paper 24)

With ``u`` held fixed, grad Q = (lb1, J01^T n1 + lb0 e) and grad R = (-ln1, J01^T b1 - ln0 e)
on the manifold: the normal and tangential relative velocities of the two material points
at the contact. The equations of motion are

    I theta'' + f dQ/dtheta + lam dR/dtheta = 0
    G(q) q'' + (G'/2 + S) q' + f dQ/dq + lam dR/dq = u_c                 (paper 27-28)
    u_c = -c q' - J01^T (fd/r)(O01 - Om)                                 (paper 32)

so that at equilibrium f = -(fd/r) Q1 and lam = -(fd/r) R1 (MODELS.md signs). The contact
moves by the update law (29) in arclength, ``s' = (q1' + q2' - theta')/(kappa0 + kappa1)``,
written for any parameterisation as ``u0' = s'/|c0'(u0)|``, ``u1' = s'/|c1'(u1)|``.
"""
from __future__ import annotations

from dataclasses import replace
from functools import lru_cache

import sympy as sp

from grasping_sym.derive.contour_functions import FINGERTIP, OBJECT
from grasping_sym.derive.system import ConstrainedSystem
from grasping_sym.model.planar import PARAMETERS, PlanarFingerScene


def _rot(a: sp.Expr, v: sp.Matrix) -> sp.Matrix:
    c, s = sp.cos(a), sp.sin(a)
    return sp.Matrix([c * v[0] - s * v[1], s * v[0] + c * v[1]])


def template_parameters(gravity: bool) -> tuple[str, ...]:
    """Names of every parameter of a template, in order (the pivot and gravity included)."""
    return (*PARAMETERS, "xm", "ym", *(("gx", "gy") if gravity else ()))


def has_gravity(scene: PlanarFingerScene) -> bool:
    """Whether the scene models gravity at all (no terms are derived otherwise)."""
    return scene.gravity is not None and any(scene.gravity)


def parameter_values(scene: PlanarFingerScene) -> dict[str, float]:
    """Values of every template parameter for ``scene`` (solves the initial configuration)."""
    values = {k: float(scene.params[k]) for k in PARAMETERS}
    values["xm"], values["ym"] = scene.pivot
    if has_gravity(scene):
        values["gx"], values["gy"] = (float(g) for g in scene.gravity)
    return values


def derive_planar(scene: PlanarFingerScene) -> ConstrainedSystem:
    """The closed-loop pieces of ``scene``: its template with the scene's choices.

    Parameters stay symbols; ``system.params`` are the run-time inputs and
    ``system.constants`` the values of the others, which the translation to CasADi folds
    into the code. ``system.outputs`` holds only the outputs the scene requests.
    """
    template = derive_template(scene.shared_parameter, has_gravity(scene))
    values = parameter_values(scene)
    symbols = {str(sym): sym for sym in template.params}
    return replace(
        template,
        outputs={k: template.outputs[k] for k in scene.outputs},
        params=[symbols[k] for k in scene.runtime],
        constants={symbols[k]: v for k, v in values.items() if k not in scene.runtime},
    )


@lru_cache(maxsize=8)
def derive_template(shared: bool, gravity: bool) -> ConstrainedSystem:
    """Derive the 2D model for any contours, with every parameter a symbol.

    Depends only on the structure: one shared contact parameter ``s`` (both contours
    unit-speed) or two (``u0``, ``u1``), and whether gravity is modelled. The contours enter
    through the abstract functions of ``contour_functions``; every output is derived.
    """
    th, q1, q2 = sp.symbols("theta q1 q2", real=True)
    dth, dq1, dq2 = sp.symbols("dtheta dq1 dq2", real=True)
    if shared:
        s = sp.Symbol("s", real=True)
        u0 = u1 = s
        us = [s]
    else:
        u0, u1 = sp.symbols("u0 u1", real=True)
        us = [u0, u1]
    q = sp.Matrix([th, q1, q2])
    v = sp.Matrix([dth, dq1, dq2])
    P = {k: sp.Symbol(k, real=True) for k in template_parameters(gravity)}
    Om = sp.Matrix([P["xm"], P["ym"]])

    # ---- finger kinematics and Lagrangian (uniform rods, joints at the origin)
    l11, l12, m11, m12 = P["l11"], P["l12"], P["m11"], P["m12"]
    d1 = sp.Matrix([sp.sin(q1), sp.cos(q1)])
    d12 = sp.Matrix([sp.sin(q1 + q2), sp.cos(q1 + q2)])
    O01 = l11 * d1 + l12 * d12
    com1 = l11 / 2 * d1
    com2 = l11 * d1 + l12 / 2 * d12
    qf = sp.Matrix([q1, q2])
    vf = sp.Matrix([dq1, dq2])
    J01 = O01.jacobian(qf)
    vcom1, vcom2 = com1.jacobian(qf) * vf, com2.jacobian(qf) * vf
    kin = (m11 * vcom1.dot(vcom1) + m12 * vcom2.dot(vcom2)
           + m11 * l11**2 / 12 * dq1**2 + m12 * l12**2 / 12 * (dq1 + dq2) ** 2
           + P["I"] * dth**2) / 2
    pot = sp.Integer(0)
    if gravity:
        g = sp.Matrix([P["gx"], P["gy"]])
        pot = -(m11 * g.dot(com1) + m12 * g.dot(com2))
    M = sp.hessian(kin, v)
    Mv = M * v
    # h = M' v - dK/dq + dV/dq  (Euler-Lagrange with L = K - V)
    h = Mv.jacobian(q) * v - sp.Matrix([kin]).jacobian(q).T + sp.Matrix([pot]).jacobian(q).T

    # ---- contour geometry at the contact, through abstract Frenet functions
    F0, F1 = FINGERTIP, OBJECT
    X0, Y0, T0x, T0y = F0.X(u0), F0.Y(u0), F0.Tx(u0), F0.Ty(u0)
    X, Y, T1x, T1y = F1.X(u1), F1.Y(u1), F1.Tx(u1), F1.Ty(u1)
    kappa0 = F0.kappa(u0)
    kappa1 = -F1.kappa(u1)
    lb0 = X0 * T0x + Y0 * T0y
    ln0 = X0 * T0y - Y0 * T0x
    lb1 = -X * T1x - Y * T1y
    ln1 = -X * T1y + Y * T1x
    b1 = _rot(-th, sp.Matrix([T1x, T1y]))
    n1 = sp.Matrix([b1[1], -b1[0]])
    b0 = _rot(sp.pi / 2 - q1 - q2, sp.Matrix([T0x, T0y]))
    delta = sp.atan2(b1[0] * b0[1] - b1[1] * b0[0], b1.dot(b0))
    Q1 = (O01 - Om).dot(n1)
    R1 = (O01 - Om).dot(b1)
    C = sp.Matrix([Q1 + ln0 + ln1 - lb0 * delta, R1 + lb0 + lb1 + ln0 * delta])

    # ---- update law (29), for any parameterisation
    sdot = (dq1 + dq2 - dth) / (kappa0 + kappa1)
    if shared:
        sigma = sp.Matrix([sdot])
    else:
        sigma = sp.Matrix([sdot / F0.speed(u0), sdot / F1.speed(u1)])

    # ---- constraint derivatives along the motion (u carried by sigma)
    z = sp.Matrix([*q, *us])
    zdot = sp.Matrix([*v, *sigma])
    Cz = C.jacobian(z)
    A = Cz[:, :3]
    Cdot = Cz * zdot
    # C' is a function of (z, v) (u' = sigma(z, v) written out), so along the motion
    # C'' = dC'/dz z' + dC'/dv a: the dependence of u'' on a enters through dC'/dv.
    Ahat = Cdot.jacobian(v)
    bhat = Cdot.jacobian(z) * zdot

    # ---- controller (32), with gravity compensation when gravity is modelled
    ctrl = -P["c"] * vf - J01.T * (P["fd"] / P["r"]) * (O01 - Om)
    if pot != 0:
        ctrl += sp.Matrix([pot]).jacobian(qf).T
    tau = sp.Matrix([0, *ctrl])

    f, lam = sp.symbols("f lam", real=True)
    system = ConstrainedSystem(
        state=[*q, *v, *us], n=3, params=[], mass_matrix=M, bias=h, force=tau,
        constraint=C, constraint_jac=A, constraint_rate=Cdot, acc_jac=Ahat, acc_bias=bhat,
        csm_damping=sp.Matrix([2 * P["gf"], 2 * P["gl"]]),
        csm_stiffness=sp.Matrix([P["wf"], P["wl"]]),
        contact_rates=sigma, multipliers=[f, lam],
    )
    available = {
        "Q": C[0], "R": C[1], "f": f, "lam": lam,
        "delta_f": f + P["fd"] / P["r"] * Q1, "delta_lam": lam + P["fd"] / P["r"] * R1,
        "N1": ln0 * lb1 - lb0 * ln1, "kappa_sum": kappa0 + kappa1,
        "constraint_residual": sp.Max(sp.Abs(C[0]), sp.Abs(C[1])),
        "tangency_defect": delta, "kinetic_energy": kin, "potential_energy": pot,
        "power": vf.dot(ctrl),
    }
    system.outputs = available
    system.params = list(P.values())
    return system
