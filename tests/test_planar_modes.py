"""Contact modes of a planar finger (model.planar_modes, derive.planar_modes, runtime.modes;
docs/conventions.md section 8): checked against the rolling model, the rolling model's own cone
event, the energy balance of a slide, the contours' geometry computed here from their
formulas, and the laws of an impact."""
from __future__ import annotations

import contextlib
import functools
import math
import pickle

import casadi as ca
import numpy as np
import pytest
import sympy as sp
from scipy.integrate import simpson
from scipy.optimize import minimize

import grasping_sym as gs
from grasping_sym.errors import (
    FrictionConeError,
    InputScheduleError,
    IntegratorError,
    InvalidSceneError,
    RunArgumentError,
)
from grasping_sym.geometry.curves import T
from grasping_sym.runtime import modes
from grasping_sym.runtime.settings import RunSettings

TOL = {"rtol": 1e-10, "atol": 1e-12}


@pytest.fixture(scope="module")
def base():
    return gs.scenes.paper2d()


@pytest.fixture(scope="module")
def model(base):
    return gs.build(gs.scenes.with_modes(base))


@pytest.fixture(scope="module")
def rolling(base):
    return gs.build(base)


@contextlib.contextmanager
def _alone(model):
    """``model`` running every stretch itself: no rolling model (``Model.rolling``) for the
    stretches where the contact rolls."""
    kept, model.rolling = model.rolling, None
    try:
        yield model
    finally:
        model.rolling = kept


def _x0(base) -> np.ndarray:
    x = base.initial_state()
    return np.concatenate([x[:6], [x[6], x[6]]])


@functools.lru_cache(maxsize=4)
def _formulas(curve):
    """``u -> (x, y, x', y')`` of a contour, from its SymPy formulas."""
    return sp.lambdify(T, [curve.x, curve.y, sp.diff(curve.x, T), sp.diff(curve.y, T)], "numpy")


def _world_points(base, x):
    """The two contours' points at ``u0``, ``u1`` (world, m) and their unit normals, from the
    contours' formulas (docs/conventions.md section 1: the fingertip's frame at O01 turned by
    pi/2 - q1 - q2, the object's at the pivot turned by -theta)."""
    p = base.params
    th, q1, q2, u0, u1 = x[0], x[1], x[2], x[6], x[7]

    def rot(a):
        return np.array([[math.cos(a), -math.sin(a)], [math.sin(a), math.cos(a)]])

    def point_tangent(curve, u):
        X, Y, dX, dY = (float(v) for v in _formulas(curve)(u))
        return np.array([X, Y]), np.array([dX, dY]) / math.hypot(dX, dY)

    o01 = np.array([p["l11"] * math.sin(q1) + p["l12"] * math.sin(q1 + q2),
                    p["l11"] * math.cos(q1) + p["l12"] * math.cos(q1 + q2)])
    c0, t0 = point_tangent(base.fingertip, u0)
    c1, t1 = point_tangent(base.object, u1)
    Rf, Ro = rot(math.pi / 2 - q1 - q2), rot(-th)
    return o01 + Rf @ c0, Rf @ t0, np.array(base.pivot) + Ro @ c1, Ro @ t1


def test_rolling_mode_is_the_rolling_model(base, model, rolling):
    """Mode 0 is the paper2d model: the same right-hand side at random states (to 1e-12
    relative), and without a friction limit the same motion (to 1e-9), never switching."""
    rng = np.random.default_rng(7)
    x_start = base.initial_state()
    for _ in range(10):
        x = x_start + rng.normal(scale=[0.05, 0.05, 0.05, 0.5, 0.5, 0.5, 0.05])
        a, b = rolling.rhs(x), model.rhs(np.concatenate([x, [x[6]]]))
        scale = np.abs(a[:6]) + 1e-12
        assert np.max(np.abs(a[:6] - b[:6]) / scale) < 1e-12
        assert abs(b[6] - a[6]) < 1e-12 * abs(a[6]) and abs(b[7] - a[6]) < 1e-12 * abs(a[6])
    te = np.linspace(0.0, 0.3, 31)
    with _alone(model):  # mode 0 itself, not the rolling model that runs such a run
        r = model.simulate(0.3, t_eval=te, **TOL)
    r0 = rolling.simulate(0.3, t_eval=te, method="radau", **TOL)
    assert r.events == [] and set(r.modes) == {"rolling"} and r.stats["rolling_model_segments"] == 0
    assert np.max(np.abs(r.x[:, :6] - r0.x[:, :6])) < 1e-9


