"""The paper formulation of a 3D scene's contacts (``scene.formulation == 'paper'``).

Contact states ``eta_i = (u_f, v_f, u_o, v_o, s, Psi0 (9), Psi1 (9))``: the paper's (Es),
(Efs) with the geodesic curvatures of (31)-(32) (and the geodesic torsion the printed (Efs)
omits, see the oracle ``tests/oracles/reference3d_paper.py``). The bodies' accelerations come
from the same Lagrangian pieces as the regular formulation's (``derive.loop3d``), evaluated at
the contact points carried by the paper's states and the frame angle read from the two
surfaces' frames there. It divides by ``D_i = omega0.e0 + omega1.e1`` (output
``frame_denominator{i}``), 0/0 at rest.
"""
from __future__ import annotations

from dataclasses import dataclass

import casadi as ca

from grasping_sym.derive.bodies3d import Bodies, Finger
from grasping_sym.derive.loop3d import Contact, Formulation

#: 1/s, damping of the paper formulation's frames' orthonormality drift (zero on SO(3)).
FRAME_GAIN = 50.0


def _frame_angle(eta, frame, object_surface, R):
    """psi read from the two surfaces' frames at the carried points."""
    xo = R @ object_surface["x"]
    return ca.atan2(-ca.dot(xo, frame[:, 1]), ca.dot(xo, frame[:, 0]))


def _coordinates(b: Bodies, cs: list[Contact]):
    """``C`` depends on the contact coordinates only through the carried ``(u, v)``: psi does
    not enter it."""
    return ca.vertcat(*[e[:4] for e in b.etas]), ca.vertcat(*[c.rates[:4] for c in cs])


def _darboux(kg, tg, kn):
    return ca.vertcat(ca.horzcat(0, -kn, tg), ca.horzcat(kn, 0, -kg), ca.horzcat(-tg, kg, 0))


def _curvatures(s: dict, P: ca.SX):
    """Normal curvature, geodesic torsion along the frame ``P``'s ``b`` and its surface
    coordinates' direction ``a`` (``T a = b``)."""
    Tp = ca.pinv(s["Tm"])
    a, cc = Tp @ P[:, 1], Tp @ P[:, 2]
    return -(a.T @ s["II"] @ a), cc.T @ s["II"] @ a, a


@dataclass
class _Tracking:
    """One contact's rates with its geodesic curvatures ``kg`` still symbols."""

    rates: ca.SX
    r25: ca.SX          # (25), whose time derivative fixes kg
    D: ca.SX            # omega0.e0 + omega1.e1
    Dn: ca.SX           # omega0.n0 + omega1.n1
    sdot: ca.SX
    drift: ca.SX        # the frames' worst orthonormality defect


def _contact_tracking(eta: ca.SX, c: Contact, fin: Finger, b: Bodies, k0, k1) -> _Tracking:
    """(Es), (Efs) for one contact with geodesic curvatures ``k0``, ``k1`` (object, finger)."""
    I3 = ca.DM.eye(3)
    P0 = ca.reshape(eta[5:14], 3, 3)
    P1 = ca.reshape(eta[14:23], 3, 3)
    w0 = b.R @ b.om
    w1 = fin.W @ fin.dq
    F0, F1 = b.R @ P0, fin.Pi @ P1
    kn0, tg0, a0 = _curvatures(c.object, P0)
    kn1, tg1, a1 = _curvatures(c.tip, P1)
    D = ca.dot(w0, F0[:, 2]) + ca.dot(w1, F1[:, 2])
    sdot = -D / (kn0 + kn1)
    Dn = ca.dot(w0, F0[:, 0]) + ca.dot(w1, F1[:, 0])
    r25 = ca.dot(w0, F0[:, 1]) - ca.dot(w1, F1[:, 1]) - (tg1 - tg0) * sdot
    P0dot = P0 @ _darboux(k0, tg0, kn0) * sdot - 0.5 * FRAME_GAIN * P0 @ (P0.T @ P0 - I3)
    P1dot = P1 @ _darboux(k1, tg1, kn1) * sdot - 0.5 * FRAME_GAIN * P1 @ (P1.T @ P1 - I3)
    rates = ca.vertcat(a1 * sdot, a0 * sdot, sdot, ca.reshape(P0dot, 9, 1), ca.reshape(P1dot, 9, 1))
    drift = ca.fmax(ca.mmax(ca.fabs(P0.T @ P0 - I3)), ca.mmax(ca.fabs(P1.T @ P1 - I3)))
    return _Tracking(rates=rates, r25=r25, D=D, Dn=Dn, sdot=sdot, drift=drift)


def _state_rates(scene, b: Bodies, cs: list[Contact], xdot_bodies: ca.SX):
    """Rates of ``(u_f, v_f, u_o, v_o, s, Psi0, Psi1)`` per contact: (Es), (Efs), (31)-(32);
    and the outputs ``frame_denominator{i}``, ``frame_orthonormality``."""
    kg = ca.SX.sym("kg", 2 * len(b.etas))
    tracks = [_contact_tracking(eta, c, fin, b, kg[2 * i], kg[2 * i + 1])
              for i, (eta, c, fin) in enumerate(zip(b.etas, cs, b.fingers))]
    eta_dot = ca.vertcat(*[tr.rates for tr in tracks])
    eta_dot = ca.substitute(eta_dot, kg, _geodesic_curvatures(tracks, kg, b.x, ca.vertcat(xdot_bodies, eta_dot)))
    extra = {f"frame_denominator{i}": tr.D for i, tr in enumerate(tracks, start=1)}
    extra["frame_orthonormality"] = ca.mmax(ca.vertcat(*[tr.drift for tr in tracks]))
    return eta_dot, extra


def _geodesic_curvatures(tracks: list[_Tracking], kg: ca.SX, x: ca.SX, xdot: ca.SX) -> ca.SX:
    """Each contact's ``(kg0, kg1)``: d/dt (25) = 0 is affine in them; (27): ``kg0 + kg1 =
    -Dn / s'``."""
    sol = []
    for i, tr in enumerate(tracks):
        d25 = ca.jtimes(tr.r25, x, xdot)
        kk = kg[2 * i:2 * i + 2]
        c0 = ca.substitute(d25, kg, ca.DM.zeros(kg.numel()))
        c12 = ca.jacobian(d25, kk)
        Amat = ca.vertcat(ca.horzcat(1, 1), c12)
        rhs = ca.vertcat(-tr.Dn / tr.sdot, -c0)
        sol.append(ca.solve(Amat, rhs))
    return ca.vertcat(*sol)


def _start_conditions(b: Bodies, cs: list[Contact]) -> dict:
    """None: the paper formulation starts from the regular one's start (``derive.start3d``)."""
    return {}


#: Contact states ``(u_f, v_f, u_o, v_o, s, Psi0, Psi1)`` (moving frames): singular at rest.
PAPER = Formulation(name="paper", n_eta=23, extra=True, frame_angle=_frame_angle,
                    constraint_coordinates=_coordinates, state_rates=_state_rates,
                    start_conditions=_start_conditions)
