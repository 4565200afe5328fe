"""What atlases of charts cost (issue 29, part 3).

    python -m benchmarks.atlas        # writes benchmarks/results/atlas.md and atlas.json

- a chart switch: a ball rolling lap after lap round a turntable (``tests/test_atlas.py``'s
  closed-form case), its chart's pole on the contact's path (a switch every lap of the
  contact), against the same ball with its pole on the circle's axis (the contact stays at one
  latitude: only the longitude's wraps), the same physical run; per switch, the wall time the
  switches add and the Python time spent making them (``stats["switch_time"]``), and the
  steps they add (each switch restarts the integration);
- a grasp (paper3d's fingers holding a ball) whose fingertip's and ball's charts switch, against
  the same grasp on atlases whose poles are far from the contacts (no switch) and on one-chart
  surfaces (no atlas): what an atlas costs when nothing switches, and what a switch adds.

Every ratio's baseline is measured in the same run.
"""
from __future__ import annotations

import json
import math
import platform
from pathlib import Path

import numpy as np
from scipy.spatial.transform import Rotation

import grasping_sym as gs
from benchmarks import timing
from grasping_sym.geometry import surface_library as sl
from grasping_sym.runtime.atlas import Atlases

RESULTS = Path(__file__).resolve().parent / "results"
#: Rounds of interleaved calls (each case once a round; the best of each): this machine's
#: speed drifts by 10-30 % over seconds, which back-to-back repeats of one case would read as
#: a difference between cases.
ROUNDS = 15


def interleaved(calls: dict) -> dict:
    """``timing.interleaved`` over ``ROUNDS`` rounds."""
    return timing.interleaved(calls, ROUNDS)
R, M, OMEGA, RC = 0.05, 0.1, 10.0, 0.1
TOL = {"rtol": 1e-10, "atol": 1e-12}


def _frame_with_pole(w) -> np.ndarray:
    w = np.asarray(w, float) / np.linalg.norm(w)
    x = np.cross([0.0, 1.0, 0.0] if abs(w[1]) < 0.9 else [1.0, 0.0, 0.0], w)
    x /= np.linalg.norm(x)
    return np.column_stack([x, np.cross(w, x), w])


def _lap_ball(pole_on_path: bool, atlas: bool = True):
    """The turntable ball of ``tests/test_atlas.py``: its chart's pole on the contact's circle,
    or on the circle's axis ``a`` (the contact then stays at one latitude). ``atlas=False``:
    one chart whose longitude never ends (+-100 rad), the pole on the axis."""
    a = np.array([RC, 0.0, R]) / math.hypot(RC, R)
    if pole_on_path:
        s = 0.5
        wx = -R * (1 + s) / RC
        w = np.array([wx, math.sqrt(1 - wx**2 - s**2), s])
    else:
        w = a
    R0 = _frame_with_pole(w)
    c0 = np.array([RC, 0.0, R])
    v0 = 2 / 7 * OMEGA * np.cross([0.0, 0.0, 1.0], c0)
    om = np.array([5 * OMEGA * RC / (7 * R), 0.0, OMEGA])
    d = R0.T @ [0.0, 0.0, -1.0]
    surface = sl.sphere(R, atlas=True) if atlas else sl.sphere(R, lon=(-100.0, 100.0))
    scene = gs.scenes.body_on_plane(surface, mass=M, inertia=(0.4 * M * R * R,) * 3,
                                    plane_spin=OMEGA, position=tuple(c0), rotation=R0, velocity=tuple(v0),
                                    omega=tuple(R0.T @ om), support=(math.atan2(d[1], d[0]), math.asin(d[2])),
                                    name="bench_lap_" + ("on_path" if pole_on_path else "off_path" if atlas
                                                         else "one_chart"))
    return gs.build(scene)