def test_each_modes_branch_of_the_rhs_is_the_general_rhs(base, model):
    """The compiled rhs takes, by the mode it is called with, a branch with that mode folded
    in (``rhs_branches``: rolling, sliding and apart, 57 %, 64 % and 19 % of the general
    rhs's instructions): the compiled general rhs's numbers at states off the rolling model's
    (``u0 != u1``, as after a slip) and either slip sign, to round-off (CasADi's folding adds
    or multiplies by exact 0s and 1s)."""
    counts = model.manifest["op_counts"]
    assert all(counts[f"rhs_modes_{m}_sx_instructions"] < 0.7 * counts["rhs_sx_instructions"] for m in "012")
    general = ca.external(f"{model.name}_rhs_any", str(model.library_path))
    rng = np.random.default_rng(11)
    x_start = _x0(base)
    for mode, slip in ((0, 1.0), (1, 1.0), (1, -1.0), (2, 1.0)):
        p = model.default_params.copy()
        p[model.p_names.index("mode")], p[model.p_names.index("slip")] = mode, slip
        for _ in range(3):
            x = x_start + rng.normal(scale=[0.05, 0.05, 0.05, 0.5, 0.5, 0.5, 0.05, 0.05])
            a, b = model.rhs(x, p), np.ravel(general(0.0, x, [], p, [])[0])
            assert np.max(np.abs(a - b)) < 1e-15 * np.max(np.abs(b)), (mode, slip)


@pytest.fixture(scope="module")
def slide(model):
    """paper2d with mu = 0.2: rolls, slides from the cone's edge, sticks again."""
    return model.simulate(0.25, mu=0.2, t_eval=np.linspace(0.0, 0.25, 2501), **TOL)


def test_slip_starts_where_the_rolling_model_leaves_its_cone(base, rolling, slide):
    """The first switch (rolling -> sliding, on the cone) is at the time the rolling model's
    own cone check stops it (FrictionConeError, located independently on its lam and f)."""
    with pytest.raises(FrictionConeError) as err:
        rolling.simulate(0.25, mu=0.2, t_eval=np.linspace(0.0, 0.25, 251), method="radau", **TOL)
    first = slide.events[0]
    assert (first["from"], first["to"], first["witness"]) == ("rolling", "sliding", "cone")
    assert abs(first["t"] - err.value.t) < 1e-8
    later = slide.events[1]
    assert (later["from"], later["to"], later["witness"]) == ("sliding", "rolling", "slip")
    assert later["reset"] < 1e-9  # the slip speed had reached 0 by itself
    sliding = slide.modes == "sliding"
    assert sliding.sum() > 100
    # Coulomb's law while sliding: |lam| = mu f, against the slip
    f, lam, vt = (slide[k][sliding] for k in ("normal_force", "lam", "vt"))
    assert np.max(np.abs(np.abs(lam) - 0.2 * f)) < 1e-12 * np.max(f)
    assert np.all(lam * vt >= 0)
    assert np.max(slide["cone_ratio"]) <= 0.2 + 1e-12


