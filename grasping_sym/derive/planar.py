"""SymPy derivation of the 2D finger-object model (Yoshida-Arimoto-Tahara 2009).

Conventions: ``grasping_sym.model.planar`` and docs/conventions.md section 1. With unit tangents
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
    G(q) q'' + (G'/2 + S) q' + f dQ/dq + lam dR/dq = tau                 (paper 27-28)

The joint torques ``tau`` are symbols of the template (``tau_q1, tau_q2``; with several
fingers ``tau_q11, ...``): the controller is a layer of its own (``grasping_sym.model.controllers``),
so the contact dynamics are derived once for every controller. The paper's law (32),

    tau = -c q' - J01^T (fd/r)(O01 - Om)                                 (paper 32)

(``paper_law``; ``derive_planar`` closes the loop with it), gives at equilibrium
f = -(fd/r) Q1 and lam = -(fd/r) R1 (docs/conventions.md signs). The contact
moves by the update law (29) in arclength, ``s' = (q1' + q2' - theta')/(kappa0 + kappa1)``,
written for any parameterisation as ``u0' = s'/|c0'(u0)|``, ``u1' = s'/|c1'(u1)|``.
"""
from __future__ import annotations

from dataclasses import replace
from functools import lru_cache

import sympy as sp

from grasping_sym.derive.system import ConstrainedSystem
from grasping_sym.model.planar import FREE_PARAMETERS, PARAMETERS, PlanarFingerScene
from grasping_sym.symbolic.contour_functions import OBJECT, fingertip_functions


def _rot(a: sp.Expr, v: sp.Matrix) -> sp.Matrix:
    c, s = sp.cos(a), sp.sin(a)
    return sp.Matrix([c * v[0] - s * v[1], s * v[0] + c * v[1]])


def template_parameters(gravity: bool, n_fingers: int = 1, free: bool = False) -> tuple[str, ...]:
    """Names of every parameter of a template, in order (the pivot and gravity included).

    Finger 1 is the paper's (joints at the origin, ``l11, l12, m11, m12``); finger ``i >= 2``
    adds its links ``l{i}1, l{i}2, m{i}1, m{i}2`` and its base ``xb{i}, yb{i}``. A free
    object adds its mass ``M``; ``xm, ym`` are then the start's mass centre, which only the
    paper's law reads (the point it pulls toward).
    """
    extra = tuple(f"{k}{i}{j}" for i in range(2, n_fingers + 1) for k, j in
                  (("l", 1), ("l", 2), ("m", 1), ("m", 2), ("xb", ""), ("yb", "")))
    return (*PARAMETERS, *(FREE_PARAMETERS if free else ()), "xm", "ym",
            *(("gx", "gy") if gravity else ()), *extra, *torque_names(n_fingers))


def torque_names(n_fingers: int = 1) -> tuple[str, ...]:
    """The template's joint-torque symbols, finger by finger (``tau_q1, tau_q2`` for one)."""
    if n_fingers == 1:
        return ("tau_q1", "tau_q2")
    return tuple(f"tau_q{i}{j}" for i in range(1, n_fingers + 1) for j in (1, 2))


def has_gravity(scene: PlanarFingerScene) -> bool:
    """Whether the scene models gravity at all (no terms are derived otherwise)."""
    return scene.gravity is not None and any(scene.gravity)


def parameter_values(scene: PlanarFingerScene) -> dict[str, float]:
    """Values of every template parameter for ``scene`` (solves the initial configuration)."""
    values = {k: float(scene.params[k]) for k in scene.parameter_names}
    values["xm"], values["ym"] = scene.pivot
    if has_gravity(scene):
        values["gx"], values["gy"] = (float(g) for g in scene.gravity)
    for i, f in enumerate(scene.extra_fingers, start=2):
        values.update({f"l{i}1": float(f.lengths[0]), f"l{i}2": float(f.lengths[1]),
                       f"m{i}1": float(f.masses[0]), f"m{i}2": float(f.masses[1]),
                       f"xb{i}": float(f.base[0]), f"yb{i}": float(f.base[1])})
    return values


