"""The NumPy/SciPy reference of the 3D rolling contact (one finger, pivoted object).

Checks: the constraint Jacobian is the relative velocity of the material points; a 1 s run
stays on the contact manifold and balances energy; the quaternion stays unit; with a
spherical object the contact rolls and the system comes to rest with finite rates.
"""
from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.integrate import solve_ivp

from tests.oracles import contact3d_numeric as c3n
from tests.oracles.reference3d import SL_ETA, SL_QUAT, Reference3D, Scene3D

TOL = {"method": "LSODA", "rtol": 1e-10, "atol": 1e-12}


@pytest.fixture(scope="module")
def ellipsoid_model() -> Reference3D:
    return Reference3D()


@pytest.fixture(scope="module")
def sphere_model() -> Reference3D:
    return Reference3D(Scene3D(semi_axes=(0.025, 0.025, 0.025)))


def _quat_mul(a, b):
    aw, av, bw, bv = a[0], a[1:], b[0], b[1:]
    return np.r_[aw * bw - av @ bv, aw * bv + bw * av + np.cross(av, bv)]


def _advance(x: np.ndarray, V: np.ndarray, h: float) -> np.ndarray:
    """The configuration after time h at constant speeds V, exactly on SO(3); eta unchanged."""
    y = x.copy()
    y[0:2] += h * V[0:2]
    w = V[2:5]
    nw = np.linalg.norm(w)
    dq = np.r_[math.cos(nw * h / 2), math.sin(nw * h / 2) * w / nw] if nw > 0 else np.r_[1.0, 0, 0, 0]
    y[SL_QUAT] = _quat_mul(x[SL_QUAT], dq)    # body-frame omega: quat (x) exp(omega h / 2)
    return y


@pytest.mark.parametrize("model_name", ["ellipsoid_model", "sphere_model"])
def test_initial_contact_is_consistent(model_name, request):
    m = request.getfixturevalue(model_name)
    o = m.outputs(m.initial_state())
    assert max(abs(o["Qn"]), abs(o["Qb"]), abs(o["Qe"]), o["residual_max"]) <= 1e-12
    assert o["krel_name"] == "regular" and o["krel_min_eig"] > 0


@pytest.mark.parametrize("model_name", ["ellipsoid_model", "sphere_model"])
def test_constraint_rows_are_relative_velocity(model_name, request):
    """A V = d/dt C with eta fixed (central differences on SO(3)) = v_finger - v_object.

    Sampled at the start and at two later points of the manifold (short runs with
    admissible initial speeds), each with random speeds V.
    """
    m = request.getfixturevalue(model_name)
    rng = np.random.default_rng(7)
    x0 = m.initial_state()
    states = [x0] + [solve_ivp(m, (0, 0.05), m.initial_state(m.admissible_speeds(x0) @ rng.normal(size=2)),
                               **TOL).y[:, -1] for _ in range(2)]
    for x in states:
        assert m.outputs(x)["residual_max"] <= 1e-9
        V = rng.normal(size=5)
        p = m.pieces(x)
        AV = p["A"] @ V
        h = 1e-6
        fd = (m.pieces(_advance(x, V, h))["C"] - m.pieces(_advance(x, V, -h))["C"]) / (2 * h)
        scale = np.linalg.norm(AV)
        assert np.linalg.norm(fd - AV) <= 1e-7 * scale, (fd, AV)
        # contact3d's relative motion (object relative to finger) is the opposite velocity,
        # with (Qn, Qb, Qe) along (n_f, x_f, y_f)
        uf, vf = x[SL_ETA][:2]
        cf = c3n.contact_frame_world(m.fingertip, p["Pi"], p["r"], uf, vf)
        v_rel, _ = c3n.relative_motion(cf.frame, cf.point, (p["W"] @ V[:2], p["J"] @ V[:2], p["r"]),
                                      (p["R"] @ V[2:], np.zeros(3), m.pivot))
        # (off the manifold by |C| ~ 1e-12 m the two differ by O(|C| curvature |V|))
        assert np.linalg.norm(AV + v_rel[[2, 0, 1]]) <= 1e-9 * scale
        # on the manifold d(C')/dV = A: the contact rates add no acceleration term
        assert np.max(np.abs(p["Ahat"] - p["A"])) <= 1e-9 * np.max(np.abs(p["A"]))


@pytest.fixture(scope="module")
def ellipsoid_run(ellipsoid_model):
    """1 s from rest (LSODA, rtol 1e-10), with the quadratures of the controller power and of the constraint power."""
    m = ellipsoid_model

    def f(t, y):
        x = y[:16]
        xdot, mu = m._solve(x)
        p = m.pieces(x)
        return np.concatenate([xdot, [x[6:8] @ p["u"], mu @ (p["A"] @ x[6:11])]])

    y0 = np.r_[m.initial_state(), 0.0, 0.0]
    sol = solve_ivp(f, (0.0, 1.0), y0, **TOL)
    assert sol.status == 0, sol.message
    ts, Y = sol.t, sol.y          # the integrator's own steps (dense output is less accurate)
    outs = [m.outputs(Y[:16, i]) for i in range(ts.size)]
    return ts, Y, outs


