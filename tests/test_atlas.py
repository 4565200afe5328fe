"""Atlases of charts (``geometry.atlas``, ``runtime.atlas``; docs/conventions.md section 15).

The map across charts is checked against the charts themselves (SymPy's surfaces evaluated at
both ends: the same point, the same normal, the frame turned by the angle the run time
adds to ``psi``). A whole run is checked against a case with a closed form (MODELS.md
section 3): a ball rolling without spin round a circle on a turntable, whose contact runs
over its chart's poles lap after lap.
"""
from __future__ import annotations

import dataclasses
import math

import casadi as ca
import numpy as np
import pytest
from scipy.spatial.transform import Rotation

import grasping_sym as gs
from grasping_sym.assemble import casadi_api
from grasping_sym.derive.bodies3d import surface_sx
from grasping_sym.errors import (
    ContactLeftContourError,
    FrictionConeError,
    IntegratorError,
    InvalidSceneError,
    InvalidSurfaceError,
    RunArgumentError,
)
from grasping_sym.geometry import surface_library as sl
from grasping_sym.geometry.atlas import manifest_entry
from grasping_sym.runtime import atlas as atlas_
from grasping_sym.runtime import batch as batch_
from grasping_sym.runtime import checks as checks_
from grasping_sym.runtime import fastpath
from grasping_sym.runtime import modes as modes_
from grasping_sym.runtime import outputs as outputs_
from grasping_sym.runtime import run as run_
from grasping_sym.viz.plots3d import contact_traces
from tests.scenes import BALL_R, pressed_ball

TURNED = Rotation.from_rotvec([0.3, -0.5, 0.7]).as_matrix()
SURFACES = {
    "sphere": lambda: sl.sphere(0.05, center=(0.01, 0.0, -0.02), rotation=TURNED, atlas=True),
    "ellipsoid": lambda: sl.ellipsoid(0.05, 0.035, 0.02, rotation=TURNED, atlas=True),
    "superquadric": lambda: sl.superquadric(0.04, 0.03, 0.05, n=4, center=(0.0, 0.02, 0.0), atlas=True),
}


def _chart(surface, chart: int):
    return surface if chart == 0 else surface.atlas.second


@pytest.mark.parametrize("name", sorted(SURFACES))
def test_a_point_at_a_charts_edge_maps_to_the_same_point_normal_and_turned_frame(name):
    """At random points near either chart's edge (|v| in [1.2, 1.3]) and on the longitude's
    seam: the run time's map gives the same point and normal in the other chart (SymPy's
    charts evaluated at both ends, 1e-15 m), the frame turned by exactly ``delta`` (the
    angle added to psi), and a latitude well inside the new chart."""
    surface = SURFACES[name]()
    entry = surface.atlas.manifest()
    rng = np.random.default_rng(7)
    for _ in range(40):
        chart = int(rng.integers(2))
        u, v = rng.uniform(-3 * math.pi, 3 * math.pi), rng.choice([-1, 1]) * rng.uniform(1.2, 1.3)
        new, u1, v1, delta = atlas_.transition(entry, chart, u, v)
        assert new == 1 - chart and abs(v1) < 0.38 and -math.pi <= u1 <= math.pi
        a, b = _chart(surface, chart).evaluate(u, v), _chart(surface, new).evaluate(u1, v1)
        assert np.abs(a["point"] - b["point"]).max() < 1e-15
        assert np.abs(a["normal"] - b["normal"]).max() < 1e-14
        turn = math.atan2(b["x"] @ a["y"], b["x"] @ a["x"])
        assert abs(math.remainder(turn - delta, 2 * math.pi)) < 1e-13
    # the seam: a longitude past the chart's +-3 pi wraps in the same chart, nothing turned
    assert atlas_.transition(entry, 0, 3 * math.pi + 0.01, 0.2) == pytest.approx((0, -math.pi + 0.01, 0.2, 0.0))


@pytest.mark.parametrize("name", sorted(SURFACES))
def test_the_blended_surface_is_each_chart_exactly(name):
    """The compiled model's one surface (both charts, the chart a parameter) is chart 0 at
    c = 0 and chart 1 at c = 1: point, frame and Montana's forms, to round-off."""
    surface = SURFACES[name]()
    u, v, c = ca.SX.sym("u"), ca.SX.sym("v"), ca.SX.sym("c")
    keys = ("S", "x", "y", "n", "M", "K", "T")
    both = surface_sx(surface, u, v, chart=c)
    f = ca.Function("f", [u, v, c], [both[k] for k in keys])
    for chart in (0, 1):
        one = surface_sx(_chart(surface, chart), u, v)
        g = ca.Function("g", [u, v], [one[k] for k in keys])
        for uv in ((0.3, -0.7), (-2.5, 1.25), (2.0, 0.1)):
            for got, want in zip(f(*uv, chart), g(*uv)):
                assert np.abs(np.array(got) - np.array(want)).max() <= 1e-15 * max(1.0, np.abs(np.array(want)).max())


def test_an_atlas_takes_no_domain_of_its_own():
    with pytest.raises(InvalidSurfaceError, match="lon and lat are the atlas's own"):
        sl.sphere(0.05, lat=(-1.0, 1.0), atlas=True)
    with pytest.raises(InvalidSurfaceError, match="atlas = 'yes' must be True or False"):
        sl.ellipsoid(0.05, 0.04, 0.03, atlas="yes")


# --------------------------------------------------------------- a whole run across charts
R, M, OMEGA, RC = 0.05, 0.1, 10.0, 0.1


def _lap_scene(pole_on_path: bool = True, surface=None, name: str = "lap_atlas"):
    """A ball rolling without spin (relative to the table) round a circle of radius ``RC``
    about a turntable's axis (MODELS.md section 3, in the table's frame); its chart's pole on
    the contact's path, which the contact therefore crosses every lap (else on the circle's
    axis ``a``: the contact stays at one latitude of ``surface``, by default the atlas).

    Closed form: the centre turns about the axis at 2 Omega / 7, ``c = Rz(2 Omega t / 7) c0``;
    the ball at ``R(t) = Rz(2 Omega t / 7) Rot(a, beta phi) R0`` with ``phi = 5 Omega t / 7``
    (the lap angle on the table), ``beta = sqrt(1 + (RC / R)^2)``, ``a`` the unit vector from
    the circle's centre to the ball's. After a lap on the table (``phi = 2 pi``) the ball has
    turned by ``2 pi beta`` about ``a``, as MODELS.md says."""
    a = np.array([RC, 0.0, R]) / math.hypot(RC, R)
    s = 0.5                      # the pole w: w . a = -R / |(RC, R)| (on the contact's circle)
    wx = -R * (1 + s) / RC
    w = np.array([wx, math.sqrt(1 - wx**2 - s**2), s])
    w = w if pole_on_path else a
    xb = np.cross([0.0, 1.0, 0.0] if abs(w[1]) < 0.9 else [1.0, 0.0, 0.0], w)
    xb /= np.linalg.norm(xb)
    R0 = np.column_stack([xb, np.cross(w, xb), w])
    c0 = np.array([RC, 0.0, R])
    v0 = 2 / 7 * OMEGA * np.cross([0.0, 0.0, 1.0], c0)
    om = np.array([5 * OMEGA * RC / (7 * R), 0.0, OMEGA])    # no spin relative to the table
    d = R0.T @ [0.0, 0.0, -1.0]
    surface = sl.sphere(R, atlas=True) if surface is None else surface
    scene = gs.scenes.body_on_plane(surface, mass=M, inertia=(0.4 * M * R * R,) * 3, plane_spin=OMEGA,
                                    position=tuple(c0), rotation=R0, velocity=tuple(v0),
                                    omega=tuple(R0.T @ om), support=(math.atan2(d[1], d[0]), math.asin(d[2])),
                                    name=name)
    return scene, a, R0, c0


@pytest.fixture(scope="module")
def lap_model():
    scene, a, R0, c0 = _lap_scene()
    return gs.build(scene), a, R0, c0


