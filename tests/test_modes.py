"""Contact that can change (issue 27): a free body on a plane of the world, rolling, sliding,
separated, with impacts, against closed-form answers for a uniform solid sphere (MODELS.md
section 5: an incline's rolling/sliding threshold ``tan b <= (7/2) mu``, accelerations
``(5/7) g sin b`` and ``g (sin b - mu cos b)``, spin growth ``(5/2) mu g cos b / r``; a
launched slide that stops at ``t = 2 v0 / (7 mu g)`` with ``v = (5/7) v0``; a drop and its
bounces), and the cases with no consistent answer stopping by name."""
from __future__ import annotations

import math

import numpy as np
import pytest

import grasping_sym as gs
from grasping_sym.errors import ChatteringError, InvalidSceneError, PainleveError
from grasping_sym.geometry import surface_library
from grasping_sym.runtime import integrators, modes
from grasping_sym.runtime.compiled import CompiledLibrary

G, R, M = 9.81, 0.05, 0.1
TIGHT = dict(rtol=1e-10, atol=1e-12)


@pytest.fixture(scope="module", params=[0.3, 0.8], ids=lambda b: f"incline{b}")
def incline(request):
    b = request.param
    return b, gs.build(gs.scenes.sphere_on_incline(R, M, b, name=f"incline{int(b * 10)}"))


@pytest.fixture(scope="module")
def flat():
    return gs.build(gs.scenes.sphere_on_incline(R, M, 0.0, name="flat"))


def _downhill(b):
    return -np.array([0.0, math.cos(b), math.sin(b)])


def test_a_sphere_rolls_down_an_incline_at_five_sevenths_g_sin_b(incline):
    b, model = incline
    mu = 1.2 * math.tan(b) / 3.5
    res = model.simulate(0.1, mu=mu, **TIGHT)
    assert set(res.modes) == {"rolling"} and not res.events
    a = res.x[-1, 7:10] @ _downhill(b) / 0.1
    assert abs(a / (5 / 7 * G * math.sin(b)) - 1) < 1e-9
    assert abs(res["normal_force"][-1] / (M * G * math.cos(b)) - 1) < 1e-9
    assert abs(res["gap"]).max() < 1e-12


def test_a_sphere_slides_down_a_steeper_incline_and_spins_up(incline):
    b, model = incline
    mu = 0.8 * math.tan(b) / 3.5
    res = model.simulate(0.1, mu=mu, **TIGHT)
    assert set(res.modes) == {"sliding"} and not res.events
    a = res.x[-1, 7:10] @ _downhill(b) / 0.1
    assert abs(a / (G * (math.sin(b) - mu * math.cos(b))) - 1) < 1e-9
    spin = abs(res.x[-1, 12]) / 0.1   # about the body's z axis: the world's x axis here
    assert abs(spin / (2.5 * mu * G * math.cos(b) / R) - 1) < 1e-9


def test_the_rolling_sliding_threshold_is_tan_b_over_seven_halves(incline):
    b, model = incline
    lo, hi = 0.5 * math.tan(b) / 3.5, 2.0 * math.tan(b) / 3.5     # sliding at lo, rolling at hi
    for _ in range(60):
        mid = 0.5 * (lo + hi)
        rolls = model.simulate(1e-4, mu=mid, t_eval=[0.0, 1e-4]).modes[0] == "rolling"
        lo, hi = (lo, mid) if rolls else (mid, hi)
    b_threshold = math.atan(3.5 * hi)
    assert abs(b_threshold - b) < 1e-9


@pytest.mark.parametrize("method", ["radau", "dop853"])
def test_a_launched_slide_stops_and_rolls_at_the_closed_form_time(flat, method):
    mu, v0 = 0.2, 1.0
    model = flat
    x0 = model.initial_state()
    x0[7:10] = [0.0, -v0, 0.0]        # sliding, no spin
    tol = TIGHT if method == "radau" else dict(rtol=1e-12, atol=1e-14)
    res = model.simulate(0.3, x0=x0, mu=mu, method=method, **tol)
    (stop,) = res.events
    assert (stop["from"], stop["to"], stop["witness"]) == ("sliding", "rolling", "slip")
    assert abs(stop["t"] - 2 * v0 / (7 * mu * G)) < 1e-9
    assert stop["reset"] < 1e-9
    v_end = -res.x[-1, 8]
    assert abs(v_end / (5 / 7 * v0) - 1) < 1e-9
    assert abs(res.x[-1, 12] * R / v_end - 1) < 1e-9     # rolling: v = omega r


