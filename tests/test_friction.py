"""The friction cone at every contact (issue 27, part 1): its outputs, its check, its event.

The slip-onset times are checked against an independent answer: the root of the rolling
run's own |F_t|/f = mu, found from a dense rolling run (no friction given) by cubic
interpolation of its samples, not by the package's event location.
"""
from __future__ import annotations

import math
import pickle

import numpy as np
import pytest
from scipy.interpolate import CubicSpline
from scipy.optimize import brentq

import grasping_sym as gs
from grasping_sym.errors import FrictionConeError, InvalidSceneError, RunArgumentError

TIGHT = dict(method="radau", rtol=1e-10, atol=1e-12)


@pytest.fixture(scope="module")
def paper2d():
    return gs.build(gs.scenes.paper2d())


@pytest.fixture(scope="module")
def paper3d():
    return gs.build(gs.scenes.paper3d())


def _root_of_dense_run(t, ratio, mu):
    """The first time ``ratio`` reaches ``mu``: a cubic spline through the samples around the
    first sample at or above it, and Brent's method on the spline."""
    i = int(np.flatnonzero(ratio >= mu)[0])
    assert i > 0, "the ratio starts above mu"
    lo, hi = max(i - 4, 0), min(i + 4, len(t))
    spline = CubicSpline(t[lo:hi], ratio[lo:hi] - mu)
    return brentq(spline, t[i - 1], t[i], xtol=1e-15)


def test_slip_onset_paper2d_is_the_root_of_the_rolling_run(paper2d):
    t_end, mu = 0.1, 0.2
    dense = paper2d.simulate(t_end, t_eval=np.linspace(0.0, t_end, 20001), **TIGHT)
    ratio = np.abs(dense["lam"]) / dense["f"]
    t_root = _root_of_dense_run(dense.t, ratio, mu)
    with pytest.raises(FrictionConeError) as info:
        paper2d.simulate(t_end, mu=mu, **TIGHT)
    err = info.value
    assert abs(err.t - t_root) < 1e-9, (err.t, t_root)
    assert err.contact == 1 and err.mu == mu
    assert abs(err.ratio - mu) < 1e-9
    assert "leaves its friction cone" in str(err) and "contact 1" in str(err)


def test_slip_onset_paper3d_is_the_root_of_the_rolling_run(paper3d):
    t_end, mu = 0.06, 0.08
    dense = paper3d.simulate(t_end, t_eval=np.linspace(0.0, t_end, 6001), **TIGHT)
    roots = []
    for i in (1, 2):
        ratio = np.hypot(dense[f"lam{i}"], dense[f"eta{i}"]) / dense[f"f{i}"]
        roots.append(_root_of_dense_run(dense.t, ratio, mu) if ratio.max() >= mu else math.inf)
    first = int(np.argmin(roots))
    with pytest.raises(FrictionConeError) as info:
        paper3d.simulate(t_end, mu=mu, **TIGHT)
    err = info.value
    assert err.contact == first + 1
    assert abs(err.t - roots[first]) < 1e-9, (err.t, roots)
    assert abs(err.ratio - mu) < 1e-9


def test_cone_outputs_for_every_contact(paper3d):
    res = paper3d.simulate(0.02, mu=(0.5, 0.7))
    for i, mu in ((1, 0.5), (2, 0.7)):
        f, ft = res[f"f{i}"], np.hypot(res[f"lam{i}"], res[f"eta{i}"])
        np.testing.assert_array_equal(res[f"normal_force{i}"], f)
        np.testing.assert_allclose(res[f"tangential_force{i}"], ft, rtol=1e-15)
        np.testing.assert_allclose(res[f"cone_ratio{i}"], ft / f, rtol=1e-15)
        np.testing.assert_allclose(res[f"cone_margin{i}"], mu * f - ft, rtol=1e-15, atol=1e-15)
    assert "cone_ratio1" not in paper3d.simulate(0.02).outputs  # no mu: nothing added


