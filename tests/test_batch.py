"""Model.simulate_many: many runs in one C call over threads, bit for bit the single runs."""
from __future__ import annotations

import numpy as np
import pytest

import grasping_sym as gs
from grasping_sym.runtime.batch import EVENT, REFUSED

SETTINGS = dict(method="radau", rtol=1e-3, atol=1e-7, project=True)


@pytest.fixture(scope="module")
def model():
    return gs.build(gs.scenes.paper2d(name="batch2d", gf=0, gl=0, wf=0, wl=0, runtime=("fd",)))


@pytest.fixture(scope="module")
def starts(model):
    return np.array([model.initial_state(q1=q) for q in (0.55, 0.6, 0.65, 0.7)])


def _single(model, i, batch_x0, fd, **kw):
    return model.simulate(3.0, x0=batch_x0[i], params={"fd": float(fd[i])}, **kw)


@pytest.mark.parametrize("method", ["radau", "dopri5", "dop853", "rk4"])
def test_runs_are_bit_identical_to_single_simulate_calls(model, starts, method):
    fd = np.array([0.4, 0.55, 0.7, 0.9])
    kw = dict(method=method, rtol=1e-6, atol=1e-8, project=True, h=5e-4)
    t_eval = np.linspace(0.0, 3.0, 13)
    for threads in (1, 2):
        batch = model.simulate_many(3.0, x0=starts, params={"fd": fd}, threads=threads,
                                    t_eval=t_eval, outputs=True, **kw)
        assert batch.ok.all(), batch.errors
        for i in range(len(fd)):
            single = _single(model, i, starts, fd, t_eval=t_eval, **kw)
            assert np.array_equal(single.x, batch.x[i])
            assert np.array_equal(single.x[-1], batch.x_final[i])
            for k, v in single.outputs.items():
                assert np.array_equal(v, batch.outputs[k][i]), k
            assert single.stats["n_steps"] == batch.stats["n_steps"][i]
    final = model.simulate_many(3.0, x0=starts, params={"fd": fd}, **kw)
    assert final.x is None and final.t.tolist() == [0.0, 3.0]
    for i in range(len(fd)):
        single = _single(model, i, starts, fd, t_eval=[0.0, 3.0], outputs=False, **kw)
        assert np.array_equal(single.x[-1], final.x_final[i])


def test_a_failing_run_is_recorded_with_the_single_runs_error_and_loses_nothing(model, starts):
    fd = np.full(4, 0.6)
    x0 = starts.copy()
    x0[1, model.state_names.index("dq1")] = 50.0  # off the velocity constraints: refused
    batch = model.simulate_many(3.0, x0=x0, params={"fd": fd}, max_steps=5, **SETTINGS)
    # run 1 refused at the start; the others stop at max_steps (5 steps cannot reach 3 s)
    assert batch.status[1] == REFUSED
    assert "InconsistentInitialStateError" in batch.errors[1] and "Cdot" in batch.errors[1]
    for i in (0, 2, 3):
        assert batch.status[i] == -6
        with pytest.raises(gs.errors.IntegratorError) as exc:
            _single(model, i, x0, fd, max_steps=5, **SETTINGS)
        assert batch.errors[i] == f"{type(exc.value).__name__}: {exc.value}"
        assert np.isnan(batch.x_final[i]).all()
    good = model.simulate_many(3.0, x0=x0, params={"fd": fd}, **SETTINGS)
    assert good.status.tolist() == [0, REFUSED, 0, 0]
    for i in (0, 2, 3):
        single = _single(model, i, x0, fd, t_eval=[0.0, 3.0], outputs=False, **SETTINGS)
        assert np.array_equal(single.x[-1], good.x_final[i])
    assert "1 initial state refused" in repr(good)


@pytest.fixture(scope="module")
def driven():
    return gs.build(gs.scenes.paper2d(inputs="torques"))


def test_events_and_failures_are_found_as_simulate_finds_them(driven):
    # torques that pull the finger off (the contact opens: f <= 0) or roll the contact off its
    # contour (state s leaves its domain in the C loop; with u2 = -0.2 the contact opens first,
    # at 0.0106 s, between the output rows: the C loops watch f at every step)
    U = np.array([[0.0, 0.0], [-0.12, 0.0], [0.0, -0.12], [-0.2, 0.0]])
    t_eval = np.linspace(0, 0.5, 51)
    kw = dict(method="radau", rtol=1e-6, atol=1e-8)
    batch = driven.simulate_many(0.5, u=U, t_eval=t_eval, outputs=True, **kw)
    assert batch.status[0] == 0 and batch.status[1] == EVENT and batch.status[2] == -2
    assert batch.status[3] == EVENT  # f < 0 at the start already
    for i in (1, 2, 3):
        with pytest.raises(gs.errors.IntegratorError) as exc:
            driven.simulate(0.5, u=U[i], t_eval=t_eval, **kw)
        assert batch.errors[i] == f"{type(exc.value).__name__}: {exc.value}"
        assert np.isnan(batch.x[i]).all()
    assert "ContactOpenedError" in batch.errors[1] and "ContactLeftContourError" in batch.errors[2]
    assert np.array_equal(batch.x[0], driven.simulate(0.5, u=U[0], t_eval=t_eval, **kw).x)


