"""Run-time guards: short runs, parameter and argument checks, velocity-consistent starts,
a wall-time limit and Ctrl-C for every method, and a domain exit located at its step under
SUNDIALS too."""
from __future__ import annotations

import json
import math
import subprocess
import sys
import textwrap

import numpy as np
import pytest
import sympy as sp

import grasping_sym as gs
from grasping_sym.errors import ContactLeftContourError, InconsistentInitialStateError, IntegratorError
from grasping_sym.geometry import library

METHODS = ("cvodes", "idas", "radau", "dopri5", "rk4")


@pytest.fixture(scope="module")
def runtime_model():
    return gs.build(gs.scenes.paper2d(runtime=("fd", "m11", "gf")))


@pytest.mark.parametrize("method", METHODS)
def test_a_very_short_run_moves(runtime_model, method):
    r = runtime_model.simulate(0.0004, method=method)
    assert r.t.tolist() == [0.0, 0.0004]
    assert np.max(np.abs(r.x[-1] - r.x[0])) > 1e-3  # the fingers accelerate at once
    if method in ("cvodes", "idas"):  # refused by name: SUNDIALS cannot start on it
        with pytest.raises(ValueError, match="use method='radau'"):
            runtime_model.simulate(1e-300, method=method)
        return
    tiny = runtime_model.simulate(1e-300, method=method)
    assert tiny.t.tolist() == [0.0, 1e-300] and np.all(np.isfinite(tiny.x))
    assert np.any(tiny.x[-1] != tiny.x[0])  # speeds grow from 0 by ~1e-298


@pytest.mark.parametrize("params, error, match", [
    ({"fd": -1.0}, ValueError, r"params\['fd'\] = -1.0 must be > 0"),
    ({"m11": 0.0}, ValueError, "must be > 0"),
    ({"gf": -0.1}, ValueError, "must be >= 0"),
    ({"fd": math.nan}, ValueError, "finite"),
    ({"fd": math.inf}, ValueError, "finite"),
    ({"fd": True}, TypeError, "is bool"),
    ({"fd": "0.5"}, TypeError, "is str"),
    ([("fd", 0.5)], TypeError, "give a dict"),
])
def test_runtime_parameters_are_checked(runtime_model, params, error, match):
    with pytest.raises(error, match=match):
        runtime_model.simulate(0.01, params=params)


def test_numbers_of_numpy_and_sympy_are_accepted(runtime_model):
    ref = runtime_model.simulate(0.05, params={"fd": 0.5, "m11": 0.04}).x[-1]
    for fd, m11 in ((np.float32(0.5), np.float64(0.04)), (sp.Float(0.5), sp.Rational(1, 25))):
        got = runtime_model.simulate(np.float64(0.05), params={"fd": fd, "m11": m11},
                                     max_steps=np.int64(10**6)).x[-1]
        np.testing.assert_allclose(got, ref, rtol=1e-6, atol=1e-9)


@pytest.mark.parametrize("kwargs, error, match", [
    ({"t_final": True}, TypeError, "t_final = True is bool"),
    ({"t_final": 1.0, "t_eval": ["0", "1"]}, TypeError, "t_eval must be numbers"),
    ({"t_final": 1e7}, ValueError, "output rows"),
    ({"t_final": 1.0, "max_steps": True}, ValueError, "max_steps"),
    ({"t_final": 1.0, "time_limit": -1.0}, ValueError, "time_limit"),
])
def test_arguments_of_simulate_are_checked(runtime_model, kwargs, error, match):
    with pytest.raises(error, match=match):
        runtime_model.simulate(**kwargs)


def test_speeds_off_the_velocity_constraints_are_refused(runtime_model):
    x0 = runtime_model.initial_state()
    x0[runtime_model.state_names.index("dq1")] = 0.1  # the fingertip slides on the object
    with pytest.raises(InconsistentInitialStateError, match="velocity constraints"):
        runtime_model.simulate(0.1, x0=x0)
    runtime_model.simulate(0.01, x0=x0, checks=False)  # allowed when asked for