def test_a_start_outside_the_cone_is_refused_at_t0(paper2d):
    y0 = paper2d.simulate(1e-3, t_eval=[0.0, 1e-3])
    ratio0 = abs(y0["lam"][0]) / y0["f"][0]
    with pytest.raises(FrictionConeError) as info:
        paper2d.simulate(0.1, mu=0.5 * ratio0)
    assert info.value.t == 0.0 and "at the start" in str(info.value)


def test_record_lets_the_rolling_run_go_on(paper2d):
    res = paper2d.simulate(0.2, mu=0.2, slip="record")
    assert res["cone_margin1"].min() < 0 < res["cone_margin1"][0]
    assert res.t[-1] == 0.2


def test_many_runs_carry_mu_and_stop_as_single_runs_do(paper2d):
    mus = np.array([0.1, 0.2, 0.3, math.inf])
    batch = paper2d.simulate_many(0.2, mu=mus, t_eval=np.linspace(0, 0.2, 201), outputs=True)
    assert batch.status.tolist() == [-11, -11, 0, 0]
    for i, mu in enumerate(mus[:2]):
        with pytest.raises(FrictionConeError) as info:
            paper2d.simulate(0.2, mu=mu, t_eval=np.linspace(0, 0.2, 201))
        assert batch.errors[i] == f"FrictionConeError: {info.value}"
    single = paper2d.simulate(0.2, mu=0.3, t_eval=np.linspace(0, 0.2, 201))
    np.testing.assert_array_equal(batch.outputs["cone_ratio1"][2], single["cone_ratio1"])
    assert np.all(np.isinf(batch.outputs["cone_margin1"][3]))
    record = paper2d.simulate_many(0.2, mu=mus, slip="record", t_eval=np.linspace(0, 0.2, 201),
                                   outputs=True)
    assert record.ok.all()


def test_scene_friction_is_the_default_and_travels_with_the_model():
    scene = gs.scenes.paper2d(friction=gs.contact.coulomb(mu=0.2))
    model = gs.build(scene)
    assert model.friction == gs.contact.coulomb(0.2)
    with pytest.raises(FrictionConeError):
        model.simulate(0.2)
    model.simulate(0.2, mu=math.inf)  # a run may lift the limit
    other = pickle.loads(pickle.dumps(model))
    assert other.friction == gs.contact.coulomb(0.2)
    with pytest.raises(FrictionConeError):
        other.simulate(0.2)
    plain = pickle.loads(pickle.dumps(gs.build(gs.scenes.paper2d())))
    assert plain.friction is None
    plain.simulate(0.2)


@pytest.mark.parametrize("mu, words", [
    (-0.1, "must be a number >= 0"), ("0.3", "is str"), (float("nan"), "must be a number >= 0"),
    ((0.1, 0.2), "one number >= 0 or 1"), (True, "is bool")])
def test_bad_mu_is_refused_by_name(paper2d, mu, words):
    with pytest.raises(RunArgumentError, match=words):
        paper2d.simulate(0.01, mu=mu)


def test_restitution_is_refused_where_nothing_can_impact(paper2d):
    with pytest.raises(RunArgumentError, match="no impacts"):
        paper2d.simulate(0.01, e=0.3)


def test_bad_friction_laws_are_refused_by_name():
    with pytest.raises(InvalidSceneError, match="must be a number >= 0"):
        gs.contact.coulomb(mu=-1)
    with pytest.raises(InvalidSceneError, match=r"e = 2 must be a number in \[0, 1\]"):
        gs.contact.coulomb(mu=0.3, e=2)
    with pytest.raises(InvalidSceneError, match="2 entries for 1 contact"):
        gs.scenes.paper2d(friction=gs.contact.coulomb(mu=(0.1, 0.2)))
    with pytest.raises(InvalidSceneError, match="friction = 0.3 is float"):
        gs.scenes.paper2d(friction=0.3)
    with pytest.raises(RunArgumentError, match=r"shape \(2, 3\)"):
        gs.build(gs.scenes.paper2d()).simulate_many(0.01, mu=np.zeros((2, 3)) + 0.3)