def test_a_dropped_sphere_lands_at_the_free_fall_time_and_stays(flat):
    model = flat
    h = 0.1
    x0 = model.initial_state()
    x0[2] = R + h
    res = model.simulate(0.3, x0=x0, mu=gs.contact.coulomb(0.5, e=0.0), **TIGHT)
    impact = res.events[0]
    assert (impact["from"], impact["witness"], impact["to"]) == ("separated", "gap", "rolling")
    assert abs(impact["t"] - math.sqrt(2 * h / G)) < 1e-9
    # an output time at the event itself (the dense output's root and the located one may lie
    # on either side of it): every output time is reported, in order
    grid = [0.0, impact["t"], 0.2, 0.3]
    at = model.simulate(0.3, x0=x0, mu=gs.contact.coulomb(0.5, e=0.0), t_eval=grid, **TIGHT)
    assert list(at.t) == grid and at.x.shape == (4, len(model.state_names))
    assert res["gap"].min() > -1e-12
    flight = res.t < impact["t"]
    assert np.ptp(res["energy"][flight]) < 1e-9 * res["energy"][0]   # conserved in flight
    after = ~flight
    assert np.abs(res["normal_speed"][after]).max() < 1e-12
    assert abs(res["energy"][-1] - M * G * R) < 1e-12                 # at rest on the table


def test_bounces_lose_energy_at_every_impact_and_come_to_rest(flat):
    model = flat
    h, e = 0.1, 0.5
    x0 = model.initial_state()
    x0[2] = R + h
    res = model.simulate(0.6, x0=x0, mu=gs.contact.coulomb(0.5, e=e), **TIGHT)
    impacts = [ev for ev in res.events if ev["witness"] == "gap"]
    assert len(impacts) > 3
    # every impact at the free flights' times: the rebound at e v from an approach at v, until
    # one slower than REST_SPEED is plastic (the last flights last 0.3 and 0.14 ms, inside
    # one watched interval: found by probing the step's dense output, c/watch.c)
    t, v = math.sqrt(2 * h / G), math.sqrt(2 * G * h)
    for k, ev in enumerate(impacts):
        assert abs(ev["t"] - t) < 1e-9, k
        assert (ev["to"] == "rolling") == (v <= modes.REST_SPEED)
        v *= e
        t += 2 * v / G
    assert impacts[-1]["to"] == "rolling" and len(impacts) == 12
    energy = res["energy"]
    assert np.all(np.diff(energy) <= 1e-9 * energy[0])                # never increases
    assert res.modes[-1] == "rolling" and abs(res.x[-1, 9]) < 1e-9


def test_bounces_past_unwatched_points_are_where_watching_every_point_finds_them(flat, monkeypatch):
    """The gap's points left unwatched in flight (its margin far from 0 at its rate,
    ``c/watch.c``) change nothing: the same impacts at the same times (1e-12 s) as a run
    watching every point, also with nearly every point left (a safety of 1e-9: each impact
    found among the steps' ends kept and bracketed in its own step)."""
    x0 = flat.initial_state()
    x0[2] = R + 0.1
    law = gs.contact.coulomb(0.5, e=0.5)
    default = flat.simulate(0.6, x0=x0, mu=law, **TIGHT)
    assert default.stats["left_unwatched"] > default.stats["watched"] / 2
    runs = []
    for safety in (0.0, 1e-9):
        monkeypatch.setattr(modes, "WATCH_SAFETY", safety)
        runs.append(flat.simulate(0.6, x0=x0, mu=law, **TIGHT))
    every, most = runs
    assert every.stats["left_unwatched"] == 0 and most.stats["left_unwatched"] > 2 * most.stats["watched"]
    for other in (default, most):
        assert [(e["from"], e["to"]) for e in other.events] == [(e["from"], e["to"]) for e in every.events]
        assert max(abs(a["t"] - b["t"]) for a, b in zip(other.events, every.events)) < 1e-12
        assert np.max(np.abs(other.x - every.x)) < 1e-9