def test_run_stays_in_contact(ellipsoid_run):
    ts, Y, outs = ellipsoid_run
    gap = max(max(abs(o["Qn"]), abs(o["Qb"]), abs(o["Qe"])) for o in outs)
    world = max(max(o["normal"], o["frame"], abs(o["angle"]), o["point"]) for o in outs)
    assert gap <= 1e-9, gap
    assert world <= 1e-8, world
    # the scene really moves: the contact travels on both bodies and the object turns
    assert np.linalg.norm(Y[SL_ETA, -1][:4] - Y[SL_ETA, 0][:4]) > 0.1
    assert all(o["f"] > 0 for o in outs)                   # the finger pushes throughout
    assert all(o["krel_name"] == "regular" for o in outs)


def test_energy_balance(ellipsoid_run):
    """KE(t) - KE(0) = int q'.u dt.

    Exactly, dKE/dt = q'.u - mu.(A V): besides the controller only the constraint forces do
    work, and A V is the relative velocity of the material points, zero on the manifold. In
    the run Baumgarte holds |A V| at the integrator's error level (~1e-12 m/s) with
    |mu| <= 2 N, so their work over 1 s is a few 1e-12 J (carried along as a quadrature and
    checked); the states are accurate to rtol 1e-10, so KE (quadratic in the speeds) is good
    to ~1e-9 of its peak. Tolerance: 1e-8 of the peak kinetic energy (6.7e-4 J) for both.
    """
    ts, Y, outs = ellipsoid_run
    ke = np.array([o["kinetic_energy"] for o in outs])
    err = np.max(np.abs(ke - ke[0] - Y[16]))
    assert ke.max() > 1e-4                                 # not trivially at rest
    assert np.max(np.abs(Y[17])) <= 1e-8 * ke.max()        # constraint forces do ~no work
    assert err <= 1e-8 * ke.max(), (err, ke.max())


def test_quaternion_stays_unit(ellipsoid_run):
    """spatial.py's Baumgarte term (k = 10 1/s) keeps |quat| = 1 to the integrator's error.

    The unit-form rotation is ``|quat|^2 R_true + (1 - |quat|^2) I``, so its orthonormality
    error is bounded by ~4 |1 - |quat|^2| ~ 8 |1 - |quat|| (entries of I - R_true reach 2).
    """
    ts, Y, outs = ellipsoid_run
    norm_err = max(abs(o["quat_norm_error"]) for o in outs)
    assert norm_err <= 1e-10
    assert max(o["orthonormality"] for o in outs) <= 8 * norm_err + 1e-15


def test_sphere_rolls_to_rest(sphere_model):
    """Spherical object: start rolling (no spin about the normal, which nothing damps) and
    run until the speeds fall below 1e-6 of their peak; every rate stays finite at rest."""
    m = sphere_model
    x0 = m.initial_state()
    p = m.pieces(x0)
    d = p["R"].T @ (p["r"] - m.pivot)
    spin = np.r_[0.0, 0.0, *(d / np.linalg.norm(d))]   # turning about the contact normal
    assert np.linalg.norm(p["A"] @ spin) <= 1e-14
    N = m.admissible_speeds(x0)
    c = N.T @ p["M"] @ spin
    V0 = N @ np.array([c[1], -c[0]])                         # admissible, M-orthogonal to spin
    V0 *= 3.0 / np.linalg.norm(V0[:2])                       # |q'| = 3 rad/s
    x0 = m.initial_state(V0)
    assert np.max(np.abs(p["A"] @ V0)) <= 1e-14

    peak = np.linalg.norm(V0)
    T = 3.0
    sol = solve_ivp(m, (0.0, T), x0, dense_output=True, **TOL)
    assert sol.status == 0, sol.message
    assert np.all(np.isfinite(sol.y))
    ts = np.linspace(0.0, T, 601)
    Y = sol.sol(ts)
    speed = np.linalg.norm(Y[6:11], axis=0)
    assert speed.max() <= 1.01 * peak
    rest = np.flatnonzero(speed < 1e-6 * peak)
    assert rest.size and rest[0] < ts.size - 100, "did not reach rest"
    # at rest and after: all rates finite, contact rates ~0, still on the manifold
    for i in range(rest[0], ts.size, 25):
        xdot = m.rhs(Y[:, i])
        o = m.outputs(Y[:, i])
        assert np.all(np.isfinite(xdot))
        assert np.max(np.abs(xdot[SL_ETA])) <= 1e-4
        assert o["residual_max"] <= 1e-8 and max(abs(o["Qn"]), abs(o["Qb"]), abs(o["Qe"])) <= 1e-9
        assert math.isfinite(o["f"]) and o["f"] > 0
    xdot_rest = m.rhs(np.r_[Y[:6, -1], np.zeros(5), Y[11:, -1]])   # exactly zero speeds
    assert np.all(np.isfinite(xdot_rest)) and np.all(xdot_rest[SL_ETA] == 0.0)
    # the contact point moved on the object (rolling) and on the fingertip
    assert np.linalg.norm(Y[13:15, -1] - x0[13:15]) > 1e-2
    assert np.linalg.norm(Y[11:13, -1] - x0[11:13]) > 1e-2
