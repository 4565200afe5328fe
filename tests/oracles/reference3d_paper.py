"""The paper's moving-frame formulation (Arimoto-Yoshida 2011, (25)-(33), (Es), (Efs)) of
the one-finger scene of :mod:`tests.oracles.reference3d`.

The bodies (finger ``q``, object quaternion, speeds), the constraints ``(Qn, Qb, Qe)``, the
multipliers, Baumgarte and the controller are reference3d's, evaluated by
``Reference3D._solve`` at the contact coordinates ``(u_f, v_f, u_o, v_o, psi)`` carried by
THIS formulation (``psi`` is recomputed from the two surface frames at those points, so no
state of the regular formulation is used). Only the tracking of the contact differs:

State (40)::

    x_ref[:11] (q, quat, q', omega)  (u_f, v_f, u_o, v_o) (4)  s (1)  Psi0 (9)  Psi1 (9)

``Psi0 = (n0, b0, e0)`` (object frame coordinates) and ``Psi1 = (n1, b1, e1)`` (fingertip
frame coordinates) are stored as 9 numbers, column-major (n, b, e), right-handed
(``e = n x b``), ``n`` the OUTWARD normal of its own surface. They follow the Darboux
(Frenet-Serret on a surface) equations ``Psi' = Psi Omega(kg, tg, kn) s' `` with::

    Omega = [[0, -kn, tg], [kn, 0, -kg], [-tg, kg, 0]]     (dn/ds = kn b - tg e, ...)

``kn = -a^T II a`` (positive for convex, ``II`` w.r.t. the outward normal, ``b = S_u a1 + S_v a2``),
``tg = c^T II a`` (geodesic torsion, ``e = S_u c1 + S_v c2``). The paper's (Efs) omits the
geodesic torsion ``tg``: that is exact only along lines of curvature (e.g. on a sphere);
on the ellipsoid it is not, so it is kept here. Orthonormality: the skew ``Omega`` keeps
``Psi`` on SO(3) in exact arithmetic; the integration drift is damped by
``-(k/2) Psi (Psi^T Psi - I)`` with ``k = FRAME_GAIN`` (zero on SO(3), so the solution is
unchanged), and the error is an output (2.9e-10 after 0.1 s of rolling on the ellipsoid).

Derivation (signs checked numerically by the tests): the frames must keep
``R Psi0 D = Pi Psi1``, ``D = diag(-1, 1, -1)`` (n1 = -n0, b1 = b0, e1 = -e0). With
``Delta = omega0 - omega1`` (world) in the components of ``(n0, b0, e0)``::

    Delta_n = -(kg0 + kg1) s'       (paper (27))
    Delta_b = (tg1 - tg0) s'        (paper (25), with tg = 0 there)
    Delta_e = -(kn0 + kn1) s'       (paper (26)/(Es))

so ``s' = -(omega0.e0 + omega1.e1)/(kn0 + kn1)`` in these (right-handed, outward) frames;
the paper's ``+`` sign comes from its opposite sign of angular velocity (its eq (8), see
docs/design-3d.md). The two geodesic curvatures follow, as in (28)-(32), from (27) and the
time derivative of (25) (computed by AD, including the accelerations from the dynamics as
the paper's (40)): a 2x2 linear system whose determinant is proportional to
``D = omega0.e0 + omega1.e1 = -(kn0 + kn1) s'``, and (27) itself divides by ``s'``. At rest
both are 0/0: :class:`MovingFrameSingularityError`.

Surface coordinates: ``(u, v)' = T^+ b s'`` with ``T = [S_u S_v]`` (least squares in the
tangent plane), for both surfaces.
"""
from __future__ import annotations

import casadi as ca
import numpy as np

from grasping_sym.errors import MovingFrameSingularityError
from grasping_sym.geometry.surfaces import ParametricSurface, U, V
from grasping_sym.symbolic.translate import SympyToCasadi
from tests.oracles.reference3d import SL_DQ, SL_OM, SL_QUAT, Reference3D, Scene3D

N_STATE = 34
SL_BODY, SL_UV, SL_S, SL_PSI0, SL_PSI1 = slice(0, 11), slice(11, 15), 15, slice(16, 25), slice(25, 34)
FRAME_GAIN = 50.0          # 1/s, damping of the frames' orthonormality drift
SINGULARITY_TOL = 1e-6     # relative threshold on |D| / ((kn0 + kn1) * speed_scale)


