"""The paper2d scene written as a multibody user would: ``sympy.physics.mechanics`` + PyDy (Cython).

A peer for the benchmarks: the same scene as ``grasping_sym.model.scenes.paper2d()`` (docs/conventions.md section 1,
Yoshida-Arimoto-Tahara 2009), derived with ``KanesMethod`` and compiled with PyDy's
``generate_ode_function(..., generator='cython')``, the way ``pydy.system.System`` does it.

Usage::

    python -m benchmarks.peers.pydy_paper2d           # timings, agreement, work-precision
    python -m benchmarks.peers.pydy_paper2d --quick   # fewer tolerances and repeats

The model, written independently of ``grasping_sym.derive.planar`` (only the numbers of the scene,
its pivot and its initial state come from ``grasping_sym``):

- frames: ``N`` inertial; link 1 ``A`` = ``N`` turned by ``-q1`` about z (the paper measures joint
  angles clockwise from +y; the link runs along ``A.y``); link 2 ``B`` = ``A`` turned by ``-q2``;
  the fingertip frame ``F`` (fixed in link 2) = ``B`` turned by ``+pi/2`` (so that ``F`` is ``N``
  turned by ``pi/2 - q1 - q2``, docs/conventions.md); the object frame ``Ob`` = ``N`` turned by ``-theta``;
- bodies: uniform rods (mass centre at mid-length, ``m l^2/12`` about it) and the object pivoted
  at ``Om`` with inertia ``I`` about it; no gravity;
- contours, written from the paper's eqs (37)-(40), both unit-speed in the one contact parameter
  ``s``: fingertip point ``P0 = O01 + X0(s) F.x + Y0(s) F.y``, object point
  ``P1 = Om + X(s) Ob.x + Y(s) Ob.y``; unit tangents ``T0 = X0' F.x + Y0' F.y``, ``T1 = X' Ob.x + Y' Ob.y``;
- generalized coordinates ``(q1, q2, theta, s)`` and speeds ``u = (q1', q2', theta', s')``
  (kinematic equations ``q' = u``);
- three holonomic configuration constraints: the contact points coincide, ``(P0 - P1).N.x = 0``
  and ``(P0 - P1).N.y = 0``, and the tangents are aligned, ``(T1 x T0).N.z = 0``. One ``s`` for
  both contours *is* rolling: the time derivative of ``P0(q, s) - P1(theta, s)`` is the relative
  velocity of the two material points plus ``(T0 - T1) s'``, and ``T0 = T1`` by the third
  constraint. The velocity constraints are the time derivatives of the three (``KanesMethod``
  substitutes ``q' = u``); KanesMethod differentiates them once more for the accelerations;
- independent coordinate and speed: ``s`` and ``s'`` (default; ``independent='q1'`` is the
  alternative). Dependent: ``(q1, q2, theta)`` and their rates. Why ``s``: the dependent block of
  the velocity-constraint Jacobian is then the three joint/object angle columns, which along the
  3 s run has condition number ~76-86 (rows in m, m, 1; columns in rad); it is singular only
  where the pivot ``Om`` lies on the line through the finger base and the elbow (no relative
  rotation possible, the contact cannot roll), far from this scene. With ``q1`` independent the
  block ``(q2, theta, s)`` mixes rad and m columns (condition ~1.4e4-4.4e4 unscaled) and is
  singular where the elbow, the contact point and ``Om`` are collinear. ``s`` is also monotone
  here (0 to -4.79e-3 m); the dependent coordinates are listed with ``s`` last when ``q1`` is
  independent, since SymPy's LU solve pivots on the first symbolically non-zero entry and the
  ``s`` column of the contact rows, ``T0 - T1``, is zero on the manifold;
- the controller (32) ``u = -c q' - J01^T (fd/r)(O01 - Om)`` as joint torques (a function of the
  state): ``-tau1 + tau2`` about ``N.z`` on link 1 and ``-tau2`` on link 2 (``N.z`` points against
  the positive joint rotation);
- parameters ``l11 l12 m11 m12 I fd c r xm ym`` are PyDy ``constants`` (array argument); the contour
  coefficients are numbers in the expressions (they are the shape, as in the generated C of
  ``grasping_sym``).

No Baumgarte stabilisation: the generated ODE integrates all eight states (four coordinates, four
speeds: ``pydy.system.System``'s "min mass matrix" form, ``M(q) u' = F(q, u)`` with the three
acceleration-level constraint rows inside ``M``, solved by ``numpy.linalg.solve`` at every call),
so the configuration constraints drift; the drift is measured with ``grasping_sym``'s own ``Q`` and
``R`` outputs on the PyDy states (the contact gap), and ``work_precision`` also reports PyDy's own
three residuals, the third being the tangency defect, which ``Q`` and ``R`` do not see (see
``PydyPeer.with_tangency``: ``grasping_sym`` keeps tangency only through its update law for ``s'``).

Two PyDy pitfalls met here: the generated function returns one reused output buffer (``peer.rhs``
copies it; without the copy scipy's Radau and BDF get a zero finite-difference Jacobian and crawl or
fail), and odeint's default ``mxstep`` (500 steps per output interval) is too small for a 3 s run
at tight tolerances (``simulate`` passes 1e6). PyDy compiles by ``os.chdir`` into its build
directory and back.

State maps: PyDy's state is ``[q, u]`` in KanesMethod's order (independent first), e.g.
``(s, q1, q2, theta, s', q1', q2', theta')`` for the default. ``to_ours`` selects
``(theta, q1, q2, theta', q1', q2', s)`` (``grasping_sym``'s ``state_names``); ``from_ours`` takes the
coordinates and the three rates from ours and solves PyDy's velocity constraints (least squares
over the three rows) for ``s'``. On the manifold that is the update law (29) of ``grasping_sym``.
"""
from __future__ import annotations