def _by_python(model, t_end: float, **kw):
    """``model.simulate`` as a library without ``c/wrap.c`` runs it: the C loop stops at each
    chart's edge and Python maps the state and starts the loop again (``kw``: the run's
    arguments; without outputs unless given)."""
    model.library.can_wrap = False
    try:
        return model.simulate(t_end, **{**TOL, "outputs": False, **kw})
    finally:
        model.library.can_wrap = True


#: The C loops the restarts' window is cut into (``_change_work``).
RESTARTS = 50


def _change_work(models: dict, t_end: float, changes: int) -> dict:
    """What a change of chart costs inside the loop: one step not taken (counted rejected) and a
    start again from the mapped state (its rhs, its first step chosen anew, its Jacobian and LU
    factorisations). The start again, timed: a window of the steady lap run (a twentieth) in
    one C loop against the same cut into ``RESTARTS`` C loops (``radau5`` called alone, each
    from the last one's end: each start a restart, with its Python call); the step, timed: the
    switching run's C loop time per attempted step. Their sum bounds a change's cost (a restart
    chooses its first step from two rhs; a change, from three)."""
    def loop(model, x, a, b):
        with model.library.wrapping(Atlases(model).wrap_slots, []):
            return model.library.radau5(x, np.array([a, b]), p=model.default_params, lo=model.lower,
                                        hi=model.upper, **TOL)

    sw, st = models["switching"], models["steady"]
    window = t_end / 20        # (about 250 steps, cut into RESTARTS: the restarts' time is most of it)
    cuts = np.linspace(0.0, window, RESTARTS + 1)

    def cut() -> float:
        """The cut window's time in its C loops alone (each loop's ``wall_time``: the C call)."""
        x, inside = st.initial_state(), 0.0
        for a, b in zip(cuts[:-1], cuts[1:]):
            _, X, stats = loop(st, x, float(a), float(b))
            x, inside = X[-1], inside + stats["wall_time"]
        return inside

    wall = interleaved({"switching": lambda: loop(sw, sw.initial_state(), 0.0, t_end),
                        "whole": lambda: loop(st, st.initial_state(), 0.0, window), "cut": cut})
    inside = {"whole": min(loop(st, st.initial_state(), 0.0, window)[2]["wall_time"] for _ in range(ROUNDS)),
              "cut": min(cut() for _ in range(ROUNDS))}
    stats = loop(sw, sw.initial_state(), 0.0, t_end)[2]
    attempted = stats["n_steps"] + stats["n_rejected"]
    step = wall["switching"] / attempted
    restart, in_c = ((w["cut"] - w["whole"]) / (RESTARTS - 1) for w in (wall, inside))
    return {"attempted_steps": int(attempted), "rejected": int(stats["n_rejected"]), "loop_s": wall["switching"],
            "step_us": 1e6 * step, "restart_us": 1e6 * restart, "restart_in_c_us": 1e6 * in_c,
            "in_loop_us": 1e6 * (step + in_c)}