def test_an_impact_among_unwatched_steps_comes_before_a_failure(flat):
    """A loop that fails (here: its step limit) with steps' ends left unwatched looks for the
    event among them first (``gs_watch_failed``): the falling sphere's impact, found at the
    5th step's end when every end but the last is left (a safety of 1e-9), is the same event
    when the loop may take 4 steps only."""
    x0 = flat.initial_state()
    x0[2] = R + 0.1
    p = modes._BodyRun(flat, None, (0.5,), 0.5).params([modes.SEPARATED])
    gap = list(flat.columns).index("gap")

    def fall(max_steps):
        flat.library.watch([[(gap, 1.0)]], [modes.GAP_RETURN], dt=modes.WATCH_DT, probe=[True], safety=1e-9)
        try:
            return integrators.c_loop(flat, "radau", x0, np.array([0.0, 0.3]), p, rtol=1e-10, atol=1e-12,
                                      max_steps=max_steps, h=None, time_limit=None)[2]
        finally:
            flat.library.unwatch()

    whole = fall(10**6)
    n = whole["n_steps"]
    assert abs(whole["event"]["t"] - math.sqrt(2 * 0.1 / G)) < 1e-3 and n > 2
    cut = fall(n - 1)
    assert cut["n_steps"] == n - 1 and cut["event"]["t"] == whole["event"]["t"]
    assert np.array_equal(cut["event"]["x_step"], whole["event"]["x_step"])


def test_a_run_that_ends_at_or_just_after_an_impact_ends_there(flat):
    """A run whose last output time is the located impact's, or within its location tolerance
    after it (no method can step that short), ends with the state after the impact; one that
    ends later steps on. (A run ending 1e-16 s after the impact stopped with 'step size fell
    below the minimum'.)"""
    x0 = flat.initial_state()
    x0[2] = R + 0.1
    law = gs.contact.coulomb(0.5, e=0.5)
    t1 = flat.simulate(0.2, x0=x0, mu=law, **TIGHT).events[0]["t"]
    for dt in (0.0, 1e-16, 2e-14, 1e-9):
        r = flat.simulate(t1 + dt, x0=x0, mu=law, t_eval=[0.0, t1 + dt], **TIGHT)
        assert r.t[-1] == t1 + dt and len(r.events) == 1, dt
        assert abs(r.events[0]["t"] - t1) < 1e-13
        assert r.x[-1, 9] > 0.5 * math.sqrt(2 * G * 0.1) * 0.99  # rebounding: after the impact


def test_events_are_located_in_c_as_in_python(flat, monkeypatch):
    """The dropped sphere's impacts located by ``gs_watch_refine`` (the secant steps in C) and
    by ``runtime.events.refine`` (the same in Python, when C gives none) agree to 1e-13 s."""
    x0 = flat.initial_state()
    x0[2] = R + 0.1
    law = gs.contact.coulomb(0.5, e=0.5)
    in_c = flat.simulate(0.6, x0=x0, mu=law, **TIGHT)
    monkeypatch.setattr(CompiledLibrary, "watch_refine", lambda self, *args: None)
    in_python = flat.simulate(0.6, x0=x0, mu=law, **TIGHT)
    assert len(in_c.events) == len(in_python.events) == 12
    assert max(abs(a["t"] - b["t"]) for a, b in zip(in_c.events, in_python.events)) < 1e-13


def _ellipsoid(**start):
    """An elongated ellipsoid (semi-axes 40, 20, 20 mm; chart poles along its y axis, so that
    it rocks about y along the chart's equator) on a table: one compiled model, any start."""
    a, c = 0.04, 0.02
    chart = np.array([[1.0, 0.0, 0.0], [0.0, 0.0, -1.0], [0.0, 1.0, 0.0]])
    inertia = (M * 2 * c * c / 5, M * (a * a + c * c) / 5, M * (a * a + c * c) / 5)
    surface = surface_library.ellipsoid(a, c, c, rotation=chart, lon=(-8 * math.pi, 8 * math.pi))
    return gs.build(gs.scenes.body_on_plane(surface, mass=M, inertia=inertia, support=(math.pi, 0.0),
                                            name="ellipsoid", **start))


def _tilt(th):
    return np.array([[math.cos(th), 0, -math.sin(th)], [0, 1, 0], [math.sin(th), 0, math.cos(th)]])


def test_painleve_stops_by_name():
    """The ellipsoid leaning at 0.5 rad, its low end sliding toward it with mu = 3: sliding has
    no consistent normal force."""
    with pytest.raises(PainleveError, match="Painleve"):
        _ellipsoid(rotation=_tilt(0.5), velocity=(-1.0, 0.0, 0.0)).simulate(0.01, mu=3.0)


def test_chattering_stops_by_name(flat, monkeypatch):
    monkeypatch.setattr(modes, "MAX_SWITCHES", 4)
    monkeypatch.setattr(modes, "SWITCH_WINDOW", 1.0)
    x0 = flat.initial_state()
    x0[2] = R + 0.1
    with pytest.raises(ChatteringError, match="switches of contact modes"):
        flat.simulate(0.6, x0=x0, mu=gs.contact.coulomb(0.5, e=0.5))