def test_the_slip_onset_is_located_in_c_down_to_the_witness_noise(model, slide, monkeypatch):
    """The cone's witness on the trajectory integrated again one step at a time carries the
    Newton iterations' noise (~3e-13 here, 1e-13 s): a secant trial no nearer 0 within 1e-12 s
    ends the location in C (``gs_watch_refine``) at the nearer trial, where it used to fall to
    Python's secants and Brent's method (~20 integrations more) chasing 1e-14 s."""
    from grasping_sym.runtime import events

    def no_python(*args, **kwargs):
        raise AssertionError("located in Python")

    monkeypatch.setattr(events, "refine", no_python)
    again = model.simulate(0.25, mu=0.2, t_eval=np.linspace(0.0, 0.25, 2501), **TOL)
    assert [(e["from"], e["to"]) for e in again.events] == [(e["from"], e["to"]) for e in slide.events]
    assert abs(again.events[0]["t"] - slide.events[0]["t"]) < 1e-12
    assert abs(again.events[0]["value"]) < 1e-12


def test_the_rolling_model_runs_the_rolling_stretches(model, slide):
    """Where the contact rolls with ``u0 = u1`` (paper2d's one contact parameter), the base
    scene's rolling model integrates the run (``Model.rolling``), watching its own
    ``mu f - |lam|`` and ``f`` at every step: the same switches at the same times (1e-9 s) and
    the same samples (1e-8) as the model with modes run alone. The stick after the slide has
    ``u0 != u1``: the model with modes runs it."""
    assert model.rolling is not None
    assert slide.stats["segments"] == 3 and slide.stats["rolling_model_segments"] == 1
    with _alone(model):
        alone = model.simulate(0.25, mu=0.2, t_eval=slide.t, **TOL)
    assert alone.stats["rolling_model_segments"] == 0
    assert [(e["from"], e["to"], e["witness"]) for e in alone.events] == \
        [(e["from"], e["to"], e["witness"]) for e in slide.events]
    assert max(abs(a["t"] - b["t"]) for a, b in zip(alone.events, slide.events)) < 1e-9
    assert np.max(np.abs(alone.x - slide.x)) < 1e-8
    assert (alone.modes == slide.modes).all()


def test_a_repeated_rolling_run_takes_the_short_way_with_the_full_ways_numbers(model, slide, monkeypatch):
    """A call with the settings and the start of a call that began rolling runs as that call's
    first segment (``modes.short_way``, without the full way's checks and start): the same
    samples, outputs, modes and stats, bit for bit. One that slips from there goes the full
    way, which locates the switch (``slide``'s events and samples, bit for bit), and the
    start is forgotten. A state or
    output times the full way refuses are refused by name as before."""
    te = np.linspace(0.0, 0.05, 51)                                  # the first slip: 0.063 s
    model.run_cache.pop("modes_short", None)
    full = model.simulate(0.05, mu=0.2, t_eval=te, **TOL)
    assert full.events == [] and model.run_cache["modes_short"]

    def no_full_way(*args, **kwargs):
        raise AssertionError("the full way ran")

    x0 = model.initial_state()
    given = model.simulate(0.05, mu=0.2, t_eval=te, x0=x0, **TOL)      # a start given: its own
    with monkeypatch.context() as m:
        m.setattr(modes, "run", no_full_way)
        short = model.simulate(0.05, mu=0.2, t_eval=te, **TOL)
        short_given = model.simulate(0.05, mu=0.2, t_eval=te, x0=x0.copy(), **TOL)
    for a, b in ((short, full), (short_given, given)):
        assert np.array_equal(a.t, b.t) and np.array_equal(a.x, b.x)
        assert b.outputs and all(np.array_equal(a[k], b[k]) for k in b.outputs)
        assert (a.modes == b.modes).all() and a.events == [] and a.params == b.params
        assert {k: v for k, v in a.stats.items() if k not in ("wall_time", "loop_time")} == \
            {k: v for k, v in b.stats.items() if k not in ("wall_time", "loop_time")}
    again = model.simulate(0.25, mu=0.2, t_eval=slide.t, **TOL)          # the short way's segment slips
    assert again.events == slide.events and np.array_equal(again.x, slide.x)
    assert all(b"" not in plan[3] for plan in model.run_cache["modes_short"].values())  # forgotten
    nx = len(model.state_names)
    with pytest.raises(RunArgumentError, match="shape"):
        model.simulate(0.05, mu=0.2, t_eval=te, x0=np.zeros((1, nx)), **TOL)
    with pytest.raises(RunArgumentError, match="strictly increasing"):
        model.simulate(0.05, mu=0.2, t_eval=[0.0, 0.03, 0.02, 0.05], **TOL)