def lap_switches(laps: int = 5) -> dict:
    t_end = laps * 14 * math.pi / (5 * OMEGA)
    models = {"switching": _lap_ball(True), "steady": _lap_ball(False), "one_chart": _lap_ball(False, False)}
    runs = {k: (lambda m=m: m.simulate(t_end, **TOL, outputs=False)) for k, m in models.items()}
    runs["switching_by_python"] = lambda: _by_python(models["switching"], t_end)
    wall = interleaved(runs)
    out = {}
    for key, run in runs.items():
        res = run()
        py = min(run().stats["switch_time"] for _ in range(ROUNDS))
        loop = min(run().stats["loop_time"] for _ in range(ROUNDS))
        out[key] = {"switches": len(res.chart_switches),
                    "chart_changes": sum(s["from"] != s["to"] for s in res.chart_switches),
                    "in_loop": sum(s["in_loop"] for s in res.chart_switches),
                    "steps": int(res.stats["n_steps"]), "wall_s": wall[key], "switch_python_s": py,
                    "loop_s": loop}
    sw, st, one, bp = out["switching"], out["steady"], out["one_chart"], out["switching_by_python"]
    # the steady atlas's rhs costs more than the one chart's (its chart 1 is chart 0 turned by a
    # full Q, computed at every call): that part of the difference is not the switches'
    X = {k: np.tile(models[k].initial_state(), (2000, 1)) for k in ("steady", "one_chart")}
    rhs = interleaved({k: (lambda k=k: models[k].rhs_batch(X[k])) for k in X})
    n_rhs = int(models["steady"].simulate(t_end, **TOL, outputs=False).stats["n_rhs"])
    extra = n_rhs * (rhs["steady"] - rhs["one_chart"]) / 2000
    changes = max(1, sw["chart_changes"])
    out["per_change"] = {
        # the same run with its changes made by Python (the loop stopped at each edge)
        "saved_us": 1e6 * (bp["wall_s"] - sw["wall_s"]) / changes,
        # in the loop: counted (``_change_work``)
        **_change_work(models, t_end, changes)}
    out["per_switch"] = {"python_us": 1e6 * bp["switch_python_s"] / max(1, bp["chart_changes"]),
                         "wrap_us": 1e6 * (st["wall_s"] - one["wall_s"] - extra) / st["switches"],
                         # the Python around the C loops (the run's wall less its loops'), per switch,
                         # against the one chart's; and the loops' own difference per switch
                         "outside_loops_us": 1e6 * ((st["wall_s"] - st["loop_s"]) - (one["wall_s"] - one["loop_s"]))
                         / st["switches"],
                         "in_loops_us": 1e6 * (st["loop_s"] - one["loop_s"]) / st["switches"],
                         "rhs_us": {k: 1e6 * v / 2000 for k, v in rhs.items()}, "n_rhs": n_rhs}
    out["restarts"] = restarts(models["steady"], t_end, sw["switches"])
    return out


def restarts(model, t_end: float, n: int) -> dict:
    """What restarting the integration costs, apart from the switch's map: the steady lap run
    cut into ``n + 1`` runs (each from the last one's end, as a switch restarts it) against
    the run in one piece."""
    cuts = np.linspace(0.0, t_end, n + 2)

    def pieces():
        x, steps = None, 0
        for a, b in zip(cuts[:-1], cuts[1:]):
            res = model.simulate(float(b - a), x0=x, **TOL, outputs=False)
            x, steps = res.x[-1], steps + int(res.stats["n_steps"])
        return steps

    whole = model.simulate(t_end, **TOL, outputs=False).stats["n_steps"]
    wall = interleaved({"whole": lambda: model.simulate(t_end, **TOL, outputs=False), "cut": pieces})
    return {"restarts": n, "steps_whole": int(whole), "steps_cut": pieces(), "whole_s": wall["whole"],
            "cut_s": wall["cut"], "per_restart_us": 1e6 * (wall["cut"] - wall["whole"]) / n}


def _pole_ahead(start, toward, angle: float) -> np.ndarray:
    axis = np.cross(start, toward)
    return _frame_with_pole(Rotation.from_rotvec(angle * axis / np.linalg.norm(axis)).apply(start))


def _ball_grasp(name, tip, ball, guesses=None):
    return gs.build(_ball_scene(name, tip, ball, guesses))


def _ball_scene(name, tip, ball, guesses=None):
    import dataclasses
    base = gs.scenes.paper3d()
    fingers = [dataclasses.replace(base.fingers[0], tip=tip), base.fingers[1]]
    if guesses is not None:
        x, names = guesses
        fingers = [dataclasses.replace(f, tip_contact=tuple(x[names.index(f"{c}_f{i}")] for c in "uv"),
                                       object_contact=tuple(x[names.index(f"{c}_o{i}")] for c in "uv"))
                   for i, f in enumerate(fingers, 1)]
    return gs.scenes.paper3d(name=name, fingers=fingers, k_center=0.0, object_surface=ball,
                             inertia=(0.4 * 0.04 * 0.025**2,) * 3, mass=0.04)