def test_integrator_cache_is_bounded(runtime_model):
    from grasping_sym.runtime.integrators import INTEGRATOR_CACHE_SIZE, _thread_cache
    for k in range(INTEGRATOR_CACHE_SIZE + 4):
        runtime_model.simulate(0.01 + 1e-3 * k, method="cvodes", outputs=False)
    assert len(_thread_cache(runtime_model)["integrators"]) == INTEGRATOR_CACHE_SIZE


@pytest.fixture(scope="module")
def slow_model():
    """paper2d without the constraint stabilisation (not stiff: every method runs long)."""
    return gs.build(gs.scenes.planar_finger(library.paper_fingertip(), library.paper_object(),
                                            name="slow2d", outputs=(), gf=0.0, gl=0.0, wf=0.0,
                                            wl=0.0))


#: s: radau's run far longer than a test (1e4 s at rtol 1e-12 take it 0.2 s, since its Newton
#: iteration stops at the stage values' rounding; 1e6 s take 18 s)
RADAU_LONG = 1e6


def _long(method: str) -> dict:
    """Arguments for a run far longer than a test: 1e4 s (radau: ``RADAU_LONG``) at tight
    tolerances."""
    end = RADAU_LONG if method == "radau" else 1e4
    kw = {"t_eval": [0.0, end], "rtol": 1e-12, "atol": 1e-14, "max_steps": 10**12,
          "checks": False}
    if method == "rk4":
        kw = {"t_eval": [0.0, 1e4], "h": 1e-7, "checks": False}
    return kw


def _run_long(model, method: str, time_limit=None):
    """A run far longer than a test. dopri5 through the library with its stiffness test off
    (the resting scene turns stiff for it after ~60 s)."""
    if method == "dopri5":
        return model.library.dopri5(model.initial_state(), [0.0, 1e4], rtol=1e-12, atol=1e-14,
                                    max_steps=10**9, nstiff=0, time_limit=time_limit)
    kw = _long(method)
    return model.simulate(kw["t_eval"][-1], method=method, time_limit=time_limit, **kw)


@pytest.mark.parametrize("method", METHODS)
def test_time_limit_stops_every_method(slow_model, method):
    """The limit stops the run within 1.5 s of its start; the method's one-time set-up (a
    SUNDIALS integrator's, a library another worker may still be writing) is done first."""
    import time
    slow_model.simulate(0.01, method=method)
    t0 = time.perf_counter()
    with pytest.raises(IntegratorError, match="wall-time limit of 0.3 s"):
        _run_long(slow_model, method, time_limit=0.3)
    assert time.perf_counter() - t0 < 1.5


@pytest.mark.parametrize("method", ["cvodes", "idas", "radau"])
def test_a_deadline_left_behind_stops_no_later_run(slow_model, method):
    """A run without a time limit ignores a deadline an earlier run left set (as one did when
    a signal landed between a SUNDIALS run's stop and its clean-up: the next run, with no
    limit, failed at once on the stale deadline)."""
    import time
    slow_model.library._lib.gs_set_time_limit(1e-9)
    time.sleep(1e-3)
    r = slow_model.simulate(0.01, method=method)
    assert r.t[-1] == 0.01 and np.all(np.isfinite(r.x))


@pytest.mark.parametrize("method", ["cvodes", "idas"])
def test_time_limit_stops_sundials_in_another_thread(slow_model, method):
    """No signal handler outside the main thread: the step budget in C reads the deadline
    (the method's one-time set-up done first, as above)."""
    import concurrent.futures
    import time
    slow_model.simulate(0.01, method=method)
    t0 = time.perf_counter()
    with concurrent.futures.ThreadPoolExecutor(1) as pool:
        future = pool.submit(_run_long, slow_model, method, 0.3)
        with pytest.raises(IntegratorError, match="wall-time limit of 0.3 s"):
            future.result(timeout=60)
    assert time.perf_counter() - t0 < 1.5