def test_many_runs_carry_mu_and_e_and_equal_single_runs(flat, tmp_path):
    x0 = flat.initial_state()
    x0[2] = R + 0.1
    grid = np.linspace(0.0, 0.5, 51)
    es = np.array([0.0, 0.3, 0.6])
    batch = flat.simulate_many(0.5, x0=x0, mu=0.5, e=es, t_eval=grid, outputs=True)
    assert batch.ok.all() and len(batch.events[0]) == 1 and len(batch.events[1]) > 1
    for i, e in enumerate(es):
        single = flat.simulate(0.5, x0=x0, mu=0.5, e=e, t_eval=grid)
        np.testing.assert_array_equal(batch.x[i], single.x)
        assert batch.events[i] == single.events
    # a sweep over e of the same drop: the highest rebound speed is e times the impact's
    drop = gs.build(gs.scenes.sphere_on_incline(R, M, 0.0, position=(0.0, 0.0, R + 0.1),
                                                start="as given", name="flat"))   # flat's code
    ds = gs.sweep(drop, {"e": [0.3, 0.6]}, 0.4, store=tmp_path / "e.zarr", mu=0.5,
                  measures=["max:vz"], samples=4001, progress=False)
    v1 = math.sqrt(2 * G * 0.1)
    np.testing.assert_allclose(ds["max_vz"].values, [0.3 * v1, 0.6 * v1], rtol=2e-3)


def test_bad_run_arguments_of_modes_are_refused_by_name(flat):
    from grasping_sym.errors import RunArgumentError
    with pytest.raises(RunArgumentError, match="runs one of"):
        flat.simulate(0.1, method="rk4")
    with pytest.raises(RunArgumentError, match=r"e = 1.5 must be a number in \[0, 1\]"):
        flat.simulate(0.1, e=1.5)
    with pytest.raises(RunArgumentError, match="takes none"):
        flat.simulate(0.1, params={"mu": 0.3})


def test_the_modes_figure_draws_the_bands_and_refuses_a_run_without_modes(flat, tmp_path):
    x0 = flat.initial_state()
    x0[2] = R + 0.02
    res = flat.simulate(0.3, x0=x0, mu=gs.contact.coulomb(0.5, e=0.5))
    assert gs.viz.modes(res, tmp_path / "modes.png").stat().st_size > 10_000
    plain = gs.SimulationResult(res.t, res.x, res.state_names, {}, "radau")   # no modes recorded
    with pytest.raises(ValueError, match="no contact modes"):
        gs.viz.modes(plain, tmp_path / "none.png")


def test_a_ball_on_a_turntable_circles_at_two_sevenths_of_its_rate():
    """A uniform ball rolling on a plane turning at Omega about its normal (a driven surface of
    the world): its centre's velocity turns at (2/7) Omega at constant speed (no slip:
    (1 + m r^2 / I) x'' = Omega z x x')."""
    omega, r0 = 2.0, np.array([0.1, 0.0, 0.0])
    chart = np.array([[0.0, 0.0, 1.0], [0.0, 1.0, 0.0], [-1.0, 0.0, 0.0]])   # sphere_on_incline's, b = 0
    v0 = np.cross([0.0, 0.0, omega], r0)           # carried along with the table
    scene = gs.scenes.sphere_on_incline(R, M, 0.0, plane_spin=omega, position=tuple(r0),
                                        velocity=tuple(v0), omega=tuple(chart.T @ [0.0, 0.0, omega]),
                                        friction=gs.contact.coulomb(0.5), name="turntable")
    res = gs.build(scene).simulate(1.0, **TIGHT)
    assert set(res.modes) == {"rolling"} and not res.events
    a = 2 / 7 * omega * 1.0
    turned = np.array([[math.cos(a), -math.sin(a), 0.0], [math.sin(a), math.cos(a), 0.0], [0.0, 0.0, 1.0]]) @ v0
    assert np.abs(res.x[-1, 7:10] - turned).max() < 1e-9 * np.linalg.norm(v0)


def test_a_drop_is_animated_and_its_modes_drawn(flat, tmp_path):
    x0 = flat.initial_state()
    x0[2] = R + 0.02
    res = flat.simulate(0.3, x0=x0, mu=gs.contact.coulomb(0.5, e=0.5))
    gif = gs.viz.animate(res, tmp_path / "drop.gif", fps=10)
    assert gif.stat().st_size > 10_000
    (png,) = gs.viz.write_figures(res.scene, res, tmp_path)
    assert png.name.endswith("_modes.png") and png.stat().st_size > 10_000
    assert "switches of contact modes" in gs.viz.summary_lines(res.scene, res)[0]


