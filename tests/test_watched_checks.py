"""The run-time checks watched at every step (``runtime.watch``), whatever the output times.

The case: paper2d's object rolled fast (60 rad/s along the rolling direction) under a weak grip
(fd = 0.3 N). The finger cannot follow: its normal force ``f`` falls below 0 at t = 0.0281 s and
is positive again from 0.038 s on. Rows at t = 0 and t = 0.2 s alone show ``f > 0`` both times, so
a check read at the output rows returns such a run as a success; the watched check names it, at
the root of ``f``, which the test finds independently on a dense run with the checks off.
"""
import math

import numpy as np
import pytest

import grasping_sym as gs
from grasping_sym.errors import ContactOpenedError, FrictionConeError
from tests.test_hard_cases import rolling_velocity

TIGHT = dict(rtol=1e-10, atol=1e-13)


@pytest.fixture(scope="module")
def weak():
    return gs.build(gs.scenes.paper2d(runtime=("fd", "m11", "gf"), fd=0.3))


@pytest.fixture(scope="module")
def fast_start(weak):
    x0 = weak.initial_state()
    x0[3:6] = -60.0 * rolling_velocity(weak, x0)
    return x0


@pytest.fixture(scope="module")
def root_of_f(weak, fast_start):
    """The first zero of ``f`` on a dense run with the checks off: linear between rows 1e-6 s
    apart (the interpolation's error ~f'' dt^2 / (8 f') is far below 1e-9 s), and ``f`` at
    the rows 0 and 0.2 s."""
    t = np.linspace(0.0, 0.2, 200_001)
    r = weak.simulate(0.2, x0=fast_start, t_eval=t, checks=False, method="radau", **TIGHT)
    f = r["f"]
    i = int(np.flatnonzero(f <= 0)[0])
    root = t[i - 1] + f[i - 1] / (f[i - 1] - f[i]) * (t[i] - t[i - 1])
    assert np.any(f[i:] > 0) and f[-1] > 0 and f[0] > 0  # it closes again: the rows see none
    return root


@pytest.mark.parametrize("method", ["radau", "dop853", "dopri5"])
def test_a_contact_that_opens_between_two_output_rows_is_named_at_its_root(weak, fast_start, root_of_f, method):
    with pytest.raises(ContactOpenedError, match="normal force f crosses 0") as info:
        weak.simulate(0.2, x0=fast_start, t_eval=[0.0, 0.2], outputs=False, method=method, **TIGHT)
    err = info.value
    assert "located at the step" in str(err)
    assert abs(err.t - root_of_f) <= 1e-8, (err.t, root_of_f)
    assert abs(err.force) <= 1e-9 < err.force_before
    assert abs(weak.outputs(err.x)["f"]) <= 1e-9  # the state it names is the one at the root
    t_rows, _ = err.trajectory
    assert t_rows.tolist() == [0.0]  # the rows before it


def test_the_short_way_watches_as_the_full_way(weak, fast_start):
    """A start and settings the full way accepted (a run that ends before the contact opens)
    send later calls the short way (``runtime.fastpath``): a longer run from it is watched
    there too, and goes the full way, which names the event."""
    kw = dict(outputs=False, method="radau", **TIGHT)
    weak.simulate(0.02, x0=fast_start, t_eval=[0.0, 0.02], **kw)
    plan = next(p for p in weak.short_way.plans.values() if fast_start.tobytes() in p.checked)
    assert plan.checked[fast_start.tobytes()]  # the checks it watches from that start
    with pytest.raises(ContactOpenedError, match="located at the step"):
        weak.simulate(0.2, x0=fast_start, t_eval=[0.0, 0.2], **kw)
    assert weak.simulate(0.02, x0=fast_start, t_eval=[0.0, 0.02], **kw).stats["n_steps"] > 0