def test_constant_and_tabled_inputs_match_single_runs(driven):
    m = driven
    U = np.array([[0.0, 0.0], [0.01, -0.01], [-0.02, 0.005]])
    t_eval = np.linspace(0, 0.5, 11)
    kw = dict(method="radau", rtol=1e-6, atol=1e-8)
    batch = m.simulate_many(0.5, u=U, t_eval=t_eval, **kw)
    for i in range(3):
        assert np.array_equal(m.simulate(0.5, u=U[i], t_eval=t_eval, **kw).x, batch.x[i])
    table = gs.inputs.piecewise_linear([0.0, 0.2, 0.35], [[0, 0], [0.02, -0.01], [0.0, 0.01]])
    x0 = np.array([m.initial_state(q1=q) for q in (0.55, 0.6)])
    batch = m.simulate_many(0.5, x0=x0, u=table, t_eval=t_eval, outputs=True, **kw)
    for i in range(2):
        single = m.simulate(0.5, x0=x0[i], u=table, t_eval=t_eval, **kw)
        assert np.array_equal(single.x, batch.x[i])
        assert np.array_equal(single.outputs["f"], batch.outputs["f"][i])


def test_bad_arguments_are_refused_by_name(model, starts):
    with pytest.raises(ValueError, match="number of runs differs"):
        model.simulate_many(1.0, x0=starts, params={"fd": np.ones(3)})
    with pytest.raises(ValueError, match="'cvodes'"):
        model.simulate_many(1.0, method="cvodes")
    with pytest.raises(ValueError, match=r"params\['fd'\] must be .* run 2"):
        model.simulate_many(1.0, params={"fd": [0.5, 0.6, np.nan]})
    with pytest.raises(ValueError, match="not a run-time parameter"):
        model.simulate_many(1.0, params={"mass": [1.0]})
    with pytest.raises(ValueError, match="non-finite entries in 1 row"):
        bad = starts.copy()
        bad[2, 0] = np.inf
        model.simulate_many(1.0, x0=bad)
    with pytest.raises(ValueError, match="threads"):
        model.simulate_many(1.0, threads=0)


def test_a_time_limit_stops_the_batch_and_keeps_what_finished(model):
    fd = np.full(400, 0.6)
    batch = model.simulate_many(3.0, params={"fd": fd}, method="radau", rtol=1e-10, atol=1e-12,
                                threads=1, time_limit=0.02)
    stopped = batch.status == -9
    assert stopped.any() and batch.ok.any()
    assert (batch.ok | stopped).all()
    assert np.isnan(batch.x_final[stopped]).all() and np.isfinite(batch.x_final[batch.ok]).all()
    assert all("wall-time limit of 0.02 s" in e for e in batch.errors[stopped])
    assert all(e == "" for e in batch.errors[batch.ok])


def test_a_law_that_reads_the_time_runs_and_is_checked_as_simulate_runs_it():
    law = gs.controllers.paper2d() + gs.controllers.feedforward(["2e-3 * sin(10 * t)", "0"])
    m = gs.build(gs.scenes.paper2d(name="batch_timed", controller=law))
    assert m.manifest["outputs_time"]
    x0 = np.array([m.initial_state(), m.initial_state(q1=0.6), m.initial_state()])
    x0[2, m.state_names.index("dq1")] = 5.0  # off the velocity constraints: refused
    t_eval = np.linspace(0, 0.5, 11)
    kw = dict(method="radau", rtol=1e-6, atol=1e-8)
    batch = m.simulate_many(0.5, x0=x0, t_eval=t_eval, outputs=True, **kw)
    assert batch.status.tolist() == [0, 0, REFUSED]
    for i in (0, 1):
        single = m.simulate(0.5, x0=x0[i], t_eval=t_eval, **kw)
        assert np.array_equal(single.x, batch.x[i])
        assert np.array_equal(single.outputs["f"], batch.outputs["f"][i])
    assert "Cdot" in batch.errors[2]


def test_the_runs_run_by_simulates_code_get_the_batchs_codes():
    """``failures.status_of``, shared by the batches of models with modes and with atlases: a
    refused start, an event, a contact off its contour, a stiff run, a C loop's own code."""
    from grasping_sym import errors
    from grasping_sym.runtime import batch, failures

    x = np.zeros(2)
    stiff = errors.IntegratorError(0.0, x, "stiff")
    stiff.stiff = True
    steps = errors.IntegratorError(0.0, x, "too many steps")
    steps.code = -6
    cases = [(errors.InconsistentInitialStateError(1e-6, "off"), batch.REFUSED),
             (errors.FrictionConeError(0.1, x, "slips"), batch.EVENT),
             (errors.ContactModeError(0.1, x, "Painleve"), batch.EVENT),
             (errors.ContactLeftContourError(0.1, x, "left"), -2),
             (stiff, -8), (steps, -6), (errors.IntegratorError(0.0, x, "?"), -3)]
    for exc, code in cases:
        assert failures.status_of(exc) == code, exc
        assert code in batch.STATUS
