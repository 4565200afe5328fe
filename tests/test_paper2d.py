"""The paper's 2D scene (docs/conventions.md section 1): check values, settling, invariants, energy.

Expected values come from docs/conventions.md, the paper's figures, or closed-form formulas written
here from the contour definitions (paper eqs 37-40), never from the package's own output.
"""
from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.integrate import cumulative_simpson

import grasping_sym as gs
from grasping_sym.model.planar import DEFAULT_OUTPUTS

S_OBJ = 3.363e-3  # vertex offset of the object catenary (paper eq 39-40), m
T_FINAL = 3.0


# ------------------------------------------------------------------ closed-form contours
def _fingertip(s):
    """X0, Y0, X0', Y0' of paper eqs (37)-(38)."""
    w = np.sqrt(1 + (40 * s) ** 2)
    return 0.035 - w / 40, np.arcsinh(40 * s) / 40, -40 * s / w, 1 / w


def _object(s):
    """X, Y, X', Y' of paper eqs (39)-(40)."""
    u = s - S_OBJ
    w = np.sqrt(1 + (100 * u) ** 2)
    return -0.03 + w / 100, np.arcsinh(100 * u) / 100, 100 * u / w, 1 / w


# ------------------------------------------------------------------ fixtures
@pytest.fixture(scope="module")
def energy_result():
    """paper2d with the energy outputs, reported every 0.1 ms (for the power quadrature)."""
    model = gs.build(gs.scenes.paper2d(
        outputs=("Q", "R", "tangency_defect", "kinetic_energy", "power")))
    return model.simulate(T_FINAL, rtol=1e-10, atol=1e-12,
                          t_eval=np.linspace(0.0, T_FINAL, 30001))


@pytest.fixture(scope="module")
def runtime_model():
    return gs.build(gs.scenes.paper2d(runtime=("fd", "c")))


def _manifold_states(result, n, seed):
    """States at random times of a run (|Q|, |R| <= 1e-10), velocities rescaled.

    The velocity of a run lies in the one-dimensional null space of the 2x3 constraint
    Jacobian, so any multiple of it keeps the state on the constraint manifold.
    """
    rng = np.random.default_rng(seed)
    X = result.x[rng.integers(1, len(result.t), n)].copy()
    X[:, 3:6] *= rng.uniform(-3.0, 3.0, size=(n, 1))
    return X


# ------------------------------------------------------------------ initial state
def test_initial_configuration_check_values():
    scene = gs.scenes.paper2d()
    assert scene.q2_0 == pytest.approx(0.72277938, abs=5e-9)
    assert scene.pivot[0] == pytest.approx(0.12303738, abs=5e-9)
    assert scene.pivot[1] == pytest.approx(0.08350109, abs=5e-9)
    # tangency from the closed forms: q1 + q2 = pi/2 + theta + theta1(0) - psi0(0)
    psi0 = math.atan(-40 * 0.0)
    theta1 = math.atan(100 * (0.0 - S_OBJ))
    assert scene.q2_0 == pytest.approx(math.pi / 2 + theta1 - psi0 - math.pi / 6, abs=1e-14)


def test_initial_state_vector(paper2d_model):
    x0 = paper2d_model.initial_state()
    assert paper2d_model.state_names == ("theta", "q1", "q2", "dtheta", "dq1", "dq2", "s")
    np.testing.assert_allclose(x0, [0, math.pi / 6, 0.72277938, 0, 0, 0, 0], rtol=0, atol=5e-9)