import argparse
import json
import os
import statistics
import sys
import tempfile
import time
from dataclasses import dataclass, field
from typing import NamedTuple

import numpy as np
import sympy as sp
import sympy.physics.mechanics as me

#: The constants of the PyDy function, in the order of its ``p`` array.
PARAM_NAMES = ("l11", "l12", "m11", "m12", "I", "fd", "c", "r", "xm", "ym")
#: ``grasping_sym``'s state order (``model.state_names`` of paper2d).
OUR_STATES = ("theta", "q1", "q2", "dtheta", "dq1", "dq2", "s")
#: Paper eqs (37)-(40): fingertip catenary ``(k0, x0)``, object catenary ``(k1, x1, s1)``.
FINGERTIP_K, FINGERTIP_X0 = 20.0, 0.035
OBJECT_K, OBJECT_X0, OBJECT_S0 = 50.0, -0.03, 3.363e-3
#: Mass of the object (kg). Its mass centre is the fixed pivot, so it does not enter the equations.
OBJECT_MASS = 0.040
#: Benchmark settings shared with ``benchmarks.work_precision`` (3 s run, atol = rtol * 1e-2,
#: residual sampled every 0.25 ms).
T_FINAL = 3.0
ATOL_FACTOR = 1e-2
DENSE_DT = 2.5e-4

_t = me.dynamicsymbols._t


# ---------------------------------------------------------------------- derivation
@dataclass
class Derivation:
    """Everything KanesMethod produced, and the seconds it took."""

    kane: me.KanesMethod
    coordinates: list
    speeds: list
    constants: list
    configuration_constraints: sp.Matrix
    velocity_constraints: sp.Matrix
    independent: str
    seconds: float