def test_a_slip_found_past_unwatched_steps_is_where_watching_every_step_finds_it(model, slide, monkeypatch):
    """Steps left unwatched while the cone's margin is far from 0 at its rate (``c/watch.c``,
    ``modes.WATCH_SAFETY``) change nothing: the same switches, at the same times (1e-12 s),
    the same samples (1e-9) as a run watching every step; and, with nearly every step left
    (a safety of 1e-9), a slip onset found among the steps' ends kept, each bracketed in its
    own step."""
    assert 0 < slide.stats["watched"] < slide.stats["left_unwatched"]
    for safety in (0.0, 1e-9):
        monkeypatch.setattr(modes, "WATCH_SAFETY", safety)
        other = model.simulate(0.25, mu=0.2, t_eval=slide.t, **TOL)
        assert (other.stats["left_unwatched"] == 0) == (safety == 0.0)
        assert [(e["contact"], e["from"], e["to"], e["witness"]) for e in other.events] == \
            [(e["contact"], e["from"], e["to"], e["witness"]) for e in slide.events]
        assert max(abs(a["t"] - b["t"]) for a, b in zip(other.events, slide.events)) < 1e-12
        assert np.max(np.abs(other.x - slide.x)) < 1e-9
    assert other.stats["watched"] < other.stats["n_steps"] / 5


def test_a_failure_while_the_rolling_model_runs_names_the_model_with_modes_state(model):
    """A run stopped (max_steps) in a stretch the rolling model integrates reports the model with
    modes' state (u0, u1, not the rolling model's s): its state, its trajectory; and a model
    sent to another process keeps its rolling model."""
    with pytest.raises(IntegratorError, match="too many steps") as err:
        model.simulate(0.1, max_steps=5)
    names = model.state_names
    assert len(err.value.x) == len(names) and "u0=" in str(err.value) and "s=" not in str(err.value)
    assert err.value.trajectory[1].shape[1] == len(names)
    sent = pickle.loads(pickle.dumps(model))
    assert sent.rolling is not None and sent.rolling.state_names == model.rolling.state_names


def test_a_slide_loses_what_friction_dissipates(slide):
    """Energy balance along the slide: d(K + V)/dt = the joints' power - lam v_t (the normal
    force does no work on a closed contact), integrated by Simpson's rule over the output grid."""

    rows = np.flatnonzero(slide.modes == "sliding")
    rows = rows[(rows > rows[0]) & (rows < rows[-1])]  # whole samples inside the slide
    t = slide.t[rows]
    E = slide["kinetic_energy"][rows] + slide["potential_energy"][rows]
    rate = slide["power"][rows] - slide["lam"][rows] * slide["vt"][rows]
    dissipated = simpson(slide["lam"][rows] * slide["vt"][rows], x=t)
    assert dissipated > 1e-7  # the slide dissipates something measurable
    assert abs((E[-1] - E[0]) - simpson(rate, x=t)) < 1e-6 * dissipated