def test_a_slide_that_turns_past_ninety_degrees_goes_on_sliding():
    """Launched uphill and sideways on a steep incline, the slip turns by more than 90 degrees
    while it is fast: no stop (no reset), and friction only takes energy away."""
    b = 0.3
    model = gs.build(gs.scenes.sphere_on_incline(R, M, b, name="incline3"))
    x0 = model.initial_state()
    x0[7:10] = 0.6 * np.array([0.0, math.cos(b), math.sin(b)]) + [0.2, 0.0, 0.0]
    res = model.simulate(0.3, x0=x0, mu=0.05, **TIGHT)
    v = res.x[:, 7:10]
    assert v[0] @ v[-1] < 0                                  # turned past 90 degrees
    assert not res.events and set(res.modes) == {"sliding"}
    assert res["slip_speed"].min() > 0.05
    assert np.diff(res["energy"]).max() < 0


def test_a_tilted_ellipsoid_dropped_on_a_table_never_gains_energy():
    """An elongated body (an inverse inertia at the contact that couples the normal and the
    tangential directions) dropped tilted: bounces, slides and rolls; its energy never
    increases and it never sinks into the table."""
    model = _ellipsoid(rotation=_tilt(0.5), position=(0.0, 0.0, 0.1), start="as given")
    for mu, e in ((0.5, 0.0), (0.2, 0.5), (1.0, 0.3)):
        res = model.simulate(0.4, mu=mu, e=e, **TIGHT)
        assert res.events and res.events[0]["witness"] == "gap"
        energy = res["energy"]
        assert np.diff(energy).max() < 1e-10 * energy[0], (mu, e)
        assert res["gap"].min() > -1e-12, (mu, e)


#: Two tumbling drops of a 50 x 30 x 20 mm ellipsoid (with an atlas) found by a review: the
#: slide's start and the impact's sliding impulse were followed by a plain fixed-point
#: iteration on 3-vectors, which circled (the slip's image turning faster than the direction)
#: and returned a direction 145 degrees from its own image: the first run died with
#: EventLocationError at 0.122 s, the second's impact at 0.193 s was refused as Painleve's.
TUMBLES = {
    "slide": ((0.0, 0.0, 0.1, 0.22630964095587783, -0.09428411458946381, 0.022439712167186952, -0.969221807154769,
               -0.651281012443394, 0.8624447963157468, -0.6255920840343272, 13.383064815789057, 24.376872103424464,
               7.658591654269448, 2.8505535897213696, -1.140410895034064), 0.1962968851147534),
    "impact": ((0.0, 0.0, 0.1, -0.5906360717572919, 0.4285945654336741, 0.6432851433954003, 0.2316030084143862,
                0.7316522837854408, -0.5014400184670523, -1.3791606182879854, -21.435748337548883, 18.289344062575623,
                -0.40126909230960844, 3.0119143841815967, 0.08053336327056321), 0.4719097193587902),
}


@pytest.fixture(scope="module")
def tumbler():
    m, (a, b, c) = 0.1, (0.05, 0.03, 0.02)
    inertia = (m / 5 * (b * b + c * c), m / 5 * (a * a + c * c), m / 5 * (a * a + b * b))
    return gs.build(gs.scenes.body_on_plane(surface_library.ellipsoid(a, b, c, atlas=True), mass=m, inertia=inertia,
                                            start="as given", position=(0.0, 0.0, 0.1), name="tumbler"))


