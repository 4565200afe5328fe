"""simulate's short way (runtime.fastpath): the same numbers as the full path, and every
problem still named by the full path."""
from __future__ import annotations

import numpy as np
import pytest

import grasping_sym as gs

KW = dict(method="radau", rtol=1e-6, atol=1e-8, t_eval=[0.0, 1.0], outputs=False)


def _same(a, b):
    assert np.array_equal(a.t, b.t) and np.array_equal(a.x, b.x)
    assert {k: v for k, v in a.stats.items() if k not in ("wall_time", "loop_time")} == \
        {k: v for k, v in b.stats.items() if k not in ("wall_time", "loop_time")}
    assert a.params == b.params and a.method == b.method and a.outputs == b.outputs == {}


@pytest.mark.parametrize("method", ["radau", "dopri5", "dop853"])
def test_the_short_way_gives_the_full_paths_numbers(paper2d_model, method):
    m = paper2d_model
    kw = {**KW, "method": method, "rtol": 1e-8, "atol": 1e-10}
    first = m.simulate(1.0, **kw)  # the full path; its settings become a plan
    assert m.short_way.plans and all(plan.checked for plan in m.short_way.plans.values())
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


#: Arguments equal to a plan's or plainly like its output times that the full path refuses by
#: name: the short ways (``fastpath``, ``modes.short_way``) must not run them.
REFUSED = [
    ({"outputs": 0}, "outputs = 0 is int"),
    ({"max_steps": 1_000_000.0}, "max_steps = 1000000.0 must be an integer"),
    ({"t_eval": np.array([False, True])}, "array of bool"),
    ({"t_eval": ["0", "1.0"]}, "array of <U"),
    ({"t_eval": [0.0, 1.0 + 0j]}, "array of complex"),
    ({"t_eval": np.array([0.0, 1.0], dtype=object)}, "array of object"),
]


@pytest.mark.parametrize("modes", [False, True], ids=["rolling", "modes"])
def test_what_the_full_path_refuses_the_short_ways_refuse(paper2d_model, modes):
    """With a plan of the same settings in place (``True == 1``, ``1.0 == 1``: the keys hold
    each value's type), every argument the full path refuses is refused by name, not run."""
    m = gs.build(gs.scenes.with_modes(gs.scenes.paper2d())) if modes else paper2d_model
    kw = {**KW, "max_steps": 1_000_000, "mu": 1.0}
    m.simulate(1.0, **kw)
    m.simulate(1.0, **kw)  # the short way, planned
    for change, words in REFUSED:
        with pytest.raises(gs.errors.RunArgumentError, match=words.replace("(", r"\(")):
            m.simulate(1.0, **{**kw, **change})
    with pytest.raises(gs.errors.RunArgumentError, match="t_final = inf"):
        m.simulate(float("inf"), **{**kw, "t_eval": [0.0, float("inf")]})
    with pytest.raises(gs.errors.RunArgumentError, match="mu"):
        m.simulate(1.0, **{**kw, "mu": True})