def test_initial_lengths_check_values():
    """ln0 + ln1 and lb0 + lb1 of docs/conventions.md, and their relation to O01 - Om (paper 7-10)."""
    scene = gs.scenes.paper2d()
    X0, Y0, dX0, dY0 = _fingertip(0.0)
    X, Y, dX, dY = _object(0.0)
    psi0, th1 = math.atan(dX0 / dY0), math.atan(dX / dY)
    lb0 = X0 * math.sin(psi0) + Y0 * math.cos(psi0)
    lb1 = -X * math.sin(th1) - Y * math.cos(th1)
    ln0 = X0 * math.cos(psi0) - Y0 * math.sin(psi0)
    ln1 = -X * math.cos(th1) + Y * math.sin(th1)
    assert ln0 + ln1 == pytest.approx(0.029488, abs=5e-7)
    assert lb0 + lb1 == pytest.approx(-0.003069, abs=5e-7)
    # on the manifold (docs/conventions.md): with (x, y) = Om, (x01, y01) = O01, theta = 0
    q1, q2 = math.pi / 6, scene.q2_0
    x01 = 0.065 * (math.sin(q1) + math.sin(q1 + q2))
    y01 = 0.065 * (math.cos(q1) + math.cos(q1 + q2))
    x, y = scene.pivot
    assert (x - x01) * math.cos(th1) - (y - y01) * math.sin(th1) == pytest.approx(ln0 + ln1, abs=1e-15)
    assert (x - x01) * math.sin(th1) + (y - y01) * math.cos(th1) == pytest.approx(lb0 + lb1, abs=1e-15)


def test_initial_outputs(paper2d_result):
    out = paper2d_result.outputs
    assert out["kappa_sum"][0] == pytest.approx(129.84, abs=5e-3)
    assert out["kappa_sum"][0] == pytest.approx(40 + 100 / (1 + (100 * S_OBJ) ** 2), rel=1e-13)
    assert abs(out["Q"][0]) <= 1e-15 and abs(out["R"][0]) <= 1e-15
    # N1 = ln0 lb1 - lb0 ln1 at s = 0 from the closed forms
    X0, Y0, dX0, dY0 = _fingertip(0.0)
    X, Y, dX, dY = _object(0.0)
    lb0, ln0 = X0 * dX0 + Y0 * dY0, X0 * dY0 - Y0 * dX0
    lb1, ln1 = -X * dX - Y * dY, -X * dY + Y * dX
    assert out["N1"][0] == pytest.approx(ln0 * lb1 - lb0 * ln1, rel=1e-12)


# ------------------------------------------------------------------ the 3 s run
def test_constraints_stay_satisfied(paper2d_result):
    assert paper2d_result.t[-1] == pytest.approx(T_FINAL)
    assert np.max(np.abs(paper2d_result["Q"])) <= 1e-10
    assert np.max(np.abs(paper2d_result["R"])) <= 1e-10
    assert np.max(paper2d_result["constraint_residual"]) <= 1e-10


@pytest.mark.parametrize("name", ["delta_f", "delta_lam", "N1"])
def test_equilibrium_errors_decay(paper2d_result, name):
    """Paper figs: Delta f, Delta lambda and N1 tend to 0 (closed-loop relations 33-36)."""
    v = np.abs(paper2d_result[name])
    assert v.max() > 0
    assert v[-1] <= v.max() / 100, f"{name}: largest {v.max():.3g}, at 3 s {v[-1]:.3g}"


def test_contact_drifts_to_about_minus_5mm(paper2d_result):
    s_end = paper2d_result["s"][-1]
    assert -6e-3 <= s_end <= -4e-3


def test_motion_settles(paper2d_result):
    v = np.abs(paper2d_result.x[:, 3:6])
    assert v.max() > 0.1  # it did move
    assert np.all(v[-1] <= 1e-3 * v.max())


def test_catenary_invariant(paper2d_result):
    """q1 + q2 - theta - (atan(2*20 s) + atan(2*50 (s - 3.363e-3))) stays pi/2.

    Tangency is q1 + q2 = pi/2 + theta + theta1(s) - psi0(s) with theta1 = atan(X'/Y')
    = atan(100 (s - 3.363e-3)) and psi0 = atan(X0'/Y0') = -atan(40 s); its drift measures the
    error of the s equation (29).
    """
    r = paper2d_result
    s = r["s"]
    inv = r["q1"] + r["q2"] - r["theta"] - (np.arctan(40 * s) + np.arctan(100 * (s - S_OBJ)))
    assert np.max(np.abs(inv - math.pi / 2)) <= 1e-9
    assert np.ptp(s) > 4e-3  # the contact really moved


def test_tangency_defect_output_stays_zero(energy_result):
    assert np.max(np.abs(energy_result["tangency_defect"])) <= 1e-9


