"""Closed-loop equations of a 3D grasping scene (``model.grasp3d``) as CasADi SX.

Division of labour: SymPy derives every formula from the definitions -- the fingers'
kinematics and Lagrangian dynamics (``derive.spatial``), the surfaces' fundamental forms and
Montana forms (``geometry.surfaces``), the contact update law on generic forms
(``derive.contact3d``) -- and ``symbolic.translate`` turns them into SX with shared
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

import casadi as ca

from grasping_sym.derive.bodies3d import (  # noqa: F401 - their import path for the floors above
    Bodies,
    _finger_symbolic,  # benchmarks/paper3d.py times the SymPy stages one by one
    bodies,
    finger_function,
    finger_sx,
    state_slices,
    surface_sx,
    template_of,
)
from grasping_sym.derive.grasp3d_paper import FRAME_GAIN, PAPER  # noqa: F401 - FRAME_GAIN: its path
from grasping_sym.derive.loop3d import (  # noqa: F401 - their import path for the floors above
    Contact,
    Formulation,
    _generic_rates,  # benchmarks/paper3d.py
    applied_forces,
    close,
    constraint_derivatives,
    contact_rates_sx,
    contacts,
    dynamics,
    fingertip_centre,
    geometry,
    outputs,
    relative_curvature_min,
    split_torques,
)
from grasping_sym.derive.system import ConstrainedSystem
from grasping_sym.model.grasp3d import GraspScene3D


# ------------------------------------------------------------------ the regular formulation
def _regular_frame_angle(eta, frame, object_surface, R):
    return eta[4]


def _regular_coordinates(b: Bodies, cs: list[Contact]):
    """``(u_f, v_f, u_o, v_o, psi)`` of every contact, carried by Montana's rates."""
    return (ca.vertcat(*[ca.vertcat(e[:4], c.psi) for e, c in zip(b.etas, cs)]),
            ca.vertcat(*[c.rates for c in cs]))


def _regular_state_rates(scene, b, cs, xdot_bodies):
    return None, {}


def _regular_start_conditions(b: Bodies, cs: list[Contact]) -> dict[str, ca.SX]:
    """The gaps C, the normals opposed, the frame angle psi read from the surfaces' frames,
    a unit quaternion."""
    out: dict[str, ca.SX] = {}
    for i, (c, eta) in enumerate(zip(cs, b.etas), start=1):
        xf, yf = c.frame[:, 0], c.frame[:, 1]
        n_o, x_o = b.R @ c.object["n"], b.R @ c.object["x"]
        psi = eta[4]
        out.update({
            f"Qn{i}": c.gap[0], f"Qb{i}": c.gap[1], f"Qe{i}": c.gap[2],
            f"normal_x{i}": ca.dot(xf, n_o), f"normal_y{i}": ca.dot(yf, n_o),
            # psi = atan2(-x_o.y_f, x_o.x_f), as sin/cos: no branch cut in the condition
            f"frame_angle{i}": ca.sin(psi) * ca.dot(x_o, xf) + ca.cos(psi) * ca.dot(x_o, yf),
        })
    out["quaternion_norm"] = ca.dot(b.quat, b.quat) - 1
    return out


#: Contact states ``(u_f, v_f, u_o, v_o, psi)``, Montana's rolling rates: regular at rest.
REGULAR = Formulation(name="regular", n_eta=5, extra=False, frame_angle=_regular_frame_angle,
                      constraint_coordinates=_regular_coordinates, state_rates=_regular_state_rates,
                      start_conditions=_regular_start_conditions)

FORMULATIONS = {"regular": REGULAR, "paper": PAPER}