@pytest.mark.parametrize("case", sorted(TUMBLES))
def test_a_tumbling_ellipsoid_slides_and_lands_along_directions_that_are_fixed_points(tumbler, case, monkeypatch):
    """Every slip direction the run takes (a slide's start: the slip's acceleration along
    it; an impact's sliding impulse: the slip it leaves along it, Moreau's law) is a fixed
    point of its map to 1e-9 in angle, or, at the cone's edge (the map's image there ~0,
    ``modes.EDGE``), the direction opposing the rolling force; the run reaches its end, and
    its energy never grows."""
    taken = []
    plain = modes._direction

    def spy(d, along, iterations=50, normal=None):
        out = plain(d, along, iterations, normal)
        v, small = along(out)
        if np.linalg.norm(v) > max(small, modes.EDGE * np.linalg.norm(along(-out)[0])):
            taken.append(math.atan2(np.linalg.norm(np.cross(v, out)), np.dot(v, out)))
        else:  # at the cone's edge (a slide's start where the cone was crossed): d itself
            assert np.array_equal(out, d)
        return out

    monkeypatch.setattr(modes, "_direction", spy)
    x0, mu = TUMBLES[case]
    res = tumbler.simulate(0.3, x0=np.array(x0), params={"chart": 0}, mu=mu, e=0.0,
                           t_eval=np.linspace(0.0, 0.3, 31), **TIGHT)
    assert res.t[-1] == 0.3 and taken and max(taken) < 1e-9, taken
    where = {"slide": ("rolling", "sliding", 0.1218), "impact": ("separated", "sliding", 0.1933)}[case]
    assert any((e["from"], e["to"]) == where[:2] and abs(e["t"] - where[2]) < 1e-3 for e in res.events)
    energy = res["energy"]
    assert np.diff(energy).max() < 1e-10 * abs(energy).max()


def test_a_slide_from_the_cone_edge_follows_the_exact_coulomb_slip(tumbler):
    """The tumbling ellipsoid of ``TUMBLES["impact"]`` with mu = 0.43578: at 0.0969 s its
    rolling force reaches the cone's edge and a slide starts, its slip speed growing as the
    square of the time from the integration's noise. The sliding direction ``v_t/|v_t|`` of
    that noise jumped by up to 90 degrees from step to step, and the run stopped with
    ``EventLocationError`` 3 ns into the slide (at rtol 1e-10). With the onset's continuous
    direction (``derive.body_plane``, ``slip_onset``) the run goes on; 0.1 ms into the slide
    its state is the one an independent integrator (SciPy's Radau at rtol 1e-12) gives from
    the same start with Coulomb's own direction ``v_t/|v_t|`` (no onset), and the slip has
    grown along the direction opposing the rolling force at the edge."""
    from scipy.integrate import solve_ivp

    x0, mu = np.array(TUMBLES["impact"][0]), 0.4357787464585925
    run = dict(x0=x0, params={"chart": 0}, mu=mu, e=0.0, **TIGHT)
    first = tumbler.simulate(0.12, t_eval=np.linspace(0.0, 0.12, 13), **run)
    (t0,) = [e["t"] for e in first.events if (e["from"], e["to"]) == ("rolling", "sliding")]
    assert 0.0968 < t0 < 0.0969 and first.t[-1] == 0.12
    dt = 1e-4
    res = tumbler.simulate(t0 + dt, t_eval=[0.0, t0, t0 + dt], **run)
    assert [e["t"] for e in res.events] == [e["t"] for e in first.events if e["t"] <= t0]
    xa, xb = res.x[1], res.x[2]
    names = tumbler.p_names
    p = np.array(tumbler.default_params, dtype=float)
    p[names.index("mode")], p[names.index("mu")] = 1.0, mu
    ft = np.array([res[f"rolling_Ft_{c}"][1] for c in "xyz"])
    d0 = -ft / np.linalg.norm(ft)
    p[names.index("slip_x"):names.index("slip_x") + 3] = d0
    p[names.index("chart")] = res.charts["chart"][1]    # the chart (u, v) is read in there
    assert p[names.index("slip_onset")] == 0.0          # Coulomb's direction, no onset
    with np.errstate(over="ignore"):  # SciPy's difference Jacobian where v_t/|v_t| turns at v_t ~ 0
        exact = solve_ivp(lambda t, x: tumbler.library.rhs(x, p), (0.0, dt), xa, method="Radau",
                          rtol=1e-12, atol=1e-15).y[:, -1]
    assert np.abs(xb - exact).max() < 10 * TIGHT["rtol"] * np.abs(exact).max()
    vt = np.array([res[f"vt_{c}"][2] for c in "xyz"])
    y = tumbler.library.outputs(exact, p)
    vt_exact = np.array([y[tumbler.output_names.index(f"vt_{c}")] for c in "xyz"])
    assert 1e-6 < np.linalg.norm(vt) < 1e-4 and vt @ d0 > 0.999 * np.linalg.norm(vt)
    assert np.linalg.norm(vt - vt_exact) < 2e-4 * np.linalg.norm(vt_exact)