def test_sliding_contact_points_stay_one_point(base, slide):
    """While sliding, the contours' points at u0 and u1, computed here from their formulas,
    coincide and their tangents are parallel, though u0 and u1 move apart."""
    rows = np.flatnonzero(slide.modes == "sliding")[::40]
    for k in rows:
        p0, t0, p1, t1 = _world_points(base, slide.x[k])
        assert np.linalg.norm(p0 - p1) < 1e-10
        assert abs(t0[0] * t1[1] - t0[1] * t1[0]) < 1e-9
    u = slide.x[:, 6:8]
    assert abs((u[rows[-1], 0] - u[rows[0], 0]) - (u[rows[-1], 1] - u[rows[0], 1])) > 1e-4


@pytest.fixture(scope="module")
def drop(base, model):
    """The finger pulled back 0.02 rad: apart, pulled in by the law, hits the object."""
    x0 = _x0(base)
    x0[1] -= 0.02
    return model.simulate(0.05, x0=x0, mu=0.3, e=0.0, t_eval=np.linspace(0.0, 0.05, 501), **TOL)


def test_gap_is_the_distance_between_the_contours(base, drop):
    """Apart, ``gap`` is the shortest distance between the two contours: found here by sampling
    both and refining, independently of the model's common-normal points."""

    rows = np.flatnonzero(drop.modes == "separated")[::20]
    assert len(rows) >= 3
    for k in rows:
        x = drop.x[k]

        def dist(u, x=x):
            y = x.copy()
            y[6:8] = u
            p0, _, p1, _ = _world_points(base, y)
            return float(np.linalg.norm(p0 - p1))

        grid = np.linspace(-0.025, 0.025, 21)
        best = min(((a, b) for a in grid for b in grid), key=dist)
        res = minimize(dist, best, method="Nelder-Mead",
                       options={"xatol": 1e-12, "fatol": 1e-16, "maxiter": 4000})
        assert abs(res.fun - drop["gap"][k]) < 1e-10
        assert drop["gap"][k] > 0


def test_the_finger_returns_and_rolls(drop):
    """One plastic impact where the gap closes, then the contact holds (mu = 0.3)."""
    assert [(e["from"], e["to"], e["witness"]) for e in drop.events] == [("separated", "rolling", "gap")]
    k = np.searchsorted(drop.t, drop.events[0]["t"])
    assert np.all(drop["gap"][:k] > 0) and np.max(np.abs(drop["gap"][k + 1:])) < 1e-12
    assert np.all(drop.modes[k + 1:] == "rolling") and np.all(drop["normal_force"][k + 1:] > 0)


def test_impact_laws(base, model):
    """At random approaching velocities: e = 0 ends the approach and never adds energy;
    a stuck impact leaves no slip, a sliding one an impulse on the cone's edge; frictionless
    with e = 1 keeps the kinetic energy and reverses the normal speed."""
    rng = np.random.default_rng(3)
    x_start = _x0(base)
    s = RunSettings.__new__(RunSettings)
    seen = set()
    for mu, e in ((0.3, 0.0), (0.05, 0.0), (0.0, 1.0), (0.3, 0.5)):
        r = modes._PlanarRun(model, s, (mu,), e)
        for _ in range(25):
            x = x_start.copy()
            x[3:6] = rng.normal(scale=0.5, size=3)
            y = r.outputs(x, r.params([modes.ROLLING]))
            if not y["vn_fixed"] > modes.REST_SPEED:
                continue
            try:
                after, _, stuck, _ = r.impact(0.0, x, y, [modes.SEPARATED])
            except gs.errors.ContactModeError:
                assert e > 0  # only restitution with friction may want energy
                continue
            ya = r.outputs(after, r.params([modes.ROLLING]))
            assert ya["kinetic_energy"] <= y["kinetic_energy"] * (1 + 1e-12)
            assert abs(ya["vn_fixed"] + e * y["vn_fixed"]) < 1e-12
            if stuck:
                assert abs(ya["vt"]) < 1e-12
            seen.add(stuck)
            if mu == 0.0:
                assert abs(ya["kinetic_energy"] - y["kinetic_energy"]) < 1e-12 * y["kinetic_energy"]
    assert seen == {True, False}
    # the impact's terms (W, M^-1 g) are a compiled function of their own, read at impacts
    # only: not outputs computed at every output time, not shown
    internal = model.manifest["internal_outputs"]
    assert internal["names"] == ["W_nn", "W_nt", "W_tt", *(f"Minv_g{k}_{i}" for k in "QR" for i in range(3))]
    assert not set(internal["names"]) & set(model.columns)
    fn = model.library.function(internal["function"])
    with pytest.raises(ValueError, match=f"takes x of {len(model.state_names)} and p of"):
        fn(x_start[:3], model.default_params)