def derive_planar(scene: PlanarFingerScene) -> ConstrainedSystem:
    """The closed-loop pieces of ``scene`` under the paper's law (32): its template with the
    scene's choices and the joint torques of :func:`paper_law` (the SymPy path the tests
    check the controller layer against).

    Parameters stay symbols; ``system.params`` are the run-time inputs and
    ``system.constants`` the values of the others, which the translation to CasADi folds
    into the code. ``system.outputs`` holds only the outputs the scene requests.
    """
    template = derive_template(scene.shared_parameter, has_gravity(scene), scene.n_fingers,
                               scene.free)
    values = parameter_values(scene)
    symbols = {str(sym): sym for sym in template.params}
    law = paper_law(template, scene.n_fingers, has_gravity(scene))
    return replace(
        template,
        force=template.force.xreplace(law),
        outputs={k: sp.sympify(template.outputs[k]).xreplace(law) for k in scene.outputs},
        params=[symbols[k] for k in scene.runtime],
        constants={symbols[k]: v for k, v in values.items() if k not in scene.runtime},
    )


def paper_law(template: ConstrainedSystem, n_fingers: int, gravity: bool) -> dict:
    """The paper's law (32) per finger, ``-c q' - J01^T (fd/r)(O01 - Om)`` plus the finger's
    gravity torque when gravity is modelled, as a substitution of the template's torques."""
    P = {str(s): s for s in template.params}
    Om = sp.Matrix([P["xm"], P["ym"]])
    law = {}
    for i in range(1, n_fingers + 1):
        fin = _finger(i, n_fingers, P, gravity)
        tau = -P["c"] * fin["v"] - fin["J01"].T * (P["fd"] / P["r"]) * (fin["O01"] - Om)
        if fin["pot"] != 0:
            tau += sp.Matrix([fin["pot"]]).jacobian(fin["q"]).T
        names = torque_names(n_fingers)[2 * i - 2:2 * i]
        law.update({P[k]: e for k, e in zip(names, tau)})
    return law


def _finger(i: int, n_fingers: int, P: dict, gravity: bool):
    """Kinematics and Lagrangian pieces of finger ``i`` (uniform rods)."""
    one = n_fingers == 1
    q1, q2 = sp.symbols("q1 q2" if one else f"q{i}1 q{i}2", real=True)
    dq1, dq2 = sp.symbols("dq1 dq2" if one else f"dq{i}1 dq{i}2", real=True)
    l1, l2, m1, m2 = (P[f"{k}{i}{j}"] for k, j in (("l", 1), ("l", 2), ("m", 1), ("m", 2)))
    base = sp.Matrix([P[f"xb{i}"], P[f"yb{i}"]]) if i > 1 else sp.zeros(2, 1)
    d1 = sp.Matrix([sp.sin(q1), sp.cos(q1)])
    d12 = sp.Matrix([sp.sin(q1 + q2), sp.cos(q1 + q2)])
    O01 = base + l1 * d1 + l2 * d12
    com1 = base + l1 / 2 * d1
    com2 = base + l1 * d1 + l2 / 2 * d12
    qf, vf = sp.Matrix([q1, q2]), sp.Matrix([dq1, dq2])
    vcom1, vcom2 = com1.jacobian(qf) * vf, com2.jacobian(qf) * vf
    kin = (m1 * vcom1.dot(vcom1) + m2 * vcom2.dot(vcom2)
           + m1 * l1**2 / 12 * dq1**2 + m2 * l2**2 / 12 * (dq1 + dq2) ** 2) / 2
    pot = sp.Integer(0)
    if gravity:
        g = sp.Matrix([P["gx"], P["gy"]])
        pot = -(m1 * g.dot(com1) + m2 * g.dot(com2))
    return {"q": qf, "v": vf, "O01": O01, "J01": O01.jacobian(qf), "kin": kin, "pot": pot}


def _contact(fin: dict, F0, u0, u1, th, Om):
    """Contact geometry of one finger with the object, through abstract Frenet functions."""
    F1 = OBJECT
    q1, q2 = fin["q"]
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
    Q1 = (fin["O01"] - Om).dot(n1)
    R1 = (fin["O01"] - Om).dot(b1)
    return {"C": [Q1 + ln0 + ln1 - lb0 * delta, R1 + lb0 + lb1 + ln0 * delta], "Q1": Q1, "R1": R1,
            "O01": fin["O01"], "n1": n1, "b1": b1,
            "delta": delta, "kappa_sum": kappa0 + kappa1, "N1": ln0 * lb1 - lb0 * ln1}