def test_a_slip_that_stops_within_the_tolerances_noise_stops_on_the_dense_output(tumbler):
    """The tumbling ellipsoid of ``TUMBLES["impact"]`` with mu = 0.45 at the default tolerances:
    at 0.0687 s its slip stops, the slip witness changing sign on the dense output within
    5 ns, but the trajectory integrated again from the step's start does not reproduce the
    change (the witness there is at the tolerances' noise). The run stopped with
    ``EventLocationError`` (2 of a sweep's 32 mu, 0.30 to 0.61). The stop is taken at the
    dense output's root, the run's own solution to its tolerances, and the event says so
    (``located``): the run then takes the switches of the tight run (rtol 1e-10), within
    1e-6 s (3e-8 s measured), the stop within 1e-7 s (8e-9 s measured)."""
    x0 = np.array(TUMBLES["impact"][0])
    run = dict(x0=x0, params={"chart": 0}, mu=0.45, e=0.0, t_eval=np.linspace(0.0, 0.1, 11))
    res, tight = tumbler.simulate(0.1, **run), tumbler.simulate(0.1, **run, **TIGHT)
    switches = [[(e["from"], e["to"], e["witness"]) for e in r.events] for r in (res, tight)]
    assert switches[0] == switches[1] and len(switches[0]) == 4
    stop = [e for e in res.events if e["witness"] == "slip"]
    assert len(stop) == 1 and stop[0]["located"] == "dense output"
    assert all("located" not in e for e in tight.events)
    assert max(abs(a["t"] - b["t"]) for a, b in zip(res.events, tight.events)) < 1e-6
    assert abs(stop[0]["t"] - next(e["t"] for e in tight.events if e["witness"] == "slip")) < 1e-7
    assert res.t[-1] == 0.1


@pytest.mark.parametrize("eps, loose", [(1e-4, 2e-6), (1e-5, 1e-5)])
def test_a_short_slide_on_a_shaken_belt_stops_where_coulomb_says(eps, loose):
    """A ball on a belt whose acceleration ``A sin(w t)`` peaks ``eps`` above the rolling limit
    ``7/2 mu g`` (mu = 0.1): it rolls until ``sin(w t1) = 1/(1 + eps)``, then slides (the
    contact point accelerates at ``7/2 mu g`` against the belt's ``A sin(w t)``) and stops
    where the slip ``A/w (cos w t1 - cos w t) - 7/2 mu g (t - t1)`` returns to 0: 4.2 ms
    later, its slip never above 6.5e-7 m/s (eps 1e-4); 1.3 ms, 2e-8 m/s (1e-5). At the default
    tolerances the slide's onset (``derive.slip_onset``) is ~5e-6 m/s wide and its slip
    witness armed above that: the stop went unseen, the slip reversed with friction along it
    (feeding it) for 2 ms (1.25 ms armed at a tenth of it): such a stop is located where the
    witness last crossed 0 (``modes._last_zero``). The old rule stopped the first with
    EventLocationError. Both
    times are found within ``loose`` s at the default tolerances (8e-7 and 5e-6 measured: the
    slip's slope at the stop is 1.1e-3 and 2e-4 m/s^2) and within 1e-8 s at rtol 1e-10 (1.8e-9
    measured); friction never does work on the slip."""
    from scipy.optimize import brentq

    mu, g, w = 0.1, 9.81, 10.0
    A = 3.5 * mu * g * (1 + eps)
    model = gs.build(gs.scenes.sphere_on_incline(R, M, 0.0, name="shaken", friction=gs.contact.coulomb(mu),
                                                 plane_motion=(0, f"{A}/{w}*t - {A}/{w**2}*sin({w}*t)", 0)))
    t1 = math.asin(1 / (1 + eps)) / w
    def slip(t):
        return A / w * (math.cos(w * t1) - math.cos(w * t)) - 3.5 * mu * g * (t - t1)
    t2 = brentq(slip, t1 + 1e-4, t1 + 0.1)
    for tol, within in (({}, loose), (TIGHT, 1e-8)):
        res = model.simulate(0.2, t_eval=np.linspace(0.0, 0.2, 2001), **tol)
        assert [(e["from"], e["to"]) for e in res.events] == [("rolling", "sliding"), ("sliding", "rolling")]
        assert abs(res.events[0]["t"] - t1) < within and abs(res.events[1]["t"] - t2) < within, (t1, t2)
        sliding = res.modes == "sliding"
        power = sum(res[f"Ft_{c}"] * res[f"vt_{c}"] for c in "xyz")[sliding]
        assert sliding.sum() > 10 and power.max() <= 0.0
    # with two output times the same stop (the segment is integrated again for its last zero:
    # from the output times alone it came 2-3.5 ms late)
    sparse = model.simulate(0.2, t_eval=[0.0, 0.2])
    assert [e["t"] for e in sparse.events] == [e["t"] for e in model.simulate(0.2).events]
    assert abs(sparse.events[1]["t"] - t2) < loose