def _singular(denominator: float, threshold: float, s_dot: float, t: float | None = None,
              reason: str | None = None) -> MovingFrameSingularityError:
    """``errors.MovingFrameSingularityError`` with ``denominator`` (rad/s), ``threshold`` (rad/s),
    and ``s_dot`` (m/s) set; ``t`` (s) NaN if unknown."""
    reason = reason or (
        f"moving-frame formulation singular: |omega0.e0 + omega1.e1| = {abs(denominator):.3e} rad/s "
        f"< {threshold:.3e} rad/s (s' = {s_dot:.3e} m/s); the trace direction b is undefined as the "
        "contact stops. Use the regular formulation (Reference3D)")
    err = MovingFrameSingularityError(float("nan") if t is None else t, None, reason,
                                      denominator=denominator, threshold=threshold)
    err.s_dot = s_dot
    return err


def _darboux(kg, tg, kn):
    return ca.vertcat(ca.horzcat(0, -kn, tg), ca.horzcat(kn, 0, -kg), ca.horzcat(-tg, kg, 0))


class PaperReference3D:
    """The moving-frame formulation of :class:`Scene3D` (see the module docstring).

    ``speed_scale`` (m/s) = ``r_tip * gain``: the largest contact speed the closed loop
    imposes on its fastest time scale (the Baumgarte rate ``g`` corrects a position error of
    the size of the tip in ``1/g``). The error is raised when ``|D| < SINGULARITY_TOL
    (kn0 + kn1) speed_scale``, i.e. ``|s'| < 1e-6 speed_scale`` (3 um/s for the default
    scene): below it ``kg s'`` = (O(|s'|) numerator) / D has lost six of the ~16 digits
    relative to the loop's speed scale, and keeps losing one per decade as the motion decays.
    """

    def __init__(self, scene: Scene3D | None = None, reference: Reference3D | None = None, *,
                 geodesic_torsion: bool = True):
        self.ref = reference or Reference3D(scene)
        self.geodesic_torsion = geodesic_torsion     # False: the paper's (Efs) as printed (tg = 0)
        self.scene = self.ref.scene
        self.speed_scale = self.scene.r_tip * self.scene.gain
        self._build()

    def _surf(self, surface: ParametricSurface, u, v) -> dict:
        tr = SympyToCasadi({U: u, V: v})
        x, y, n = surface.frame
        return {"S": tr(surface.S), "T": ca.horzcat(tr(surface.S_u), tr(surface.S_v)),
                "II": tr(surface.second_fundamental_form), "x": tr(x), "y": tr(y), "n": tr(n)}

    def _build(self) -> None:
        X = ca.SX.sym("X", 34)
        acc = ca.SX.sym("acc", 5)
        kg = ca.SX.sym("kg", 2)
        body_fun = self.ref._fun
        # body pieces from reference3d (only r, Pi, R, W are needed: no eta dependence)
        names = self.ref._names
        xr = ca.vertcat(X[SL_BODY], X[SL_UV], 0)
        outs = dict(zip(names, body_fun(xr)))
        r, Pi, R, W = outs["r"], outs["Pi"], outs["R"], outs["W"]
        dq, om = X[SL_DQ], X[SL_OM]
        quat_dot = outs["quat_dot"]
        sf = self._surf(self.ref.fingertip, X[11], X[12])
        so = self._surf(self.ref.object_surface, X[13], X[14])
        P0 = ca.reshape(X[SL_PSI0], 3, 3)
        P1 = ca.reshape(X[SL_PSI1], 3, 3)
        w0 = R @ om                       # object angular velocity, world
        w1 = W @ dq                       # finger angular velocity, world
        F0, F1 = R @ P0, Pi @ P1          # world frames

        def curv(s, P):
            Tp = ca.pinv(s["T"])
            a, c = Tp @ P[:, 1], Tp @ P[:, 2]
            return -(a.T @ s["II"] @ a), (c.T @ s["II"] @ a) * float(self.geodesic_torsion), a

        kn0, tg0, a0 = curv(so, P0)
        kn1, tg1, a1 = curv(sf, P1)
        D = ca.dot(w0, F0[:, 2]) + ca.dot(w1, F1[:, 2])
        ksum = kn0 + kn1
        sdot = -D / ksum
        Dn = ca.dot(w0, F0[:, 0]) + ca.dot(w1, F1[:, 0])
        r25 = ca.dot(w0, F0[:, 1]) - ca.dot(w1, F1[:, 1]) - (tg1 - tg0) * sdot
        I3 = ca.DM.eye(3)
        P0dot = P0 @ _darboux(kg[0], tg0, kn0) * sdot - 0.5 * FRAME_GAIN * P0 @ (P0.T @ P0 - I3)
        P1dot = P1 @ _darboux(kg[1], tg1, kn1) * sdot - 0.5 * FRAME_GAIN * P1 @ (P1.T @ P1 - I3)
        Xdot = ca.vertcat(dq, quat_dot, acc, a1 * sdot, a0 * sdot, sdot,
                          ca.reshape(P0dot, 9, 1), ca.reshape(P1dot, 9, 1))
        # d/dt (25) = 0: affine in kg
        dr25 = ca.jtimes(r25, X, Xdot)
        c0 = ca.substitute(dr25, kg, ca.DM.zeros(2))
        c12 = ca.jacobian(dr25, kg)
        # psi from the two Montana frames at the carried contact points
        Cf = Pi @ ca.horzcat(sf["x"], sf["y"], sf["n"])
        xo = R @ so["x"]
        psi = ca.atan2(-ca.dot(xo, Cf[:, 1]), ca.dot(xo, Cf[:, 0]))
        pf = r + Pi @ sf["S"]
        po = ca.DM(self.ref.pivot) + R @ so["S"]
        self._geom = ca.Function("paper_geom", [X], [psi, D, ksum, sdot, Dn, pf, po, F0, F1,
                                                     Pi @ sf["n"], R @ so["n"], so["T"]])
        self._rates = ca.Function("paper_rates", [X, acc, kg], [Xdot, c0, c12])

    # ------------------------------------------------------------------ numeric
    def reference_state(self, x: np.ndarray) -> np.ndarray:
        """reference3d's 16-state at ``x``: body, ``(u_f, v_f, u_o, v_o)`` and psi from the frames."""
        psi = float(self._geom(x)[0])
        return np.concatenate([x[SL_BODY], x[SL_UV], [psi]])

    def rhs(self, x: np.ndarray, t: float | None = None) -> np.ndarray:
        """``x'`` (34); raises :class:`MovingFrameSingularityError` near rest."""
        x = np.asarray(x, float)
        psi, D, ksum, sdot, Dn = (float(v) for v in self._geom(x)[:5])
        thr = SINGULARITY_TOL * abs(ksum) * self.speed_scale
        if not abs(D) >= thr:          # also catches NaN
            raise _singular(D, thr, sdot, t)
        xr = np.concatenate([x[SL_BODY], x[SL_UV], [psi]])
        xdot_ref, _ = self.ref._solve(xr)
        acc = xdot_ref[6:11]
        _, c0, c12 = (np.asarray(v.full(), float) for v in self._rates(x, acc, np.zeros(2)))
        # (27): kg0 + kg1 = -Dn / s';  d/dt(25): c0 + c12 . kg = 0
        Amat = np.array([[1.0, 1.0], c12.ravel()])
        kgv = np.linalg.solve(Amat, np.array([-Dn / sdot, -float(c0.item())]))
        xdot = np.asarray(self._rates(x, acc, kgv)[0].full(), float).ravel()
        xdot[SL_QUAT] = xdot_ref[SL_QUAT]
        if not np.all(np.isfinite(xdot)):
            raise _singular(D, thr, sdot, t, reason=(
                f"moving-frame formulation: non-finite rates at |omega0.e0 + omega1.e1| = {abs(D):.3e} "
                f"rad/s (threshold {thr:.3e} rad/s, s' = {sdot:.3e} m/s). Use the regular formulation "
                "(Reference3D)"))
        return xdot

    def __call__(self, t: float, x: np.ndarray) -> np.ndarray:
        return self.rhs(x, t)

    def denominator(self, x: np.ndarray) -> tuple[float, float, float]:
        """``(D, kn0 + kn1, s')`` at ``x``."""
        g = self._geom(np.asarray(x, float))
        return float(g[1]), float(g[2]), float(g[3])

    def initial_state(self, x_ref: np.ndarray) -> np.ndarray:
        """The paper state matching reference3d's state ``x_ref``, with ``b`` the rolling direction.

        ``b0(0) = b1(0)`` is the direction of the contact velocity given by the regular
        formulation's rates (the paper's condition that (25) holds at t = 0); needs a moving
        contact.
        """
        x_ref = np.asarray(x_ref, float)
        p = self.ref.pieces(x_ref)
        R, Pi, sigma = p["R"], p["Pi"], p["sigma"]
        geo = self._geom(np.concatenate([x_ref[:15], np.zeros(19)]))
        vc = R @ np.asarray(geo[11].full(), float) @ sigma[2:4]   # world contact velocity on the object
        if not np.linalg.norm(vc) > 0:
            raise _singular(0.0, 0.0, float(np.linalg.norm(vc)), 0.0, reason=(
                f"the paper formulation cannot start at rest: the contact does not move at x_ref (its "
                f"speed over the object surface is |s'| = {np.linalg.norm(vc):.3e} m/s), so b is undefined "
                "and D = -(kn0 + kn1) s' = 0; start from a rolling state (rolling_start)"))
        b = vc / np.linalg.norm(vc)
        nf_w, no_w = np.asarray(geo[9].full(), float).ravel(), np.asarray(geo[10].full(), float).ravel()
        F0 = np.column_stack([no_w, b, np.cross(no_w, b)])
        F1 = np.column_stack([nf_w, b, np.cross(nf_w, b)])
        x = np.zeros(N_STATE)
        x[SL_BODY] = x_ref[:11]
        x[SL_UV] = x_ref[11:15]
        x[SL_PSI0] = (R.T @ F0).ravel(order="F")
        x[SL_PSI1] = (Pi.T @ F1).ravel(order="F")
        return x

    def outputs(self, x: np.ndarray) -> dict[str, float]:
        """``D, kn_sum, s_dot``; ``frame_orthonormality`` (max |Psi^T Psi - I| of both);
        ``frame_match`` (max |R Psi0 diag(-1,1,-1) - Pi Psi1|); ``normal_drift`` (max |n - n_surface|);
        contact points ``p_f, p_o`` (world, m)."""
        x = np.asarray(x, float)
        g = [np.asarray(v.full(), float) for v in self._geom(x)]
        P0 = x[SL_PSI0].reshape(3, 3, order="F")
        P1 = x[SL_PSI1].reshape(3, 3, order="F")
        F0, F1 = g[7], g[8]
        Dm = np.diag([-1.0, 1.0, -1.0])
        return {"D": float(g[1].item()), "kn_sum": float(g[2].item()), "s_dot": float(g[3].item()),
                "frame_orthonormality": float(max(np.max(np.abs(P.T @ P - np.eye(3))) for P in (P0, P1))),
                "frame_match": float(np.max(np.abs(F0 @ Dm - F1))),
                "normal_drift": float(max(np.max(np.abs(F0[:, 0] - g[10].ravel())),
                                          np.max(np.abs(F1[:, 0] - g[9].ravel())))),
                "p_f": g[5].ravel(), "p_o": g[6].ravel()}


def rolling_start(ref: Reference3D, speed: float = 3.0) -> np.ndarray:
    """reference3d's initial state with admissible speeds ``|q'| = speed`` (rad/s) that carry no
    spin of the object about the line from the pivot to the fingertip centre (the motion the
    finger's damping cannot reach, as in ``tests/test_reference3d.py``): the motion then decays
    to rest under the controller's damping (sphere: within ~1 s)."""
    x0 = ref.initial_state()
    p = ref.pieces(x0)
    d = p["R"].T @ (p["r"] - ref.pivot)
    spin = np.r_[0.0, 0.0, *(d / np.linalg.norm(d))]
    N = ref.admissible_speeds(x0)
    c = N.T @ p["M"] @ spin
    V0 = N @ np.array([c[1], -c[0]])
    return ref.initial_state(V0 * speed / np.linalg.norm(V0[:2]))


__all__ = ["rolling_start", "PaperReference3D", "N_STATE", "SL_BODY", "SL_UV", "SL_S",
           "SL_PSI0", "SL_PSI1"]