@lru_cache(maxsize=8)
def derive_template(shared: bool, gravity: bool, n_fingers: int = 1,
                    free: bool = False) -> ConstrainedSystem:
    """Derive the 2D model for any contours, with every parameter a symbol.

    Depends only on the structure: one shared contact parameter ``s`` (both contours
    unit-speed) or two (``u0``, ``u1``), whether gravity is modelled, the number of
    fingers (``n_fingers > 1``: each finger ``i`` has its own fingertip contour, contact
    parameters ``u0_{i}, u1_{i}`` and joints ``q{i}1, q{i}2``; ``shared`` must be false),
    and whether the object is free (``free``: its mass centre ``Om = (x, y)`` is a state,
    with kinetic energy ``M |Om'|^2 / 2`` and, under gravity, potential ``-M g.Om``; the
    pivot's ``I theta'^2 / 2`` becomes the turn about the mass centre). The contours enter
    through the abstract functions of ``contour_functions``; every output is derived.
    """
    if n_fingers < 1 or (n_fingers > 1 and shared):
        raise ValueError(f"n_fingers = {n_fingers}, shared = {shared}: need n_fingers >= 1, and "
                         "separate contact parameters (shared=False) for several fingers")
    one = n_fingers == 1
    th, dth = sp.symbols("theta dtheta", real=True)
    P = {k: sp.Symbol(k, real=True) for k in template_parameters(gravity, n_fingers, free)}
    fingers = [_finger(i, n_fingers, P, gravity) for i in range(1, n_fingers + 1)]
    obj_q, obj_v = [th], [dth]
    kin0, pot0 = P["I"] * dth**2 / 2, sp.Integer(0)
    if free:
        x, y, dx, dy = sp.symbols("x y dx dy", real=True)
        obj_q, obj_v = [x, y, th], [dx, dy, dth]
        Om = sp.Matrix([x, y])
        kin0 += P["M"] * (dx**2 + dy**2) / 2
        if gravity:
            pot0 = -P["M"] * (P["gx"] * x + P["gy"] * y)
    else:
        Om = sp.Matrix([P["xm"], P["ym"]])
    q = sp.Matrix([*obj_q, *[x for f in fingers for x in f["q"]]])
    v = sp.Matrix([*obj_v, *[x for f in fingers for x in f["v"]]])
    kin = sum((f["kin"] for f in fingers), kin0)
    pot = sum((f["pot"] for f in fingers), pot0)
    M = sp.hessian(kin, v)
    Mv = M * v
    # h = M' v - dK/dq + dV/dq  (Euler-Lagrange with L = K - V)
    h = Mv.jacobian(q) * v - sp.Matrix([kin]).jacobian(q).T + sp.Matrix([pot]).jacobian(q).T
    us, C, sigma, contacts = _contacts(fingers, shared, one, th, dth, Om)
    A, Cdot, Ahat, bhat = _constraint_derivatives(C, q, v, us, sigma, shared)

    # ---- joint torques: symbols (the controller layer gives them)
    taus = [P[k] for k in torque_names(n_fingers)]
    ctrls = [sp.Matrix(taus[2 * i:2 * i + 2]) for i in range(n_fingers)]
    tau = sp.Matrix([*[0] * len(obj_q), *taus])

    mus = sp.symbols("f lam" if one else " ".join(f"f{i} lam{i}" for i in range(1, n_fingers + 1)),
                     real=True)
    system = ConstrainedSystem(
        state=[*q, *v, *us], n=len(q), params=[], mass_matrix=M, bias=h, force=tau,
        constraint=C, constraint_jac=A, constraint_rate=Cdot, acc_jac=Ahat, acc_bias=bhat,
        csm_damping=sp.Matrix([2 * P["gf"], 2 * P["gl"]] * n_fingers),
        csm_stiffness=sp.Matrix([P["wf"], P["wl"]] * n_fingers),
        contact_rates=sigma, multipliers=list(mus),
    )
    system.outputs = _outputs(contacts, mus, P, C, kin, pot, fingers, ctrls, one, Om)
    system.params = list(P.values())
    return system