def test_casadi_cone_margin_matches_the_runs_cone(paper3d):
    res = paper3d.simulate(0.05, mu=(0.3, 0.4))
    cone = paper3d.casadi_function("cone")
    k = len(res.t) // 2
    f, margin = (v.full().ravel() for v in cone(res.x[k], np.zeros(0), np.zeros(0), [0.3, 0.4]))
    for i, mu in ((1, 0.3), (2, 0.4)):
        np.testing.assert_allclose(f[i - 1], res[f"normal_force{i}"][k], rtol=1e-12)
        want = (mu * res[f"normal_force{i}"][k]) ** 2 - res[f"tangential_force{i}"][k] ** 2
        np.testing.assert_allclose(margin[i - 1], want, rtol=1e-10)
        assert np.sign(margin[i - 1]) == np.sign(res[f"cone_margin{i}"][k])


def test_the_cone_figure_shades_where_the_rolling_run_would_slip(paper2d, tmp_path):
    res = paper2d.simulate(0.3, mu=0.2, slip="record")
    out = gs.viz.cone(res, tmp_path / "cone.png")
    assert out.stat().st_size > 10_000
    with pytest.raises(ValueError, match="no friction-cone outputs"):
        gs.viz.cone(paper2d.simulate(0.01), tmp_path / "none.png")


def test_a_tuple_is_one_mu_per_contact_for_every_run_and_a_batch_watches_the_cone_at_every_step(paper3d):
    """A batch's cone is watched by its C loops at every step (``runtime.watch``): with output
    times or without (the start and the end only), it names the exit simulate names, at the
    same located time; rk4, which reads its rows, still needs output times."""
    grid = np.linspace(0.0, 0.06, 61)
    batch = paper3d.simulate_many(0.06, x0=np.tile(paper3d.initial_state(), (2, 1)), mu=(0.5, 0.08),
                                  t_eval=grid)
    with pytest.raises(FrictionConeError) as info:
        paper3d.simulate(0.06, mu=(0.5, 0.08), t_eval=grid, outputs=False)  # as the batch's runs
    assert batch.errors.tolist() == [f"FrictionConeError: {info.value}"] * 2
    assert "located at the step" in str(info.value)
    with pytest.raises(FrictionConeError) as rows:  # its outputs at rows 1 ms apart: read there
        paper3d.simulate(0.06, mu=(0.5, 0.08), t_eval=grid)
    assert "located between the outputs" in str(rows.value) and abs(rows.value.t - info.value.t) <= 1e-9
    sparse = paper3d.simulate_many(0.06, x0=np.tile(paper3d.initial_state(), (2, 1)), mu=(0.5, 0.08))
    assert sparse.errors.tolist() == batch.errors.tolist()
    with pytest.raises(RunArgumentError, match="no t_eval"):
        paper3d.simulate_many(0.06, mu=0.3, method="rk4")


def test_a_model_started_elsewhere_keeps_its_friction_law():
    model = gs.build(gs.scenes.paper2d(friction=gs.contact.coulomb(mu=0.2)))
    moved = model.with_start(q1=0.55)
    assert moved.friction == model.friction
    with pytest.raises(FrictionConeError):
        moved.simulate(0.3)


def test_a_contact_that_pulls_from_the_start_opens_rather_than_slips():
    from grasping_sym.errors import ContactOpenedError
    model = gs.build(gs.scenes.paper2d(inputs="torques"))
    with pytest.raises(ContactOpenedError):
        model.simulate(0.1, u=[0.0, 0.05], mu=0.3)


def test_held_needs_a_friction_coefficient(paper2d, tmp_path):
    with pytest.raises(ValueError, match="'held' \\(with mu, for grasp scenes\\)"):
        gs.sweep(paper2d, {"theta_0": [0.0]}, 0.1, store=tmp_path / "held.zarr", measures=["held"],
                 progress=False)
