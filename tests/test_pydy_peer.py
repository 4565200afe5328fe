"""The PyDy peer of paper2d (``benchmarks/peers/pydy_paper2d.py``) is the same model as ours.

``sympy.physics.mechanics`` (KanesMethod with the holonomic contact constraints, dependent
coordinates and speeds) compiled by PyDy's Cython generator, against the compiled paper2d.
On the constraint manifold the two right-hand sides are the same function: ours adds only the
CSM (Baumgarte) terms ``2 g C' + w C``, which vanish there. The PyDy build (Cython + C compiler)
takes ~2-5 s and is done once for the module.
"""
from __future__ import annotations

import numpy as np
import pytest

pytest.importorskip("pydy", reason="pydy is in the test extra: pip install -e .[test]")

from benchmarks.peers import pydy_paper2d as peer_mod  # noqa: E402

GAINS = ("gf", "gl", "wf", "wl")


@pytest.fixture(scope="module")
def peer(tmp_path_factory):
    return peer_mod.build(tmp_path_factory.mktemp("pydy-peer"))


@pytest.fixture(scope="module")
def model_no_csm(paper2d_model):
    """paper2d with the CSM gains as run-time inputs, to be set to 0: the bare equations."""
    import grasping_sym as gs

    return gs.build(gs.scenes.paper2d(runtime=GAINS))


@pytest.fixture(scope="module")
def manifold_states(paper2d_model, peer):
    """31 states of our 3 s trajectory (CVODES rtol = atol = 1e-13), every 0.1 s, on the manifold.

    Ours hold |Q|, |R| < 1e-15 m, but tangency only through the update law for s (never
    corrected): PyDy's third constraint sees a defect ~1e-12 rad, i.e. s off by ~1e-14 m, which
    ``with_tangency`` removes (moving s along the common tangent changes Q, R at second order).
    """
    r = paper2d_model.simulate(3.0, method="cvodes", rtol=1e-13, atol=1e-13, t_eval=np.linspace(0.0, 3.0, 31))
    assert max(np.max(np.abs(r["Q"])), np.max(np.abs(r["R"]))) < 1e-15
    X = np.array([peer.with_tangency(x) for x in r.x])
    assert np.max(np.abs(X[:, 6] - r.x[:, 6])) < 1e-13
    Xp = np.array([peer.from_ours(x) for x in X])
    assert np.max(np.abs(peer.configuration_residual(Xp))) < 1e-15
    assert np.max(np.abs(peer.velocity_residual(Xp))) < 1e-12
    out = paper2d_model.outputs_batch(X)
    assert max(np.max(np.abs(out["Q"])), np.max(np.abs(out["R"]))) < 1e-15
    return X


def test_state_maps(peer, paper2d_model):
    assert paper2d_model.state_names == peer_mod.OUR_STATES
    assert peer.state_names == ("s", "q1", "q2", "theta", "ds", "dq1", "dq2", "dtheta")
    x = np.array([0.1, 0.5, 0.7, 0.2, -0.3, 0.4, -1e-3])
    assert np.array_equal(peer.to_ours(peer.from_ours(x)), x)
    # the constants are grasping_sym's, the pivot its solved Om (docs/conventions.md check value)
    assert peer.p[peer_mod.PARAM_NAMES.index("xm")] == pytest.approx(0.12303738, abs=1e-8)
    x0 = paper2d_model.initial_state()
    xp0 = peer.from_ours(x0)
    assert np.max(np.abs(peer.configuration_residual(xp0))) < 1e-15
    assert np.max(np.abs(peer.velocity_residual(xp0))) == 0.0
    # PyDy's generated function reuses its output buffer; peer.rhs must not
    assert peer.rhs(0.0, xp0) is not peer.rhs(0.0, xp0)


