"""An integrator failure raises IntegratorError with the time, the state and the reason."""
from __future__ import annotations

import numpy as np
import pytest

from grasping_sym.errors import IntegratorError


def test_cvodes_step_budget_failure_names_time_state_reason(paper2d_model):
    with pytest.raises(IntegratorError) as info:
        paper2d_model.simulate(3.0, method="cvodes", max_steps=50, t_eval=[0.0, 3.0])
    err = info.value
    assert 0.0 < err.t < 3.0
    assert err.x is not None and err.x.shape == (7,) and np.all(np.isfinite(err.x))
    assert "max_steps = 50 step attempts in total" in err.reason
    assert "theta=" in str(err) and f"{err.t:.6g}" in str(err)
    # the reported state is the trajectory's state at that time
    ref = paper2d_model.simulate(err.t, method="cvodes", t_eval=[0.0, err.t], outputs=False).x[-1]
    np.testing.assert_allclose(err.x, ref, rtol=1e-6, atol=1e-9)


def test_rk4_unstable_step_reports_non_finite_with_time(paper2d_model):
    # the CSM gains (gl = 3000 1/s) make RK4 unstable above h ~ 9e-4 s
    with pytest.raises(IntegratorError) as info:
        paper2d_model.simulate(3.0, method="rk4", h=5e-3, t_eval=np.linspace(0, 3, 601))
    err = info.value
    assert "non-finite" in err.reason or "left" in err.reason
    assert 0.0 <= err.t < 3.0


@pytest.mark.parametrize("method", ["cvodes", "idas"])
def test_sundials_max_steps_is_a_total_over_all_outputs(paper2d_model, method):
    """SUNDIALS's own limit restarts at every output time; the budget in C (c/budget.c)
    counts the whole run: with an output every ms (3000 intervals, each far below the limit),
    the run stops once it has attempted max_steps steps, and a run given exactly the
    attempts it needs completes."""
    run = paper2d_model.simulate(3.0, method=method, outputs=False)
    needed = run.stats["n_attempts"]
    assert run.stats["n_steps"] <= needed < 2 * run.stats["n_steps"] + 50
    again = paper2d_model.simulate(3.0, method=method, outputs=False, max_steps=needed)
    np.testing.assert_array_equal(again.x, run.x)
    with pytest.raises(IntegratorError, match="in total") as info:
        paper2d_model.simulate(3.0, method=method, outputs=False, max_steps=needed // 2)
    assert 0.0 < info.value.t < 3.0
    assert info.value.x is not None and np.all(np.isfinite(info.value.x))


def test_idas_integrates_a_run_reported_only_at_its_end(paper2d_model):
    """IDAS's initial-condition solver takes the first output time as its time scale; told
    1e4 s it failed (IDA_CONV_FAIL) before the first step. It is told at most 1 ms now."""
    long = paper2d_model.simulate(1e4, method="idas", t_eval=[0.0, 1e4], outputs=False)
    ref = paper2d_model.simulate(1e4, method="radau", rtol=1e-9, atol=1e-10,
                                 t_eval=[0.0, 1e4], outputs=False)
    np.testing.assert_allclose(long.x[-1], ref.x[-1], rtol=0, atol=1e-7)
