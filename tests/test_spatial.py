"""Spatial finger chains and the free rigid body (grasping_sym.model.chains, derive.spatial).

Independent checks: the 2D derivation of derive.planar, the paper's W1 and W2 (eq 39), finite
differences of the forward kinematics, conservation laws and the closed-form precession of a
torque-free axisymmetric body.
"""
from __future__ import annotations

import math

import numpy as np
import pytest
import sympy as sp
from scipy.integrate import solve_ivp

from grasping_sym.derive.planar import derive_template
from grasping_sym.derive.spatial import (
    BAUMGARTE_RATE,
    finger_dynamics,
    finger_kinematics,
    free_body,
    quaternion_product,
    quaternion_rate_matrix,
    quaternion_to_matrix,
    skew,
)
from grasping_sym.errors import InvalidBodyError
from grasping_sym.model.chains import (
    FINGER1_Q_OPPOSED,
    FINGER2_Q_OPPOSED,
    FingerChain,
    RevoluteJoint,
    finger1,
    finger2,
)

RNG = np.random.default_rng(20110321)
GRAVITY = (0.0, -9.81, 0.0)


def _by_name(expr: sp.Expr, symbols) -> sp.Expr:
    """Replace symbols of ``expr`` by the same-named ones of ``symbols`` (assumptions differ)."""
    names = {str(s): s for s in symbols}
    return expr.xreplace({s: names[str(s)] for s in expr.free_symbols if str(s) in names})


@pytest.fixture(scope="module")
def fingers():
    """Numeric kinematics and dynamics of both presets, lambdified."""
    out = {}
    for chain in (finger1(), finger2()):
        kin = finger_kinematics(chain)
        dyn = finger_dynamics(kin, GRAVITY)
        q, dq = list(kin.q), list(kin.dq)
        out[chain.name] = {
            "kin": kin, "dyn": dyn, "n": chain.n,
            "r": sp.lambdify([q], kin.r, "numpy"), "Pi": sp.lambdify([q], kin.Pi, "numpy"),
            "J": sp.lambdify([q], kin.J, "numpy"), "W": sp.lambdify([q], kin.W, "numpy"),
            "G": sp.lambdify([q], dyn.G, "numpy"), "h": sp.lambdify([q, dq], dyn.h, "numpy"),
            "K": sp.lambdify([q, dq], dyn.kinetic_energy, "numpy"),
            "P": sp.lambdify([q], dyn.potential_energy, "numpy"),
            "dP": sp.lambdify([q], dyn.gravity_gradient, "numpy"),
        }
    return out


# ------------------------------------------------------------------------ 2D cross-check


def test_finger1_reduces_to_the_planar_finger():
    """Finger 1 at the origin is the 2D finger: O01, the fingertip frame, G and gravity."""
    kin = finger_kinematics(finger1(base=(0.0, 0.0, 0.0)), symbolic=True)
    dyn = finger_dynamics(kin, sp.symbols("gx gy", real=True) + (0,))
    planar = derive_template(True, True)
    q11, q12 = kin.q
    to_finger = {sp.Symbol("q1", real=True): q11, sp.Symbol("q2", real=True): q12}
    ours = [*kin.q, *kin.dq, *kin.params, *dyn.gravity]
    l11, l12 = (next(s for s in kin.params if str(s) == n) for n in ("l11", "l12"))

    O01 = sp.Matrix([l11 * sp.sin(q11) + l12 * sp.sin(q11 + q12),
                     l11 * sp.cos(q11) + l12 * sp.cos(q11 + q12), 0])
    assert sp.simplify(kin.r - O01) == sp.zeros(3, 1)
    a = sp.pi / 2 - q11 - q12
    Rot = sp.Matrix([[sp.cos(a), -sp.sin(a), 0], [sp.sin(a), sp.cos(a), 0], [0, 0, 1]])
    assert sp.simplify(kin.Pi - Rot) == sp.zeros(3, 3)

    G2 = _by_name(planar.mass_matrix[1:, 1:].xreplace(to_finger), ours)
    assert sp.simplify(dyn.G - G2) == sp.zeros(2, 2)
    P2 = _by_name(planar.outputs["potential_energy"].xreplace(to_finger), ours)
    assert sp.simplify(dyn.potential_energy - P2) == 0

    # numerically at random q, with the paper's values, against the 2D template's G
    G_fun = sp.lambdify([kin.q], dyn.G.subs(kin.params), "numpy")
    values = {str(k): v for k, v in kin.params.items()}
    G2_fun = sp.lambdify([kin.q], G2.subs({s: values[str(s)] for s in G2.free_symbols
                                           if str(s) in values}), "numpy")
    for _ in range(10):
        qv = RNG.uniform(-math.pi, math.pi, 2)
        np.testing.assert_allclose(G_fun(qv), G2_fun(qv), rtol=1e-13, atol=0)