@pytest.mark.parametrize("threads", [1, 2])
def test_a_batch_watches_each_run_as_simulate_does(weak, fast_start, threads):
    """``simulate_many`` without output times (the start and the end only): each run watched
    in its thread, the opening one named as ``simulate`` names it, the others untouched."""
    X0 = np.array([weak.initial_state(), fast_start, weak.initial_state(), fast_start])
    batch = weak.simulate_many(0.2, x0=X0, method="radau", threads=threads, **TIGHT)
    assert batch.status.tolist()[::2] == [0, 0] and all(s != 0 for s in batch.status[1::2])
    with pytest.raises(ContactOpenedError) as info:
        weak.simulate(0.2, x0=fast_start, t_eval=[0.0, 0.2], method="radau", **TIGHT)
    assert batch.errors[1] == batch.errors[3] == f"ContactOpenedError: {info.value}"
    alone = weak.simulate(0.2, t_eval=[0.0, 0.2], outputs=False, method="radau", **TIGHT)
    np.testing.assert_array_equal(batch.x_final[0], alone.x[-1])  # bit for bit, watched or not


def test_a_batch_watches_each_runs_own_cone(weak):
    """Per-run ``mu`` without output times: each run's cone watched with its own coefficient
    (a start outside its cone at t = 0; one left at its located time; one held; ``inf``
    never leaves), as ``simulate`` finds them."""
    mus = np.array([0.05, 0.2, 0.5, math.inf])
    model = gs.build(gs.scenes.paper2d())
    batch = model.simulate_many(3.0, x0=np.tile(model.initial_state(), (4, 1)), mu=mus)
    assert batch.status.tolist()[2:] == [0, 0]
    for i in (0, 1):
        with pytest.raises(FrictionConeError) as info:
            model.simulate(3.0, mu=mus[i], t_eval=[0.0, 3.0], outputs=False)
        assert batch.errors[i] == f"FrictionConeError: {info.value}"
    assert "at t = 0 s" in batch.errors[0]
    assert "located at the step" in batch.errors[1]


def test_a_start_past_a_check_stops_at_once_whatever_the_outputs(weak, fast_start):
    """A witness at or below 0 at the start is never armed by the C loop: the run names it at
    t = 0 (a finger pulled off by its torque), with outputs or without."""
    pulled = gs.build(gs.scenes.paper2d(inputs="torques"))
    for outputs in (True, False):
        with pytest.raises(ContactOpenedError, match=r"<= 0 at t = 0 s, the start") as info:
            pulled.simulate(0.1, u=[0.0, 0.2], t_eval=[0.0, 0.1], outputs=outputs)
        assert info.value.t == 0.0


def test_a_torque_step_that_pulls_the_finger_off_stops_at_its_knot():
    """An input table's knot restarts the loop, which arms only the witnesses above 0 there: a
    torque stepped at 0.05 s to one that pulls the finger off (f < 0 at once) stops the run at
    the knot by name, in simulate (outputs or none) and in simulate_many (one segment per
    batch), rather than returning it as a success."""
    pulled = gs.build(gs.scenes.paper2d(inputs="torques"))
    table = gs.inputs.zero_order_hold([0.0, 0.05], [[0.0, 0.0], [0.0, 0.2]])
    for outputs in (True, False):
        with pytest.raises(ContactOpenedError, match="where the integration restarts") as info:
            pulled.simulate(0.1, u=table, t_eval=[0.0, 0.1], outputs=outputs)
        assert info.value.t == 0.05
    batch = pulled.simulate_many(0.1, x0=np.tile(pulled.initial_state(), (2, 1)), u=table)
    assert batch.errors.tolist() == [f"ContactOpenedError: {info.value}"] * 2
    held = gs.inputs.zero_order_hold([0.0, 0.05], [[0.0, 0.0], [0.0, 0.001]])  # a small step: it holds
    assert pulled.simulate_many(0.1, x0=np.tile(pulled.initial_state(), (2, 1)), u=held).status.tolist() == [0, 0]


def test_a_named_error_survives_a_pickle(weak, fast_start):
    """A run's named error crosses a process boundary whole (a Dask worker's, back to its
    client): its type, message, time, state and the attributes the check set."""
    import pickle

    with pytest.raises(ContactOpenedError) as info:
        weak.simulate(0.2, x0=fast_start, t_eval=[0.0, 0.2], outputs=False, method="radau", **TIGHT)
    err = info.value
    back = pickle.loads(pickle.dumps(err))
    assert type(back) is ContactOpenedError and str(back) == str(err)
    assert (back.t, back.force, back.force_before) == (err.t, err.force, err.force_before)
    np.testing.assert_array_equal(back.x, err.x)
    cone = FrictionConeError(0.5, None, "a cone", contact=2, mu=0.3, normal=1.0, tangential=0.4)
    again = pickle.loads(pickle.dumps(cone))
    assert (again.contact, again.mu, again.normal, again.tangential, str(again)) == \
        (2, 0.3, 1.0, 0.4, str(cone))