def derive(independent: str = "s") -> Derivation:
    """Kane's equations of the paper2d scene with its holonomic contact constraints.

    ``independent`` is the independent generalized coordinate: ``'s'`` (default), ``'q1'`` or
    ``'theta'``; the other three are dependent (see the module docstring).
    """
    t0 = time.perf_counter()
    q1, q2, th, s = me.dynamicsymbols("q1 q2 theta s")
    u1, u2, u3, u4 = me.dynamicsymbols("u1 u2 u3 u4")
    l11, l12, m11, m12, inertia, fd, c, r, xm, ym = sp.symbols(PARAM_NAMES, real=True)

    # contours, paper eqs (37)-(40): unit speed in s
    k0, k1 = sp.Float(FINGERTIP_K), sp.Float(OBJECT_K)
    X0 = sp.Float(FINGERTIP_X0) - sp.sqrt(1 + 4 * k0**2 * s**2) / (2 * k0)
    Y0 = sp.asinh(2 * k0 * s) / (2 * k0)
    w = s - sp.Float(OBJECT_S0)
    X1 = sp.Float(OBJECT_X0) + sp.sqrt(1 + 4 * k1**2 * w**2) / (2 * k1)
    Y1 = sp.asinh(2 * k1 * w) / (2 * k1)

    # frames
    N, A, B, F, Ob = (me.ReferenceFrame(n) for n in ("N", "A", "B", "F", "Ob"))
    A.orient_axis(N, N.z, -q1)
    B.orient_axis(A, A.z, -q2)
    F.orient_axis(B, B.z, sp.pi / 2)
    Ob.orient_axis(N, N.z, -th)

    # points
    O = me.Point("O")  # noqa: E741 - the paper's origin
    O.set_vel(N, 0)
    G1 = O.locatenew("G1", l11 / 2 * A.y)
    E = O.locatenew("E", l11 * A.y)
    G2 = E.locatenew("G2", l12 / 2 * B.y)
    O01 = E.locatenew("O01", l12 * B.y)
    for point, base, frame in ((G1, O, A), (E, O, A), (G2, E, B), (O01, E, B)):
        point.v2pt_theory(base, N, frame)
    Om = O.locatenew("Om", xm * N.x + ym * N.y)
    Om.set_vel(N, 0)
    P0 = O01.locatenew("P0", X0 * F.x + Y0 * F.y)
    P1 = Om.locatenew("P1", X1 * Ob.x + Y1 * Ob.y)
    T0 = X0.diff(s) * F.x + Y0.diff(s) * F.y
    T1 = X1.diff(s) * Ob.x + Y1.diff(s) * Ob.y

    # holonomic constraints and their time derivatives
    gap = P0.pos_from(P1)
    config = sp.Matrix([gap.dot(N.x), gap.dot(N.y), T1.cross(T0).dot(N.z)])
    vel = config.diff(_t)

    # bodies
    link1 = me.RigidBody("link1", G1, A, m11, (me.inertia(A, 0, 0, m11 * l11**2 / 12), G1))
    link2 = me.RigidBody("link2", G2, B, m12, (me.inertia(B, 0, 0, m12 * l12**2 / 12), G2))
    obj = me.RigidBody("object", Om, Ob, sp.Float(OBJECT_MASS), (me.inertia(Ob, 0, 0, inertia), Om))

    # controller (32) as joint torques
    r01 = O01.pos_from(O).to_matrix(N)[:2, 0]
    J01 = r01.jacobian([q1, q2])
    tau = -c * sp.Matrix([u1, u2]) - J01.T * (fd / r) * O01.pos_from(Om).to_matrix(N)[:2, 0]
    loads = [(A, (-tau[0] + tau[1]) * N.z), (B, -tau[1] * N.z)]

    kd = [q1.diff(_t) - u1, q2.diff(_t) - u2, th.diff(_t) - u3, s.diff(_t) - u4]
    split = {
        "s": ([s], [q1, q2, th], [u4], [u1, u2, u3]),
        "q1": ([q1], [q2, th, s], [u1], [u2, u3, u4]),
        "theta": ([th], [q1, q2, s], [u3], [u1, u2, u4]),
    }
    if independent not in split:
        raise ValueError(f"independent = {independent!r}: choose one of {sorted(split)}")
    q_ind, q_dep, u_ind, u_dep = split[independent]
    kane = me.KanesMethod(N, q_ind=q_ind, u_ind=u_ind, kd_eqs=kd, q_dependent=q_dep,
                          configuration_constraints=config, u_dependent=u_dep,
                          velocity_constraints=vel)
    kane.kanes_equations([link1, link2, obj], loads)
    kane.mass_matrix, kane.forcing  # noqa: B018 - formed here so that their cost counts as derivation
    seconds = time.perf_counter() - t0
    return Derivation(kane=kane, coordinates=list(kane.q), speeds=list(kane.u),
                      constants=[l11, l12, m11, m12, inertia, fd, c, r, xm, ym],
                      configuration_constraints=config, velocity_constraints=vel,
                      independent=independent, seconds=seconds)