def test_rhs_equals_bare_equations(peer, model_no_csm, manifold_states):
    """Against our equations with the CSM gains 0: the same function evaluated two ways.

    Measured: accelerations agree to <= 1.6e-11 rad/s^2 (largest acceleration 171 rad/s^2, at
    t = 0). That is rounding: changing the state by ~1 ulp moves PyDy's accelerations by up to
    ~1e-11 rad/s^2, and the velocities of our states satisfy PyDy's velocity constraints only to
    ~2e-13 m/s. Bound 1e-10 rad/s^2 (6e-13 of the largest acceleration; 6x the worst measured).
    ``s'`` comes from PyDy's velocity constraints (``from_ours``) and equals our update law (29)
    to rounding (~2e-18 m/s). ``s''`` (no state of ours) against the central difference of our
    ``s'`` along our flow (step 1e-6 s, truncation ~1e-12): measured 2e-12, |s''| up to 1.7 m/s^2.
    """
    a = peer_mod.rhs_agreement(peer, model_no_csm, manifold_states, model_params=np.zeros(4))
    assert a["max_abs_acc"] > 100.0
    assert a["max_abs_acc_diff"] < 1e-10
    assert a["max_abs_sdot_diff"] < 1e-16
    assert a["max_abs_sddot_diff_vs_fd"] < 1e-10


def test_rhs_equals_paper2d_on_the_manifold(peer, paper2d_model, manifold_states):
    """Against the real paper2d model (the paper's CSM gains, wf = 2.25e6, wl = 9e6 1/s^2).

    On the exact manifold the CSM terms vanish; at our states (|Q|, |R| ~ 1e-17 m, velocity
    residual ~1e-13 m/s) they are ~ w |C| + 2 g |C'| ~ 1e-10 m/s^2 of constraint acceleration,
    which moves the joint accelerations by up to ~1e-8 rad/s^2 (measured 5e-9). Bound 1e-7.
    (That the whole difference is the CSM term is the test above, with the gains set to 0.)
    """
    a = peer_mod.rhs_agreement(peer, paper2d_model, manifold_states)
    assert a["max_abs_acc_diff"] < 1e-7
    assert a["max_abs_sdot_diff"] < 1e-16
    for x in manifold_states:
        assert np.array_equal(peer.rhs_ours(x)[:3], x[3:6])


@pytest.fixture(scope="module")
def reference_final(paper2d_model):
    """Our 3 s final state at CVODES rtol = atol = 1e-14 (CVODES 1e-13 is ~5e-12 off it)."""
    return paper2d_model.simulate(3.0, method="cvodes", rtol=1e-14, atol=1e-14, t_eval=[0.0, 3.0],
                                  outputs=False).x[-1]


@pytest.mark.parametrize("method, rtol, bound", [("odeint", 1e-12, 1e-10), ("Radau", 1e-8, 1e-9)])
def test_run_agrees_with_ours(peer, paper2d_model, reference_final, method, rtol, bound):
    """3 s from our x0: PyDy (no stabilisation, all 8 states integrated) ends where we do.

    Measured final-state differences (max over our 7 states): odeint rtol 1e-12 ~1e-12, Radau
    rtol 1e-8 ~1e-12 (scipy's Radau needs ``peer.rhs``'s copy of PyDy's reused output buffer).
    The drift off the contact constraints, measured by our Q and R, stays below 1e-11 m.
    """
    r = peer.simulate(3.0, rtol=rtol, atol=rtol * 1e-2, method=method, t_eval=np.linspace(0.0, 3.0, 301))
    assert np.max(np.abs(r.x[-1] - reference_final)) < bound
    assert r.x[-1][6] == pytest.approx(-4.79e-3, abs=1e-5)  # the contact drifts as in the paper
    assert peer_mod.constraint_residual(paper2d_model, r.x) < 1e-11


def test_work_precision_rows(peer, paper2d_model, reference_final):
    rows = peer_mod.work_precision(reference_final, (1e-6, 1e-9), peer=peer, model=paper2d_model, repeats=1)
    assert [row.tol for row in rows] == [1e-6, 1e-9]
    (tol6, wall6, err6, res6), (tol9, wall9, err9, res9) = rows
    assert 0 < wall6 < 1.0 and 0 < wall9 < 1.0
    assert err9 < err6 < 1e-5
    assert res9 < res6 < 1e-6