def _carried(x, names, side, i, old, new, Rn, r):
    iu, iv, ip = names.index(f"u_{side}{i}"), names.index(f"v_{side}{i}"), names.index(f"psi{i}")
    g0 = old.evaluate(x[iu], x[iv])
    e = Rn.T @ (g0["point"] / r)
    u, v = math.atan2(e[1], e[0]), math.asin(e[2])
    g1 = new.evaluate(u, v)
    x = x.copy()
    x[iu], x[iv], x[ip] = u, v, x[ip] + math.atan2(g1["x"] @ g0["y"], g1["x"] @ g0["x"])
    return x


def grasp(t_end: float = 0.5) -> dict:
    tip = sl.sphere(0.01, name="fingertip 1", lon=(-3 * math.pi, 3 * math.pi))
    ball = sl.sphere(0.025, lon=(-math.pi / 2, 3 * math.pi / 2), name="ball")
    one = _ball_grasp("bench_ball_one_chart", tip, ball)
    names, x0 = one.state_names, one.initial_state()
    p_tip = tip.evaluate(x0[names.index("u_f1")], x0[names.index("v_f1")])["point"] / 0.01
    p_ball = ball.evaluate(x0[names.index("u_o1")], x0[names.index("v_o1")])["point"] / 0.025
    cases = {"one_chart": (one, x0)}
    poles = {"atlas_switching": (_pole_ahead(p_tip, [0, 1.0, 0], 0.3), _pole_ahead(p_ball, [0, 1.0, 0], 0.3)),
             "atlas_steady": (_frame_with_pole(np.cross(p_tip, [0, 1.0, 0])),
                              _frame_with_pole(np.cross(p_ball, [0, 1.0, 0]))),
             "atlas_unturned": (np.eye(3), np.eye(3))}
    for key, (Rt, Ro) in poles.items():
        atip = sl.sphere(0.01, rotation=Rt, atlas=True, name="fingertip 1")
        aball = sl.sphere(0.025, rotation=Ro, atlas=True, name="ball")
        x = _carried(x0, names, "f", 1, tip, atip, Rt, 0.01)
        for i in (1, 2):
            x = _carried(x, names, "o", i, ball, aball, Ro, 0.025)
        cases[key] = (_ball_grasp(f"bench_ball_{key}", atip, aball, (x, names)), x)
    wall = interleaved({k: (lambda m=m, x=x: m.simulate(t_end, x0=x, **TOL)) for k, (m, x) in cases.items()})
    out = {}
    for key, (model, x) in cases.items():
        res = model.simulate(t_end, x0=x, **TOL)
        out[key] = {"switches": len(res.chart_switches), "steps": int(res.stats["n_steps"]), "wall_s": wall[key],
                    "ratio_to_one_chart": wall[key] / wall["one_chart"]}
    sw, st = out["atlas_switching"], out["atlas_steady"]
    out["per_switch_added_wall_us"] = 1e6 * (sw["wall_s"] - st["wall_s"]) / max(1, sw["switches"] - st["switches"])
    return out


#: The sliding grasp's friction coefficient, the time its one-chart run's contact on the
#: fingertip reaches the point where the atlas's chart-0 pole is put, and the run's end (it
#: slides from 0.9 ms and lets go at 69 ms).
SLIDE_MU, SLIDE_POLE_AT, SLIDE_END = 0.02, 0.05, 0.06