# ---------------------------------------------------------------------- compiled peer
@dataclass
class PydyPeer:
    """The compiled PyDy model of paper2d and the maps between its state and ``grasping_sym``'s.

    Attributes
    ----------
    ode
        PyDy's generated function ``ode(x, t, p)`` (odeint signature), ``x`` in PyDy's order.
    p
        The constants, ordered as ``PARAM_NAMES``.
    state_names
        PyDy's state order (``[q, u]`` of KanesMethod).
    timings
        Seconds: ``derivation`` (frames, points, constraints, KanesMethod, ``kanes_equations``,
        mass matrix and forcing), ``codegen_compile`` (``generate_ode_function`` with
        ``generator='cython'``: C printing with CSE, Cython, the C compiler, import).
    """

    derivation: Derivation
    ode: object
    p: np.ndarray
    state_names: tuple[str, ...]
    x0_ours: np.ndarray
    timings: dict = field(default_factory=dict)
    directory: str | None = None

    def __post_init__(self) -> None:
        names = list(self.state_names)
        nq = len(names) // 2
        self._to_ours = np.array([names.index(n) for n in ("theta", "q1", "q2")]
                                 + [nq + names[:nq].index(n) for n in ("theta", "q1", "q2")]
                                 + [names.index("s")])
        self._coord_from_ours = np.array([OUR_STATES.index(n) for n in names[:nq]])
        d = self.derivation
        k_nh, f_nh = d.kane._k_nh, d.kane._f_nh
        self._vel_jac = sp.lambdify([d.coordinates, d.constants], k_nh, "numpy", cse=True)
        self._vel_bias = sp.lambdify([d.coordinates, d.constants], f_nh, "numpy", cse=True)
        self._config = sp.lambdify([d.coordinates, d.constants], d.configuration_constraints,
                                   "numpy", cse=True)
        self._s_speed = nq + names[:nq].index("s")

    # ------------------------------------------------------------------ calls and maps
    def rhs(self, t: float, x) -> np.ndarray:
        """``x' = f(t, x)`` in PyDy's state order (solve_ivp signature), a new array.

        PyDy's generated function returns the same preallocated array at every call (its "min
        mass matrix" path fills one ``xdot`` buffer); solve_ivp's Radau and BDF keep ``f(y)`` while
        they difference ``f(y + h)`` for the Jacobian, so without this copy their Jacobian is
        zero and they crawl or fail. odeint copies by itself.
        """
        return self.ode(np.ascontiguousarray(x, dtype=float), t, self.p).copy()

    def to_ours(self, x) -> np.ndarray:
        """PyDy state(s) (last axis) to ``grasping_sym``'s order; also maps derivatives."""
        return np.asarray(x, dtype=float)[..., self._to_ours]

    def from_ours(self, x) -> np.ndarray:
        """One ``grasping_sym`` state to PyDy's: ``s'`` from PyDy's velocity constraints."""
        x = np.asarray(x, dtype=float)
        nq = len(self._coord_from_ours)
        q = x[self._coord_from_ours]
        u = np.array([0.0 if n == "s" else x[OUR_STATES.index("d" + n)]
                      for n in self.state_names[:nq]])
        K = np.asarray(self._vel_jac(q, self.p), dtype=float)
        f = np.asarray(self._vel_bias(q, self.p), dtype=float).ravel()
        js = self._s_speed - nq
        rest = K @ u + f  # K u + f = 0 is the velocity constraint (f = 0: scleronomic)
        col = K[:, js]
        u[js] = -float(col @ rest) / float(col @ col)
        return np.concatenate([q, u])

    def with_tangency(self, x, *, iterations: int = 3) -> np.ndarray:
        """A ``grasping_sym`` state with ``s`` re-solved from PyDy's tangency constraint (Newton).

        ``grasping_sym`` holds the contact constraints ``Q``, ``R`` (``s`` fixed) by CSM but
        tangency only through the update law (29) for ``s'``: the integration error of ``s`` is
        never corrected. It shows in PyDy's third constraint, not in ``Q``, ``R``: along a CVODES
        rtol 1e-10 run the tangency defect reaches ~3.5e-11 rad (``s`` off by ~3.6e-13 m, the
        defect's slope being ``kappa0 + kappa1`` ~ 100 1/m) while ``|Q|``, ``|R|`` stay ~1e-17 m.
        Moving ``s`` along the common tangent changes the gap only at second order, so the
        returned state satisfies PyDy's three constraints and ours to rounding.
        """
        x = np.array(x, dtype=float)
        js = OUR_STATES.index("s")
        h = 1e-7
        for _ in range(iterations):
            g = self._tangency(x)
            xh = x.copy()
            xh[js] += h
            x[js] -= g * h / (self._tangency(xh) - g)
        return x

    def _tangency(self, x) -> float:
        return float(np.asarray(self._config(x[self._coord_from_ours], self.p), dtype=float).ravel()[2])

    def rhs_ours(self, x) -> np.ndarray:
        """PyDy's right-hand side at one ``grasping_sym`` state, in ``grasping_sym``'s order."""
        return self.to_ours(self.rhs(0.0, self.from_ours(x)))

    def configuration_residual(self, xp) -> np.ndarray:
        """PyDy's own three configuration constraints (m, m, 1) at PyDy state(s) (rows)."""
        X = np.atleast_2d(np.asarray(xp, dtype=float))
        nq = len(self._coord_from_ours)
        C = np.asarray(self._config(X[:, :nq].T, self.p), dtype=float)  # (3, 1, n): vectorised
        return C.reshape(3, len(X)).T

    def velocity_residual(self, xp) -> np.ndarray:
        """PyDy's three velocity constraints ``K u + f`` at PyDy state(s) (rows)."""
        X = np.atleast_2d(np.asarray(xp, dtype=float))
        nq = len(self._coord_from_ours)
        out = []
        for x in X:
            K = np.asarray(self._vel_jac(x[:nq], self.p), dtype=float)
            f = np.asarray(self._vel_bias(x[:nq], self.p), dtype=float).ravel()
            out.append(K @ x[nq:] + f)
        return np.array(out)

    # ------------------------------------------------------------------ simulate
    def simulate(self, t_final: float = T_FINAL, *, rtol: float = 1e-8, atol: float = 1e-10,
                 method: str = "LSODA", t_eval=None, x0=None, max_steps: int = 1_000_000) -> SimResult:
        """Integrate from ``grasping_sym``'s ``x0`` (default: the scene's initial state).

        ``method``: ``'odeint'`` (``scipy.integrate.odeint``, LSODA in Fortran: what
        ``pydy.system.System.integrate`` uses) or any ``scipy.integrate.solve_ivp`` method
        (``'LSODA'``, ``'Radau'``, ``'BDF'``, ``'DOP853'``, ``'RK45'``). ``t_eval`` defaults to
        ``[0, t_final]``. ``max_steps`` is odeint's ``mxstep`` (its default, 500 per output
        interval, stops a 3 s run at tight tolerances).
        """
        from scipy.integrate import odeint, solve_ivp  # noqa: PLC0415

        xp0 = self.from_ours(self.x0_ours if x0 is None else x0)
        t_eval = np.array([0.0, t_final] if t_eval is None else t_eval, dtype=float)
        t0 = time.perf_counter()
        if method == "odeint":
            X, info = odeint(self.ode, xp0, t_eval, args=(self.p,), rtol=rtol, atol=atol,
                             mxstep=max_steps, full_output=True)
            wall = time.perf_counter() - t0
            ok = info["message"].startswith("Integration successful")
            stats = {"nfev": int(info["nfe"][-1]), "njev": int(info["nje"][-1]),
                     "nsteps": int(info["nst"][-1]), "message": info["message"]}
            t = t_eval
        else:
            sol = solve_ivp(self.rhs, (float(t_eval[0]), float(t_eval[-1])), xp0, method=method,
                            t_eval=t_eval, rtol=rtol, atol=atol)
            wall = time.perf_counter() - t0
            ok = bool(sol.success)
            X, t = sol.y.T, sol.t
            stats = {"nfev": int(sol.nfev), "njev": int(sol.njev), "message": sol.message}
        if not ok:
            raise RuntimeError(f"PyDy peer: {method} failed at rtol={rtol:g}: {stats['message']}")
        stats["wall_time"] = wall
        return SimResult(t=np.asarray(t), x=self.to_ours(X), x_pydy=np.asarray(X), stats=stats)


