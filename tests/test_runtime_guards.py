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


def _long(method: str) -> dict:
    """Arguments for a run far longer than a test: 1e4 s at tight tolerances."""
    kw = {"t_eval": [0.0, 1e4], "rtol": 1e-12, "atol": 1e-14, "max_steps": 10**9,
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
    return model.simulate(1e4, method=method, time_limit=time_limit, **_long(method))


@pytest.mark.parametrize("method", METHODS)
def test_time_limit_stops_every_method(slow_model, method):
    import time
    t0 = time.perf_counter()
    with pytest.raises(IntegratorError, match="wall-time limit of 0.3 s"):
        _run_long(slow_model, method, time_limit=0.3)
    assert time.perf_counter() - t0 < 1.5


@pytest.mark.parametrize("method", ["cvodes", "idas"])
def test_time_limit_stops_sundials_in_another_thread(slow_model, method):
    """No signal handler outside the main thread: the step budget in C reads the deadline."""
    import concurrent.futures
    import time
    t0 = time.perf_counter()
    with concurrent.futures.ThreadPoolExecutor(1) as pool:
        future = pool.submit(_run_long, slow_model, method, 0.3)
        with pytest.raises(IntegratorError, match="wall-time limit of 0.3 s"):
            future.result(timeout=60)
    assert time.perf_counter() - t0 < 1.5


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
        m.simulate_many(1e4, x0=np.tile(m.initial_state(), (4, 1)), method="radau", rtol=1e-12,
                        atol=1e-14, max_steps=10**9, threads=2)
    else:
        m.simulate(1e4, method=method, **kw)
    print(json.dumps({"outcome": "finished"}))
except KeyboardInterrupt:
    print(json.dumps({"outcome": "KeyboardInterrupt", "delay": time.perf_counter() - sent["t"]}))
"""


@pytest.mark.parametrize("method", [*METHODS, "simulate_many"])
def test_ctrl_c_stops_every_method_within_a_tenth_of_a_second(slow_model, method):
    kw = {} if method == "simulate_many" else _long(method)
    out = subprocess.run([sys.executable, "-c", textwrap.dedent(_CTRL_C), method,
                          json.dumps(kw)], capture_output=True, text=True, timeout=120)
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
    model = gs.build(gs.scenes.paper3d(name="excursion3d", fingers=(
        dataclasses.replace(base.fingers[0], tip=tip), *base.fingers[1:])))
    with pytest.raises(ContactLeftContourError) as ref:
        model.simulate(1.0, method="radau", rtol=1e-6, atol=1e-9)
    for method in ("cvodes", "idas"):
        with pytest.raises(ContactLeftContourError, match="u_f1 left the contour's domain") as info:
            model.simulate(1.0, method=method, rtol=1e-6, atol=1e-9, t_eval=[0.0, 0.5, 1.0])
        assert abs(info.value.t - ref.value.t) < 1e-3, method