def _default_sigint():
    """The child's SIGINT at its default, as a shell starts it, whatever disposition this
    test worker holds."""
    import signal
    signal.signal(signal.SIGINT, signal.SIG_DFL)


_CTRL_C = """
import json, os, signal, sys, threading, time
import grasping_sym as gs
from grasping_sym.geometry import library
m = gs.build(gs.scenes.planar_finger(library.paper_fingertip(), library.paper_object(),
                                     name="slow2d", outputs=(), gf=0.0, gl=0.0, wf=0.0, wl=0.0))
kw = json.loads(sys.argv[2])
method = sys.argv[1]
sent = {}
def fire():
    sent["t"] = time.perf_counter()
    os.kill(os.getpid(), signal.SIGINT)
threading.Timer(0.5, fire).start()
try:
    if method == "dopri5":
        m.library.dopri5(m.initial_state(), [0.0, 1e4], rtol=1e-12, atol=1e-14, max_steps=10**9,
                         nstiff=0)
    elif method == "simulate_many":  # four long runs on two threads: every thread stops
        import numpy as np
        m.simulate_many(1e6, x0=np.tile(m.initial_state(), (4, 1)), method="radau", rtol=1e-12,
                        atol=1e-14, max_steps=10**12, threads=2)
    else:
        m.simulate(kw["t_eval"][-1], method=method, **kw)
    print(json.dumps({"outcome": "finished"}))
except KeyboardInterrupt:
    print(json.dumps({"outcome": "KeyboardInterrupt", "delay": time.perf_counter() - sent["t"]}))
"""


@pytest.mark.parametrize("method", [*METHODS, "simulate_many"])
def test_ctrl_c_stops_every_method_within_a_tenth_of_a_second(slow_model, method):
    kw = {} if method == "simulate_many" else _long(method)
    out = subprocess.run([sys.executable, "-c", textwrap.dedent(_CTRL_C), method,
                          json.dumps(kw)], capture_output=True, text=True, timeout=120,
                         preexec_fn=_default_sigint)
    res = json.loads(out.stdout.strip().splitlines()[-1])
    assert res["outcome"] == "KeyboardInterrupt", out.stderr[-1000:]
    assert res["delay"] < 0.1, res


def test_domain_exit_is_located_at_its_step_under_sundials():
    """Outputs 0.5 s apart: cvodes and idas still report the exit where rk4 (checking every
    0.1 ms step) finds it, not at the next output."""
    scene = gs.scenes.planar_finger(library.circle(0.015, span=0.4), library.paper_object(),
                                    name="short_contour", outputs=("Q",))
    model = gs.build(scene)
    with pytest.raises(ContactLeftContourError) as ref:
        model.simulate(1.0, method="rk4")
    for method in ("cvodes", "idas"):
        with pytest.raises(ContactLeftContourError, match="Radau step") as info:
            model.simulate(1.0, method=method, t_eval=[0.0, 0.5, 1.0])
        assert abs(info.value.t - ref.value.t) < 2e-3, method


def test_an_excursion_out_of_the_domain_between_outputs_is_found_under_sundials():
    """paper3d with fingertip 1's longitude cut at 0.09 rad: its contact coordinate rises to
    0.106 near t = 0.06 s and comes back to 0.058. With outputs 0.5 s apart the outputs never
    show it; the C loops see it at their step, CVODES (its rhs NaN outside the domains) fails
    at the crossing and the exit is named there; IDAS integrates the excursion out of the
    domains as one more state, which has grown at the next output, and the Radau loop then
    finds the exit at its step."""
    import dataclasses

    from grasping_sym.geometry import surface_library as sl
    base = gs.scenes.paper3d()
    tip = sl.sphere(0.01, lon=(-math.pi, 0.09), name="tip_short")
    # SUNDIALS cannot project: the scene holds its constraints by the gain of 300 1/s
    model = gs.build(gs.scenes.paper3d(name="excursion3d", gain=300.0, fingers=(
        dataclasses.replace(base.fingers[0], tip=tip), *base.fingers[1:])))
    with pytest.raises(ContactLeftContourError) as ref:
        model.simulate(1.0, method="radau", rtol=1e-6, atol=1e-9)
    assert "u_f1 = " in str(ref.value) and "component" not in str(ref.value)  # the state by name, not only its index
    for method in ("cvodes", "idas"):
        with pytest.raises(ContactLeftContourError, match="u_f1 left the contour's domain") as info:
            model.simulate(1.0, method=method, rtol=1e-6, atol=1e-9, t_eval=[0.0, 0.5, 1.0])
        assert abs(info.value.t - ref.value.t) < 1e-3, method