@dataclass
class SimResult:
    """Times (s), states in ``grasping_sym``'s order (rows), PyDy's states, integrator stats."""

    t: np.ndarray
    x: np.ndarray
    x_pydy: np.ndarray
    stats: dict


def _scene_numbers():
    """Parameters (PyDy order) and the initial state of ``grasping_sym``'s paper2d."""
    from grasping_sym.model import scenes  # noqa: PLC0415

    scene = scenes.paper2d()
    values = dict(scene.params)
    values["xm"], values["ym"] = scene.pivot
    return np.array([values[k] for k in PARAM_NAMES], dtype=float), scene.initial_state()


def build(directory: str | os.PathLike | None = None, *, independent: str = "s") -> PydyPeer:
    """Derive with KanesMethod and compile with PyDy's Cython generator.

    ``directory``: where PyDy writes and compiles its sources (created if missing, kept). By
    default PyDy's own choice: a new directory under the system temporary directory, removed
    once the extension is imported. Never the working directory.
    """
    from pydy.codegen.ode_function_generators import generate_ode_function  # noqa: PLC0415

    d = derive(independent)
    kane = d.kane
    kin = sp.Matrix([kane.kindiffdict()[q.diff(_t)] for q in d.coordinates])
    tmp_dir = None if directory is None else os.fspath(directory)
    t0 = time.perf_counter()
    ode = generate_ode_function(kane.forcing, d.coordinates, d.speeds, d.constants,
                                mass_matrix=kane.mass_matrix, coordinate_derivatives=kin,
                                generator="cython", constants_arg_type="array",
                                tmp_dir=tmp_dir)
    codegen = time.perf_counter() - t0
    p, x0 = _scene_numbers()
    # KanesMethod orders u as u_ind + u_dep, aligned with q_ind + q_dep (u = q')
    names = tuple(str(v.func) for v in d.coordinates)
    return PydyPeer(derivation=d, ode=ode, p=p, state_names=names + tuple("d" + n for n in names),
                    x0_ours=x0, timings={"derivation": d.seconds, "codegen_compile": codegen},
                    directory=tmp_dir)