@pytest.mark.parametrize("method, rtol", [("radau", 1e-4), ("dop853", 1e-5), ("dopri5", 1e-4)])
def test_long_steps_do_not_hide_the_opening(weak, fast_start, root_of_f, method, rtol):
    """At loose tolerances the steps are long and the watch looks only where a check's margin
    could run out at 8 times its rate (``runtime.watch.CHECK_SPAN``): the 9 ms opening is still
    named, at its root to the run's own accuracy."""
    with pytest.raises(ContactOpenedError) as info:
        weak.simulate(0.2, x0=fast_start, t_eval=[0.0, 0.2], outputs=False, method=method, rtol=rtol,
                      atol=rtol / 100)
    assert abs(info.value.t - root_of_f) <= 1e-4


@pytest.fixture(scope="module")
def pulsed():
    """paper2d at rest under its law plus a 2 ms torque pulse at the second joint
    (``0.3 exp(-((t - 0.8) / 1 ms)^2)`` N m, a law of time): the pulse pulls the fingertip off
    the object at once, its normal force below 0 for ~2 ms from t = 0.79883 s (a review's
    case). The grasp's rest state, and the root of ``f`` on a run at rtol 1e-10 with rows 10 ns
    apart around it (linear between them)."""
    import sympy as sp

    t = sp.Symbol("t")
    law = gs.controllers.paper2d() + gs.controllers.feedforward([0, 0.3 * sp.exp(-((t - 0.8) / 0.001) ** 2)])
    model = gs.build(gs.scenes.paper2d(controller=law, name="pulsed"))
    rest = model.simulate(0.5, t_eval=[0.0, 0.5], outputs=False, checks=False, **TIGHT).x[-1]
    rows = np.concatenate([[0.0], np.linspace(0.7985, 0.799, 50_001)])
    f = model.simulate(0.799, x0=rest, t_eval=rows, checks=False, **TIGHT)["f"]
    i = int(np.flatnonzero(f <= 0)[0])
    return model, rest, rows[i - 1] + f[i - 1] / (f[i - 1] - f[i]) * (rows[i] - rows[i - 1])


@pytest.mark.parametrize("method", ["radau", "dop853"])
def test_a_pulse_of_a_law_of_time_is_watched(pulsed, method):
    """The witnesses' rates at rest foresee nothing of a law's pulse: a model whose outputs read
    the time leaves no point unwatched (``c/watch.c``). Before, radau stepped over the pulse in
    one 30 ms step and dop853 left its steps' points unwatched: both returned a success."""
    model, rest, root = pulsed
    with pytest.raises(ContactOpenedError, match="located at the step") as info:
        model.simulate(1.2, x0=rest, t_eval=[0.0, 1.2], outputs=False, method=method)
    assert abs(info.value.t - root) < 1e-8, (info.value.t, root)
    batch = model.simulate_many(1.2, x0=np.array([rest, rest]), method=method, threads=2)
    assert all(s != 0 for s in batch.status) and batch.errors[0].startswith("ContactOpenedError")


def test_a_check_at_the_tolerance_noise_is_named_as_the_rows_name_it(weak, fast_start):
    """At rtol 1e-4 a faster roll's opening sits at the integration's noise: integrating again
    from the step's start does not reproduce it. The watch names the check's own error at the
    dense output's root, and says so, as the rows' path does (it raised EventLocationError)."""
    x0 = weak.initial_state()
    x0[3:6] = -59.0 * rolling_velocity(weak, x0)
    kw = dict(method="dop853", rtol=1e-4, atol=1e-6)
    with pytest.raises(ContactOpenedError, match="located on the integration's dense output"):
        weak.simulate(0.2, x0=x0, t_eval=[0.0, 0.2], outputs=False, **kw)
    for t_eval, outputs in (([0.0, 0.2], True), (None, False), (None, True)):
        with pytest.raises(ContactOpenedError):
            weak.simulate(0.2, x0=x0, t_eval=t_eval, outputs=outputs, **kw)
    assert weak.simulate_many(0.2, x0=x0[None, :], **kw).errors[0].startswith("ContactOpenedError")