def sliding_grasp() -> dict:
    """The ball grasp with contact modes at mu = 0.02: it slides from 0.9 ms. Its fingertip's
    atlas has chart 0's pole where the one-chart run's contact is at 50 ms: the slide crosses
    the chart's edge (latitude 1.3, 0.27 rad from the pole). The change made in the C loop, the
    slip direction turned there with the fingertip's frame (``c/wrap.c``), against the same run
    with the loop stopped at the edge and the change made by Python (a library without wraps);
    and the one-chart run, which the atlas's follows."""
    tip = sl.sphere(0.01, name="fingertip 1", lon=(-3 * math.pi, 3 * math.pi))
    ball = sl.sphere(0.025, lon=(-math.pi / 2, 3 * math.pi / 2), name="ball")
    one = gs.build(gs.scenes.with_modes(_ball_scene("bench_slide_one_chart", tip, ball)))
    names, x0 = one.state_names, one.initial_state()
    ref = one.simulate(SLIDE_POLE_AT, mu=SLIDE_MU, **TOL)
    pole = tip.evaluate(ref["u_f1"][-1], ref["v_f1"][-1])["point"] / 0.01
    Rt = _frame_with_pole(pole)
    atip = sl.sphere(0.01, rotation=Rt, atlas=True, name="fingertip 1")
    x = _carried(x0, names, "f", 1, tip, atip, Rt, 0.01)
    model = gs.build(gs.scenes.with_modes(_ball_scene("bench_slide_atlas", atip, ball, (x, names))))

    calls = {"in_loop": lambda: model.simulate(SLIDE_END, x0=x, mu=SLIDE_MU, **TOL),
             "by_python": lambda: _by_python(model, SLIDE_END, x0=x, mu=SLIDE_MU, outputs=True),
             "one_chart": lambda: one.simulate(SLIDE_END, mu=SLIDE_MU, **TOL)}
    wall = interleaved(calls)
    out = {}
    for key, call in calls.items():
        res = call()
        changes = [s for s in res.chart_switches if s["from"] != s["to"]]
        out[key] = {"changes": len(changes), "in_loop": sum(bool(s["in_loop"]) for s in changes),
                    "modes": sorted(set(np.asarray(res.modes).ravel().tolist())),
                    "segments": int(res.stats["segments"]), "steps": int(res.stats["n_steps"]),
                    "wall_s": wall[key], "x_end": res.x[-1].tolist(),
                    # Python's making of the run's switches (modes' and charts'), the best of 5
                    "switch_s": min([res.stats["switch_time"]] + [call().stats["switch_time"] for _ in range(4)])}
    loop, py = out["in_loop"], out["by_python"]
    out["saved_per_change_us"] = 1e6 * (py["wall_s"] - loop["wall_s"]) / max(1, loop["changes"])
    out["python_making_per_change_us"] = 1e6 * (py["switch_s"] - loop["switch_s"]) / max(1, loop["changes"])
    body = [k for k, n in enumerate(names) if not n.startswith(("u_", "v_", "psi"))]
    out["state_apart"] = {
        "python": float(np.abs(np.subtract(loop["x_end"], py["x_end"])).max()),
        "one_chart_body": float(np.abs(np.subtract(loop["x_end"], out["one_chart"]["x_end"])[body]).max())}
    return out


def object_atlas() -> dict:
    """paper3d with a superquadric object (n = 4), its contacts on the chart's equator, on one
    chart and on an atlas (nothing switches: the blend of the two charts' SymPy forms, the
    atlas of a surface whose chart 1 is not chart 0 turned), ``simulate(3.0)`` with every
    default, and the rhs alone (20 000 states in one batch call)."""
    def scene(atlas: bool):
        kw = {"atlas": True} if atlas else {"lon": (-math.pi / 2, 3 * math.pi / 2)}
        obj = sl.superquadric(0.020, 0.025, 0.030, n=4, name="object superquadric", **kw)
        return gs.build(gs.scenes.paper3d(object_surface=obj, name="bench_sq_" + ("atlas" if atlas else "one_chart")))
    one, two = scene(False), scene(True)
    X1, X2 = (np.tile(m.initial_state(), (20000, 1)) for m in (one, two))
    rhs = interleaved({"one_chart": lambda: one.rhs_batch(X1), "atlas": lambda: two.rhs_batch(X2)})
    run = interleaved({"one_chart": lambda: one.simulate(3.0), "atlas": lambda: two.simulate(3.0)})
    return {"rhs_us": {k: 1e6 * v / 20000 for k, v in rhs.items()}, "run_s": run,
            "rhs_ratio": rhs["atlas"] / rhs["one_chart"], "run_ratio": run["atlas"] / run["one_chart"]}