# ---------------------------------------------------------------------- checks against grasping_sym
def rhs_agreement(peer: PydyPeer, model, X, *, model_params=None) -> dict:
    """PyDy's right-hand side against ``model.rhs`` at ``grasping_sym`` states ``X`` (rows).

    Returns the largest absolute differences of the accelerations ``(theta'', q1'', q2'')`` (rad/s^2),
    of ``s'`` (m/s), and the largest acceleration itself. ``s''`` (PyDy's ``ds'`` rate), which
    ``grasping_sym`` has no state for, is compared with the central difference of ``model``'s
    ``s'`` along its own flow (step 1e-6 s): agreement ~1e-6 relative at best.
    ``model_params``: run-time parameters of ``model`` (e.g. zero CSM gains).
    """
    X = np.atleast_2d(np.asarray(X, dtype=float))
    call = (lambda x: model.rhs(x)) if model_params is None else (lambda x: model.rhs(x, model_params))
    acc, sdot, sdd, amax, sdd_max = 0.0, 0.0, 0.0, 0.0, 0.0
    js = peer.state_names.index("ds")
    h = 1e-6
    for x in X:
        ours = call(x)
        xp = peer.from_ours(x)
        full = peer.rhs(0.0, xp)
        mine = peer.to_ours(full)
        acc = max(acc, float(np.max(np.abs(mine[3:6] - ours[3:6]))))
        sdot = max(sdot, abs(float(mine[6] - ours[6])))
        amax = max(amax, float(np.max(np.abs(ours[3:6]))))
        s_dd = (call(x + h * ours)[6] - call(x - h * ours)[6]) / (2 * h)
        sdd = max(sdd, abs(float(full[js] - s_dd)))
        sdd_max = max(sdd_max, abs(s_dd))
    return {"states": len(X), "max_abs_acc_diff": acc, "max_abs_acc": amax, "max_abs_sdot_diff": sdot,
            "max_abs_sddot_diff_vs_fd": sdd, "max_abs_sddot": sdd_max}


def constraint_residual(model, X_ours) -> float:
    """``max(|Q|, |R|)`` (m) of ``grasping_sym``'s outputs over the states ``X_ours`` (rows)."""
    out = model.outputs_batch(np.ascontiguousarray(X_ours, dtype=float))
    return float(max(np.max(np.abs(out["Q"])), np.max(np.abs(out["R"]))))


def rhs_cost_us(peer: PydyPeer, x_ours, *, number: int = 20_000, repeat: int = 5) -> dict:
    """Microseconds per call: PyDy's generated function as odeint calls it (``ode(x, t, p)``, its
    result in a reused buffer) and the solve_ivp wrapper ``peer.rhs`` (one copy more)."""
    from benchmarks.timing import best_per_call  # noqa: PLC0415

    xp = np.ascontiguousarray(peer.from_ours(x_ours))
    ode, p = peer.ode, peer.p
    return {"pydy_ode_us": best_per_call(lambda: ode(xp, 0.0, p), number=number, repeat=repeat) * 1e6,
            "solve_ivp_wrapper_us": best_per_call(lambda: peer.rhs(0.0, xp), number=number,
                                                  repeat=repeat) * 1e6}


class WPRow(NamedTuple):
    """One tolerance of ``work_precision``."""

    tol: float                        # rtol (atol = rtol * atol_factor)
    wall_s: float                     # median wall time of a 3 s run (integration only)
    error: float                      # max |final state - reference| over grasping_sym's 7 states
    max_constraint_residual: float    # max(|Q|, |R|) (m) over a dense run (every DENSE_DT s)


def work_precision(reference_final_state, tolerances=(1e-6, 1e-7, 1e-8, 1e-9, 1e-10, 1e-11, 1e-12), *,
                   method: str = "odeint", peer: PydyPeer | None = None, model=None,
                   atol_factor: float = ATOL_FACTOR, atol: float | None = None,
                   repeats: int = 5, t_final: float = T_FINAL,
                   details: list | None = None) -> list[WPRow]:
    """Wall time against final-state error of the PyDy peer, one row per ``rtol`` in ``tolerances``.

    Each run starts from ``grasping_sym``'s initial state and integrates ``t_final`` seconds with
    ``method`` (``'odeint'``, as ``pydy.system.System`` does, or a ``solve_ivp`` method),
    ``atol = rtol * atol_factor`` (as ``benchmarks.work_precision``) unless ``atol`` is given. Wall time: median of
    ``repeats`` runs after one untimed run, outputs at ``[0, t_final]`` only. Error: max-norm over
    ``grasping_sym``'s state ``(theta, q1, q2, dtheta, dq1, dq2, s)`` against
    ``reference_final_state`` (ordered so). Constraint residual: one more run with outputs every
    ``DENSE_DT`` s, mapped to ``grasping_sym``'s states and measured by ``model``'s outputs ``Q`` and
    ``R`` (``model.outputs_batch``), as for ``grasping_sym``'s own runs. ``peer`` and ``model`` are
    built when not given. ``details``, if a list, receives one dict per row with ``method``,
    ``atol``, ``nfev``, the final state and PyDy's own constraint residuals over the dense run:
    the contact gap (m; what ``Q``, ``R`` measure) and the tangency defect (rad; ``Q`` and ``R`` do
    not see it, see ``PydyPeer.with_tangency``).
    """
    if peer is None:
        peer = build()
    if model is None:
        import grasping_sym as gs  # noqa: PLC0415

        model = gs.build(gs.scenes.paper2d())
    x_ref = np.asarray(reference_final_state, dtype=float)
    rows = []
    dense = np.linspace(0.0, t_final, round(t_final / DENSE_DT) + 1)
    for tol in tolerances:
        kw = {"rtol": tol, "atol": tol * atol_factor if atol is None else atol,
              "method": method}
        peer.simulate(t_final, **kw)
        walls = []
        for _ in range(repeats):
            r = peer.simulate(t_final, **kw)
            walls.append(r.stats["wall_time"])
        error = float(np.max(np.abs(r.x[-1] - x_ref)))
        rd = peer.simulate(t_final, t_eval=dense, **kw)
        rows.append(WPRow(tol, float(statistics.median(walls)), error, constraint_residual(model, rd.x)))
        if details is not None:
            own = np.abs(peer.configuration_residual(rd.x_pydy))
            details.append({"method": method, "rtol": tol, "atol": kw["atol"], "nfev": r.stats["nfev"],
                            "pydy_max_gap_m": float(own[:, :2].max()), "pydy_max_tangency_rad": float(own[:, 2].max()),
                            "x_final": r.x[-1].tolist()})
    return rows