def test_a_ball_rolls_lap_after_lap_over_its_charts_poles(lap_model):
    """Five laps on the table: the contact runs 11 times round its circle on the ball,
    through chart 0's pole each time. Every row's pose is the closed form's (rotation 5e-9,
    centre 1e-10 m), at the lap times too (MODELS.md's lap case: turned by 2 pi beta about
    ``a``); each row's contact coordinates, read in the row's chart, are the ball's lowest
    point."""
    model, a, R0, c0 = lap_model
    lap = 14 * math.pi / (5 * OMEGA)
    t_eval = np.union1d(np.linspace(0.0, 5 * lap, 401), lap * np.arange(1, 6))
    res = model.simulate(5 * lap, t_eval=t_eval, rtol=1e-10, atol=1e-12)
    assert not res.events and set(res.modes) == {"rolling"}
    switches = res.chart_switches
    assert len(switches) >= 10 and res.stats["chart_switches"] == len(switches)
    # every change made inside the C loop (c/wrap.c): one segment; the same changes as the
    # loop stopped at each edge and Python's map (a library without c/wrap.c), each within a
    # step of its time (the loop chooses its first step after a change anew), the body's
    # states to 1e-9 (the contact's coordinates differ in rows between two such times)
    assert res.stats["segments"] == 1 and all(rec["in_loop"] for rec in switches)
    model.library.can_wrap = False
    try:
        by_python = model.simulate(5 * lap, t_eval=t_eval, rtol=1e-10, atol=1e-12)
    finally:
        model.library.can_wrap = True
    assert not any(rec["in_loop"] for rec in by_python.chart_switches)
    assert [(r["chart"], r["from"], r["to"]) for r in by_python.chart_switches] == \
        [(r["chart"], r["from"], r["to"]) for r in switches]
    assert max(abs(a["t"] - b["t"]) for a, b in zip(switches, by_python.chart_switches)) < 1e-3
    body = [k for k, n in enumerate(res.state_names) if n not in ("u", "v")]
    assert np.abs(by_python.x[:, body] - res.x[:, body]).max() < 1e-9
    assert {s["from"] for s in switches} == {0, 1} and set(res.charts["chart"]) == {0, 1}
    t = res.t
    beta = math.sqrt(1 + (RC / R) ** 2)
    Rz = Rotation.from_rotvec(np.outer(2 * OMEGA * t / 7, [0.0, 0.0, 1.0])).as_matrix()
    exact = Rz @ Rotation.from_rotvec(np.outer(beta * 5 * OMEGA * t / 7, a)).as_matrix() @ R0
    assert np.abs(res.object_rotations() - exact).max() < 5e-9
    assert np.abs(res.x[:, :3] - Rz @ c0).max() < 1e-10
    at_laps = np.isin(t, lap * np.arange(1, 6))
    turned = Rotation.from_rotvec(np.outer(2 * np.pi * beta * np.arange(1, 6), a)).as_matrix() @ R0
    assert np.abs(Rz[at_laps] @ turned - res.object_rotations()[at_laps]).max() < 5e-9
    # each row's (u, v) in its chart is the ball's point touching the table
    body = model.scene.surface
    lowest = np.einsum("nji,j->ni", res.object_rotations(), [0.0, 0.0, -R])
    for chart in (0, 1):
        rows = res.charts["chart"] == chart
        point = (body if chart == 0 else body.atlas.second).evaluate(res["u"][rows], res["v"][rows])["point"]
        assert np.abs(point - lowest[rows]).max() < 1e-9
    # the contact went over the pole of chart 0: the rows in chart 1 reach it
    d = body.atlas.second.evaluate(res["u"][res.charts["chart"] == 1], res["v"][res.charts["chart"] == 1])["point"] / R
    assert np.abs(d[:, 2]).max() > math.cos(0.05)