def test_bounces_settle(base, model):
    """With e = 0.5 the finger bounces, each return located from its apex, until an impact
    slower than REST_SPEED is plastic; then it rolls."""
    x0 = _x0(base)
    x0[1] -= 0.02
    r = model.simulate(0.04, x0=x0, mu=0.3, e=0.5, t_eval=np.linspace(0.0, 0.04, 81), **TOL)
    bounces = [ev for ev in r.events if ev["to"] == "separated"]
    assert len(bounces) >= 4 and r.events[-1]["to"] == "rolling" and r.modes[-1] == "rolling"
    times = [ev["t"] for ev in r.events]
    assert all(b > a for a, b in zip(times, times[1:]))


def test_modes_many_runs_and_refusals(base, model):
    """simulate_many carries mu per run; a scene modes cannot take is refused by name."""
    res = model.simulate_many(0.1, x0=np.tile(_x0(base), (2, 1)), mu=np.array([0.2, 1.0]),
                              t_eval=np.linspace(0.0, 0.1, 11), **TOL)
    assert [e["to"] for e in res.events[0]] == ["sliding"] and res.events[1] == []
    with pytest.raises(InvalidSceneError, match="runtime"):
        gs.scenes.with_modes(gs.scenes.paper2d(runtime=("fd",)))
    with pytest.raises(RunArgumentError, match="params"):
        model.simulate(0.1, params={"mu": 0.2})


def test_a_sweep_over_mu_measures_the_first_slip(model, slide, tmp_path):
    """gs.sweep over mu with modes: ``first_slip:1`` is the located switch (0 where the contact
    slides from the start, inf where it never slides), ``held`` 1 while the finger touches."""
    ds = gs.sweep(model, {"mu": [0.05, 0.2, 1.0]}, t_final=0.1, measures=("held", "first_slip:1"),
                  store=tmp_path / "s.zarr", progress=False, **TOL)
    first = ds["first_slip_1"].values
    assert first[0] == 0.0 and abs(first[1] - slide.events[0]["t"]) < 1e-9 and np.isinf(first[2])
    assert list(ds["held"].values) == [1.0, 1.0, 1.0]