# ---------------------------------------------------------------------- report
_COLD_CODE = """
import json, tempfile, time
t0 = time.perf_counter()
from benchmarks.peers import pydy_paper2d as pp
t_import = time.perf_counter() - t0
with tempfile.TemporaryDirectory(prefix="pydy-paper2d-") as d:
    peer = pp.build(d)
print(json.dumps({**peer.timings, "import_s": t_import}))
"""


def cold_timings(runs: int = 1) -> list[dict]:
    """Derivation and codegen+compile seconds, each in a fresh interpreter (cold SymPy caches)."""
    from benchmarks.timing import in_fresh_process  # noqa: PLC0415

    with tempfile.TemporaryDirectory(prefix="gs-peer-cache-") as cache:
        return [in_fresh_process(_COLD_CODE, cache) for _ in range(runs)]


def report(*, quick: bool = False, log=print) -> dict:
    """Everything the benchmark table needs, measured in this process (builds in temp dirs)."""
    import grasping_sym as gs  # noqa: PLC0415
    from benchmarks.timing import best_per_call  # noqa: PLC0415

    out: dict = {}
    with tempfile.TemporaryDirectory(prefix="gs-peer-cache-") as cache:
        old = os.environ.get("GRASPING_SYM_CACHE")
        os.environ["GRASPING_SYM_CACHE"] = cache
        try:
            model = gs.build(gs.scenes.paper2d())
            gains = ("gf", "gl", "wf", "wl")
            model0 = gs.build(gs.scenes.paper2d(runtime=gains))
        finally:
            if old is None:
                os.environ.pop("GRASPING_SYM_CACHE", None)
            else:
                os.environ["GRASPING_SYM_CACHE"] = old
    cold = cold_timings(1 if quick else 3)
    out["cold"] = cold
    log("cold (fresh interpreter): " + "; ".join(
        f"derivation {c['derivation']:.2f} s, codegen+compile {c['codegen_compile']:.2f} s" for c in cold))
    with tempfile.TemporaryDirectory(prefix="pydy-paper2d-") as d:
        peer = build(d)
    out["warm"] = peer.timings
    out["state_names"] = peer.state_names

    # reference: grasping_sym, CVODES 1e-14 (as benchmarks.work_precision's full mode), cross-checked
    # by CVODES 1e-13, IDAS 1e-13 and grasping_sym's Radau 1e-12 (atol 1e-10)
    def final(method, **kw):
        return model.simulate(T_FINAL, method=method, t_eval=[0.0, T_FINAL], outputs=False, **kw).x[-1]

    ref = final("cvodes", rtol=1e-14, atol=1e-14)
    checks = {"cvodes 1e-13": final("cvodes", rtol=1e-13, atol=1e-13),
              "idas 1e-13": final("idas", rtol=1e-13, atol=1e-13),
              "radau 1e-12": final("radau", rtol=1e-12, atol=1e-10)}
    out["reference"] = {"method": "cvodes 1e-14", "x_final": ref.tolist(),
                        "cross_checks": {k: float(np.max(np.abs(v - ref))) for k, v in checks.items()}}
    log("reference grasping_sym cvodes 1e-14; differences: " + ", ".join(
        f"{k} {v:.1e}" for k, v in out["reference"]["cross_checks"].items()))

    # right-hand sides on the manifold: our trajectory (CVODES 1e-13), s re-solved from tangency
    grid = np.linspace(0.0, T_FINAL, 61)
    traj = model.simulate(T_FINAL, method="cvodes", rtol=1e-13, atol=1e-13, t_eval=grid)
    X = np.array([peer.with_tangency(x) for x in traj.x])
    Xp = np.array([peer.from_ours(x) for x in traj.x])
    out["traj"] = {"max_QR": float(max(np.max(np.abs(traj["Q"])), np.max(np.abs(traj["R"])))),
                   "max_tangency_defect": float(np.max(np.abs(peer.configuration_residual(Xp)[:, 2]))),
                   "max_s_correction": float(np.max(np.abs(X[:, 6] - traj.x[:, 6])))}
    tr = out["traj"]
    log(f"our trajectory (cvodes 1e-13, 61 states): max |Q|,|R| {tr['max_QR']:.1e} m, tangency "
        f"defect {tr['max_tangency_defect']:.1e} rad (s re-solved by <= {tr['max_s_correction']:.1e} m)")
    out["rhs_agreement"] = rhs_agreement(peer, model, X)
    out["rhs_agreement_no_csm"] = rhs_agreement(peer, model0, X, model_params=np.zeros(4))
    out["rhs_agreement_no_csm_raw_states"] = rhs_agreement(peer, model0, traj.x, model_params=np.zeros(4))
    for k, label in (("rhs_agreement", "paper2d (CSM gains on)"), ("rhs_agreement_no_csm", "CSM gains 0"),
                     ("rhs_agreement_no_csm_raw_states", "CSM gains 0, s not re-solved")):
        a = out[k]
        log(f"rhs vs {label}: max |acc diff| {a['max_abs_acc_diff']:.2e} rad/s^2 (max |acc| "
            f"{a['max_abs_acc']:.2e}), |s' diff| {a['max_abs_sdot_diff']:.2e} m/s, |s'' - FD| "
            f"{a['max_abs_sddot_diff_vs_fd']:.2e} (max |s''| {a['max_abs_sddot']:.2e})")

    # 3 s runs at tight tolerance against ours
    runs = {}
    for method, tol in (("odeint", 1e-13), ("LSODA", 1e-13), ("Radau", 1e-11)):
        r = peer.simulate(T_FINAL, rtol=tol, atol=tol * ATOL_FACTOR, method=method, t_eval=grid)
        runs[f"{method} {tol:g}"] = {
            "final_error": float(np.max(np.abs(r.x[-1] - ref))),
            "max_error_on_grid": float(np.max(np.abs(r.x - traj.x))),
            "max_QR": constraint_residual(model, r.x),
            "pydy_config_residual_final": float(np.max(np.abs(peer.configuration_residual(r.x_pydy[-1])))),
            "wall_s": r.stats["wall_time"], "nfev": r.stats["nfev"]}
        log(f"3 s run {method} rtol {tol:g}: final error {runs[f'{method} {tol:g}']['final_error']:.2e}, "
            f"max over 61 samples {runs[f'{method} {tol:g}']['max_error_on_grid']:.2e}")
    out["tight_runs"] = runs

    # cost of one right-hand side
    x_mid = traj.x[len(traj.x) // 3]
    cost = rhs_cost_us(peer, x_mid, number=5_000 if quick else 20_000)
    cost["grasping_sym_model_rhs_us"] = best_per_call(lambda: model.rhs(x_mid), number=20_000, repeat=5) * 1e6
    out["rhs_cost_us"] = cost
    log(f"rhs: PyDy ode {cost['pydy_ode_us']:.2f} us/call, solve_ivp wrapper {cost['solve_ivp_wrapper_us']:.2f} "
        f"us; grasping_sym model.rhs {cost['grasping_sym_model_rhs_us']:.2f} us")

    # work-precision
    tols = (1e-6, 1e-8, 1e-10, 1e-12) if quick else tuple(10.0**-k for k in range(6, 13))
    wp = {}
    for method in ("odeint", "LSODA", "Radau"):
        details: list = []
        rows = work_precision(ref, tols, method=method, peer=peer, model=model, repeats=3 if quick else 7,
                              details=details)
        wp[method] = [{**row._asdict(), **{k: v for k, v in d.items() if k != "x_final"}}
                      for row, d in zip(rows, details)]
        for row in wp[method]:
            log(f"  {method:6s} rtol {row['tol']:.0e}: {row['wall_s'] * 1e3:8.2f} ms  error {row['error']:.2e}  "
                f"max |Q|,|R| {row['max_constraint_residual']:.2e}  PyDy gap {row['pydy_max_gap_m']:.1e} m, "
                f"tangency {row['pydy_max_tangency_rad']:.1e} rad  nfev {row['nfev']}")
    out["work_precision"] = wp
    return out


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="fewer tolerances and repeats")
    parser.add_argument("--json", help="write the figures to this JSON file")
    args = parser.parse_args(argv)
    out = report(quick=args.quick)
    if args.json:
        with open(args.json, "w") as f:
            json.dump(out, f, indent=1)
    return 0


if __name__ == "__main__":
    sys.exit(main())