def repeating(turns: float = 10.5) -> dict:
    """A torus rolling upright as a wheel (``tests/test_atlas.py``'s exact case): with
    ``atlas=True`` its rim's angle repeats and the contact goes on a turn back at every edge
    (a wrap); on one chart whose angle never ends (+-100 rad) nothing happens. The same
    compiled surface: the difference is the wraps'."""
    a, V = 0.065, 1.0
    turn = Rotation.from_euler("x", 90, degrees=True).as_matrix()
    d = turn.T @ [0.0, 0.0, -1.0]

    def wheel(atlas: bool):
        ring = sl.torus(0.05, 0.015, atlas=True) if atlas else \
            sl.torus(0.05, 0.015, u=(-100.0, 100.0), v=(-math.pi, math.pi))
        return gs.build(gs.scenes.body_on_plane(
            ring, mass=0.1, inertia=(1e-4, 1e-4, 1.6e-4), position=(0.0, 0.0, a), rotation=turn,
            velocity=(V, 0.0, 0.0), omega=tuple(turn.T @ [0.0, V / a, 0.0]),
            support=(math.atan2(d[1], d[0]), 0.0), name="bench_wheel_" + ("atlas" if atlas else "one_chart")))

    t_end = turns * 2 * math.pi * a / V
    models = {"wrapping": wheel(True), "one_chart": wheel(False)}
    calls = {k: (lambda m=m: m.simulate(t_end, **TOL, outputs=False)) for k, m in models.items()}
    calls["one_chart_again"] = calls["one_chart"]  # the same call twice: what the timing's noise is
    wall = interleaved(calls)
    out = {}
    for key, m in models.items():
        res = m.simulate(t_end, **TOL, outputs=False)
        out[key] = {"wraps": len(res.chart_switches), "steps": int(res.stats["n_steps"]), "wall_s": wall[key]}
    wraps = out["wrapping"]["wraps"]
    out["per_wrap_us"] = 1e6 * (wall["wrapping"] - wall["one_chart"]) / wraps
    out["noise_per_wrap_us"] = 1e6 * abs(wall["one_chart_again"] - wall["one_chart"]) / wraps
    return out