def test_W_are_the_papers_eq39_with_its_sign():
    """W_i = -W_i(paper eq 39): the paper's finger angular velocity has the sign of its eq (8)."""
    k1 = finger_kinematics(finger1())
    k2 = finger_kinematics(finger2())
    W1_paper = sp.Matrix([[0, 0], [0, 0], [1, 1]])
    q21 = k2.q[0]
    W2_paper = sp.Matrix([[1, 0, 0], [0, sp.sin(q21), sp.sin(q21)], [0, sp.cos(q21), sp.cos(q21)]])
    assert sp.simplify(k1.W + W1_paper) == sp.zeros(3, 2)
    assert sp.simplify(k2.W + W2_paper) == sp.zeros(3, 3)
    # eq (8): Pi1' = Pi1 Omega1 with Omega1 = [[0, p1', 0], [-p1', 0, 0], [0, 0, 0]], p1 = q11 + q12
    t = sp.Symbol("t")
    q_t = [sp.Function(f"q1{k}")(t) for k in (1, 2)]
    Pi_t = k1.Pi.xreplace(dict(zip(k1.q, q_t)))
    p1dot = sum(sp.diff(qk, t) for qk in q_t)
    Omega1 = sp.Matrix([[0, p1dot, 0], [-p1dot, 0, 0], [0, 0, 0]])
    assert sp.simplify(Pi_t.diff(t) - Pi_t * Omega1) == sp.zeros(3, 3)


def test_presets_oppose_across_the_object():
    """At the documented opposed angles the fingertip centres face each other 0.06 m apart."""
    r1 = np.array(finger_kinematics(finger1()).r.subs(
        dict(zip(finger_kinematics(finger1()).q, FINGER1_Q_OPPOSED))), dtype=float).ravel()
    k2 = finger_kinematics(finger2())
    r2 = np.array(k2.r.subs(dict(zip(k2.q, FINGER2_Q_OPPOSED))), dtype=float).ravel()
    np.testing.assert_allclose(r1, [-0.03, 0.065 * math.cos(math.pi / 6), 0.0], atol=1e-15)
    np.testing.assert_allclose(r2, [0.03, 0.065 * math.cos(math.pi / 6), 0.0], atol=1e-15)


# -------------------------------------------------------------------- kinematics, inertia


@pytest.mark.parametrize("name", ["1", "2"])
def test_J_and_W_by_finite_differences(fingers, name):
    f = fingers[name]
    n, step = f["n"], 1e-5
    for _ in range(5):
        q = RNG.uniform(-math.pi, math.pi, n)
        J_fd = np.zeros((3, n))
        W_fd = np.zeros((3, n))
        for k in range(n):
            e = np.zeros(n)
            e[k] = step
            J_fd[:, k] = (f["r"](q + e) - f["r"](q - e)).ravel() / (2 * step)
            dPi = (f["Pi"](q + e) - f["Pi"](q - e)) / (2 * step)
            Om = dPi @ f["Pi"](q).T  # = [omega]x in the inertial frame
            assert np.max(np.abs(Om + Om.T)) < 1e-8
            W_fd[:, k] = [Om[2, 1], Om[0, 2], Om[1, 0]]
        np.testing.assert_allclose(f["J"](q), J_fd, rtol=0, atol=1e-7)
        np.testing.assert_allclose(f["W"](q), W_fd, rtol=0, atol=1e-7)
        Pi = f["Pi"](q)
        assert np.max(np.abs(Pi.T @ Pi - np.eye(3))) < 1e-14