def test_energy_balance(energy_result):
    """docs/conventions.md section 3: with no gravity and the constraints held, d/dt KE = q'.u ('power').

    KE(t) - KE(0) is compared with the integral of the power (cumulative Simpson on the
    0.1 ms output grid). Tolerance 1e-11 J, i.e. 5e-7 of the peak kinetic energy
    (~2.1e-5 J): Simpson's quadrature error on this grid is ~1e-13 J, the constraint forces'
    work with |Q|, |R| ~1e-14 m is far smaller, and the integrator error at rtol 1e-10 is
    ~4e-13 J (at rtol 1e-8 the same check gives ~4e-11 J and would fail). A missing or
    wrongly signed term of the power or of the dynamics shows up at the level of KE itself.
    """
    r = energy_result
    ke, power = r["kinetic_energy"], r["power"]
    work = cumulative_simpson(power, x=r.t, initial=0.0)
    assert ke.max() > 1e-5 and np.max(np.abs(work)) > 1e-5  # a non-trivial exchange
    assert ke[0] == 0.0
    assert np.max(np.abs(ke - ke[0] - work)) <= 1e-11


def test_integrators_agree_on_final_state(paper2d_model, paper2d_result):
    ref = paper2d_result.x[-1]
    idas = paper2d_model.simulate(T_FINAL, method="idas", rtol=1e-10, atol=1e-12, outputs=False)
    rk4 = paper2d_model.simulate(T_FINAL, method="rk4", h=1e-4, outputs=False)
    assert rk4.stats["h"] == pytest.approx(1e-4)
    np.testing.assert_allclose(idas.x[-1], ref, rtol=0, atol=1e-8)
    np.testing.assert_allclose(rk4.x[-1], ref, rtol=0, atol=1e-8)


# ------------------------------------------------------------------ run-time parameters
def test_runtime_parameters_give_the_folded_rhs(paper2d_model, paper2d_result, runtime_model):
    assert runtime_model.param_names == ("fd", "c")
    # the compiled functions' p: the run-time parameters, then the pivot the start fixes
    assert runtime_model.p_names == ("fd", "c", "xm", "ym")
    pivot = gs.scenes.paper2d().pivot
    np.testing.assert_array_equal(runtime_model.default_params, [0.5, 0.006, *pivot])
    assert runtime_model.start_params == {"xm": pivot[0], "ym": pivot[1]}
    X = _manifold_states(paper2d_result, 25, seed=1)
    p = np.array([0.5, 0.006])
    folded = np.array([paper2d_model.rhs(x) for x in X])
    runtime = np.array([runtime_model.rhs(x, p) for x in X])
    err = np.abs(runtime - folded) / np.maximum(1.0, np.abs(folded))
    assert err.max() <= 1e-12


def test_runtime_parameters_give_the_folded_trajectory(paper2d_result, runtime_model):
    r = runtime_model.simulate(T_FINAL, rtol=1e-10, atol=1e-12, params={"fd": 0.5, "c": 0.006})
    assert r.params == {"fd": 0.5, "c": 0.006}
    np.testing.assert_allclose(r.x[-1], paper2d_result.x[-1], rtol=0, atol=1e-10)


def test_runtime_sweep_needs_no_rebuild(runtime_model):
    """A sweep over fd reuses one loaded model; each value matches a folded build."""
    lib, path = runtime_model.library, runtime_model.library_path
    finals = {}
    for fd in (0.5, 0.7):
        r = runtime_model.simulate(T_FINAL, rtol=1e-10, atol=1e-12, params={"fd": fd},
                                   outputs=False)
        assert r.params["fd"] == fd and r.params["c"] == 0.006
        finals[fd] = r.x[-1]
    assert runtime_model.library is lib and runtime_model.library_path == path
    assert np.max(np.abs(finals[0.7] - finals[0.5])) > 1e-6
    # the run-time value is really used: a scene with fd = 0.7 folded in agrees
    folded = gs.build(gs.scenes.paper2d(fd=0.7)).simulate(
        T_FINAL, rtol=1e-10, atol=1e-12, outputs=False)
    np.testing.assert_allclose(finals[0.7], folded.x[-1], rtol=0, atol=1e-10)


def test_default_outputs_of_paper2d(paper2d_model):
    assert paper2d_model.output_names == DEFAULT_OUTPUTS
