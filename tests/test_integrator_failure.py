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
    assert "CV_TOO_MUCH_WORK" in err.reason and "max_steps" in err.reason
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