@pytest.mark.parametrize("method", ["radau", "dop853"])
def test_a_longitudes_wraps_are_made_in_the_loop(method, monkeypatch):
    """The lap ball with its pole on the circle's axis: the contact stays at one latitude and
    its longitude runs on, a turn every 0.39 s. Each time it reaches +-3 pi the C loop wraps it
    a turn back at the step (``c/wrap.c``) and goes on: one loop for the whole run, the same
    steps as on one chart whose longitude never ends (+-100 rad), and the same rows to 1e-11
    (the longitude's modulo 2 pi). Each wrap is recorded as a switch within chart 0, at a
    step's start, a turn back: ``remainder(u, 2 pi)``."""
    real_short = modes_.short_way
    steady = gs.build(_lap_scene(False, name="lap_steady")[0])
    once = gs.build(_lap_scene(False, sl.sphere(R, lon=(-100.0, 100.0)), name="lap_one_chart")[0])
    kw = dict(t_eval=np.linspace(0.0, 2.0, 101), rtol=1e-10, atol=1e-12, method=method, outputs=False)
    res, ref = steady.simulate(2.0, **kw), once.simulate(2.0, **kw)
    assert res.stats["segments"] == 1 and res.stats["n_steps"] == ref.stats["n_steps"]
    iu = res.state_names.index("u")
    gap = res.x - ref.x
    gap[:, iu] = np.remainder(gap[:, iu] + math.pi, 2 * math.pi) - math.pi
    assert np.abs(gap).max() < 1e-11 and np.abs(res.x[:, iu]).max() < 3 * math.pi
    assert np.abs(ref.x[:, iu]).max() > 10 * math.pi      # (the one chart's ran on)
    # from (-pi, pi], a wrap at 3 pi, 5 pi, ... of the one chart's longitude (it runs one way)
    assert len(res.chart_switches) == int((np.abs(ref.x[:, iu]).max() - math.pi) // (2 * math.pi)) == 4
    assert not res.events
    for rec in res.chart_switches:
        assert (rec["chart"], rec["from"], rec["to"], rec["delta"]) == ("chart", 0, 0, 0.0)
        assert 3 * math.pi - 0.2 < abs(rec["u"][0]) < 3 * math.pi
        assert rec["u"][1] == pytest.approx(math.remainder(rec["u"][0], 2 * math.pi), abs=1e-15)
        assert rec["v"][0] == rec["v"][1] and 0.0 < rec["t"] < 2.0
    # a run that only wraps is remembered for the short way (runtime.modes), which wraps alike
    short = []
    monkeypatch.setattr(modes_, "short_way", lambda *a: short.append(real_short(*a)) or short[-1])
    again = steady.simulate(2.0, **kw)
    assert short and short[0] is again
    assert np.array_equal(again.x, res.x) and again.chart_switches == res.chart_switches


# --------------------------------------------------------------- a grasp across charts
#: pivot3d's object as a rounded box (its contact runs 0.4 rad over it in 2 s, and 0.9 rad over
#: the fingertip): the same shape twice, the second turned by -90 degrees about y with its
#: semi-axes permuted, so that its chart-0 pole lies on -x, where the contact goes
BOX = (0.020, 0.025, 0.030)
TURN_Y = np.array([[0.0, 0.0, -1.0], [0.0, 1.0, 0.0], [1.0, 0.0, 0.0]])


def test_a_batch_of_bodies_carries_each_runs_charts(lap_model):
    """simulate_many of a body on a plane runs run by run (its modes): each run's charts, as
    simulate gives them, with its switches."""
    model = lap_model[0]
    t_eval = np.linspace(0.0, 0.5, 51)
    one = model.simulate(0.5, t_eval=t_eval, rtol=1e-10, atol=1e-12)
    batch = model.simulate_many(0.5, x0=np.stack([model.initial_state()] * 2), t_eval=t_eval,
                                rtol=1e-10, atol=1e-12)
    assert one.chart_switches and (batch.status == 0).all()
    for charts, x in zip(batch.charts, batch.x):
        assert np.array_equal(charts["chart"], one.charts["chart"]) and np.array_equal(x, one.x)
    # the runs on two threads (runtime.pool) and on one: the same, bit for bit
    ones = [model.simulate_many(0.5, x0=np.stack([model.initial_state()] * 2), t_eval=t_eval, threads=k,
                                rtol=1e-10, atol=1e-12) for k in (1, 2)]
    assert np.array_equal(ones[0].x, ones[1].x) and np.array_equal(ones[1].x[0], one.x)


def _pivot(name: str, tip, box, guesses=None):
    """pivot3d with the fingertip ``tip`` and the object ``box``; ``guesses``: the state whose
    contact coordinates are the start's guesses."""
    finger = gs.scenes.pivot3d().fingers[0]
    finger = dataclasses.replace(finger, tip=tip)
    if guesses is not None:
        x, names = guesses
        finger = dataclasses.replace(finger, tip_contact=tuple(x[names.index(f"{c}_f1")] for c in "uv"),
                                     object_contact=tuple(x[names.index(f"{c}_o1")] for c in "uv"))
    return gs.scenes.pivot3d(name=name, fingers=(finger,), object_surface=box)


def _pole_ahead(start: np.ndarray, toward, angle: float) -> np.ndarray:
    """A rotation whose z axis (the chart's pole) lies ``angle`` rad from ``start`` toward
    ``toward``."""
    axis = np.cross(start, toward)
    w = Rotation.from_rotvec(angle * axis / np.linalg.norm(axis)).apply(start)
    x = np.cross([0.0, 0.0, 1.0], w)
    x /= np.linalg.norm(x)
    return np.column_stack([x, np.cross(w, x), w])


def _in_chart(state, names, side, old, new, turn):
    """``state`` with the contact on ``side`` (``"f"``, ``"o"``) carried from the surface
    ``old`` to ``new`` (the same shape, written in another chart, turned by ``turn``): its
    point's coordinates in ``new`` (a radial surface: the direction ``S / |S|``) and psi turned
    by the angle between the charts' frames (docs/conventions.md section 15), by the surfaces'
    own SymPy geometry."""
    iu, iv, ip = names.index(f"u_{side}1"), names.index(f"v_{side}1"), names.index("psi1")
    g0 = old.evaluate(state[iu], state[iv])
    e = turn.T @ (g0["point"] / np.linalg.norm(g0["point"]))
    u, v = math.atan2(e[1], e[0]), math.asin(e[2])
    g1 = new.evaluate(u, v)
    assert np.abs(g1["point"] - g0["point"]).max() < 1e-16
    out = state.copy()
    out[iu], out[iv], out[ip] = u, v, state[ip] + math.atan2(g1["x"] @ g0["y"], g1["x"] @ g0["x"])
    return out


@pytest.fixture(scope="module")
def pivot_grasps():
    """pivot3d on one-chart surfaces, and on atlases whose chart-0 poles lie on the contact's
    paths (the fingertip's: a sphere turned; the box's: turned with its axes permuted, the
    blend of two charts), and the same physical start in each."""
    tip = sl.sphere(0.01, name="fingertip", lon=(-3 * math.pi, 3 * math.pi))
    box = sl.superquadric(*BOX, n=4, name="box", lon=(-3 * math.pi, 3 * math.pi))
    ref = gs.build(_pivot("pivot_one_chart", tip, box))
    names, x0 = ref.state_names, ref.initial_state()
    start = tip.evaluate(x0[names.index("u_f1")], x0[names.index("v_f1")])["point"] / 0.01
    Rt = _pole_ahead(start, [0.0, -1.0, 0.0], 0.3)
    atip = sl.sphere(0.01, rotation=Rt, atlas=True, name="fingertip")
    abox = sl.superquadric(BOX[2], BOX[1], BOX[0], n=4, rotation=TURN_Y, atlas=True, name="box")
    xa = _in_chart(_in_chart(x0, names, "f", tip, atip, Rt), names, "o", box, abox, TURN_Y)
    model = gs.build(_pivot("pivot_atlases", atip, abox, (xa, names)))
    return {"ref": ref, "model": model, "x0": x0, "xa": xa, "tip": tip, "atip": atip, "box": box,
            "abox": abox}


def test_a_grasp_runs_on_across_its_fingertips_and_objects_charts(pivot_grasps):
    """The same grasp twice: with one-chart surfaces whose poles are far from the contact,
    and with atlases whose chart-0 poles lie on its paths over the fingertip and over the
    box, started at the same physical state. The run with atlases switches chart on both
    sides (psi turned for a fingertip's chart and for an object's, the box's charts a blend);
    every other state agrees with the one-chart run to 1e-9 over 1.5 s, and each row's
    contact point, read in its chart, to 1e-12 m."""
    g = pivot_grasps
    ref, model, x0, xa = g["ref"], g["model"], g["x0"], g["xa"]
    names = ref.state_names
    assert model.p_names == ("chart_f1", "chart_o1")
    kw = dict(rtol=1e-10, atol=1e-12, t_eval=np.linspace(0.0, 1.5, 301))
    ra, rr = model.simulate(1.5, x0=xa, **kw), ref.simulate(1.5, x0=x0, **kw)
    assert {s["chart"] for s in ra.chart_switches} == {"chart_f1", "chart_o1"}
    assert all(s["in_loop"] for s in ra.chart_switches)      # changed in the C loop (c/wrap.c)
    assert set(ra.charts["chart_f1"]) == {0, 1} and set(ra.charts["chart_o1"]) == {0, 1}
    body = [k for k, n in enumerate(names) if not n.startswith(("u_", "v_", "psi"))]
    assert np.abs(ra.x[:, body] - rr.x[:, body]).max() < 1e-9
    for side, one, atlas in (("f", g["tip"], g["atip"]), ("o", g["box"], g["abox"])):
        want = one.evaluate(rr[f"u_{side}1"], rr[f"v_{side}1"])["point"]
        got = atlas.evaluate(ra[f"u_{side}1"], ra[f"v_{side}1"], chart=ra.charts[f"chart_{side}1"])["point"]
        assert np.abs(got - want).max() < 1e-12


def test_a_failed_run_reads_each_row_in_the_charts_it_was_written_in(pivot_grasps, monkeypatch):
    """A plain grasp run stopped by ``max_steps`` after its loop changed both charts: the
    failure's check for an earlier event (``checks.raise_earlier_event``) reads each row of the
    failed loop in its own charts (before a change, the chart it changed from): every row's
    relative curvature equals the row read alone in the charts the records give it. The error
    names the charts its state is written in (``err.charts``, and its message): those the
    changes left, in which its contact points are the one-chart run's at its time."""
    model, xa = pivot_grasps["model"], pivot_grasps["xa"]
    kw = dict(rtol=1e-10, atol=1e-12, t_eval=np.linspace(0.0, 1.5, 301))
    full = model.simulate(1.5, x0=xa, **kw)
    seen = {}
    real = checks_._at_rows_in_charts

    def spy(m, t, X, p, changes):
        seen.update(t=t, X=X, p=p, out=real(m, t, X, p, changes))
        return seen["out"]
    monkeypatch.setattr(checks_, "_at_rows_in_charts", spy)
    with pytest.raises(IntegratorError, match="too many steps") as info:
        model.simulate(1.5, x0=xa, max_steps=int(0.9 * full.stats["n_steps"]), **kw)
    t, X = seen["t"], seen["X"]
    changes = [rec for rec in full.chart_switches if rec["from"] != rec["to"]]
    assert len(changes) == 2 and t[-1] > changes[-1]["t"]
    err, left = info.value, {rec["chart"]: rec["to"] for rec in changes}
    assert err.charts == left and err.t > changes[-1]["t"]
    assert str(err).endswith(f"in charts chart_f1 = {left['chart_f1']}, chart_o1 = {left['chart_o1']}")
    g = pivot_grasps
    there = g["ref"].simulate(err.t, x0=g["x0"], rtol=1e-10, atol=1e-12, t_eval=[0.0, err.t])
    for side, one, atlas in (("f", g["tip"], g["atip"]), ("o", g["box"], g["abox"])):
        names = model.state_names
        got = atlas.evaluate(err.x[names.index(f"u_{side}1")], err.x[names.index(f"v_{side}1")],
                             chart=err.charts[f"chart_{side}1"])["point"]
        want = one.evaluate(there[f"u_{side}1"][-1], there[f"v_{side}1"][-1])["point"]
        assert np.abs(got - want).max() < 1e-11
    rows_p = np.tile(seen["p"], (len(t), 1))
    for rec in changes:
        rows_p[t > rec["t"], model.p_names.index(rec["chart"])] = rec["to"]
    alone = [outputs_.at_rows(model, X[i:i + 1], rows_p[i])["krel_min1"][0] for i in range(len(t))]
    assert np.array_equal(seen["out"]["krel_min1"], alone)


def test_what_does_not_take_an_atlas_yet_says_so():
    """The paper's formulation refuses surfaces with atlases by name (it has no frame angle
    psi to carry across charts)."""
    tip = sl.sphere(0.01, atlas=True, name="fingertip 1")
    base = gs.scenes.paper3d()
    fingers = (dataclasses.replace(base.fingers[0], tip=tip), base.fingers[1])
    with pytest.raises(InvalidSceneError, match="formulation='regular'"):
        gs.scenes.paper3d(fingers=fingers, formulation="paper")


@pytest.fixture(scope="module")
def pivot_modes(pivot_grasps):
    """The grasps of ``pivot_grasps`` with contact modes: on the atlases, and on the
    one-chart surfaces."""
    g = pivot_grasps
    return {"atlas": gs.build(gs.scenes.with_modes(g["model"].scene)),
            "one": gs.build(gs.scenes.with_modes(g["ref"].scene))}


def test_a_grasp_with_modes_rolls_and_slides_across_its_charts(pivot_grasps, pivot_modes, monkeypatch):
    """A grasp with contact modes on atlases (pivot3d's one finger: its contact numbered too),
    from the same physical start as on one chart:
    - no friction limit: it rolls across both surfaces' charts as the rolling model does
      (every other state to 1e-9 over 1.5 s, the contact points to 1e-12 m);
    - mu = 0.1: it slides from the start, across the fingertip's and the object's chart
      switches, its slip turning (re-aimed: ``REAIM_ANGLE``), and sticks when the one-chart
      grasp with modes sticks (to 1e-7 s: a stop is taken below ``STOP_SPEED``), its states
      within 1e-8 of that run's, its contact points within 1e-11 m (re-aimed at 90 degrees,
      the blend of the slide's direction kicked the speeds by ~3e-7); the slide's changes of
      chart are made in the C loop, its slip turned there with the fingertip's frame: the run
      Python's changes make (states to 1e-9, the stick to 1e-10 s), less a segment each;
    - a sliding contact's slip direction, kept in its fingertip's frame, turns with it at a
      switch of the fingertip's chart: the same direction as the slip velocity's there."""
    g, model, one = pivot_grasps, pivot_modes["atlas"], pivot_modes["one"]
    ref, x0, xa = g["ref"], g["x0"], g["xa"]
    names = ref.state_names
    assert model.p_names[-2:] == ("chart_f1", "chart_o1") and model.rolling is None
    body = [k for k, n in enumerate(names) if not n.startswith(("u_", "v_", "psi"))]
    kw = dict(rtol=1e-10, atol=1e-12, t_eval=np.linspace(0.0, 1.5, 301))

    def points_apart(ra, rr):
        return max(np.abs(atlas.evaluate(ra[f"u_{side}1"], ra[f"v_{side}1"], chart=ra.charts[f"chart_{side}1"])["point"]
                          - plain.evaluate(rr[f"u_{side}1"], rr[f"v_{side}1"])["point"]).max()
                   for side, plain, atlas in (("f", g["tip"], g["atip"]), ("o", g["box"], g["abox"])))

    ra, rr = model.simulate(1.5, x0=xa, **kw), ref.simulate(1.5, x0=x0, **kw)
    assert {s["chart"] for s in ra.chart_switches} == {"chart_f1", "chart_o1"} and not ra.events
    assert np.abs(ra.x[:, body] - rr.x[:, body]).max() < 1e-9 and points_apart(ra, rr) < 1e-12

    ra, r1 = model.simulate(1.5, x0=xa, mu=0.1, **kw), one.simulate(1.5, x0=x0, mu=0.1, **kw)
    stick = [e for e in ra.events if e["to"] == "rolling"]
    assert ra.modes[0] == "sliding" and len(stick) == 1 and len(ra.events) == len(r1.events) == 1
    assert {s["chart"] for s in ra.chart_switches if s["t"] < stick[0]["t"]} == {"chart_f1", "chart_o1"}
    # the slide's changes of chart are made in the C loop (c/wrap.c), its slip turned there with
    # the fingertip's frame: the run Python's changes make, less the segment each one cut
    assert ra.chart_switches and all(s["in_loop"] for s in ra.chart_switches)
    monkeypatch.setattr(model.library, "can_wrap", False)
    rp = model.simulate(1.5, x0=xa, mu=0.1, **kw)
    monkeypatch.undo()
    assert [(s["chart"], s["from"], s["to"], s["in_loop"]) for s in rp.chart_switches] == \
        [(s["chart"], s["from"], s["to"], False) for s in ra.chart_switches]
    assert ra.stats["segments"] == rp.stats["segments"] - len(rp.chart_switches)
    assert np.abs(ra.x - rp.x).max() < 1e-9 and abs(ra.events[0]["t"] - rp.events[0]["t"]) < 1e-10
    assert abs(stick[0]["t"] - r1.events[0]["t"]) < 1e-7
    assert np.abs(ra.x[:, body] - r1.x[:, body]).max() < 1e-8 and points_apart(ra, r1) < 1e-11

    row = int(np.searchsorted(ra.t, 0.5))
    charts = {k: int(v[row]) for k, v in ra.charts.items()}
    assert charts == {"chart_f1": 1, "chart_o1": 1}
    with pytest.raises(RunArgumentError, match=r"off the fingers' contact constraints.*give them"):
        model.simulate(0.1, x0=ra.x[row], mu=0.1)
    on = model.simulate(0.1, x0=ra.x[row], mu=0.1, params=charts, t_eval=ra.t[row:row + 21] - ra.t[row],
                        rtol=1e-10, atol=1e-12)
    assert np.abs(on.x[:, body] - ra.x[row:row + 21, body]).max() < 1e-8

    sliding = model.default_params.copy()
    sliding[[model.p_names.index(k) for k in ("mode1", "mu1")]] = (1.0, 0.1)
    cols = [model.columns.index(k) for k in ("vt_x1", "vt_y1")]
    x = ra.x[np.searchsorted(ra.t, 0.01)]
    atlases = atlas_.Atlases(model)
    k = next(i for i, (entry, _, _) in enumerate(atlases.slots) if entry["param"] == "chart_f1")
    x1, p1, record = atlases.switch(k, 0.01, x, sliding)
    v0, v1 = model.library.outputs(x, sliding)[cols], model.library.outputs(x1, p1)[cols]
    assert abs(record["delta"]) > 1.0
    (turned,) = modes_._slip_across(atlases.slots[k][0], record, [modes_.SLIDING], [v0 / np.linalg.norm(v0)])
    assert np.abs(turned - v1 / np.linalg.norm(v1)).max() < 1e-12


def test_an_error_is_named_with_the_changes_made_by_its_time_only(pivot_grasps):
    """``_Charted.name``: the charts of an error at ``t`` are those the changes up to ``t``
    left, not those of a later change (a located event can come before the last change of
    the loop that found it); a model without atlases, and an error already named, are left
    as they are."""
    model = pivot_grasps["model"]
    charted = run_._Charted(model)
    x = np.asarray(pivot_grasps["xa"], dtype=float)
    p = model.default_params.copy()
    p[list(model.p_names).index("chart_f1")] = 0.0
    p[list(model.p_names).index("chart_o1")] = 0.0
    charted.switches = [{"t": 0.2, "chart": "chart_f1", "from": 0, "to": 1},
                        {"t": 0.5, "chart": "chart_o1", "from": 0, "to": 1}]
    for t, want in ((0.1, {"chart_f1": 0, "chart_o1": 0}), (0.2, {"chart_f1": 1, "chart_o1": 0}),
                    (0.3, {"chart_f1": 1, "chart_o1": 0}), (0.6, {"chart_f1": 1, "chart_o1": 1})):
        err = IntegratorError(t, x, "too many steps", model.state_names)
        charted.name(err, p)
        assert err.charts == want and str(err).endswith(
            f"in charts chart_f1 = {want['chart_f1']}, chart_o1 = {want['chart_o1']}")
        before = str(err)
        charted.name(err, p)  # once
        assert str(err) == before
    plain = IntegratorError(0.3, x, "too many steps", model.state_names)
    run_._Charted(pivot_grasps["ref"]).name(plain, pivot_grasps["ref"].default_params)
    assert not hasattr(plain, "charts") and "in charts" not in str(plain)


def test_a_failed_run_with_modes_names_the_charts_its_loop_left(pivot_grasps, pivot_modes):
    """The grasp with modes rolling (no friction limit: one segment, the charts' changes made
    in its C loop, the run's own charts unchanged) and sliding (mu = 0.1, a segment per
    re-aim) across both charts' changes, stopped by ``max_steps`` after them: the error
    names the charts its state is in (``err.charts`` and its message), those the whole run's
    changes left by then."""
    model, xa = pivot_modes["atlas"], pivot_grasps["xa"]
    for mu in (None, 0.1):
        kw = dict(mu=mu, rtol=1e-10, atol=1e-12, t_eval=np.linspace(0.0, 1.5, 301))
        full = model.simulate(1.5, x0=xa, **kw)
        changes = [rec for rec in full.chart_switches if rec["from"] != rec["to"]]
        assert len(changes) == 2 and all(rec["in_loop"] for rec in changes)
        assert mu is not None or full.stats["segments"] == 1
        with pytest.raises(IntegratorError, match="too many steps") as info:
            model.simulate(1.5, x0=xa, max_steps=int(0.9 * full.stats["n_steps"]), **kw)
        err = info.value
        left = {rec["chart"]: rec["to"] for rec in changes if rec["t"] <= err.t}
        assert err.t > changes[-1]["t"] and err.charts == left
        assert str(err).endswith(f"in charts chart_f1 = {left['chart_f1']}, chart_o1 = {left['chart_o1']}")


def test_a_grasp_that_changes_chart_in_the_loop_then_slips_slips_as_on_one_chart(pivot_grasps, pivot_modes):
    """The grasp with modes of mu = 0.473, just under its cone ratio's peak (0.4745 at 23 ms):
    it rolls, its fingertip's chart changes inside the C loop (15 ms: ``c/wrap.c``), and in
    the same segment the contact starts to slip (18 ms), then sticks (32 ms). The events,
    located from the segment's last step in the new chart, are the one-chart grasp's: the
    slip's to 1e-9 s, the stick's to 1e-7 s (a stop is taken below ``STOP_SPEED``)."""
    g, model, one = pivot_grasps, pivot_modes["atlas"], pivot_modes["one"]
    kw = dict(mu=0.473, rtol=1e-10, atol=1e-12, t_eval=np.linspace(0.0, 0.05, 11))
    ra, r1 = model.simulate(0.05, x0=g["xa"], **kw), one.simulate(0.05, x0=g["x0"], **kw)
    change = ra.chart_switches[0]
    assert change["in_loop"] and change["chart"] == "chart_f1" and change["from"] != change["to"]
    assert [(e["from"], e["to"]) for e in ra.events] == [(e["from"], e["to"]) for e in r1.events] == \
        [("rolling", "sliding"), ("sliding", "rolling")]
    assert change["t"] < ra.events[0]["t"]
    assert abs(ra.events[0]["t"] - r1.events[0]["t"]) < 1e-9 and abs(ra.events[1]["t"] - r1.events[1]["t"]) < 1e-7


def test_a_slide_in_its_onset_leaves_its_segments_changes_of_chart_to_python(pivot_modes):
    """The slots a segment's C loop takes (``modes._wrap_slots``): where the fingertip's contact
    slides, its chart changes in the loop with the slip's index in ``p`` and its witness's in
    the watch (the turn, ``c/wrap.c``); the object's chart changes with nothing to turn. A
    slide in its onset (``slip_levels``: its stop may be looked for at the slip's last zero,
    among the segment's rows and from its start, which must be in one set of charts) leaves
    every change of the segment to Python: wraps only."""
    from types import SimpleNamespace

    model = pivot_modes["atlas"]
    atlases = atlas_.Atlases(model)
    run = modes_._new_run(model, None, [0.1], 0.0)
    p = run.params([modes_.SLIDING], [np.array([0.6, 0.8, 0.0])])
    watched = run.witnesses([modes_.SLIDING], [np.array([0.6, 0.8, 0.0])])
    w = next(i for i, (name, j, _) in enumerate(watched) if name == "slip" and j == 1)
    r = SimpleNamespace(atlases=atlases, slip_levels={}, i_mode=run.i_mode, i_slip=run.i_slip,
                        slip_keys=run.slip_keys)
    slots = modes_._wrap_slots(r, p, watched)
    tip, obj = (next(k for k, (entry, _, _) in enumerate(atlases.slots) if entry["param"] == c)
                for c in ("chart_f1", "chart_o1"))
    assert slots[tip, 13] == 1 and (slots[tip, 14], slots[tip, 15]) == (model.p_names.index("slip_x1"), w)
    assert slots[obj, 13] == 1 and (slots[obj, 14], slots[obj, 15]) == (-1, -1)
    assert modes_._wrap_slots(SimpleNamespace(**{**vars(r), "slip_levels": {1: 1e-6}}), p, watched) is \
        atlases.wrap_only
    assert not atlases.wrap_only[:, 13].any()
    rolling = run.params([modes_.ROLLING], [None])
    assert modes_._wrap_slots(r, rolling, run.witnesses([modes_.ROLLING], [None])) is atlases.wrap_slots


def test_a_switching_run_draws_saves_and_refuses_what_cannot_follow_it(pivot_grasps, tmp_path):
    """After a switch: the contacts' traces (each row read in its chart) run on without a
    jump; a saved result keeps each row's charts; rk4 (one uniform grid) refuses by name;
    simulate_many runs each run by simulate's code (the batch's C loops do not switch): the
    same rows, outputs and charts, and a run it refuses recorded beside them; a run that
    reaches no edge carries its charts (chart 0) on the short way too."""
    model, xa = pivot_grasps["model"], pivot_grasps["xa"]
    res = model.simulate(0.3, x0=xa, rtol=1e-10, atol=1e-12, t_eval=np.linspace(0.0, 0.3, 301))
    assert res.chart_switches
    for trace in contact_traces(model.scene, res):
        for points in (trace.object_points, trace.tip_points):
            assert np.linalg.norm(np.diff(points, axis=0), axis=1).max() < 1e-3
    back = gs.SimulationResult.load(res.save(tmp_path / "run.npz"))
    assert all(np.array_equal(back.charts[k], v) for k, v in res.charts.items()) and back.charts
    with pytest.raises(ContactLeftContourError, match="switches chart at the step, which rk4"):
        model.simulate(0.3, x0=xa, method="rk4", h=1e-4, t_eval=np.linspace(0.0, 0.3, 31))
    off = xa.copy()
    off[model.state_names.index("q11")] += 1e-6                    # off the contact constraints
    batch = model.simulate_many(0.3, x0=np.stack([xa, off]), rtol=1e-10, atol=1e-12,
                                t_eval=np.linspace(0.0, 0.3, 301), outputs=True)
    assert batch.status.tolist() == [0, batch_.REFUSED]
    assert batch.errors[1].startswith("InconsistentInitialStateError") and batch.charts[1] is None
    assert np.array_equal(batch.x[0], res.x) and np.isnan(batch.x[1]).all()
    assert all(np.array_equal(batch.charts[0][k], v) for k, v in res.charts.items())
    assert batch.outputs and all(np.array_equal(batch.outputs[k][0], v) for k, v in res.outputs.items())
    assert batch.stats["chart_switches"][0] == len(res.chart_switches) > 0 and batch.stats["n_steps"][1] == 0
    # a friction limit: stop at the cone (an event, simulate's message) or record it, as simulate does
    grid = dict(rtol=1e-10, atol=1e-12, t_eval=np.linspace(0.0, 0.3, 301))
    with pytest.raises(FrictionConeError) as err:
        model.simulate(0.3, x0=xa, mu=0.01, **grid)
    stopped = model.simulate_many(0.3, x0=np.stack([xa]), mu=0.01, **grid)
    assert stopped.status.tolist() == [batch_.EVENT] and stopped.errors[0] == f"FrictionConeError: {err.value}"
    kept = model.simulate_many(0.3, x0=np.stack([xa]), mu=0.01, slip="record", outputs=True, **grid)
    assert kept.status.tolist() == [0] and kept.outputs["cone_margin1"][0].min() < 0
    # the batch's wall-time limit is the whole call's
    late = model.simulate_many(0.3, x0=np.stack([xa, xa]), time_limit=1e-9, **grid)
    assert (late.status == -9).all() and "the batch's wall-time limit" in late.errors[1]
    early = dict(x0=xa, rtol=1e-8, atol=1e-10, t_eval=np.linspace(0.0, 0.01, 11), outputs=False)
    for _ in range(2):  # the second call takes the short way
        quiet = model.simulate(0.01, **early)
        assert not quiet.chart_switches and set(quiet.charts) == {"chart_f1", "chart_o1"}
        assert all((v == 0).all() for v in quiet.charts.values())


def test_the_casadi_functions_of_a_grasp_on_atlases_take_its_charts(pivot_grasps):
    """``casadi_function`` of a grasp on atlases: ``p`` ends with its charts (it failed on an
    internal assertion): the ode at a row of a switching run, in that row's charts, is the
    compiled rhs there, to the two evaluations' rounding (CasADi's virtual machine against the
    generated C, through the closed loop's solve: measured over 51 rows a median of 2e-13 and
    at most 1.7e-12 of the largest component, as for the one-chart grasp, 1.4e-12; the wrong
    chart differs by ~600). ``squeeze`` of an object with an atlas takes the object's chart at
    each contact: two contacts at opposite points of an ellipsoid's equator, written in
    either chart, give the closed form of the plain one's test (``test_quality``)."""
    model = pivot_grasps["model"]
    fn = model.casadi_function()
    res = model.simulate(0.5, x0=pivot_grasps["xa"], rtol=1e-10, atol=1e-12, t_eval=np.linspace(0.0, 0.5, 11))
    charts = np.column_stack([res.charts[k] for k in ("chart_f1", "chart_o1")])
    assert {tuple(c) for c in charts} >= {(0, 0), (1, 0), (1, 1)}
    for x, c in zip(res.x, charts):
        p = c.astype(float)
        want = model.rhs(x, p)
        assert np.abs(np.asarray(fn(x, [], p)).ravel() - want).max() <= 1e-11 * np.abs(want).max()
    assert np.abs(np.asarray(fn(res.x[-1], [], 1.0 - charts[-1])).ravel() - want).max() > 1.0   # the other

    a, b, c = 0.020, 0.025, 0.030
    scene = gs.scenes.paper3d(object_surface=sl.ellipsoid(a, b, c, atlas=True, name="atlas ellipsoid"))
    names = list(scene.state_names)
    squeeze = casadi_api._squeeze(scene, ca.SX.sym("x", len(names)))
    assert squeeze.name_in() == ["x", "mu", "chart"]
    mu = np.array([0.3, 1.2])
    turn = np.array([0.9, 0.2, -0.3, 0.4]) * 1.1
    for u in (0.4, 1.1, 2.5):
        exact = 1.0 / (math.hypot(a * math.cos(u), b * math.sin(u)) * math.hypot(math.cos(u) / a, math.sin(u) / b))
        for chart in ((0, 0), (1, 1), (0, 1), (1, 0)):
            x = np.zeros(len(names))
            coords = [atlas_.coordinates((math.cos(w), math.sin(w), 0.0), c) for w, c in zip((u, u + math.pi), chart)]
            for k, v in zip(("x", "y", "z", "qw", "qx", "qy", "qz", "u_o1", "v_o1", "u_o2", "v_o2"),
                            (0.01, -0.02, 0.03, *turn, *coords[0], *coords[1])):
                x[names.index(k)] = v
            got = np.asarray(squeeze(x, mu, list(chart))).ravel()
            np.testing.assert_allclose(got, exact - 1.0 / np.sqrt(1.0 + mu ** 2), rtol=0, atol=1e-14)


def test_a_ball_on_a_table_with_its_support_at_chart_0s_pole_starts_in_chart_1():
    """A ball with ``atlas=True`` on a table below it, placed as the library places it: its
    support point is chart 0's pole (it failed with a NaN support point). The start is solved
    in chart 1 (the model's ``chart`` at the start is 1). Launched rolling, it rolls on in a
    straight line at its speed (the centre to 1e-10 m over 1.5 turns), its contact switching
    chart six times, each row's contact point, read in its chart, the lowest point of the ball
    (1e-10 m); a run that reaches no chart's edge reports chart 1, the short way too. Its
    start read in chart 0 (another point of the ball, not facing the table) is refused."""
    R_, M_, V_ = 0.05, 0.1, 0.3
    ball = sl.sphere(R_, atlas=True)
    model = gs.build(gs.scenes.body_on_plane(ball, mass=M_, inertia=(0.4 * M_ * R_ * R_,) * 3,
                                             velocity=(V_, 0.0, 0.0), omega=(0.0, V_ / R_, 0.0),
                                             name="ball_at_the_pole"))
    assert model.default_params[model.p_names.index("chart")] == 1.0
    x0 = model.initial_state()
    t_end = 1.5 * 2 * math.pi * R_ / V_
    res = model.simulate(t_end, rtol=1e-10, atol=1e-12, t_eval=np.linspace(0.0, t_end, 301))
    assert len(res.chart_switches) == 6 and res.charts["chart"][0] == 1 and not res.events
    assert np.abs(res.x[:, 0] - (x0[0] + V_ * res.t)).max() < 1e-10
    assert np.abs(res.x[:, 1:3] - x0[1:3]).max() < 1e-10
    point = ball.evaluate(res["u"], res["v"], chart=res.charts["chart"])["point"]
    q = res.x[:, 3:7]
    turn = Rotation.from_quat(np.column_stack([q[:, 1:], q[:, :1]])).as_matrix()
    world = res.x[:, :3] + np.einsum("nij,nj->ni", turn, point)
    assert np.abs(world - res.x[:, :3] + [0.0, 0.0, R_]).max() < 1e-10
    short = [model.simulate(0.05, rtol=1e-10, atol=1e-12, t_eval=[0.0, 0.05]) for _ in range(2)]
    assert model.run_cache.get("modes_short")                  # the short way kept a plan
    assert all(not r.chart_switches and set(r.charts["chart"]) == {1} for r in short)
    # the start's (u, v) read in the other chart is another point of the ball: refused by name
    with pytest.raises(RunArgumentError, match=r"does not face the plane.*give it, params=\{'chart'"):
        model.simulate(0.05, x0=x0, params={"chart": 0})


def test_a_run_goes_on_from_a_row_in_its_own_charts(pivot_grasps, lap_model):
    """``x0`` from a row of a run after a switch is written in that row's charts: ``params``
    names them (a chart is 0 or 1, else a named error), and the run from it is the run's own
    continuation: a grasp (plain run) and a ball on a turntable (a run with modes), and
    ``simulate_many`` of the grasp with each run's charts."""
    model, xa = pivot_grasps["model"], pivot_grasps["xa"]
    kw = dict(rtol=1e-10, atol=1e-12)
    whole = model.simulate(0.6, x0=xa, t_eval=np.linspace(0.0, 0.6, 61), **kw)
    i = 30
    charts = {k: int(v[i]) for k, v in whole.charts.items()}
    assert charts != {k: 0 for k in charts}          # a row after a switch
    on = model.simulate(0.3, x0=whole.x[i], params=charts, t_eval=np.linspace(0.0, 0.3, 31), **kw)
    body = [k for k, n in enumerate(model.state_names) if not n.startswith(("u_", "v_", "psi"))]
    assert np.abs(on.x[:, body] - whole.x[i:, body]).max() < 1e-8
    batch = model.simulate_many(0.3, x0=np.stack([whole.x[i]] * 2), params=charts, **kw)
    assert (batch.status == 0).all() and np.abs(batch.x_final[:, body] - whole.x[-1, body]).max() < 1e-8
    with pytest.raises(RunArgumentError, match="a chart is 0 or 1"):
        model.simulate(0.3, x0=whole.x[i], params={"chart_f1": 0.5})
    ball = lap_model[0]
    whole = ball.simulate(0.8, t_eval=np.linspace(0.0, 0.8, 81), **kw)
    i = int(np.flatnonzero(whole.charts["chart"] != whole.charts["chart"][0])[0]) + 2
    on = ball.simulate(0.8 - whole.t[i], x0=whole.x[i], params={"chart": int(whole.charts["chart"][i])},
                       t_eval=whole.t[i:] - whole.t[i], **kw)
    assert np.abs(on.x[:, :13] - whole.x[i:, :13]).max() < 1e-8


def _turntable_balls(start=None):
    """test_grasp_modes.py's ball pressed by one finger onto a turntable spinning up
    (``w(t) = 2 t`` about the vertical through ``w0``), on one chart (that file's build) and as
    a sphere's atlas whose chart-0 poles lie 0.3 rad from its bottom and top; ``start``: the
    ball's rotation at the start (a start value: the same compiled models), the finger's
    contact and the turntable's support point guessed where the world's top and bottom are.
    ``(scenes, models, atlas surface)``."""
    w0 = np.array([-0.03, 0.0, 0.0])
    R0 = np.eye(3) if start is None else start
    turn = (Rotation.from_euler("x", 0.3) * Rotation.from_euler("x", 90, degrees=True)).as_matrix()
    ball = sl.sphere(BALL_R, rotation=turn, atlas=True, name="ball atlas")

    def at(d):
        return math.atan2(d[1], d[0]), math.asin(d[2])

    up, down = R0.T @ [0.0, 1.0, 0.0], R0.T @ [0.0, -1.0, 0.0]
    scenes = (pressed_ball("press_turn", 0.0, rotation=R0, object_contact=at(up))[1],
              pressed_ball("press_turn_atlas", 0.0, rotation=R0, surface=ball, object_contact=at(turn.T @ up))[1])
    models = [gs.build(gs.scenes.with_modes(s, planes=[gs.scenes.world_plane(tuple(w0), (0.0, 1.0, 0.0), support=w,
                                                                             spin="2*t")]))
              for s, w in zip(scenes, (at(down), at(turn.T @ down)))]
    return scenes, models, ball


def _same_runs(scenes, models, ball, t_end: float = 0.5):
    """The two balls' runs (mu 0.5 on the turntable, 1 under the finger; rtol 1e-9): the same
    events, every state but the contacts' coordinates within 1e-9, both contact points, read
    in their charts, to 1e-12 m. The atlas's run."""
    kw = dict(mu=(0.5, 1.0), t_eval=np.linspace(0.0, t_end, 11), rtol=1e-9, atol=1e-11)
    plain, atlas = (m.simulate(t_end, **kw) for m in models)
    assert [(e["contact"], e["to"]) for e in plain.events] == [(e["contact"], e["to"]) for e in atlas.events]
    assert [(e["contact"], e["to"]) for e in atlas.events] == [(2, "rolling")]      # it landed
    assert abs(plain.events[0]["t"] - atlas.events[0]["t"]) < 1e-12
    body = [k for k, n in enumerate(models[0].state_names) if not n.startswith(("u_", "v_", "psi"))]
    assert np.abs(plain.x[:, body] - atlas.x[:, body]).max() < 1e-9
    for side in ("w1", "o1"):
        here = scenes[0].object_surface.evaluate(plain[f"u_{side}"], plain[f"v_{side}"])["point"]
        there = ball.evaluate(atlas[f"u_{side}"], atlas[f"v_{side}"], chart=atlas.charts[f"chart_{side}"])["point"]
        assert np.abs(here - there).max() < 1e-12
    return atlas


def test_a_plane_under_a_grasped_object_with_an_atlas_starts_in_the_chart_that_holds_it():
    """The turntable's ball (``_turntable_balls``) turned by -0.2 rad about x at the start:
    the turntable's support point and the finger's contact lie 0.1 rad from chart 0's poles
    (beyond its latitudes). Both start in chart 1 (``chart_w1``: the plane's support point
    solved there; ``chart_o1``: the grasp's contact carried there), and the ball lands and is
    carried as the one-chart ball is (``_same_runs``)."""
    scenes, models, ball = _turntable_balls(Rotation.from_euler("x", -0.2).as_matrix())
    params = dict(zip(models[1].p_names, models[1].default_params))
    assert params["chart_w1"] == 1.0 and params["chart_o1"] == 1.0
    atlas = _same_runs(scenes, models, ball)
    assert not atlas.chart_switches and set(atlas.charts["chart_w1"]) == set(atlas.charts["chart_o1"]) == {1}
def _tube():
    """An elliptic tube's contour (semi-axes 12 and 20 mm, 45 mm off the axis), two traversals."""
    return gs.curves.ellipse(0.012, 0.02, (0.045, 0.0), span=2 * math.pi, name="tube")


REPEATING = {
    "torus": lambda: sl.torus(0.05, 0.015, center=(0.0, 0.01, 0.0), rotation=TURNED, atlas=True),
    "barrel": lambda: sl.surface_of_revolution(_tube(), atlas=True, name="barrel"),
    "vase": lambda: sl.surface_of_revolution(gs.curves.ellipse(0.012, 0.02, (0.045, 0.0), span=1.2), axis="x",
                                             atlas=True, name="vase"),
}


@pytest.mark.parametrize("name", sorted(REPEATING))
def test_a_repeating_chart_carries_a_point_at_its_edge_a_period_back(name):
    """A torus, a revolved closed contour (both coordinates repeat) and a revolved open one (the
    angle only): near either edge of a repeating coordinate, the run time's map gives a point
    inside the domain, a whole period away, at the same point, normal and frame of the chart
    (SymPy's surface evaluated at both ends, 1e-15 m), nothing turned; a coordinate that does
    not repeat is left alone."""
    surface = REPEATING[name]()
    entry = manifest_entry(surface, "chart", "u", "v", "psi")
    assert entry["param"] is None and surface.atlas is None
    (u0, u1), (v0, v1) = surface.domain
    pu, pv = surface.periods
    assert pu == pytest.approx(2 * math.pi) and (pv is None) == (name == "vase")
    rng = np.random.default_rng(3)
    for _ in range(40):
        u = rng.choice([u0, u1]) + rng.uniform(-0.05, 0.05)
        v = rng.choice([v0, v1]) + rng.uniform(-0.05, 0.05) if pv is not None else rng.uniform(v0, v1)
        new, u2, v2, delta = atlas_.transition(entry, 0, u, v)
        assert new == 0 and delta == 0.0 and u0 < u2 < u1 and v0 < v2 < v1
        assert abs(math.remainder(u2 - u, pu)) < 1e-12 and abs(u2 - 0.5 * (u0 + u1)) <= pu / 2 + 1e-12
        assert (v2 == v) if pv is None else abs(math.remainder(v2 - v, pv)) < 1e-12
        a, b = surface.evaluate(u, v), surface.evaluate(u2, v2)
        for key in ("point", "normal", "x", "y"):
            assert np.abs(a[key] - b[key]).max() < 1e-15 * (1.0 if key != "point" else 0.1)


def test_a_repeating_chart_takes_no_domain_of_its_own():
    with pytest.raises(InvalidSurfaceError, match="u and v are the atlas's own"):
        sl.torus(0.05, 0.01, u=(-1.0, 1.0), atlas=True)
    with pytest.raises(InvalidSurfaceError, match="angle is the atlas's own"):
        sl.surface_of_revolution(_tube(), angle=(-1.0, 1.0), atlas=True)
    with pytest.raises(InvalidSurfaceError, match=r"less than two traversals.*span=2 \* pi"):
        sl.surface_of_revolution(gs.curves.ellipse(0.012, 0.02, (0.045, 0.0), span=math.pi), atlas=True)
    with pytest.raises(InvalidSurfaceError, match="atlas = 1 must be True or False"):
        sl.torus(0.05, 0.01, atlas=1)
    # the same surface with and without its atlas: two definitions (two models), not one
    assert sl.torus(0.05, 0.01, atlas=True).key() != sl.torus(0.05, 0.01, u=(-3 * math.pi, 3 * math.pi),
                                                              v=(-3 * math.pi, 3 * math.pi)).key()


def _wheel(surface, radius: float, lean: float, omega, velocity=None, support_v: float = 0.0, name: str = "wheel"):
    """``surface`` (its axis z) standing on a table on its rim, leaning by ``lean`` (rad) about
    the world's x, turning at ``omega`` (world, rad/s); ``velocity`` None: its centre's speed
    of rolling, found from the start's contact point (m/s)."""
    turn = Rotation.from_euler("x", math.pi / 2 + lean).as_matrix()      # its axis onto -y
    d = turn.T @ [0.0, 0.0, -1.0]
    omega = np.asarray(omega, dtype=float)
    kw = dict(mass=0.1, inertia=(1e-4, 1e-4, 1.6e-4), position=(0.0, 0.0, radius), rotation=turn,
              omega=tuple(turn.T @ omega), support=(math.atan2(d[1], d[0]), support_v), name=name)
    model = gs.build(gs.scenes.body_on_plane(surface, velocity=(0.0, 0.0, 0.0), **kw))
    if velocity is None:
        x0 = model.initial_state()
        r = turn @ surface.evaluate(x0[-2], x0[-1])["point"]
        velocity = np.cross(r, omega)
    return gs.build(gs.scenes.body_on_plane(surface, velocity=tuple(velocity), **kw))


@pytest.fixture(scope="module")
def barrel():
    return REPEATING["barrel"]()


@pytest.mark.parametrize("name", ["torus", "barrel"])
def test_a_wheel_rolls_on_across_its_seam(name, barrel):
    """A torus and a barrel (``_tube`` revolved) rolling upright on a table, 2.5 turns: the
    exact motion is a wheel's of radius ``a`` (the rim's), its centre on a straight line at
    ``V = omega a`` and its contact the rim's lowest point, ``u`` growing by 2 pi a turn. The
    rim's angle repeats: the contact crosses the edge (3 pi) once and goes on a turn back.
    The centre keeps its line to 1e-12 m and each row's contact point is the lowest point to
    1e-10 m (the tolerance's level: its coordinates are integrated, rtol 1e-10)."""
    surface = sl.torus(0.05, 0.015, atlas=True) if name == "torus" else barrel
    a, V = (0.065, 1.0) if name == "torus" else (0.057, 1.0)
    model = _wheel(surface, a, 0.0, (0.0, V / a, 0.0), velocity=(V, 0.0, 0.0), name=f"{name}_wheel")
    x0 = model.initial_state()
    t_end = 2.5 * 2 * math.pi * a / V
    res = model.simulate(t_end, rtol=1e-10, atol=1e-12, t_eval=np.linspace(0.0, t_end, 201))
    assert not res.events and not res.charts and len(res.chart_switches) == 1
    rec = res.chart_switches[0]
    assert rec["chart"] is None and rec["coordinates"] == ("u", "v") and rec["delta"] == 0.0
    assert rec["u"][0] == pytest.approx(3 * math.pi, abs=0.05)
    assert rec["u"][1] == pytest.approx(rec["u"][0] - 2 * math.pi)
    assert np.abs(res.x[:, 0] - (x0[0] + V * res.t)).max() < 1e-12
    assert np.abs(res.x[:, 1:3] - x0[1:3]).max() < 1e-12
    q = res.x[:, 3:7]
    turn = Rotation.from_quat(np.column_stack([q[:, 1:], q[:, :1]])).as_matrix()
    point = surface.evaluate(res["u"], res["v"])["point"]
    world = res.x[:, :3] + np.einsum("nij,nj->ni", turn, point)
    assert np.abs(world - res.x[:, :3] + [0.0, 0.0, a]).max() < 1e-10
    unwrapped = np.unwrap(res["u"])
    assert unwrapped[-1] - unwrapped[0] == pytest.approx(2.5 * 2 * math.pi, rel=1e-9)


def test_a_leaning_barrel_rolls_over_its_tubes_seam(barrel):
    """The barrel leaning 0.05 rad, swung upright and over by a spin about the lean's axis. Its
    support point, guessed near the contour's edge (2 pi), starts in the middle period (the
    start takes it there); run from the same start written a traversal on, 0.08 rad short of
    the edge, the contact crosses that edge once (the contour's parameter a traversal back)
    and agrees with the run from the middle, which reaches no edge: every state to 1e-9 (the tolerance's
    level, rtol 1e-10: their steps differ after the switch), v a whole period apart."""
    model = _wheel(barrel, 0.06, -0.05, (3.0, 0.2 / 0.057, 0.0), support_v=2 * math.pi - 0.01, name="barrel_wheel")
    back = model.initial_state()              # the start: its support point in the middle period
    assert -0.1 < back[-1] < 0.0
    x0 = back.copy()
    x0[-1] += 2 * math.pi                     # the same start near the edge
    kw = dict(rtol=1e-10, atol=1e-12, t_eval=np.linspace(0.0, 0.1, 51))
    res = model.simulate(0.1, x0=x0, **kw)
    twin = model.simulate(0.1, x0=back, **kw)
    assert len(res.chart_switches) == 1 and not twin.chart_switches and not res.events and not twin.events
    rec = res.chart_switches[0]
    assert rec["v"][0] == pytest.approx(2 * math.pi, abs=0.02) and abs(rec["v"][1]) < 0.02
    assert rec["u"][0] == rec["u"][1]
    assert np.abs(res.x[:, :-1] - twin.x[:, :-1]).max() < 1e-9
    gap = res.x[:, -1] - twin.x[:, -1]
    assert np.abs(np.remainder(gap + math.pi, 2 * math.pi) - math.pi).max() < 1e-9
    assert res.x[-1, -1] - twin.x[-1, -1] == pytest.approx(0.0, abs=1e-9)    # past the switch: one chart


def test_a_grasp_runs_on_across_its_revolved_fingertips_seam(pivot_grasps, monkeypatch):
    """pivot3d's fingertip written as a revolved arc (the sphere's own chart) with
    ``atlas=True``, turned about its axis so that the contact starts 0.3 rad from the angle's
    edge (-3 pi), toward which it rolls: the grasp (run by ``simulate``'s plain run, and by
    ``simulate_many``) crosses the seam once, a turn back, and agrees with the one-chart grasp
    (``pivot_grasps``' reference): every other state to 1e-9 over 1.5 s, each row's contact
    point to 1e-12 m. The model has no chart parameter."""
    real_short = fastpath.run
    g = pivot_grasps
    ref, x0, tip, box = g["ref"], g["x0"], g["tip"], g["box"]
    names = ref.state_names
    iu = names.index("u_f1")
    start = -3 * math.pi + 0.3
    turn = Rotation.from_euler("z", x0[iu] - start).as_matrix()
    arc = sl.surface_of_revolution(gs.curves.circle(0.01, by="angle", span=1.3, name="arc"), rotation=turn,
                                   atlas=True, name="fingertip")
    xs = x0.copy()
    xs[iu] = start
    model = gs.build(_pivot("pivot_revolved", arc, box, (xs, names)))
    assert model.p_names == () and [e["param"] for e in model.manifest["atlas"]] == [None]
    kw = dict(rtol=1e-10, atol=1e-12, t_eval=np.linspace(0.0, 1.5, 301))
    ra, rr = model.simulate(1.5, x0=xs, **kw), ref.simulate(1.5, x0=x0, **kw)
    assert len(ra.chart_switches) == 1 and not ra.charts
    rec = ra.chart_switches[0]
    assert rec["coordinates"] == ("u_f1", "v_f1") and rec["u"][1] == pytest.approx(rec["u"][0] + 2 * math.pi)
    other = [k for k in range(len(names)) if k != iu]
    assert np.abs(ra.x[:, other] - rr.x[:, other]).max() < 1e-9
    want = tip.evaluate(rr["u_f1"], rr["v_f1"])["point"]
    assert np.abs(arc.evaluate(ra["u_f1"], ra["v_f1"])["point"] - want).max() < 1e-12
    many = model.simulate_many(1.5, x0=np.stack([xs, xs]), **kw)
    assert (many.status == 0).all() and all(np.array_equal(x, ra.x) for x in many.x)
    # a run that only wraps is remembered for the short way (runtime.fastpath), which wraps alike
    short = []
    monkeypatch.setattr(fastpath, "run", lambda *a: short.append(real_short(*a)) or short[-1])
    model.simulate(1.5, x0=xs, outputs=False, **kw)
    again = model.simulate(1.5, x0=xs, outputs=False, **kw)
    assert short[-1] is again
    assert np.array_equal(again.x, ra.x) and again.chart_switches == ra.chart_switches


def test_a_grasps_contact_near_chart_0s_pole_starts_in_chart_1(pivot_grasps):
    """pivot3d's fingertip on a sphere's atlas turned so that chart 0's pole lies 0.1 rad from
    where the contact starts (latitude pi/2 - 0.1, beyond chart 0's 1.3): the start is solved
    in chart 0 and written in chart 1 (``chart_f1`` = 1 in the model's parameters), at the
    same point (1e-15 m) with psi turned by the frames' angle; from there the grasp runs as
    the one-chart grasp from the same physical state (every other state to 1e-9 over 0.5 s,
    the contact points to 1e-12 m). A guess at chart 0's pole has no coordinates: refused."""
    from grasping_sym.derive import start3d

    g = pivot_grasps
    ref, x0, tip = g["ref"], g["x0"], g["tip"]
    names = ref.state_names
    start = tip.evaluate(x0[names.index("u_f1")], x0[names.index("v_f1")])["point"] / 0.01
    turn = _pole_ahead(start, [0.0, -1.0, 0.0], -0.1)
    atip = sl.sphere(0.01, rotation=turn, atlas=True, name="fingertip")
    e = turn.T @ start
    finger = dataclasses.replace(gs.scenes.pivot3d().fingers[0], tip=atip,
                                 tip_contact=(math.atan2(e[1], e[0]), math.asin(e[2])),
                                 object_contact=tuple(x0[names.index(f"{c}_o1")] for c in "uv"))
    scene = gs.scenes.pivot3d(name="pivot_tip_at_pole", fingers=(finger,), object_surface=g["box"])
    with pytest.raises(InvalidSceneError, match=r"tip_contact \(0.0, 1.5707963.*off its poles"):
        gs.scenes.pivot3d(fingers=(dataclasses.replace(finger, tip_contact=(0.0, math.pi / 2)),),
                          object_surface=g["box"])
    in_chart_0, _ = start3d.initial_state(scene)
    assert abs(in_chart_0[names.index("v_f1")]) > 1.3
    model = gs.build(scene)
    assert model.p_names == ("chart_f1",) and model.default_params[0] == 1.0
    xs = model.initial_state()
    iu, iv = names.index("u_f1"), names.index("v_f1")
    here = atip.evaluate(in_chart_0[iu], in_chart_0[iv])["point"]
    assert np.abs(atip.evaluate(xs[iu], xs[iv], chart=1)["point"] - here).max() < 1e-15
    kw = dict(rtol=1e-10, atol=1e-12, t_eval=np.linspace(0.0, 0.5, 51))
    ra = model.simulate(0.5, **kw)
    rr = ref.simulate(0.5, x0=_in_chart(in_chart_0, names, "f", atip, tip, np.eye(3)), **kw)
    assert ra.charts["chart_f1"][0] == 1
    body = [k for k, n in enumerate(names) if not n.startswith(("u_f", "v_f", "psi"))]
    assert np.abs(ra.x[:, body] - rr.x[:, body]).max() < 1e-9
    want = tip.evaluate(rr["u_f1"], rr["v_f1"])["point"]
    assert np.abs(atip.evaluate(ra["u_f1"], ra["v_f1"], chart=ra.charts["chart_f1"])["point"] - want).max() < 1e-12
    # started elsewhere (with_start: continued from this start, in its charts), it keeps them
    moved = model.with_start(q11=float(xs[names.index("q11")]) + 0.005)
    assert moved.default_params[0] == 1.0
    assert moved.simulate(0.05, t_eval=[0.0, 0.05]).charts["chart_f1"][0] == 1


def test_a_plane_under_a_grasped_object_switches_its_support_points_chart_in_motion():
    """The turntable's ball (``_turntable_balls``) as built: it lands and is carried, rolling
    by ~0.3 rad toward chart 0's poles. The support point on the turntable (``chart_w1``) and
    then the finger's contact (``chart_o1``) reach chart 0's edge and switch chart in motion,
    as the one-chart ball runs (``_same_runs``)."""
    scenes, models, ball = _turntable_balls()
    atlas = _same_runs(scenes, models, ball)
    assert [(r["chart"], r["from"], r["to"]) for r in atlas.chart_switches] == [("chart_w1", 0, 1), ("chart_o1", 0, 1)]
def test_a_model_with_an_atlas_is_read_back_from_the_cache(lap_model, pivot_grasps):
    """A built model with charts in its ``p`` is found in the cache by the next build (its
    manifest's parameter count holds the charts: it was refused as invalid, and every
    ``gs.build`` of an atlas model derived and compiled it again)."""
    for model in (lap_model[0], pivot_grasps["model"]):
        again = gs.build(model.scene)
        assert again.build_info["source"] == "cache", again.build_info.get("rebuilt_because")
        assert again.p_names == model.p_names and "chart" in again.p_names[-1]


def test_a_repeating_chart_carries_only_its_repeating_coordinates():
    """What the run time carries at an edge (``runtime.atlas.Atlases``): a revolved open
    contour's angle, not its contour parameter (whose end is the surface's: a contact there
    leaves the surface, by name); a grasp in the paper's formulation (no frame angle) names
    none for a wrap, which turns nothing; a wrap of a model with no parameters cuts its run's
    rows into no stretches (``runtime.atlas.by_charts``: only a change of chart does) and
    keeps ``p`` None."""
    from types import SimpleNamespace

    from grasping_sym.runtime.run import _Charted

    vase = REPEATING["vase"]()
    entry = manifest_entry(vase, "chart", "u", "v", None)
    model = SimpleNamespace(manifest={"atlas": [entry]}, state_names=("a", "u", "v"), p_names=(),
                            lower=np.array([-np.inf, *(lo for lo, _ in vase.domain)]),
                            upper=np.array([np.inf, *(hi for _, hi in vase.domain)]))
    atlases = atlas_.Atlases(model)
    assert atlases.columns == {1: 0}
    (v0, v1) = vase.domain[1]
    at_end = ContactLeftContourError(0.1, np.array([0.0, 1.0, v1 - 1e-3]), "v left", model.state_names)
    at_end.x_rejected = np.array([0.0, 1.0, v1 + 1e-3])
    assert atlases.slot_of(at_end) is None                 # not a wrap: the surface ends there
    at_seam = ContactLeftContourError(0.1, np.array([0.0, 9.4, 0.0]), "u left", model.state_names)
    at_seam.x_rejected = np.array([0.0, 9.5, 0.0])
    assert atlases.slot_of(at_seam) == 0
    charted = _Charted(model)
    _, _, record = atlases.switch(0, 0.1, at_seam.x, None)
    charted.switches.append(record)
    assert charted.pieces(np.linspace(0.0, 0.2, 5), None) == [(0, 5, None)]  # a wrap cuts nothing
    ring = sl.torus(0.03, 0.01, atlas=True, name="ring tip")
    base = gs.scenes.paper3d()
    fingers = (dataclasses.replace(base.fingers[0], tip=ring), base.fingers[1])
    paper = gs.scenes.paper3d(fingers=fingers, formulation="paper")
    assert [e["psi"] for e in paper.atlas_manifest()["atlas"]] == [None]
