"""The compiled C (SymPy -> CasADi -> C) against ``ReferenceModel`` (SymPy -> NumPy).

States on the constraint manifold
    States are taken at random times of a simulated run (|Q|, |R| <= 1e-10 m there, checked
    below) and their velocities are multiplied by random factors in [-3, 3]. The velocity of
    a run lies in the null space of the 2x3 constraint Jacobian, which is one-dimensional, so
    every multiple of it (reversed motion included) is again a consistent velocity.

Norm
    Each block of the right-hand side and each output is compared in the max norm relative
    to its *scale over the sample*: the largest magnitude it takes over all sampled states
    (for outputs that vanish on the manifold, Q, R, the residual, the tangency defect and N1,
    the size of the terms that cancel in them: 0.1 m, 1 rad, 1e-3 m^2). Rounding errors are
    proportional to the sizes of the terms being combined, not to a result that happens to be
    small (an acceleration near rest, a constraint value of 1e-14 m), so a pointwise relative
    error would be meaningless there while this norm is not loose anywhere.

Conditioning
    With the paper's CSM gains (wf = 2.25e6, wl = 9e6 1/s^2) the accelerations and
    multipliers amplify the rounding error of C (a few 1e-16 m) by ~1e7: a change of the
    state by one unit in the last place changes the reference's own accelerations by ~1e-9
    relative. Agreement to 1e-12 is therefore asserted with the gains set to zero (run-time
    parameters), where the computation is well conditioned, and at the paper's gains the
    gain-dependent quantities are asserted to agree to within the reference's own rounding
    noise (measured by one-ulp perturbations of the state); gain-independent ones to 1e-12.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import pytest

import grasping_sym as gs
from grasping_sym.geometry import library
from grasping_sym.model.planar import OUTPUTS
from tests.oracles.reference import ReferenceModel

GAINS = ("gf", "gl", "wf", "wl")
PAPER_GAINS = np.array([1500.0, 3000.0, 225.0e4, 900.0e4])
ZERO_GAINS = np.zeros(4)
N_STATES = 24
#: outputs that depend on the multipliers (hence on the CSM gains)
MULTIPLIER_OUTPUTS = ("f", "lam", "delta_f", "delta_lam")
#: size of the cancelling terms of outputs that vanish on the manifold
OUTPUT_FLOORS = {"Q": 0.1, "R": 0.1, "constraint_residual": 0.1, "tangency_defect": 1.0,
                 "N1": 1e-3}


def _ellipse_scene(**kw):
    """Two-parameter scene: circle fingertip by angle, off-centre ellipse object."""
    return gs.scenes.planar_finger(
        library.circle(0.02, by="angle", span=1.5),
        library.ellipse(0.02, 0.012, (0.0, 0.002), start=math.pi, span=1.5, clockwise=True),
        name="ellipse_on_circle", u1_0=math.pi, **kw)


SCENES = {"paper2d": gs.scenes.paper2d, "ellipse": _ellipse_scene}


@dataclass
class Case:
    folded: object        # compiled, every parameter folded in
    runtime: object       # compiled, CSM gains as run-time inputs, every output
    ref: ReferenceModel   # NumPy reference of the runtime scene
    X: np.ndarray         # states on the manifold, one per row
    n: int                # number of coordinates


@pytest.fixture(scope="module", params=list(SCENES))
def case(request):
    make = SCENES[request.param]
    if request.param == "paper2d":
        folded = request.getfixturevalue("paper2d_model")
        run = request.getfixturevalue("paper2d_result")
    else:
        folded = gs.build(make())
        run = folded.simulate(0.3, rtol=1e-10, atol=1e-12)
    scene_rt = make(runtime=GAINS, outputs=tuple(OUTPUTS))
    runtime = gs.build(scene_rt)
    assert runtime.param_names == GAINS
    rng = np.random.default_rng(20240611)
    X = run.x[rng.integers(1, len(run.t), N_STATES)].copy()
    X[:, 3:6] *= rng.uniform(-3.0, 3.0, size=(N_STATES, 1))
    return Case(folded, runtime, ReferenceModel(scene_rt), X, 3)


def _scale(values: np.ndarray) -> float:
    return float(np.max(np.abs(values)))


def _ulp_noise(ref: ReferenceModel, x: np.ndarray, p: np.ndarray, seed: int) -> np.ndarray:
    """Largest change of the reference rhs under 8 random one-ulp perturbations of ``x``."""
    rng = np.random.default_rng(seed)
    base = ref.rhs(x, p)
    eps = np.finfo(float).eps
    return np.max([np.abs(ref.rhs(x * (1 + eps * rng.choice([-1.0, 1.0], x.size)), p) - base)
                   for _ in range(8)], axis=0)


def test_sampled_states_are_on_the_manifold(case):
    for x in case.X:
        out = case.ref.outputs(x, PAPER_GAINS)
        assert abs(out["Q"]) <= 1e-10 and abs(out["R"]) <= 1e-10
        assert abs(out["tangency_defect"]) <= 1e-9
    assert np.ptp(case.X[:, -1]) > 1e-3  # the contact moved: the states differ


def test_rhs_matches_reference_without_stabilisation(case):
    """Gains zero: velocities equal, accelerations and contact rates to 1e-12."""
    n = case.n
    got = np.array([case.runtime.rhs(x, ZERO_GAINS) for x in case.X])
    want = np.array([case.ref.rhs(x, ZERO_GAINS) for x in case.X])
    np.testing.assert_array_equal(got[:, :n], case.X[:, n:2 * n])
    np.testing.assert_array_equal(want[:, :n], case.X[:, n:2 * n])
    for block in (slice(n, 2 * n), slice(2 * n, None)):
        err = np.max(np.abs(got[:, block] - want[:, block]))
        assert err <= 1e-12 * _scale(want[:, block]), (block, err, _scale(want[:, block]))


def test_rhs_matches_reference_at_paper_gains(case):
    """Folded model at the paper's gains: within the reference's own rounding noise."""
    n = case.n
    got = np.array([case.folded.rhs(x) for x in case.X])
    want = np.array([case.ref.rhs(x, PAPER_GAINS) for x in case.X])
    np.testing.assert_array_equal(got[:, :n], case.X[:, n:2 * n])
    rates = slice(2 * n, None)  # (q1' + q2' - theta')/(kappa0 + kappa1): no gain in it
    assert np.max(np.abs(got[:, rates] - want[:, rates])) <= 1e-12 * _scale(want[:, rates])
    acc = slice(n, 2 * n)
    scale = _scale(want[:, acc])
    for i, x in enumerate(case.X):
        noise = np.max(_ulp_noise(case.ref, x, PAPER_GAINS, seed=i)[acc])
        assert noise <= 1e-7 * scale  # the reference itself is sane at this state
        err = np.max(np.abs(got[i, acc] - want[i, acc]))
        assert err <= 10 * noise + 1e-12 * scale, (i, err, noise, scale)


def test_outputs_match_reference(case):
    names = case.runtime.output_names
    assert set(names) == set(OUTPUTS)
    for p, label in ((ZERO_GAINS, "zero"), (PAPER_GAINS, "paper")):
        got = {k: np.array([case.runtime.outputs(x, p)[k] for x in case.X]) for k in names}
        want = {k: np.array([case.ref.outputs(x, p)[k] for x in case.X]) for k in names}
        for k in names:
            scale = max(_scale(want[k]), OUTPUT_FLOORS.get(k, 0.0))
            err = np.max(np.abs(got[k] - want[k]))
            if label == "paper" and k in MULTIPLIER_OUTPUTS:
                continue  # gain-amplified rounding: see the next test
            assert err <= 1e-12 * max(scale, 1e-300), (label, k, err, scale)


def test_multipliers_at_paper_gains_within_rounding_noise(case):
    """f and lam at the paper's gains, against the spread of the reference under 1-ulp changes."""
    rng = np.random.default_rng(7)
    eps = np.finfo(float).eps
    for k in MULTIPLIER_OUTPUTS:
        want = np.array([case.ref.outputs(x, PAPER_GAINS)[k] for x in case.X])
        scale = _scale(want)
        for i, x in enumerate(case.X):
            got = case.runtime.outputs(x, PAPER_GAINS)[k]
            spread = max(abs(case.ref.outputs(x * (1 + eps * rng.choice([-1.0, 1.0], x.size)),
                                              PAPER_GAINS)[k] - want[i]) for _ in range(8))
            assert spread <= 1e-7 * scale
            assert abs(got - want[i]) <= 10 * spread + 1e-12 * scale, (k, i, got, want[i], spread)


def test_folded_and_runtime_builds_agree_at_paper_gains(case):
    got = np.array([case.runtime.rhs(x, PAPER_GAINS) for x in case.X])
    want = np.array([case.folded.rhs(x) for x in case.X])
    n = case.n
    for block in (slice(n, 2 * n), slice(2 * n, None)):
        assert np.max(np.abs(got[:, block] - want[:, block])) <= 1e-12 * _scale(want[:, block])


def test_batched_equals_single(case):
    single = np.array([case.folded.rhs(x) for x in case.X])
    np.testing.assert_array_equal(case.folded.rhs_batch(case.X), single)
    single_rt = np.array([case.runtime.rhs(x, PAPER_GAINS) for x in case.X])
    np.testing.assert_array_equal(case.runtime.rhs_batch(case.X, PAPER_GAINS), single_rt)
    batch = case.runtime.outputs_batch(case.X, PAPER_GAINS)
    for i, x in enumerate(case.X):
        one = case.runtime.outputs(x, PAPER_GAINS)
        for k, v in one.items():
            assert batch[k][i] == v, (k, i)