# ------------------------------------------------------------------ checks whatever is shown
def _showing(model, shown=()):
    """``model`` loaded again as if its scene had asked to show only ``shown``: the other
    compiled outputs are the checks' own (the manifest's ``check_outputs``)."""
    from grasping_sym.runtime.model import Model

    m = model.manifest
    hidden = [k for k in m["output_names"] if k not in shown]
    return Model(model.directory, {**m, "check_outputs": hidden}, model.library_path, model.start)


def test_the_checks_run_whatever_outputs_the_model_shows(runtime_model):
    """A model that shows no outputs still refuses a start off the constraints and names a
    contact that opens (the checks read the compiled outputs it does not show); its results
    hold only what it shows."""
    from grasping_sym.errors import ContactOpenedError
    from tests.test_hard_cases import rolling_velocity

    hidden = _showing(runtime_model)
    assert hidden.output_names == () and "f" in hidden.columns
    x0 = hidden.initial_state()
    x0[1] += 0.01
    with pytest.raises(InconsistentInitialStateError, match="off the contact constraints"):
        hidden.simulate(0.01, x0=x0)
    x0 = hidden.initial_state()
    x0[3:6] = -60.0 * rolling_velocity(runtime_model, x0)  # test_hard_cases: f crosses 0 at 0.028 s
    with pytest.raises(ContactOpenedError, match="normal force f crosses 0"):
        hidden.simulate(0.5, x0=x0, rtol=1e-8, atol=1e-12, params={"fd": 0.3})
    assert hidden.simulate(0.01).outputs == {}
    some = _showing(runtime_model, ("f", "lam"))
    assert some.output_names == ("f", "lam") and set(some.simulate(0.01).outputs) == {"f", "lam"}
    batch = some.simulate_many(0.01, x0=np.array([runtime_model.initial_state(), x0]), outputs=True,
                               params={"fd": 0.3})
    assert set(batch.outputs) == {"f", "lam"}


def test_the_checks_run_whatever_outputs_the_run_returns(runtime_model):
    """``outputs=False`` returns no outputs but still checks the events along the run: a
    contact that opens is named by simulate (the full way, and the short way of a second call
    with the same settings) and by simulate_many, not returned as a success."""
    from grasping_sym.errors import ContactOpenedError
    from tests.test_hard_cases import rolling_velocity

    weak = gs.build(gs.scenes.paper2d(runtime=("fd", "m11", "gf"), fd=0.3))  # the same library
    x0 = weak.initial_state()
    x0[3:6] = -60.0 * rolling_velocity(weak, x0)  # test_hard_cases (d): f crosses 0 at 0.028 s
    grid = np.linspace(0.0, 0.06, 61)
    kw = dict(rtol=1e-8, atol=1e-12, outputs=False, t_eval=grid)
    assert weak.simulate(0.06, **kw).outputs == {}
    # x0's start checks pass (a run that ends before the contact opens), so later calls with
    # these settings take the short way (runtime.fastpath), which checks the events too
    weak.simulate(0.01, x0=x0, **{**kw, "t_eval": grid[:11]})
    from grasping_sym.runtime import fastpath
    plan = next(iter(weak.short_way.plans.values()))
    assert fastpath.run(weak, plan, 0.06, grid, None) is not None
    assert fastpath.run(weak, plan, 0.06, grid, x0) is None  # an event: the full way names it
    with pytest.raises(ContactOpenedError, match="normal force f crosses 0"):
        weak.simulate(0.06, x0=x0, **kw)
    batch = weak.simulate_many(0.06, x0=np.array([weak.initial_state(), x0]), rtol=1e-8,
                               atol=1e-12, t_eval=grid)
    assert batch.outputs == {}
    assert batch.status.tolist()[0] == 0 and batch.status.tolist()[1] != 0
    assert "normal force f crosses 0" in batch.errors[1]
    unchecked = weak.simulate(0.06, x0=x0, checks=False, **kw)  # asked for: not checked
    assert np.all(np.isfinite(unchecked.x))