# ------------------------------------------------------------------ the closed loop
def derive_grasp3d(scene: GraspScene3D, surface_fn=None, torque_inputs: bool = False,
                   torques=None, mass_properties=None) -> ConstrainedSystem:
    """The scene's closed loop as a :class:`~grasping_sym.derive.system.ConstrainedSystem` of SX.

    ``surface_fn(slot, surface, u, v, extra)`` gives a contour slot's point, frame and forms
    (the dict of :func:`surface_sx`; slot ``2 i`` is contact ``i``'s fingertip, ``2 i + 1``
    the object there); default :func:`surface_sx` itself. A structure passes the surfaces'
    values as inputs instead (``assemble.structure3d``), and the object's mass and inertia
    (``mass_properties``: SX, default the scene's numbers).

    ``p`` holds the run-time parameters ``scene.runtime``, then ``scene.start_param_names``:
    ``r_bar0`` (m), the mean of the fingertip centres at the start, where the centre spring
    of the controller is at rest (``start3d`` computes it; absent when ``k_center = 0``),
    then the inputs' coefficients (``scene.p_names``). The joint torques are the controller
    layer's (``assemble.controller``); with ``torque_inputs`` they are the last entries of
    ``p`` instead, which then holds no inputs' coefficients (a structure's, whose model
    computes the torques).
    """
    form = FORMULATIONS[scene.formulation]
    x, t = ca.SX.sym("x", len(scene.state_names)), ca.SX.sym("t")
    p_names = _param_names(scene, torque_inputs)
    p = ca.SX.sym("p", len(p_names))
    b = bodies(scene, x, form.n_eta, mass_properties)
    charts = {slot: p[p_names.index(name)] for slot, name, _ in scene.chart_slots() if name in p_names}
    surface_fn = surface_fn or (lambda slot, s, u, v, extra: surface_sx(s, u, v, extra, chart=charts.get(slot)))
    cs = contacts(scene, b, form, surface_fn)
    C = ca.vertcat(*[c.gap for c in cs])
    A, Cdot, Ahat, bhat = constraint_derivatives(C, b, *form.constraint_coordinates(b, cs))
    M, h = dynamics(scene, b)
    torques, reads_time = _joint_torques(scene, t, x, p, len(p_names), torque_inputs, torques)
    u = split_torques(scene, torques)
    tau, dissipation = applied_forces(scene, b, cs, u)
    gain = p[scene.runtime.index("gain")] if "gain" in scene.runtime else ca.SX(scene.params["gain"])
    system = ConstrainedSystem(
        state=x, n=b.Vs.numel(), params=p, mass_matrix=M, bias=h, force=tau, constraint=C,
        constraint_jac=A, constraint_rate=Cdot, acc_jac=Ahat, acc_bias=bhat,
        csm_damping=ca.repmat(2 * gain, C.numel(), 1), csm_stiffness=ca.repmat(gain * gain, C.numel(), 1),
        contact_rates=ca.vertcat(*[c.rates for c in cs]), multipliers=None,
        position_rates=b.zb_dot, param_names=p_names, t=t, reads_time=reads_time)
    xdot, system.multipliers = close(b, system.pieces())
    nb = b.zb.numel() + b.Vs.numel()
    eta_dot, extra = form.state_rates(scene, b, cs, xdot[:nb])
    system.xdot = xdot if eta_dot is None else ca.vertcat(xdot[:nb], eta_dot)
    system.outputs = {**extra, **outputs(scene, b, cs, C, system.multipliers, u, dissipation)}
    system.start_conditions = form.start_conditions(b, cs)
    system.start_values = fingertip_centre(b.fingers)
    system.geometry = geometry(scene, b, cs)
    return system


def _param_names(scene: GraspScene3D, torque_inputs: bool) -> tuple[str, ...]:
    if torque_inputs:
        return (*scene.runtime, *scene.start_param_names, *(f"tau_{k}" for k in scene.joint_names))
    return scene.p_names


def _joint_torques(scene: GraspScene3D, t, x, p, n_p: int, torque_inputs: bool,
                   law) -> tuple[ca.SX, bool]:
    """The joint torques (every finger's, in order) and whether the law reads the time: the
    last entries of ``p`` (a structure's inputs), the controller layer's (``law(scene, t, x,
    p) -> (torques, uses_object, reads_time)``, ``assemble.controller.controller_torques``,
    given by the assembly), or none (zero: what only reads the geometry and the constraints,
    the start solver and the figures)."""
    nQ = sum(f.chain.n for f in scene.fingers)
    if torque_inputs:
        return p[n_p - nQ:], False
    if law is None:
        return ca.SX.zeros(nQ, 1), False
    torques, _, reads_time = law(scene, t, x, p)
    return torques, reads_time