def main() -> None:
    lap = lap_switches()
    g = grasp()
    slide = sliding_grasp()
    sq = object_atlas()
    wheel = repeating()
    data = {"machine": platform.processor() or platform.machine(), "lap": lap, "grasp": g,
            "sliding_grasp": slide, "superquadric": sq, "wheel": wheel}
    RESULTS.mkdir(exist_ok=True)
    (RESULTS / "atlas.json").write_text(json.dumps(data, indent=2))
    ps, rs, pc = lap["per_switch"], lap["restarts"], lap["per_change"]
    st_steps, one_steps = lap["steady"]["steps"], lap["one_chart"]["steps"]
    lines = [
        "# Atlases of charts: what a switch costs, and an atlas where nothing switches",
        "",
        f"`python -m benchmarks.atlas` (rtol 1e-10, atol 1e-12; the best of {ROUNDS} interleaved calls).",
        "",
        "## A ball lapping a turntable (the closed-form case of tests/test_atlas.py), 5 laps",
        "",
        "| run | switches (chart changes; made in the loop) | steps | wall (ms) |",
        "|---|---|---|---|",
        *[f"| {k} | {v['switches']} ({v['chart_changes']}; {v['in_loop']}) | {v['steps']} | {1e3 * v['wall_s']:.2f} |"
          for k, v in ((k, lap[k]) for k in ("switching", "switching_by_python", "steady", "one_chart"))],
        "",
        "`switching`: the chart's pole on the contact's path; `switching_by_python`: the same run as a",
        "library without `c/wrap.c` makes it (the loop stops at each edge, Python maps the state and",
        "starts the loop again); `steady`: the same physical run with the",
        "pole on the circle's axis (the contact at one latitude: only the longitude's wraps, each",
        "recorded as a switch within one chart); `one_chart`: as `steady` on one chart whose longitude runs to",
        "+-100 rad (no switch at all: the same steps). The switching run takes more steps: near a chart's edge",
        "(latitude up to 1.3) the longitude moves up to 1/cos(1.3) = 3.7 times faster than the",
        "contact, and the error control follows the coordinates, not the contact.",
        "",
        "**A wrap** is made inside the C loop at the step (`c/wrap.c`): the step kept, its start and end "
        "moved a turn, the loop goes on: the same steps as `one_chart` "
        f"({st_steps} and {one_steps}), and a few additions of work. What the two runs' walls differ by, "
        f"{ps['wrap_us']:.0f} µs per wrap (less the steady atlas's dearer rhs, {ps['rhs_us']['steady']:.2f} "
        f"against {ps['rhs_us']['one_chart']:.2f} µs over {ps['n_rhs']} calls), is the atlas's dearer steps "
        "(its generated Jacobian turns its vectors too) and this machine's drift (10-30 % over seconds), "
        "not the wraps: the torus below, one compiled surface both ways, measures them alone.",
        "",
        f"**A change of chart costs at most {pc['in_loop_us']:.0f} µs in the loop** (`c/wrap.c`): one step "
        f"not taken, {pc['step_us']:.1f} µs (the switching run in one C loop: {pc['attempted_steps']} "
        f"attempted steps, {pc['rejected']} rejected, in {1e3 * pc['loop_s']:.2f} ms), and a start again "
        f"from the mapped state, {pc['restart_in_c_us']:.1f} µs (a twentieth of the steady run in one C "
        f"loop against the same cut into {RESTARTS} loops, each started from the last one's end, their time "
        f"in C; {pc['restart_us']:.1f} µs with each loop's call from Python). "
        f"Against Python's making of the same changes (the whole `simulate`), it saves "
        f"**{pc['saved_us']:.0f} µs** a change. "
        "Python's, which the loop still leaves it where a table of inputs restarts the loop:",
        f"- its making of it (the C loop's stop, the map, the record; `stats['switch_time']`, "
        f"per change): **{ps['python_us']:.0f} µs**;",
        f"- restarting the integration there: the steady run cut into {rs['restarts'] + 1} runs takes "
        f"{rs['steps_cut']} steps against {rs['steps_whole']} in one piece, "
        f"{1e3 * rs['cut_s']:.2f} against {1e3 * rs['whole_s']:.2f} ms: **{rs['per_restart_us']:.0f} µs** a "
        "restart (with a whole `simulate` call's overhead each).",
        "",
        "## A sliding contact's change of chart",
        "",
        f"The ball grasp below with contact modes at mu = {SLIDE_MU}: it slides from 0.9 ms. Its "
        "fingertip's atlas has chart 0's pole where the one-chart run's contact is at "
        f"{1e3 * SLIDE_POLE_AT:.0f} ms, so the slide crosses the chart's edge; "
        f"{1e3 * SLIDE_END:.0f} ms simulated.",
        "",
        "| run | changes of chart (made in the loop) | modes | segments | steps | wall (ms) |",
        "|---|---|---|---|---|---|",
        *[f"| {k} | {v['changes']} ({v['in_loop']}) | {', '.join(v['modes'])} | {v['segments']} | {v['steps']} | "
          f"{1e3 * v['wall_s']:.2f} |" for k, v in ((k, slide[k]) for k in ("in_loop", "by_python", "one_chart"))],
        "",
        "`in_loop`: the change made in the C loop (`c/wrap.c`), the slip's direction, kept in the "
        "fingertip's frame, turned there with the frame, in the loop's parameters and in the watch's slip "
        "witness; `by_python`: the same run with a library that wraps nothing (the loop stops at the edge, "
        f"Python maps the state, turns the slip, and starts a new segment). Python's making of the "
        f"change (`stats['switch_time']`, the best of 5, less the in-loop run's): "
        f"**{slide['python_making_per_change_us']:.0f} µs**, and a segment's restart; the walls differ by "
        f"{slide['saved_per_change_us']:.0f} µs. The two runs' final states differ by "
        f"{slide['state_apart']['python']:.1e}, and the atlas's from the one chart's (every state but the "
        f"contacts' coordinates) by {slide['state_apart']['one_chart_body']:.1e}. In the loop the change "
        "costs what the lap's does (one step not taken, a start again) and the turn of two numbers in the "
        "loop's parameters and two in the watch; the walls' difference, one change in a "
        f"{1e3 * slide['in_loop']['wall_s']:.0f} ms run, is within this machine's noise.",
        "",
        "## paper3d's fingers holding a ball (no centre spring), 0.5 s",
        "",
        "| surfaces | switches | steps | wall (ms) | against one chart |",
        "|---|---|---|---|---|",
        *[f"| {k} | {v['switches']} | {v['steps']} | {1e3 * v['wall_s']:.2f} | {v['ratio_to_one_chart']:.3f} |"
          for k, v in g.items() if isinstance(v, dict)],
        "",
        "`atlas_unturned`: atlases placed as the library places them (no rotation): nothing switches,",
        "and chart 1's turn `Q = P` has entries 0 and 1. `atlas_steady`: atlases turned so that their",
        "poles are far from the contacts, nothing switches, and the turn `Q = R P R^T` is a full matrix:",
        "the sphere's chart 1 is chart 0 turned (`derive.bodies3d.surface_sx`), which costs every jet's",
        "vectors a 3x3 product. `atlas_switching`: the poles on the contacts' paths.",
        f"Per switch: {g['per_switch_added_wall_us']:.0f} µs added (2 switches: within this machine's noise).",
        "",
        "## paper3d with a superquadric object (n = 4), `simulate(3.0)` with every default",
        "",
        "| object | rhs (µs) | run (ms) |",
        "|---|---|---|",
        *[f"| {k} | {sq['rhs_us'][k]:.2f} | {1e3 * sq['run_s'][k]:.2f} |" for k in ("one_chart", "atlas")],
        "",
        "An atlas of a surface whose chart 1 is not chart 0 turned (an ellipsoid or superquadric with",
        f"unequal axes) is the blend of its two charts' SymPy forms: rhs {sq['rhs_ratio']:.3f}, run "
        f"{sq['run_ratio']:.3f} times the one chart's. A switch between the charts' own functions",
        "(`Function.conditional`, C's `switch`: one chart evaluated) was measured slower: rhs 2.48 against",
        "2.10 µs (the blend: 2.34), its calls and copies costing more than the blend's extra terms.",
        "",
        "## A torus rolling upright as a wheel, 10.5 turns: a repeating chart",
        "",
        "| torus | wraps | steps | wall (ms) |",
        "|---|---|---|---|",
        *[f"| {k} | {wheel[k]['wraps']} | {wheel[k]['steps']} | {1e3 * wheel[k]['wall_s']:.2f} |"
          for k in ("wrapping", "one_chart")],
        "",
        "`wrapping`: `torus(..., atlas=True)`, its rim's angle over (-3 pi, 3 pi), carried a turn back at",
        "each edge; `one_chart`: the same compiled surface with the angle over +-100 rad (no edge reached).",
        f"**A wrap**: {wheel['per_wrap_us']:.0f} µs per wrap, the walls' difference (made in the C loop at "
        "the step, `c/wrap.c`: the same steps, the same compiled surface, a few additions of work), where "
        f"the same one-chart call timed twice differs by {wheel['noise_per_wrap_us']:.0f} µs per wrap: "
        "nothing this machine can measure. The model is the one chart's, so a run that reaches no edge",
        "costs what it costs without the atlas.",
        "",
    ]
    (RESULTS / "atlas.md").write_text("\n".join(lines))
    print("\n".join(lines))


if __name__ == "__main__":
    main()