def test_every_contact_is_compiled_for_the_checks_whatever_the_scene_shows():
    """The outputs the checks read are compiled whatever a scene asks to show
    (``pipeline.with_check_outputs``): every contact of a 2D or a three-finger 3D scene."""
    import dataclasses

    from grasping_sym.model import chains
    from grasping_sym.pipeline import with_check_outputs

    scene, added = with_check_outputs(gs.scenes.paper2d(outputs=()))
    assert added == ("Q", "R", "f", "lam", "kappa_sum") and scene.outputs == added
    assert with_check_outputs(gs.scenes.paper2d())[1] == ()  # the default shows them all
    base = gs.scenes.paper3d()
    third = dataclasses.replace(base.fingers[0], chain=dataclasses.replace(chains.finger1(), name="3"))
    three = gs.scenes.paper3d(name="three3d", fingers=(*base.fingers, third), dq0=None,
                              outputs=("kinetic_energy",))
    scene, added = with_check_outputs(three)
    assert {"f3", "lam3", "eta3", "krel_min3", "constraint_residual"} <= set(added)
    assert scene.outputs == ("kinetic_energy", *added)
    paper = with_check_outputs(gs.scenes.paper3d(formulation="paper", outputs=()))[1]
    assert {"frame_denominator1", "frame_denominator2"} <= set(paper)


def test_a_third_contact_that_opens_is_named(paper3d_model):
    """The trajectory check of a model with three contacts names contact 3 when its normal
    force crosses 0 (the samples as the compiled outputs give them)."""
    from grasping_sym.errors import ContactOpenedError
    from grasping_sym.runtime import checks

    t = np.linspace(0.0, 0.1, 11)
    X = np.zeros((11, len(paper3d_model.state_names)))
    outs = {"f1": np.full(11, 0.5), "f2": np.full(11, 0.5), "f3": 0.5 - 10.0 * t}
    err = checks.trajectory_event(paper3d_model, t, X, outs, {})
    assert isinstance(err, ContactOpenedError)
    assert "normal force f3 of contact 3 crosses 0 at about t = 0.05 s" in str(err)


@pytest.mark.parametrize("kwargs, match", [
    ({"max_steps": 10**30}, r"max_steps = 1000000000000000000000000000000 must be an integer from 1 "
                            r"to 9223372036854775807"),
    ({"max_steps": 2.5}, "max_steps = 2.5 must be an integer"),
    ({"time_limit": 1e300}, r"time_limit = 1e\+300 s is more than 1e\+09 s"),
    ({"method": "rk4", "h": 1e-300}, r"h = 1e-300 s over t_final = 0.01 s means 1e\+298 RK4 steps"),
    ({"t_eval": np.full(10**6, np.nan)}, r"non-finite entries at indices \[0, 1, .*9, \.\.\. \(1000000 in all\)\]"),
])
def test_run_limits_are_named_before_any_work(runtime_model, kwargs, match):
    from grasping_sym.errors import RunArgumentError

    with pytest.raises(RunArgumentError, match=match) as info:
        runtime_model.simulate(0.01, **kwargs)
    assert len(str(info.value)) < 400
    with pytest.raises(RunArgumentError, match="threads = 10000000000 must be an integer from 1 to 1024"):
        runtime_model.simulate_many(0.01, threads=10**10)


def test_the_largest_max_steps_runs(runtime_model):
    for method in ("radau", "cvodes"):
        r = runtime_model.simulate(0.01, method=method, max_steps=2**63 - 1)
        assert r.t[-1] == 0.01