def test_point_jacobian_by_finite_differences(fingers):
    f = fingers["2"]
    kin = f["kin"]
    p_tip = sp.Matrix([0.01, -0.004, 0.007])
    point = sp.lambdify([list(kin.q)], kin.r + kin.Pi * p_tip, "numpy")
    Jp = sp.lambdify([list(kin.q)], kin.point_jacobian(p_tip), "numpy")
    q = RNG.uniform(-math.pi, math.pi, 3)
    step = 1e-5
    fd = np.column_stack([(point(q + step * e) - point(q - step * e)).ravel() / (2 * step)
                          for e in np.eye(3)])
    np.testing.assert_allclose(Jp(q), fd, rtol=0, atol=1e-9)


@pytest.mark.parametrize("name", ["1", "2"])
def test_G_symmetric_positive_definite(fingers, name):
    f = fingers[name]
    assert sp.simplify(f["dyn"].G - f["dyn"].G.T) == sp.zeros(f["n"], f["n"])
    for _ in range(20):
        G = f["G"](RNG.uniform(-math.pi, math.pi, f["n"]))
        np.testing.assert_allclose(G, G.T, rtol=0, atol=1e-18)
        assert np.min(np.linalg.eigvalsh(G)) > 1e-9


def test_h_is_the_euler_lagrange_remainder(fingers):
    """h = d/dt(dK/dq') - dK/dq - G q'' on q(t) = q0 + v0 t + a0 t^2/2 at t = 0 (raw K)."""
    f = fingers["2"]
    kin = f["kin"]
    raw = finger_dynamics(kin, simplify=False)
    t = sp.Symbol("t")
    q0, v0, a0 = (sp.Matrix(RNG.uniform(-2, 2, 3)) for _ in range(3))
    path = {**dict(zip(kin.q, q0 + v0 * t + a0 * t**2 / 2)), **dict(zip(kin.dq, v0 + a0 * t))}
    at0 = {**dict(zip(kin.q, q0)), **dict(zip(kin.dq, v0))}
    K = sp.Matrix([raw.kinetic_energy])
    momentum = K.jacobian(kin.dq).T.xreplace(path)
    lhs = momentum.diff(t).subs(t, 0) - K.jacobian(kin.q).T.xreplace(at0)
    rest = lhs - f["dyn"].G.xreplace(at0) * a0 - f["dyn"].h.xreplace(at0)
    assert max(abs(float(x)) for x in rest) < 1e-15


# ----------------------------------------------------------------- conservation, fingers


def _integrate_finger(f, q0, v0, gravity: bool, t_final=1.0):
    n = f["n"]

    def rhs(_t, x):
        q, v = x[:n], x[n:]
        force = -f["h"](q, v).ravel() - (f["dP"](q).ravel() if gravity else 0.0)
        return np.concatenate([v, np.linalg.solve(f["G"](q), force)])

    sol = solve_ivp(rhs, (0.0, t_final), np.concatenate([q0, v0]), method="DOP853",
                    rtol=1e-13, atol=1e-13, dense_output=False, t_eval=np.linspace(0, t_final, 21))
    assert sol.success
    return sol


@pytest.mark.parametrize("name", ["1", "2"])
@pytest.mark.parametrize("gravity", [False, True])
def test_free_finger_conserves_energy(fingers, name, gravity):
    f = fingers[name]
    n = f["n"]
    q0 = RNG.uniform(-1.0, 1.0, n)
    v0 = RNG.uniform(-3.0, 3.0, n)
    sol = _integrate_finger(f, q0, v0, gravity)
    q, v = sol.y[:n], sol.y[n:]
    E = np.array([f["K"](q[:, i], v[:, i]) + (f["P"](q[:, i]) if gravity else 0.0)
                  for i in range(q.shape[1])])
    scale = f["K"](q0, v0)
    assert np.max(np.abs(E - E[0])) / scale <= 1e-9
    # the motion is not trivial: the kinetic energy changes by a lot
    K = np.array([f["K"](q[:, i], v[:, i]) for i in range(q.shape[1])])
    if gravity:
        assert np.ptp(K) / scale > 0.1


# --------------------------------------------------------------------------- free body


