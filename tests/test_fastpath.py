"""simulate's short way (runtime.fastpath): the same numbers as the full path, and every
problem still named by the full path."""
from __future__ import annotations

import numpy as np
import pytest

import grasping_sym as gs

KW = dict(method="radau", rtol=1e-6, atol=1e-8, t_eval=[0.0, 1.0], outputs=False)


def _same(a, b):
    assert np.array_equal(a.t, b.t) and np.array_equal(a.x, b.x)
    assert {k: v for k, v in a.stats.items() if k != "wall_time"} == \
        {k: v for k, v in b.stats.items() if k != "wall_time"}
    assert a.params == b.params and a.method == b.method and a.outputs == b.outputs == {}


@pytest.mark.parametrize("method", ["radau", "dopri5", "dop853"])
def test_the_short_way_gives_the_full_paths_numbers(paper2d_model, method):
    m = paper2d_model
    kw = {**KW, "method": method, "rtol": 1e-8, "atol": 1e-10}
    first = m.simulate(1.0, **kw)  # the full path; its settings become a plan
    assert m.short_way.plans and m.short_way.checked
    calls = []
    from grasping_sym.runtime import fastpath

    real_run = fastpath.run

    def spy(*a, **k):
        r = real_run(*a, **k)
        calls.append(r is not None)
        return r

    fastpath.run = spy
    try:
        second = m.simulate(1.0, **kw)
        x0 = m.initial_state(q1={"radau": 0.6, "dopri5": 0.62, "dop853": 0.64}[method])
        a = m.simulate(1.0, x0=x0, **kw)  # a new x0: checked on the full path first
        b = m.simulate(1.0, x0=x0, **kw)
    finally:
        fastpath.run = real_run
    assert calls == [True, False, True]
    _same(first, second)
    _same(a, b)


def test_problems_on_the_short_way_are_still_named(paper2d_model):
    m = paper2d_model
    m.simulate(1.0, **KW)
    with pytest.raises(ValueError, match="strictly increasing"):
        m.simulate(1.0, **{**KW, "t_eval": [0.0, 0.7, 0.5, 1.0]})
    bad = m.initial_state()
    bad[m.state_names.index("s")] = 1.0  # outside the contour's domain
    with pytest.raises(gs.errors.GraspingSymError, match="domain|off the contact"):
        m.simulate(1.0, x0=bad, **KW)
    with pytest.raises(gs.errors.IntegratorError, match="too many steps"):
        m.simulate(1.0, **{**KW, "max_steps": 3})
    with pytest.raises(gs.errors.IntegratorError, match="too many steps"):
        m.simulate(1.0, **{**KW, "max_steps": 3})  # now a plan: the failed run goes the full way
    with pytest.raises(ValueError, match="ends at"):
        m.simulate(2.0, **KW)