def test_many_runs_with_inputs_are_the_single_runs():
    """simulate_many of a model with modes and inputs: per-run constant inputs ``(N, 2)`` and
    one table for every run, each run bit for bit ``simulate`` with its own inputs."""
    torqued = gs.build(gs.scenes.with_modes(gs.scenes.paper2d(inputs="torques")))
    kw = dict(mu=0.2, t_eval=np.linspace(0.0, 0.1, 11), **TOL)
    U = np.array([[0.0, 0.0], [4e-3, -2e-3]])
    res = torqued.simulate_many(0.1, u=U, **kw)
    for i in range(2):
        one = torqued.simulate(0.1, u=U[i], **kw)
        assert np.array_equal(res.x[i], one.x) and res.events[i] == one.events
    assert np.max(np.abs(res.x[1] - res.x[0])) > 1e-4
    table = gs.inputs.zero_order_hold([0.0, 0.05], [[0.0, 0.0], [4e-3, -2e-3]])
    many = torqued.simulate_many(0.1, u=table, x0=np.tile(torqued.initial_state(), (2, 1)), **kw)
    one = torqued.simulate(0.1, u=table, **kw)
    assert np.array_equal(many.x[1], one.x)
    with pytest.raises(InputScheduleError):  # a wrong shape: the call's error
        torqued.simulate_many(0.1, u=np.zeros((2, 3)), **kw)
    with pytest.raises(RunArgumentError, match="different numbers of runs"):
        torqued.simulate_many(0.1, u=U, **{**kw, "mu": np.array([0.2, 0.3, 0.4])})
    # the wall-time limit: a batch's is the whole batch's (the runs it leaves get the batch's
    # code and message, as a batch of a model without modes), and a run's bounds its table's
    # pieces in all (each piece's loop reads the clock every 16th step only: a review's run of
    # 60 000 pieces went on for 1.5 s past a limit of 0.3 s)
    late = torqued.simulate_many(0.1, u=U, time_limit=1e-9, **kw)
    assert late.status.tolist() == [-9, -9] and "the batch's wall-time limit" in late.errors[1]
    dense = gs.inputs.zero_order_hold(np.linspace(0.0, 3.0, 30001), np.zeros((30001, 2)))
    with pytest.raises(IntegratorError, match="wall-time limit"):
        torqued.simulate(3.0, u=dense, t_eval=[0.0, 3.0], time_limit=0.05)
    # runs the batch's limit stops under way: the batch's code and message too (were -3, each
    # with its own limit's message quoting the time the batch had left)
    cut = torqued.simulate_many(3.0, u=dense, x0=np.tile(torqued.initial_state(), (3, 1)), t_eval=[0.0, 3.0],
                                time_limit=0.05, threads=2)
    assert cut.status.tolist() == [-9, -9, -9] and all("the batch's wall-time limit of 0.05 s" in e for e in cut.errors)


def test_max_steps_bounds_the_whole_run_not_each_segment(model):
    """A run with modes integrates one segment per mode; ``max_steps`` bounds the whole run:
    one step fewer than the run takes stops it, though each of its three segments takes
    fewer. Its stats count the mode segments (one more than the switches) and the
    integrations (one per segment without inputs)."""
    kw = dict(mu=0.2, t_eval=np.linspace(0.0, 0.25, 11))
    r = model.simulate(0.25, **kw)
    assert len(r.events) == 2 and r.stats["segments"] == 3 and r.stats["chunks"] == 3
    assert isinstance(r.events[1]["t"], float)
    with pytest.raises(IntegratorError, match="too many steps"):
        model.simulate(0.25, **kw, max_steps=r.stats["n_steps"] - 1)



def test_a_witness_past_its_event_at_a_segment_start_is_an_event_there(base, model):
    """runtime.modes._at_start: a cone or force witness at or below 0 when a segment starts
    (another contact's impact took it there; c/watch.c arms a witness only above 0, so it
    would never be watched) is an event at once; a slide's slip witness at 0 (its start from
    rest) is not, nor is anything at a consistent start."""
    x = _x0(base)
    s = RunSettings.__new__(RunSettings)
    ratio = model.simulate(1e-3, t_eval=[0.0, 1e-3], mu=1.0, **TOL)["cone_ratio"][0]
    low = modes._PlanarRun(model, s, (0.5 * ratio,), 0.0)    # the start is outside this cone
    y = low.outputs(x, low.params([modes.ROLLING]))
    assert modes._at_start(low, [modes.ROLLING], [None], y)[:2] == ("cone", 1)
    high = modes._PlanarRun(model, s, (2.0 * ratio,), 0.0)
    assert modes._at_start(high, [modes.ROLLING], [None], high.outputs(x, high.params([modes.ROLLING]))) is None
    d = np.array([1.0])
    ys = low.outputs(x, low.params([modes.SLIDING], [d]))
    assert ys["normal_force"] > 0 and ys["vt"] == pytest.approx(0.0, abs=1e-12)
    assert modes._at_start(low, [modes.SLIDING], [d], ys) is None