def test_quaternion_algebra():
    a = sp.Matrix(RNG.normal(size=4))
    b = sp.Matrix(RNG.normal(size=4))
    a, b = a / a.norm(), b / b.norm()
    Ra, Rb, Rab = (np.array(quaternion_to_matrix(x), dtype=float)
                   for x in (a, b, quaternion_product(a, b)))
    np.testing.assert_allclose(Ra @ Rb, Rab, atol=1e-14)
    np.testing.assert_allclose(Ra.T @ Ra, np.eye(3), atol=1e-14)
    c = 3.0 * a  # the homogeneous form is a rotation for any non-zero quaternion
    np.testing.assert_allclose(np.array(quaternion_to_matrix(c, unit=False), dtype=float), Ra,
                               atol=1e-14)
    w = sp.Matrix(RNG.normal(size=3))
    E = quaternion_rate_matrix(a) * w
    np.testing.assert_allclose(np.array(E, dtype=float),
                               np.array(quaternion_product(a, sp.Matrix([0, *w])) / 2, dtype=float),
                               atol=1e-15)
    # Pi0' = Pi0 [omega]x: omega is the body-frame angular velocity
    qs = sp.Matrix(sp.symbols("qw qx qy qz", real=True))
    R = quaternion_to_matrix(qs)
    Rdot = sum((R.diff(qs[i]) * (quaternion_rate_matrix(qs) * w)[i] for i in range(4)),
               sp.zeros(3, 3))
    resid = (Rdot - R * skew(w)).subs(dict(zip(qs, a)))
    assert max(abs(float(x)) for x in resid) < 1e-14


def _free_body_functions(body):
    state = list(body.state)
    return (sp.lambdify([state], body.rhs, "numpy"),
            sp.lambdify([state], body.kinetic_energy, "numpy"),
            sp.lambdify([state], body.angular_momentum, "numpy"),
            sp.lambdify([state], body.rotation, "numpy"))


def _integrate_body(rhs, x0, t_final, n_out=51):
    sol = solve_ivp(lambda _t, x: rhs(x).ravel(), (0.0, t_final), x0, method="DOP853",
                    rtol=1e-13, atol=1e-14, t_eval=np.linspace(0.0, t_final, n_out))
    assert sol.success
    return sol


def _initial_state(quat, omega, velocity=(0.0, 0.0, 0.0)):
    quat = np.asarray(quat, float)
    return np.concatenate([[0.01, 0.02, -0.03], quat / np.linalg.norm(quat), velocity, omega])


def test_torque_free_body_conserves_energy_and_momentum():
    """Three different principal moments (0.040 kg ellipsoid, semi-axes 0.03/0.02/0.015 m)."""
    a, b, c = 0.03, 0.02, 0.015
    M = 0.040
    H = np.diag([M * (b**2 + c**2) / 5, M * (a**2 + c**2) / 5, M * (a**2 + b**2) / 5])
    body = free_body(M, H.tolist())
    rhs, kin, mom, rot = _free_body_functions(body)
    x0 = _initial_state([0.9, 0.2, -0.3, 0.25], [3.0, -1.0, 4.0], velocity=(0.1, 0.0, -0.2))
    sol = _integrate_body(rhs, x0, 5.0)
    K = np.array([kin(x) for x in sol.y.T])
    L = np.array([mom(x).ravel() for x in sol.y.T])
    assert np.max(np.abs(K / K[0] - 1)) <= 1e-9
    assert np.max(np.linalg.norm(L - L[0], axis=1)) / np.linalg.norm(L[0]) <= 1e-9
    norm = np.linalg.norm(sol.y[3:7], axis=0)
    assert np.max(np.abs(norm - 1)) <= 1e-10
    ortho = max(np.max(np.abs(rot(x).T @ rot(x) - np.eye(3))) for x in sol.y.T)
    assert ortho <= 1e-10
    np.testing.assert_allclose(sol.y[:3, -1], x0[:3] + 5.0 * x0[7:10], rtol=1e-12, atol=1e-14)
    # the body really tumbles: omega changes direction in the body frame
    assert np.min(sol.y[10:13].T @ sol.y[10:13, 0]) < 0.9 * np.dot(x0[10:], x0[10:])