def _contacts(fingers: list[dict], shared: bool, one: bool, th, dth, Om):
    """``(u, C, sigma, contacts)``: the contact parameters, constraints, update law (29) for
    any parameterisation, and each contact's geometry (``_contact``)."""
    us, C, sigma, contacts = [], [], [], []
    for i, fin in enumerate(fingers, start=1):
        F0 = fingertip_functions(i)
        if shared:
            u0 = u1 = sp.Symbol("s", real=True)
            us.append(u0)
        else:
            u0, u1 = sp.symbols("u0 u1" if one else f"u0_{i} u1_{i}", real=True)
            us += [u0, u1]
        c = _contact(fin, F0, u0, u1, th, Om)
        contacts.append(c)
        C += c["C"]
        sdot = (fin["v"][0] + fin["v"][1] - dth) / c["kappa_sum"]
        sigma += [sdot] if shared else [sdot / F0.speed(u0), sdot / OBJECT.speed(u1)]
    return us, sp.Matrix(C), sp.Matrix(sigma), contacts


def _constraint_derivatives(C, q, v, us, sigma, shared: bool):
    """``(A, C', Ahat, bhat)`` along the motion (``u`` carried by ``sigma``).

    C'' = dC'/dz z' + dC'/dv a (C' is a function of (z, v), u' = sigma(z, v) written out).
    With one shared contact parameter, SymPy's terms cancel into 2 % shorter code (paper2d's
    rhs: 954 SX instructions against 972), and the template is committed; otherwise C'' is
    left to the translation to CasADi (``Ahat``, ``bhat`` None), whose AD through the Frenet
    rules takes a fraction of SymPy's time (0.05 s against 1.3 s for two fingers) and gives
    shorter code (2312 instructions against 2453 for two fingers).
    """
    z = sp.Matrix([*q, *us])
    zdot = sp.Matrix([*v, *sigma])
    Cz = C.jacobian(z)
    A = Cz[:, :len(q)]
    Cdot = Cz * zdot
    Ahat = Cdot.jacobian(v) if shared else None
    bhat = Cdot.jacobian(z) * zdot if shared else None
    return A, Cdot, Ahat, bhat


def _outputs(contacts, mus, P, C, kin, pot, fingers, ctrls, one: bool, Om) -> dict:
    """Every output of the template, ``mus`` standing for the multipliers. ``delta_f``,
    ``delta_lam`` measure the paper's equilibrium about the point its law pulls toward
    (``xm, ym``: the pivot, or a free object's start point)."""
    anchor = sp.Matrix([P["xm"], P["ym"]])
    available = {}
    for i, c in enumerate(contacts, start=1):
        tag = "" if one else str(i)
        f, lam = mus[2 * i - 2], mus[2 * i - 1]
        available.update({
            f"Q{tag}": c["C"][0], f"R{tag}": c["C"][1], f"f{tag}": f, f"lam{tag}": lam,
            f"delta_f{tag}": f + P["fd"] / P["r"] * (c["Q1"] if anchor == Om
                                                     else (c["O01"] - anchor).dot(c["n1"])),
            f"delta_lam{tag}": lam + P["fd"] / P["r"] * (c["R1"] if anchor == Om
                                                         else (c["O01"] - anchor).dot(c["b1"])),
            ("N1" if one else f"N1_{i}"): c["N1"], f"kappa_sum{tag}": c["kappa_sum"],
            f"tangency_defect{tag}": c["delta"],
        })
    available.update({
        "constraint_residual": sp.Max(*[sp.Abs(e, evaluate=False) for e in C], evaluate=False),
        "kinetic_energy": kin, "potential_energy": pot,
        "power": sum((fin["v"].dot(ctrl) for fin, ctrl in zip(fingers, ctrls)), sp.Integer(0)),
    })
    if one:  # keep the 2D outputs in their historical order
        order = ["Q", "R", "f", "lam", "delta_f", "delta_lam", "N1", "kappa_sum",
                 "constraint_residual", "tangency_defect", "kinetic_energy", "potential_energy", "power"]
        available = {k: available[k] for k in order}
    return available