def test_a_slip_direction_in_a_plane_is_found_where_the_plain_iteration_circles():
    """``modes._direction`` of 3-vectors in a plane: the map ``d -> (d_x, -3 d_y, 0)`` has its
    fixed points (its image along it, not against) at +-x; from 1 rad the plain iteration
    flips between +-y for ever, and the angle's root is found."""
    def along(d):
        return np.array([d[0], -3.0 * d[1], 0.0]), 1e-12

    d0 = np.array([math.cos(1.0), math.sin(1.0), 0.0])
    circling = modes._direction(d0, along)
    assert abs(circling[0]) < 1e-6                        # the plain iteration: near +-y
    found = modes._direction(d0, along, normal=np.array([0.0, 0.0, 1.0]))
    assert abs(abs(found[0]) - 1.0) < 1e-14 and abs(found[2]) == 0.0


def test_what_a_run_with_modes_cannot_do_is_refused_by_name(flat):
    """A model with contact modes holds its contacts by its gain and switches where its checks
    are: ``project=`` (it said the model was too old to project) and ``checks=False`` (it was
    ignored) are refused by name."""
    from grasping_sym.errors import RunArgumentError

    for project in (True, "steps", 1e-10):
        with pytest.raises(RunArgumentError, match="has contact modes"):
            flat.simulate(0.01, project=project)
    with pytest.raises(RunArgumentError, match="checks=False"):
        flat.simulate(0.01, checks=False)
    with pytest.raises(RunArgumentError, match="checks=False"):
        flat.simulate_many(0.01, x0=flat.initial_state()[None, :], checks=False)


def test_a_sweep_over_mu_finds_the_incline_threshold(tmp_path):
    b = 0.3
    model = gs.build(gs.scenes.sphere_on_incline(R, M, b, name="incline3"))
    ds = gs.sweep(model, {"mu": [0.05, 0.2]}, 0.05, store=tmp_path / "mu.zarr",
                  measures=["max:slip_speed"], progress=False)
    slides, rolls = ds["max_slip_speed"].values          # threshold tan(0.3) / 3.5 = 0.088
    assert slides > 0.01 and rolls < 1e-9


def test_a_ball_on_a_rising_conveyor_slides_then_rolls_at_two_sevenths_of_the_belt():
    """A driven plane (``plane_motion``: a belt at V along y, rising with acceleration a): the
    ball at rest slides, friction mu m (g + a) brings its contact to the belt's speed at
    t* = 2 V / (7 mu (g + a)), then it rolls at (2/7) V along the belt and rises with it; the
    normal force is m (g + a) throughout (closed forms, MODELS.md section 5's sphere)."""
    V, mu, g, r, a, mass = 0.2, 0.3, 9.81, 0.05, 2.0, 0.1
    scene = gs.scenes.sphere_on_incline(radius=r, mass=mass, incline=0.0, name="lift",
                                        friction=gs.contact.coulomb(mu),
                                        plane_motion=(0, f"{V}*t", f"{a / 2}*t**2"))
    res = gs.build(scene).simulate(0.05, t_eval=np.linspace(0.0, 0.05, 51), rtol=1e-10, atol=1e-12)
    assert res.modes[0] == "sliding" and res.modes[-1] == "rolling"
    assert [(e["from"], e["to"]) for e in res.events] == [("sliding", "rolling")]
    assert abs(res.events[0]["t"] - 2 * V / (7 * mu * (g + a))) < 1e-9
    assert abs(res.x[-1, 8] - 2 * V / 7) < 1e-9 and abs(res.x[-1, 9] - a * 0.05) < 1e-9
    assert np.max(np.abs(res["normal_force"] - mass * (g + a))) < 1e-9


@pytest.mark.parametrize("motion, words", [((0, "1 + t", 0), "not 0 at t = 0"), ((0, "x*t", 0), "unknown name 'x'"),
                                           ((0, "t"), "three expressions of t"),
                                           ((0, "t*log(t)", 0), "finite at t = 0")])
def test_a_bad_plane_motion_is_refused_by_name(motion, words):
    with pytest.raises(InvalidSceneError, match=words):
        gs.scenes.sphere_on_incline(plane_motion=motion)
    with pytest.raises(InvalidSceneError, match=words):
        gs.scenes.world_plane((0, 0, 0), (0, 1, 0), motion=motion)