def test_axisymmetric_body_precesses_at_the_closed_form_rate():
    """H = diag(I1, I1, I3): in the body (I3 - I1) w3 / I1, in the world |L| / I1 about L."""
    I1, I3 = 2.0e-6, 5.0e-6
    body = free_body(0.040, [[I1, 0, 0], [0, I1, 0], [0, 0, I3]])
    rhs, _, mom, rot = _free_body_functions(body)
    w0 = np.array([1.5, 0.0, 4.0])
    x0 = _initial_state([0.8, -0.1, 0.5, 0.3], w0)
    t_final = 5.0
    sol = _integrate_body(rhs, x0, t_final)
    t = sol.t
    lam = (I3 - I1) * w0[2] / I1
    np.testing.assert_allclose(sol.y[10], w0[0] * np.cos(lam * t), rtol=0, atol=1e-9)
    np.testing.assert_allclose(sol.y[11], w0[0] * np.sin(lam * t), rtol=0, atol=1e-9)
    np.testing.assert_allclose(sol.y[12], w0[2], rtol=0, atol=1e-9)
    L = mom(x0).ravel()
    rate = np.linalg.norm(L) / I1
    axis = sp.Matrix(L / np.linalg.norm(L))
    e3_0 = rot(x0)[:, 2]
    for ti, x in zip(t, sol.y.T):
        quat = sp.Matrix([math.cos(rate * ti / 2), *(math.sin(rate * ti / 2) * axis)])
        expected = np.array(quaternion_to_matrix(quat), dtype=float) @ e3_0
        np.testing.assert_allclose(rot(x)[:, 2], expected, rtol=0, atol=1e-9)


def test_baumgarte_term_pulls_the_quaternion_back():
    body = free_body(1.0, [[1, 0, 0], [0, 2, 0], [0, 0, 3]])
    rhs, *_ = _free_body_functions(body)
    x0 = _initial_state([1.0, 0.0, 0.0, 0.0], [0.5, 0.1, -0.2])
    x0[3:7] *= 1.001  # |quat|^2 - 1 = 2.001e-3
    sol = _integrate_body(rhs, x0, 0.5)
    e = np.sum(sol.y[3:7] ** 2, axis=0) - 1
    # e' = -2k (1 + e) e: solved exactly, e(t) = e0 exp(-2kt) / (1 + e0 (1 - exp(-2kt)))
    decay = np.exp(-2 * BAUMGARTE_RATE * sol.t)
    np.testing.assert_allclose(e, e[0] * decay / (1 + e[0] * (1 - decay)), rtol=1e-7, atol=1e-13)


def test_free_fall_and_newton_euler_form():
    g = np.array(GRAVITY)
    body = free_body(0.040, np.diag([1e-6, 2e-6, 3e-6]).tolist(), gravity=GRAVITY)
    rhs, *_ = _free_body_functions(body)
    x0 = _initial_state([1, 0, 0, 0], [0, 0, 0], velocity=(0.2, 1.0, 0.0))
    sol = _integrate_body(rhs, x0, 0.3)
    np.testing.assert_allclose(sol.y[:3, -1], x0[:3] + 0.3 * x0[7:10] + 0.045 * g, atol=1e-13)
    speeds = sp.Matrix([*body.velocity, *body.omega])
    lhs = body.mass_matrix * sp.Matrix(body.speed_rates) + body.bias
    assert sp.simplify(lhs - sp.Matrix([*body.force, *body.torque])) == sp.zeros(6, 1)
    assert len(speeds) == 6


# -------------------------------------------------------------------------- validation


def test_invalid_chain_lists_every_problem():
    with pytest.raises(InvalidBodyError) as info:
        FingerChain(
            name="3",
            base=(0.0, math.nan, 0.0),
            joints=(
                RevoluteJoint(axis=(0.0, 0.0, 0.0), vector=(0.0, 0.05, 0.0), mass=0.04),
                RevoluteJoint(axis=(0.0, 0.0, 1.0), vector=(0.0, 0.0, 0.0), mass=0.03),
                RevoluteJoint(axis=(1.0, 0.0, 0.0), vector=(0.0, 0.05, 0.0), mass=-1.0),
            ),
            tip_rotation=((1.0, 0.0, 0.0), (0.0, 2.0, 0.0), (0.0, 0.0, 1.0)),
        )
    err = info.value
    assert len(err.problems) == 5, err.problems
    text = str(err)
    for fragment in ("base", "joint 1 (q31): axis", "joint 2 (q32): link length 0 m",
                     "joint 3 (q33): mass -1.0", "tip_rotation"):
        assert fragment in text
    assert isinstance(err, ValueError)


def test_preset_checks_entry_counts():
    with pytest.raises(InvalidBodyError, match="2 entries"):
        finger2(lengths=(0.065,))
