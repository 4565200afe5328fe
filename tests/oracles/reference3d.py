"""NumPy/SciPy reference of the 3D rolling-contact dynamics, regular at rest (one finger).

Scene (``docs/design-3d.md``, "the default formulation"): finger 1 of ``model.chains``
(2 joints about -z) with a spherical fingertip of radius ``r_tip`` centred at the fingertip
frame origin, against an object that can only *rotate* about a fixed pivot at its centre (a
ball joint): an ellipsoid (or a sphere) of mass ``mass`` with the inertia of the solid body.
No gravity.

State ``x`` (16), in this order (:data:`STATE_NAMES`)::

    q (2)  quat (4)  q' (2)  omega (3)  (u_f, v_f, u_o, v_o, psi) (5)

``quat = (w, x, y, z)`` maps object coordinates to the world (``spatial.quaternion_to_matrix``,
unit form), ``omega`` is the object's angular velocity in its body frame, and the quaternion
follows ``spatial.quaternion_rate`` (with its Baumgarte term, rate ``BAUMGARTE_RATE``).
Generalised speeds ``V = (q', omega)``; coordinates ``z = (q, quat, eta)``.

Constraints. ``C = (Qn, Qb, Qe)``: the gap ``p_f - p_o`` between the finger's contact point
``r + Pi S_f(u_f, v_f)`` and the object's ``pivot + R S_o(u_o, v_o)``, with components along
``(n_f, x_f, y_f)`` of the finger's contact frame ``C_f = Pi [x_f y_f n_f]``. With ``eta``
held fixed, ``dC/dt = A V`` on the manifold, ``A V`` being the velocity of the finger's
material point minus the object's at the contact (the *negative* of ``contact3d``'s ``v``,
which is the object relative to the finger). Multipliers ``mu = (f, lam, eta)``.

Equations (``system.assemble``, NumPy backend)::

    M(q) a + h(q, V) + A^T mu = tau,      M = diag(G(q), H),  h = (h_f, omega x H omega)
    C'' + 2 g C' + g^2 C = 0              (Baumgarte on the TOTAL derivatives)
    eta' = sigma(z, V)                    (contact3d's rolling rates, v_x = v_y = 0)
    tau = (u, 0),  u = -c q' - J^T (fd / r_ctrl)(r_tip - pivot)

``C' = C_z z'(z, V)`` and ``C'' = (dC'/dV) a + (dC'/dz) z'`` are exact: automatic
differentiation in CasADi SX of the SymPy pieces (finger kinematics/dynamics from
``derive.spatial``, surface quantities from ``geometry.surfaces``, the rates from
``contact3d.contact_rates_symbolic`` on generic Montana forms), translated with
``codegen.translate.SympyToCasadi``. CasADi is used only as an AD engine and numeric
evaluator here (no code generation); the closed loop is solved in NumPy.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

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
from grasping_sym.geometry import surface_library as sl
from grasping_sym.geometry.surfaces import ParametricSurface, U, V
from grasping_sym.model.chains import FINGER1_Q_OPPOSED, finger1
from grasping_sym.model.inertia import solid_ellipsoid_inertia
from grasping_sym.symbolic.translate import SympyToCasadi
from tests.oracles import contact3d_numeric as c3n

STATE_NAMES = ("q11", "q12", "qw", "qx", "qy", "qz", "dq11", "dq12", "omegaX", "omegaY", "omegaZ",
               *c3.CONTACT_COORDS)
N_STATE = 16
SL_Q, SL_QUAT, SL_DQ, SL_OM, SL_ETA = slice(0, 2), slice(2, 6), slice(6, 8), slice(8, 11), slice(11, 16)


def quat_from_matrix(R: np.ndarray) -> np.ndarray:
    """Unit quaternion ``(w, x, y, z)`` of a rotation matrix (Shepperd's method, ``w >= 0``)."""
    R = np.asarray(R, float)
    tr = np.trace(R)
    cands = [tr, R[0, 0], R[1, 1], R[2, 2]]
    i = int(np.argmax(cands))
    if i == 0:
        w = 0.5 * math.sqrt(1 + tr)
        q = np.array([w, (R[2, 1] - R[1, 2]) / (4 * w), (R[0, 2] - R[2, 0]) / (4 * w),
                      (R[1, 0] - R[0, 1]) / (4 * w)])
    else:
        a, b, c = i - 1, i % 3, (i + 1) % 3
        s = 0.5 * math.sqrt(max(1 + R[a, a] - R[b, b] - R[c, c], 0.0))
        q = np.zeros(4)
        q[1 + a] = s
        q[0] = (R[c, b] - R[b, c]) / (4 * s)
        q[1 + b] = (R[b, a] + R[a, b]) / (4 * s)
        q[1 + c] = (R[c, a] + R[a, c]) / (4 * s)
    return q if q[0] >= 0 else -q


@dataclass(frozen=True)
class Scene3D:
    """Parameters of the one-finger pivoted-object scene (SI units).

    ``semi_axes`` of the object (all equal: a sphere), ``contact_o = (u_o, v_o)`` the object
    surface point touched at the start, ``contact_f = (u_f, v_f)`` the fingertip's, ``psi0``
    the initial frame angle, ``q0`` the finger's joint angles at the start (the pivot is placed
    so that the bodies touch there), ``gain`` the Baumgarte rate g (1/s), ``c`` the joint
    damping (N m s), ``fd`` (N) and ``r_ctrl`` (m) the pull of the controller.
    """

    semi_axes: tuple[float, float, float] = (0.020, 0.025, 0.030)
    mass: float = 0.040
    r_tip: float = 0.010
    contact_o: tuple[float, float] = (2.7, 0.25)
    contact_f: tuple[float, float] = (0.0, 0.1)
    psi0: float = 0.4
    q0: tuple[float, float] = FINGER1_Q_OPPOSED
    gain: float = 300.0
    c: float = 0.006
    fd: float = 0.5
    r_ctrl: float = 0.010


class Reference3D:
    """The closed loop of :class:`Scene3D`: ``rhs``, ``outputs``, ``initial_state``.

    Attributes
    ----------
    fingertip, object_surface
        The two :class:`ParametricSurface` (fingertip frame / object frame).
    pivot
        m, the fixed object centre (world), chosen by the initial contact.
    H
        kg m^2, the object's inertia about the pivot (body frame).
    """

    def __init__(self, scene: Scene3D | None = None):
        self.scene = s = scene or Scene3D()
        a, b, c = s.semi_axes
        if a == b == c:
            self.object_surface = sl.sphere(a, name="object sphere")
        else:
            self.object_surface = sl.ellipsoid(a, b, c, name="object ellipsoid")
        self.fingertip = sl.sphere(s.r_tip, name="fingertip")
        self.H = solid_ellipsoid_inertia(s.mass, a, b, c)
        self.chain = finger1()
        kin = finger_kinematics(self.chain)
        dyn = finger_dynamics(kin)
        # initial contact fixes the pivot: finger at q0, object pose from the contact
        fk = sp.lambdify([list(kin.q)], [kin.r, kin.Pi], "numpy")
        r0, Pi0 = (np.asarray(m, float) for m in fk(list(s.q0)))
        self._eta0 = np.array([*s.contact_f, *s.contact_o, s.psi0], float)
        R0, p0 = c3n.object_pose_from_contact(self.fingertip, (Pi0, r0.ravel()), self.object_surface, self._eta0)
        self.pivot = np.asarray(p0, float)
        self._quat0 = quat_from_matrix(R0)
        self._build(kin, dyn)

    # ------------------------------------------------------------------ symbolic -> SX
    def _surface_sx(self, surface: ParametricSurface, u: ca.SX, v: ca.SX) -> dict[str, ca.SX]:
        tr = SympyToCasadi({U: u, V: v})
        x, y, n = surface.frame
        return {"S": tr(surface.S), "x": tr(x), "y": tr(y), "n": tr(n),
                "M": tr(surface.montana_metric), "K": tr(surface.curvature_form), "T": tr(surface.torsion_form)}

    def _build(self, kin, dyn) -> None:
        s = self.scene
        q, quat, dq, om, eta = (ca.SX.sym(n, k) for n, k in
                                (("q", 2), ("quat", 4), ("dq", 2), ("om", 3), ("eta", 5)))
        tr_f = SympyToCasadi({**{kin.q[i]: q[i] for i in range(2)}, **{kin.dq[i]: dq[i] for i in range(2)}})
        r, Pi, J, W = tr_f(kin.r), tr_f(kin.Pi), tr_f(kin.J), tr_f(kin.W)
        G, h_f = tr_f(dyn.G), tr_f(dyn.h)
        qs, ws = sp.Matrix(sp.symbols("qw qx qy qz", real=True)), sp.Matrix(sp.symbols("wX wY wZ", real=True))
        tr_q = SympyToCasadi({**{qs[i]: quat[i] for i in range(4)}, **{ws[i]: om[i] for i in range(3)}})
        R = tr_q(quaternion_to_matrix(qs))
        quat_dot = tr_q(quaternion_rate(qs, ws))
        Eq = tr_q(quaternion_rate_matrix(qs))
        sf = self._surface_sx(self.fingertip, eta[0], eta[1])
        so = self._surface_sx(self.object_surface, eta[2], eta[3])
        pivot = ca.DM(self.pivot)
        p_f = r + Pi @ sf["S"]
        p_o = pivot + R @ so["S"]
        Cf = Pi @ ca.horzcat(sf["x"], sf["y"], sf["n"])
        gap = Cf.T @ (p_f - p_o)
        C = ca.vertcat(gap[2], gap[0], gap[1])            # (Qn, Qb, Qe)
        # relative twist of the object w.r.t. the finger, finger contact frame (contact3d)
        w_rel = Cf.T @ (R @ om - W @ dq)
        # contact3d's rolling rates, derived on generic forms, with the surfaces' forms substituted
        ff, fo = c3.MontanaForms.generic("f"), c3.MontanaForms.generic("o")
        psi_s = sp.Symbol("psi", real=True)
        w_s = sp.symbols("w_x w_y w_z", real=True)
        rates = c3.contact_rates_symbolic(ff, fo, psi_s, w_s).vector

        def form_entries(d):
            M_, K_, T_ = d["M"], d["K"], d["T"]
            return [M_[0, 0], M_[0, 1], M_[1, 1], K_[0, 0], K_[0, 1], K_[1, 1], T_[0, 0], T_[0, 1]]

        sym_map = {**dict(zip(ff.entries(), form_entries(sf))), **dict(zip(fo.entries(), form_entries(so))),
                   psi_s: eta[4], **{w_s[i]: w_rel[i] for i in range(3)}}
        sym_map = {k: v for k, v in sym_map.items() if isinstance(k, sp.Symbol)}
        sigma = SympyToCasadi(sym_map)(rates)

        z = ca.vertcat(q, quat, eta)
        Vs = ca.vertcat(dq, om)
        zdot = ca.vertcat(dq, quat_dot, sigma)
        Cz = ca.jacobian(C, z)
        A = ca.jacobian(Cz @ ca.vertcat(dq, Eq @ om, ca.SX.zeros(5)), Vs)   # eta held fixed
        Cdot = Cz @ zdot
        Ahat = ca.jacobian(Cdot, Vs)
        bhat = ca.jacobian(Cdot, z) @ zdot
        H = ca.DM(self.H)
        Mm = ca.diagcat(G, H)
        h = ca.vertcat(h_f, ca.cross(om, H @ om))
        u = -s.c * dq - J.T @ ((s.fd / s.r_ctrl) * (r - pivot))
        tau = ca.vertcat(u, ca.SX.zeros(3))
        ke = 0.5 * dq.T @ G @ dq + 0.5 * om.T @ H @ om
        x = ca.vertcat(q, quat, dq, om, eta)
        names = ["M", "h", "tau", "A", "Ahat", "bhat", "Cdot", "C", "sigma", "quat_dot", "u", "ke",
                 "r", "Pi", "R", "J", "W", "w_rel", "Cz"]
        exprs = [Mm, h, tau, A, Ahat, bhat, Cdot, C, sigma, quat_dot, u, ke, r, Pi, R, J, W, w_rel, Cz]
        self._names = names
        self._fun = ca.Function("reference3d", [x], exprs)
        self._fast = ca.Function("reference3d_rhs", [x], exprs[:10])

    # ------------------------------------------------------------------ numeric
    def pieces(self, x: np.ndarray) -> dict[str, np.ndarray]:
        """Every evaluated piece (``M, h, tau, A, Ahat, bhat, Cdot, C, sigma, ...``) at ``x``."""
        out = self._fun(np.asarray(x, float))
        return {k: _np(v) for k, v in zip(self._names, out)}

    def _solve(self, x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        M, h, tau, A, Ahat, bhat, Cdot, C, sigma, quat_dot = (_np(v) for v in self._fast(x))
        g = self.scene.gain
        V = x[6:11]
        xdot, mu = assemble(5, V, [M, h, tau, A, Ahat, bhat, Cdot, C, np.full(3, 2 * g),
                                   np.full(3, g * g), sigma],
                            np.linalg.solve, np.concatenate, np.multiply, np.transpose,
                            qdot=np.concatenate([x[SL_DQ], quat_dot]))
        return xdot, mu

    def rhs(self, x: np.ndarray) -> np.ndarray:
        """``x' `` (16): ``(q', quat', q'', omega', eta')``."""
        return self._solve(np.asarray(x, float))[0]

    def __call__(self, t: float, x: np.ndarray) -> np.ndarray:
        """``rhs`` with the ``solve_ivp`` signature."""
        return self.rhs(x)

    def initial_state(self, speeds: np.ndarray | None = None) -> np.ndarray:
        """The consistent start: finger at ``q0``, object posed by the contact, ``eta0``.

        ``speeds = (q', omega)`` (5) must satisfy ``A V = 0`` (see :meth:`admissible_speeds`);
        default rest.
        """
        x = np.zeros(N_STATE)
        x[SL_Q] = self.scene.q0
        x[SL_QUAT] = self._quat0
        x[SL_ETA] = self._eta0
        if speeds is not None:
            x[6:11] = speeds
        return x

    def admissible_speeds(self, x: np.ndarray) -> np.ndarray:
        """5 x k basis of the speeds ``V`` with ``A V = 0`` at ``x`` (SVD null space)."""
        A = self.pieces(x)["A"]
        _, sv, Vt = np.linalg.svd(A)
        return Vt[int(np.sum(sv > 1e-12 * sv[0])):].T

    def poses(self, x: np.ndarray) -> tuple[tuple[np.ndarray, np.ndarray], tuple[np.ndarray, np.ndarray]]:
        """``((Pi, r), (R, pivot))``: fingertip and object poses (world)."""
        p = self.pieces(x)
        return (p["Pi"], p["r"]), (p["R"], self.pivot)

    def outputs(self, x: np.ndarray) -> dict[str, float]:
        """Diagnostics at ``x``.

        ``Qn, Qb, Qe`` (m); ``f, lam, eta`` (N, the multipliers); ``point, normal, frame,
        angle, residual_max`` from ``contact3d_numeric.contact_residuals`` (normals opposite, frames
        differing by psi); ``quat_norm_error = |quat| - 1``; ``orthonormality`` =
        ``max |R^T R - I|``; ``kinetic_energy`` (J); ``power = q' . u`` (W);
        ``krel_min_eig`` (1/m) and ``krel_name`` from ``relative_curvature_report``;
        ``rate_norm`` = ``|x'|`` (finite check).
        """
        x = np.asarray(x, float)
        p = self.pieces(x)
        xdot, mu = self._solve(x)
        res = c3n.contact_residuals(self.fingertip, (p["Pi"], p["r"]), self.object_surface,
                                   (p["R"], self.pivot), x[SL_ETA])
        uf, vf, uo, vo, psi = x[SL_ETA]
        rep = c3n.relative_curvature_report(self.fingertip.evaluate(uf, vf)["K_p"],
                                           self.object_surface.evaluate(uo, vo)["K_p"], psi)
        out = {"Qn": p["C"][0], "Qb": p["C"][1], "Qe": p["C"][2],
               "f": mu[0], "lam": mu[1], "eta": mu[2],
               "point": res["point"], "normal": res["normal"], "frame": res["frame"],
               "angle": res["angle"], "residual_max": res["max"],
               "quat_norm_error": float(np.linalg.norm(x[SL_QUAT]) - 1.0),
               "orthonormality": float(np.max(np.abs(p["R"].T @ p["R"] - np.eye(3)))),
               "kinetic_energy": float(p["ke"]), "power": float(x[SL_DQ] @ p["u"]),
               "krel_min_eig": rep.min_eigenvalue, "krel_name": rep.name,
               "rate_norm": float(np.linalg.norm(xdot))}
        return {k: (float(v) if not isinstance(v, str) else v) for k, v in out.items()}


def _np(v) -> np.ndarray:
    a = np.array(v.full() if hasattr(v, "full") else v, dtype=float)
    if a.shape == (1, 1):
        return a[0, 0]
    if a.ndim == 2 and a.shape[1] == 1:
        return a[:, 0]
    return a
