"""Benchmarks of the 3D grasping scene ``paper3d``: build stages, operation counts,
right-hand-side cost and work-precision of the 3 s simulation.

Usage::

    python -m benchmarks.paper3d            # full run (~2-3 minutes), results committed
    python -m benchmarks.paper3d --quick    # smoke test, into results/quick/
    python -m benchmarks.run --only paper3d # the same through the benchmark runner

Writes ``paper3d.md``, ``paper3d.json`` and ``paper3d_work_precision.png``. Every build goes
to private temporary caches; the user's cache is not touched.

- Cold builds run in fresh interpreters on a fresh cache with a scene equal to paper3d but
  named ``paper3d_cold`` (so neither the cache nor the committed ``generated/paper3d/`` C is
  reused). One more fresh process times the build in finer stages than ``model.build_info``
  (whose ``initial_state`` stage also holds the first, cold, SymPy derivation).
- Error of a simulation = max over the 33 state components of |final state - reference
  final state| (raw state difference, SI units: rad, m, rad/s, m/s, quaternion components;
  same start for every run, no quaternion sign flips).
- Timed runs: ``model.simulate(3.0, t_eval=[0, 3], outputs=False, checks=False)``; wall time
  is ``stats['wall_time']`` (integration only), median over the repeats after a first call.
"""
from __future__ import annotations

import argparse
import math
import os
import sys
import tempfile
import time
from pathlib import Path

import casadi as ca
import numpy as np

from benchmarks import work_precision as wp
from benchmarks.rhs_loop import rhs_loop_ns
from benchmarks.timing import best_per_call, in_fresh_process, median
from grasping_sym.errors import GraspingSymError

RESULTS = Path(__file__).resolve().parent / "results"
T_FINAL = wp.T_FINAL          # 3 s, as for paper2d
T_EVAL = wp.T_EVAL
TARGET_ERROR = 1e-8
#: The issue's figures for paper3d.
TARGETS = {"cold_build_s": 30.0, "run_ms": 20.0}

#: Work-precision sweep (one curve per method). Adaptive: atol = rtol * ATOL_FACTOR.
ATOL_FACTOR = 1e-2
#: Curves named ``"<method>" + wp.PROJECTED`` run on ``paper3d_proj`` (stabilisation gain 0)
#: with ``project=True``.
SWEEP = {
    "cvodes": [10.0**-k for k in range(4, 13)],
    "idas": [10.0**-k for k in range(4, 13)],
    "radau": [10.0**-k for k in range(3, 11)],
    "rk4": [5e-3, 2.5e-3, 2e-3, 1.8e-3, 1.6e-3, 1.25e-3, 1e-3, 5e-4, 2e-4, 1e-4],
    "dopri5": [10.0**-k for k in range(3, 11)],
    "radau" + wp.PROJECTED: [10.0**-k for k in range(3, 11)],
    "dopri5" + wp.PROJECTED: [10.0**-k for k in range(3, 12)],
    "dop853" + wp.PROJECTED: [10.0**-k for k in range(3, 12)],
}
QUICK_SWEEP = {"cvodes": [1e-5, 1e-7, 1e-9], "idas": [1e-5, 1e-7, 1e-9],
               "radau": [1e-4, 1e-6, 1e-8], "rk4": [2.5e-3, 1e-3, 2e-4],
               "dopri5": [1e-4, 1e-6, 1e-8], "radau" + wp.PROJECTED: [1e-4, 1e-6],
               "dopri5" + wp.PROJECTED: [1e-4, 1e-6, 1e-8],
               "dop853" + wp.PROJECTED: [1e-4, 1e-6, 1e-8]}
#: Methods searched on the (rtol, atol) grid near error 1e-8.
GRID_METHODS = ("cvodes", "idas", "radau", "dopri5" + wp.PROJECTED, "dop853" + wp.PROJECTED)
#: Extra (rtol, atol) settings of the adaptive methods near error 1e-8 (markers on the plot):
#: near there the error does not fall monotonically with the tolerances, so the cheapest
#: setting reaching 1e-8 is searched on this grid as well.
GRID_RTOLS = [1e-4, 1e-5, 1e-6, 1e-7, 1e-8, 1e-9]
GRID_ATOLS = [1e-8, 1e-9, 1e-10]
QUICK_GRID_RTOLS = [1e-5, 1e-7]
QUICK_GRID_ATOLS = [1e-8]
#: A first call slower than this (s) gets fewer repeats.
SLOW_S = 0.2


def _log(msg: str) -> None:
    print(msg, flush=True)


# ---------------------------------------------------------------------- build stages
_BUILD = """
import json, time
import grasping_sym as gs
build = gs.build  # the package imports lazily: import the build stack before the clock starts
t0 = time.perf_counter()
scene = gs.scenes.paper3d(name={name!r})
t1 = time.perf_counter()
model = gs.build(scene, force={force})
t2 = time.perf_counter()
print(json.dumps({{"scene_s": t1 - t0, "build_s": t2 - t1, "info": model.build_info,
                  "op_counts": model.manifest["op_counts"]}}))
"""

# The pipeline's own stages (pipeline.generate + compile_library), with the SymPy work that
# ``generate`` does inside its first stage pulled out in front and timed on its own. The
# private helpers called first are the very calls (same arguments, same lru_cache keys) that
# derive_grasp3d and initial3d make.
_STAGED = """
import json, time, tempfile
from pathlib import Path
import numpy as np
import sympy as sp
import grasping_sym as gs
from grasping_sym import pipeline
from grasping_sym.assemble.controller import controller_torques
from grasping_sym.assemble.functions import sx_model
from grasping_sym.derive import grasp3d as g3

T = {{}}
t = time.perf_counter()
def lap(key):
    global t
    now = time.perf_counter()
    T[key] = now - t
    t = now
scene = gs.scenes.paper3d(name="paper3d_staged")
lap("scene")
g = None if scene.gravity is None else tuple(float(v) for v in scene.gravity)
surfaces = [f.tip for f in scene.fingers] + [scene.object_surface]
for f in scene.fingers:
    g3._finger_symbolic(f.chain, g)
lap("sympy_fingers")
for s in surfaces:
    s.S, s.frame, s.montana_metric, s.curvature_form, s.torsion_form
g3._generic_rates()
lap("sympy_surfaces_rates")
sysm = g3.derive_grasp3d(scene, torques=controller_torques)
lap("translate_and_ad")
for f in scene.fingers:
    g3._finger_symbolic(f.chain, None)
lap("sympy_fingers_again_for_start")
directory = Path(tempfile.mkdtemp(prefix="gs-bench-staged-"))
manifest = pipeline.generate(scene, directory, count_ops=False)
lap("generate")
pipeline.solve_start(scene)
lap("start")
timings = manifest.pop("timings")
pipeline.compile_library(directory, manifest)
lap("compile")

# not timed as stages: op counts of the SymPy building blocks and of a generated Jacobian
exprs = []
for f in scene.fingers:
    kin, dyn = g3._finger_symbolic(f.chain, g)
    for M in (kin.r, kin.Pi, kin.J, kin.W, dyn.G, dyn.h, dyn.gravity_gradient,
              sp.Matrix([dyn.potential_energy])):
        exprs += list(sp.Matrix(M))
for s in surfaces:
    x, y, n = s.frame
    for M in (s.S, x, y, n, s.montana_metric, s.curvature_form, s.torsion_form):
        exprs += list(sp.Matrix(M))
exprs += list(g3._generic_rates()[4])
before = sum(sp.count_ops(e) for e in exprs)
repl, red = sp.cse(exprs, optimizations=None)
after = sum(sp.count_ops(r) for _, r in repl) + sum(sp.count_ops(e) for e in red)
t0 = time.perf_counter()
jac = sx_model(sysm.x, sysm.p, sysm.xdot, {{}}, "jac_count", jacobian=False).rhs.jacobian()
n_jac = jac.n_instructions()
jac_s = time.perf_counter() - t0
print(json.dumps({{"stages": T, "generate_timings": timings, "op_counts": manifest["op_counts"],
                  "sympy_ops_before_cse": int(before), "sympy_ops_after_cse": int(after),
                  "sympy_expressions": len(exprs), "jac_sx_instructions_if_generated": n_jac,
                  "jac_function_s": jac_s}}))
"""


def _summary(runs: list[dict]) -> dict:
    out = {"runs": runs, "n": len(runs), "source": runs[0]["info"].get("source"),
           "scene_s": median([r["scene_s"] for r in runs]),
           "build_s": median([r["build_s"] for r in runs])}
    for k in ("structure", "structure_compile", "compose", "write_c", "compile", "start", "total"):
        vals = [r["info"][k] for r in runs if k in r["info"]]
        if vals:
            out[k + "_s"] = median(vals)
    return out


def build_stages(*, quick: bool, main_cache: Path, log=_log) -> dict:
    """Cold builds, a staged cold build, the committed-C build and cached loads, each in a
    fresh interpreter (``import grasping_sym`` not counted)."""
    n_cold, n_cached = (1, 2) if quick else (2, 3)
    res: dict = {}
    with tempfile.TemporaryDirectory(prefix="gs-bench-paper3d-") as tmp:
        cold = []
        for i in range(n_cold):
            cold.append(in_fresh_process(_BUILD.format(name="paper3d_cold", force=True),
                                         Path(tmp) / f"cold{i}"))
            log(f"  cold build #{i + 1}: gs.build {cold[-1]['build_s']:.2f} s "
                f"({cold[-1]['info']['source']}), scene() {cold[-1]['scene_s']:.2f} s")
        res["cold"] = _summary(cold)
        cached = [in_fresh_process(_BUILD.format(name="paper3d_cold", force=False),
                                   Path(tmp) / "cold0") for _ in range(n_cached)]
        for c in cached:
            if c["info"].get("source") != "cache":
                raise RuntimeError(f"expected a cached load, got {c['info']}")
        res["cached"] = _summary(cached)
        log(f"  cached load: gs.build {res['cached']['build_s'] * 1e3:.1f} ms, "
            f"scene() {res['cached']['scene_s'] * 1e3:.0f} ms")
        staged = in_fresh_process(_STAGED.format(), Path(tmp) / "staged")
        res["staged"] = staged
        log(f"  staged: {', '.join(f'{k} {v:.2f} s' for k, v in staged['stages'].items())}")
    # the committed C, built into the main private cache so that this process loads it
    committed = in_fresh_process(_BUILD.format(name="paper3d", force=False), main_cache)
    res["committed_c"] = _summary([committed])
    log(f"  committed C: gs.build {committed['build_s']:.2f} s ({committed['info']['source']})")
    return res


# ---------------------------------------------------------------------- reference
def reference(model, *, quick: bool, log=_log) -> dict:
    """Final state at 3 s by several methods at tolerances ~1e-13; pairwise differences.

    The reference is CVODES at rtol = atol = 1e-14; the cross-check by a second method is
    the C Radau IIA at rtol = atol = 1e-13 (its tightest tolerances work on paper3d).
    """
    specs = [("cvodes 1e-14", "cvodes", dict(rtol=1e-14, atol=1e-14)),
             ("radau 1e-13", "radau", dict(rtol=1e-13, atol=1e-13))]
    if quick:
        specs[1] = ("radau 1e-12", "radau", dict(rtol=1e-12, atol=1e-12))
    else:
        specs += [("cvodes 1e-13", "cvodes", dict(rtol=1e-13, atol=1e-13)),
                  ("idas 1e-13", "idas", dict(rtol=1e-13, atol=1e-13)),
                  ("radau 1e-12", "radau", dict(rtol=1e-12, atol=1e-12)),
                  ("rk4 h=2e-5", "rk4", dict(h=2e-5))]
    runs = {}
    for label, method, kw in specs:
        t0 = time.perf_counter()
        r = model.simulate(T_FINAL, method=method, t_eval=T_EVAL, outputs=False, checks=False,
                           **kw)
        runs[label] = {"method": method, **kw, "x_final": r.x[-1].tolist(),
                       "wall_s": time.perf_counter() - t0, "stats": r.stats}
    labels = list(runs)
    diffs = {a: {b: wp.err(runs[a]["x_final"], runs[b]["x_final"]) for b in labels}
             for a in labels}
    chosen, check = labels[0], labels[1]
    d = np.array(runs[chosen]["x_final"]) - np.array(runs[check]["x_final"])
    worst = int(np.argmax(np.abs(d)))
    log(f"  reference {chosen}; {check} differs by {diffs[chosen][check]:.2e} "
        f"(largest in {model.state_names[worst]})")
    return {"chosen": chosen, "cross_check": check, "difference": diffs[chosen][check],
            "difference_state": model.state_names[worst],
            "x_ref": runs[chosen]["x_final"], "runs": runs, "pairwise": diffs}


# ---------------------------------------------------------------------- rhs cost
def rhs_cost(model, x: np.ndarray, *, quick: bool) -> dict:
    """Seconds per evaluation of the compiled rhs along the call paths (best of repeats)."""
    rep = 3 if quick else 7
    x = np.ascontiguousarray(x, dtype=float)
    per_call_target = 0.1 if quick else 0.3        # seconds of C loop per repeat
    t1 = rhs_loop_ns(model, x, 1000) * 1e-9
    n_loop = max(1000, int(per_call_target / max(t1, 1e-9)))
    out: dict = {"c_loop_ns": min(rhs_loop_ns(model, x, n_loop) for _ in range(rep)),
                 "c_loop_calls": n_loop}
    number = max(200, int(0.1 / max(t1, 1e-9)))
    out["python_rhs_us"] = best_per_call(lambda: model.rhs(x), number=number, repeat=rep) * 1e6
    batch = {}
    for n in (1, 10, 100, 10_000):
        X = np.ascontiguousarray(np.tile(x, (n, 1)))
        nb = max(1, number // n)
        per_call = best_per_call(lambda X=X: model.rhs_batch(X), number=nb, repeat=rep)
        batch[str(n)] = {"us_per_call": per_call * 1e6, "us_per_state": per_call * 1e6 / n}
    out["rhs_batch"] = batch
    ext = model.external_rhs()
    e = np.zeros(0)
    p = model.default_params  # the centre spring's rest point: a run-time input
    out["casadi_external_call_us"] = best_per_call(lambda: ext(0.0, x, e, p, e), number=500,
                                                   repeat=rep) * 1e6
    n_instr = model.manifest["op_counts"]["rhs_sx_instructions"]
    out["rhs_sx_instructions"] = n_instr
    out["ns_per_instruction"] = out["c_loop_ns"] / n_instr
    return out


# ---------------------------------------------------------------------- work-precision
def _setting_label(row: dict) -> str:
    return f"h={row['h']:g}" if "h" in row else f"rtol={row['rtol']:g} atol={row['atol']:g}"


def time_setting(model, method: str, kw: dict, x_ref: np.ndarray, quat: slice, *,
                 repeats: int, label: str | None = None, log=_log) -> dict:
    """First call, then the timed calls; error, counters, quaternion norm and dense
    diagnostics (``work_precision.dense_diagnostics``: constraint residual, energy drift).
    ``label`` names the curve (default ``method``)."""
    row: dict = {"method": label or method, **kw}
    run = dict(method=method, t_eval=T_EVAL, outputs=False, checks=False, **kw)
    try:
        t0 = time.perf_counter()
        r = model.simulate(T_FINAL, **run)
        row["first_call_s"] = time.perf_counter() - t0
    except GraspingSymError as exc:
        row["failed"] = str(exc).splitlines()[0][:300]
        row["error"] = math.inf
        log(f"  {row['method']:7s} {_setting_label(row):26s} FAILED: {row['failed'][:90]}")
        return row
    n = repeats if row["first_call_s"] < SLOW_S else max(3, repeats // 2)
    walls, calls = [], []
    for _ in range(n):
        t0 = time.perf_counter()
        r = model.simulate(T_FINAL, **run)
        calls.append(time.perf_counter() - t0)
        walls.append(r.stats["wall_time"])
    xf = r.x[-1]
    row.update({"wall_s": median(walls), "wall_min_s": min(walls), "call_s": median(calls),
                "repeats": n, "error": wp.err(xf, x_ref), "stats": r.stats,
                "quat_norm_error": abs(float(np.linalg.norm(xf[quat])) - 1.0)})
    row.update(wp.dense_diagnostics(model, method, kw))
    log(f"  {row['method']:7s} {_setting_label(row):26s} {row['wall_s'] * 1e3:8.2f} ms  "
        f"err {row['error']:.1e}  residual {row.get('max_constraint_residual', math.nan):.1e}  "
        f"drift {row.get('energy_drift_J', math.nan):.1e} J")
    return row


def work_precision(model, x_ref: np.ndarray, *, quick: bool, proj_model=None,
                   log=_log) -> tuple[list, list]:
    """The sweep (one curve per method) and the grid near error 1e-8. ``proj_model``: the
    scene with its stabilisation gain at 0, for the projection curves (skipped when None)."""
    repeats = 3 if quick else 7
    quat = slice(model.state_names.index("qw"), model.state_names.index("qz") + 1)
    sweep = sweep_of(quick)

    def run(label, kw):
        method, projected = wp.variant(label)
        if projected:
            return time_setting(proj_model, method, {**kw, "project": True}, x_ref, quat,
                                repeats=repeats, label=label, log=log)
        return time_setting(model, method, kw, x_ref, quat, repeats=repeats, log=log)

    rows = []
    for label, values in sweep.items():
        if wp.variant(label)[1] and proj_model is None:
            continue
        for v in values:
            rows.append(run(label, {"h": v} if label == "rk4" else
                            {"rtol": v, "atol": v * ATOL_FACTOR}))
    grid = []
    log("  grid near 1e-8:")
    for label in GRID_METHODS:
        if wp.variant(label)[1] and proj_model is None:
            continue
        for rtol in (QUICK_GRID_RTOLS if quick else GRID_RTOLS):
            for atol in (QUICK_GRID_ATOLS if quick else GRID_ATOLS):
                if math.isclose(atol, rtol * ATOL_FACTOR, rel_tol=1e-9):
                    continue                    # already in the sweep
                grid.append(run(label, {"rtol": rtol, "atol": atol}))
    return rows, grid


def at_target(rows: list[dict], target: float = TARGET_ERROR) -> dict:
    """Per method: cheapest measured setting with error <= target, and the wall time
    interpolated at the target on its Pareto front (``work_precision.time_at_error``)."""
    out = {}
    for method in dict.fromkeys(r["method"] for r in rows):
        mine = [r for r in rows if r["method"] == method and "wall_s" in r]
        ok = [r for r in mine if r["error"] <= target]
        best = min(ok, key=lambda r: r["wall_s"]) if ok else None
        out[method] = {
            "cheapest": None if best is None else {
                k: best[k] for k in ("rtol", "atol", "h", "wall_s", "wall_min_s", "call_s",
                                     "error", "max_constraint_residual", "energy_drift_J")
                if k in best},
            "interpolated": wp.time_at_error([(r["error"], r["wall_s"]) for r in mine], target),
        }
    return out


# ---------------------------------------------------------------------- where the time goes
def sundials_breakdown(model, x_ref: np.ndarray, settings: list[dict], *, quick: bool) -> list:
    """CVODES / IDAS with CasADi's ``record_time``: the package's options (the Jacobian by
    CasADi's forward differences of the compiled rhs, ``model.external_rhs()``) and, for
    comparison, the same with CasADi's default ``fd_method`` (central differences)."""
    x0 = model.initial_state()
    out = []
    for s in settings:
        for fd in ("default", "forward"):
            fopts = {"enable_fd": True} if fd == "default" else {"enable_fd": True,
                                                                  "fd_method": "forward"}
            ext = ca.external(f"{model.name}_rhs", str(model.library_path), fopts)
            opts = {"abstol": s["atol"], "reltol": s["rtol"], "max_num_steps": 1_000_000,
                    "disable_internal_warnings": True, "record_time": True}
            integ = ca.integrator("bench", s["method"], ext, 0.0, [T_FINAL], opts)
            integ(x0=x0, p=model.default_params)
            walls = []
            for _ in range(3 if quick else 5):
                t0 = time.perf_counter()
                r = integ(x0=x0, p=model.default_params)
                walls.append(time.perf_counter() - t0)
            st = integ.stats()
            total, rhs_t, jac_t = st["t_wall_total"], st["t_wall_daeF"], st["t_wall_jacF"]
            out.append({
                "method": s["method"], "rtol": s["rtol"], "atol": s["atol"], "fd_method": fd,
                "wall_s": median(walls), "error": wp.err(np.array(r["xf"]).ravel(), x_ref),
                "total_s": total, "rhs_s": rhs_t, "jac_s": jac_t,
                "other_s": total - rhs_t - jac_t, "n_steps": st["nsteps"],
                "n_rhs": st["n_call_daeF"], "n_jac": st["n_call_jacF"],
                "us_per_jac_call": jac_t / max(1, st["n_call_jacF"]) * 1e6,
            })
    return out


def radau_breakdown(rows: list[dict], nx: int) -> list[dict]:
    """Share of the C Radau's rhs calls spent on its forward-difference Jacobians (nx each)."""
    out = []
    for r in rows:
        if r["method"] != "radau" or "stats" not in r:
            continue
        st = r["stats"]
        fd = st["n_jac"] * nx
        out.append({"rtol": r["rtol"], "atol": r["atol"], "wall_s": r["wall_s"],
                    "n_steps": st["n_steps"], "n_rhs": st["n_rhs"], "n_jac": st["n_jac"],
                    "n_lu": st.get("n_lu"), "fd_share": fd / max(1, st["n_rhs"]),
                    "us_per_rhs": r["wall_s"] / max(1, st["n_rhs"]) * 1e6})
    return out


def sweep_of(quick: bool) -> dict:
    return QUICK_SWEEP if quick else SWEEP


# ---------------------------------------------------------------------- driver
def run(*, quick: bool, log=_log) -> dict:
    import grasping_sym as gs
    from benchmarks.machine import machine_info

    t_start = time.perf_counter()
    res: dict = {"scene": "paper3d", "quick": quick, "machine": machine_info(),
                 "targets": TARGETS, "target_error": TARGET_ERROR}
    log(f"machine: {res['machine']['cpu']}, {res['machine']['logical_cores']} cores, "
        f"load {res['machine']['load_average_1_5_15']}")
    log("paper3d 1. build stages (fresh processes, private caches)")
    res["build"] = build_stages(quick=quick, main_cache=Path(os.environ["GRASPING_SYM_CACHE"]),
                                log=log)
    # the curves without projection run the scene with a stabilisation gain (300 1/s):
    # paper3d's own is 0, its runs projecting (proj_model below)
    scene = gs.scenes.paper3d(gain=300.0, name="paper3d_gain300")
    model = gs.build(scene)
    model2d = gs.build(gs.scenes.paper2d())
    staged = res["build"]["staged"]
    res["op_counts"] = {
        "paper3d": {**model.manifest["op_counts"],
                    "jac_sx_instructions_if_generated": staged["jac_sx_instructions_if_generated"],
                    "sympy_ops_before_cse": staged["sympy_ops_before_cse"],
                    "sympy_ops_after_cse": staged["sympy_ops_after_cse"],
                    "sympy_expressions": staged["sympy_expressions"]},
        "paper2d": dict(model2d.manifest["op_counts"]),
    }
    log(f"  op counts: {res['op_counts']['paper3d']}")

    log("paper3d 2. reference")
    res["reference"] = reference(model, quick=quick, log=log)
    x_ref = np.array(res["reference"]["x_ref"])

    log("paper3d 3. rhs cost (paper3d and paper2d)")
    traj3 = model.simulate(T_FINAL, rtol=1e-10, atol=1e-12, t_eval=np.linspace(0, T_FINAL, 31),
                           outputs=False).x
    traj2 = model2d.simulate(T_FINAL, rtol=1e-10, atol=1e-12,
                             t_eval=np.linspace(0, T_FINAL, 31), outputs=False).x
    res["rhs"] = {"paper3d": rhs_cost(model, traj3[len(traj3) // 3], quick=quick),
                  "paper2d": rhs_cost(model2d, traj2[len(traj2) // 3], quick=quick)}
    for k, v in res["rhs"].items():
        log(f"  {k}: C loop {v['c_loop_ns']:.0f} ns, model.rhs {v['python_rhs_us']:.2f} us, "
            f"rhs_batch(10000) {v['rhs_batch']['10000']['us_per_state']:.2f} us/state")

    log("paper3d 4. work-precision")
    # the same scene without Baumgarte stabilisation, for the curves with projection
    proj_model = gs.build(gs.scenes.paper3d(name="paper3d_proj", gain=0.0))
    res["compiled"], res["grid"] = work_precision(model, x_ref, quick=quick,
                                                  proj_model=proj_model, log=log)
    res["baseline"] = []               # no lambdify baseline for 3D
    res["at_target"] = at_target(res["compiled"] + res["grid"])
    for m, v in res["at_target"].items():
        c = v["cheapest"]
        log(f"  {m}: cheapest <= 1e-8: " + ("none" if c is None else
            f"{c['wall_s'] * 1e3:.2f} ms ({_setting(c)}, err {c['error']:.1e})"))
    # where the time goes: SUNDIALS at their cheapest settings <= 1e-8 and at rtol 1e-8
    settings = []
    for m in ("cvodes", "idas"):
        c = res["at_target"].get(m, {}).get("cheapest")
        if c is not None:
            settings.append({"method": m, "rtol": c["rtol"], "atol": c["atol"]})
        s = {"method": m, "rtol": 1e-8, "atol": 1e-8 * ATOL_FACTOR}
        if not any(x["method"] == m and x["rtol"] == s["rtol"] and x["atol"] == s["atol"]
                   for x in settings):
            settings.append(s)
    res["breakdown"] = sundials_breakdown(model, x_ref, settings, quick=quick)
    res["radau_breakdown"] = radau_breakdown(res["compiled"], len(model.state_names))

    log("paper3d 5. peer: CasADi without compilation")
    from benchmarks import peer_curves
    res["peers"] = peer_curves.casadi_rows(scene, model, model, x_ref,
                                           sweep_of(quick)["cvodes"], quick=quick, log=log)
    ours = res["compiled"] + res["grid"]
    res["peers_equal_error"] = wp.peers_at_equal_error(ours, {
        peer_curves.CASADI: [r for r in res["peers"] if r.get("peer") == peer_curves.CASADI]})
    res["method_choice"] = wp.method_choice(ours)
    res["load_average_end"] = [round(v, 2) for v in os.getloadavg()]
    res["total_s"] = time.perf_counter() - t_start
    return res


# ---------------------------------------------------------------------- report
def _setting(r: dict) -> str:
    from benchmarks.report import _setting as setting
    return setting(r)


def summary_rows(res: dict) -> list[tuple[str, str, str, str]]:
    from benchmarks.report import _ms, _status, peer_summary_rows

    cold = res["build"]["cold"]
    rows = [("cold build of paper3d (`gs.build`, fresh cache, fresh process; no model C "
             "reused, its structure's committed C compiled)",
             f"≤ {TARGETS['cold_build_s']:g} s",
             f"{cold['build_s']:.1f} s (median of {cold['n']}; + {cold['scene_s']:.2f} s "
             f"constructing the scene)",
             _status(cold["build_s"], TARGETS["cold_build_s"]))]
    best = [(m, v["cheapest"]) for m, v in res["at_target"].items() if v["cheapest"]]
    if best:
        m, c = min(best, key=lambda mc: mc[1]["wall_s"])
        interp = [(mm, v["interpolated"]["time_s"]) for mm, v in res["at_target"].items()
                  if v["interpolated"]]
        text = (f"{_ms(c['wall_s'])} ms: {m}, {_setting(c)} (error {c['error']:.1e}; "
                f"fastest run {_ms(c['wall_min_s'])} ms)")
        if interp:
            mi, ti = min(interp, key=lambda x: x[1])
            text += f"; interpolated at exactly 1e-8: {_ms(ti)} ms ({mi})"
        status = _status(c["wall_s"] * 1e3, TARGETS["run_ms"])
    else:
        text, status = "no setting reached 1e-8", "not reached"
    rows.append(("paper3d 3 s simulation at final-state error ≤ 1e-8, median wall time "
                 "excluding build", f"≤ {TARGETS['run_ms']:g} ms", text, status))
    rows += peer_summary_rows(res["peers_equal_error"], {})
    return rows


def write_markdown(res: dict, path: Path) -> None:
    from benchmarks.report import _table

    mi = res["machine"]
    L = [
        "# paper3d benchmark",
        "",
        f"Generated by `python -m benchmarks.paper3d{' --quick' if res['quick'] else ''}` "
        f"on {mi['date_utc']} UTC (total {res['total_s']:.0f} s). Do not edit by hand.",
        "",
        "## Summary against the issue's figures",
        "",
        *_table(["figure", "target", "measured", "status"], [list(r) for r in summary_rows(res)]),
        "",
        *_fd_note(res),
        "Absolute times hold for this machine and its load only (below); ratios between "
        "methods measured in the same run travel better.",
        "",
        "## Machine",
        "",
        f"- CPU: {mi['cpu']}; {mi['logical_cores']} logical cores "
        f"({mi['usable_cores']} usable by this process)",
        f"- load average (1, 5, 15 min) at start {mi['load_average_1_5_15']}, at end "
        f"{res['load_average_end']} (other work shared the machine when the load exceeds 1)",
        f"- {mi['os']}; Python {mi['python']}; {mi['gcc']}",
        "- " + ", ".join(f"{k} {v}" for k, v in mi["versions"].items()),
        f"- git commit {mi['git_commit']}",
        "",
    ]
    L += (_build_md(res) + _ops_md(res) + _rhs_md(res) + _ref_md(res) + _wp_md(res)
          + _peers_md(res))
    path.write_text("\n".join(L) + "\n")


def _fd_note(res: dict) -> list[str]:
    """One sentence: what forward differences (the package's) save CVODES/IDAS (section 5)."""
    from benchmarks.report import _ms

    ok = [d for d in res["breakdown"] if d["fd_method"] == "forward" and d["error"] <= TARGET_ERROR]
    if not ok:
        return []
    d = min(ok, key=lambda d: d["wall_s"])
    same = [e for e in res["breakdown"] if e["fd_method"] == "default" and e["method"] ==
            d["method"] and e["rtol"] == d["rtol"] and e["atol"] == d["atol"]]
    return [f"Much of the CVODES/IDAS time is CasADi's finite-difference Jacobian of the compiled "
            f"rhs (section 5). The package asks for forward differences "
            f"(`model.external_rhs()`): {d['method']} at {_setting(d)} takes "
            f"{_ms(d['wall_s'])} ms (error {d['error']:.1e})"
            + (f", against {_ms(same[0]['wall_s'])} ms with CasADi's default (central) "
               "differences" if same else "")
            + ".", ""]


def _build_md(res: dict) -> list[str]:
    from benchmarks.report import _ms, _table

    b = res["build"]
    rows = []
    for label, d in (("paper3d_cold: cold (`force=True`, fresh cache)", b["cold"]),
                     ("paper3d: fresh cache, no `force` (compiles the committed C)",
                      b["committed_c"]),
                     ("paper3d_cold: cached (warm cache)", b["cached"])):
        rows.append([label, d["n"], d["source"], *[_ms(d.get(k)) for k in
                     ("structure_s", "structure_compile_s", "compose_s", "write_c_s",
                      "compile_s", "start_s", "total_s")], _ms(d["build_s"]), _ms(d["scene_s"])])
    st = b["staged"]["stages"]
    gt = b["staged"]["generate_timings"]
    staged_rows = [
        ["SymPy: the two fingers' kinematics and Lagrangian dynamics (with gravity)",
         st["sympy_fingers"]],
        ["SymPy: surfaces' frames and forms, Montana's contact rates",
         st["sympy_surfaces_rates"]],
        ["SymPy → CasADi SX translation + CasADi AD (constraint Jacobians, second "
         "derivatives): `derive_grasp3d`", st["translate_and_ad"]],
        ["SymPy again: the fingers without gravity (a second `lru_cache` key, asked for by "
         "the start solver `initial3d`)", st["sympy_fingers_again_for_start"]],
        [f"`pipeline.generate`: the structure ({gt.get('structure_source')}; derived: "
         "`derive_grasp3d` with the surfaces' jets as inputs, CSE, write C)",
         gt.get("structure", 0.0)],
        ["gcc: the structure's C (once per structure)", gt.get("structure_compile", 0.0)],
        ["`pipeline.generate`: the surfaces' jets and the glue (CasADi)", gt.get("compose", 0.0)],
        ["`pipeline.generate`: write the model's C", gt["write_c"]],
        ["gcc: compile the model's C and link (the driver's objects once per set of sizes)",
         st["compile"]],
        ["`pipeline.solve_start`: consistent start (Gauss-Newton, SymPy warm)", st["start"]],
    ]
    total = sum(v for k, v in st.items() if k != "scene")
    staged_rows.append(["**total** (scene construction not counted)", total])
    staged_rows = [[a, f"{v:.3f}"] for a, v in staged_rows]
    cold = b["cold"]
    derivation = (st["sympy_fingers"] + st["sympy_surfaces_rates"] + st["translate_and_ad"]
                  + st["sympy_fingers_again_for_start"] + st["start"] + gt.get("structure", 0.0))
    return [
        "## 1. Build stages",
        "",
        "Each build ran in a fresh interpreter after `import grasping_sym` (not counted), with "
        "`GRASPING_SYM_CACHE` set to a new temporary directory; medians over `n` runs, in ms. "
        "The cold build uses `gs.scenes.paper3d(name='paper3d_cold')`: the same scene under "
        "another name, so neither a cache nor the committed `generated/paper3d/` C is reused. "
        "Columns are `model.build_info` (`structure`: the scene's structure, from the cache, "
        "the committed C, or derived with SymPy and CasADi's AD and written; `structure "
        "compile`: its gcc, once per structure; `compose`: the surfaces' jets and the glue; "
        "`start` solves the consistent start after the code is compiled, apart from it, SymPy "
        "warm); `gs.build` is the wall time of the call; `scene()` is constructing the scene "
        "object. paper3d under another name shares paper3d's structure (its C is committed).",
        "",
        *_table(["build", "n", "source", "structure", "structure compile", "compose", "write C",
                 "compile", "start", "total", "gs.build", "scene()"], rows),
        "",
        "### Cold build in finer stages",
        "",
        "One more fresh process, timing the calls `gs.build` makes one by one (seconds); the "
        "SymPy work is called first on its own (the same calls, with the same cache keys, "
        "that `derive_grasp3d` and `initial3d` make inside `generate`).",
        "",
        *_table(["stage", "s"], staged_rows),
        "",
        f"In this staged run: derivation (SymPy + translation + AD + start) ≈ {derivation:.1f} s, "
        f"generation (jets, glue, write C) ≈ {gt.get('compose', 0.0) + gt['write_c']:.2f} s, compilation ≈ "
        f"{st['compile']:.1f} s (the median cold `gs.build` above: {cold['build_s']:.1f} s, "
        f"compile {cold.get('compile_s', math.nan):.1f} s). The SymPy derivation of the "
        f"fingers runs twice "
        f"({st['sympy_fingers']:.2f} s + {st['sympy_fingers_again_for_start']:.2f} s): the "
        "start solver asks for them without gravity, a separate cache entry.",
        "",
    ]


def _ops_md(res: dict) -> list[str]:
    from benchmarks.report import _table

    o3, o2 = res["op_counts"]["paper3d"], res["op_counts"]["paper2d"]

    def g(d, k):
        v = d.get(k)
        return "–" if v is None else f"{v:,}"

    return [
        "## 2. Operation counts",
        "",
        "CasADi SX instructions of the generated functions (`model.manifest['op_counts']`); "
        "'before CSE' is the SX graph as built (shared subexpressions of the graph already "
        "shared), 'after' with CasADi's common-subexpression elimination, as compiled. "
        "paper2d for scale (its rhs comes from the 2D template; it also has a generated "
        "Jacobian).",
        "",
        *_table(["quantity", "paper3d", "paper2d"], [
            ["rhs SX instructions, before CSE", g(o3, "rhs_sx_instructions_before_cse"),
             g(o2, "rhs_sx_instructions_before_cse")],
            ["rhs SX instructions, after CSE (compiled)", g(o3, "rhs_sx_instructions"),
             g(o2, "rhs_sx_instructions")],
            ["outputs SX instructions", g(o3, "outputs_sx_instructions"),
             g(o2, "outputs_sx_instructions")],
            ["rhs Jacobian SX instructions", g(o3, "jac_sx_instructions_if_generated")
             + " (not generated: counted only)", g(o2, "jac_sx_instructions")],
            ["SymPy operations of the SymPy building blocks, before `sympy.cse`",
             g(o3, "sympy_ops_before_cse"), g(o2, "sympy_ops_before_cse")],
            ["SymPy operations after `sympy.cse`", g(o3, "sympy_ops_after_cse"),
             g(o2, "sympy_ops_after_cse")],
        ]),
        "",
        f"For paper3d the SymPy part is small by design: the {o3['sympy_expressions']} SymPy "
        "expressions are the fingers' kinematics and dynamics, the surfaces' frames and forms "
        "and Montana's rates; the constraint Jacobians and second derivatives are taken by "
        "CasADi's AD on the SX graph (the 2D row counts the whole derived system).",
        "",
    ]


def _rhs_md(res: dict) -> list[str]:
    from benchmarks.report import _table

    r3, r2 = res["rhs"]["paper3d"], res["rhs"]["paper2d"]
    rows = [["compiled C, loop in C (`benchmarks/rhs_loop.py`)", f"{r3['c_loop_ns'] / 1e3:.3f}",
             f"{r2['c_loop_ns'] / 1e3:.3f}"],
            ["`model.rhs(x)` (one Python call)", f"{r3['python_rhs_us']:.3f}",
             f"{r2['python_rhs_us']:.3f}"]]
    for n in r3["rhs_batch"]:
        rows.append([f"`model.rhs_batch(X)`, n = {n} (per state)",
                     f"{r3['rhs_batch'][n]['us_per_state']:.3f}",
                     f"{r2['rhs_batch'][n]['us_per_state']:.3f}"])
    rows += [["CasADi `Function.__call__` on `model.external_rhs()`",
              f"{r3['casadi_external_call_us']:.2f}", f"{r2['casadi_external_call_us']:.2f}"],
             ["SX instructions of the rhs", str(r3["rhs_sx_instructions"]),
              str(r2["rhs_sx_instructions"])],
             ["ns per SX instruction (C loop)", f"{r3['ns_per_instruction']:.3f}",
              f"{r2['ns_per_instruction']:.3f}"]]
    return [
        "## 3. Right-hand side cost",
        "",
        "µs per evaluation (per state for the batch), best of several repeats, at a state on "
        "the trajectory at t = 1 s; both scenes measured in this run.",
        "",
        *_table(["call path", "paper3d µs", "paper2d µs"], rows),
        "",
        f"paper3d's rhs costs {r3['c_loop_ns'] / r2['c_loop_ns']:.1f}× paper2d's for "
        f"{r3['rhs_sx_instructions'] / r2['rhs_sx_instructions']:.1f}× the instructions.",
        "",
    ]


def _ref_md(res: dict) -> list[str]:
    from benchmarks.report import _e, _ms, _table

    ref = res["reference"]
    labels = list(ref["runs"])
    rows = [[a, _ms(ref["runs"][a]["wall_s"]), ref["runs"][a]["stats"].get("n_steps"),
             *[_e(ref["pairwise"][a][b]) if a != b else "–" for b in labels]] for a in labels]
    # a candidate farther from every other than they are from each other
    notes, outliers = [], []
    for a in labels:
        others = [ref["pairwise"][a][b] for b in labels if b != a]
        rest = [ref["pairwise"][b][c] for b in labels for c in labels if a not in (b, c) and b != c]
        if len(others) > 1 and rest and min(others) > 3 * max(rest):
            notes.append(f"{a} differs from all the other candidates by {min(others):.1e} or more, "
                         f"while they agree to {max(rest):.1e}: an outlier, not used.")
            outliers.append(a)
    kept = [a for a in labels if a not in outliers]
    spread = max([ref["pairwise"][a][b] for a in kept for b in kept if a != b] or [math.nan])
    return [
        "## 4. Reference final state",
        "",
        f"**Reference**: {ref['chosen']} (rtol = atol), `t_eval = [0, 3]`. **Second method**: "
        f"{ref['cross_check']} (the C Radau IIA; its tightest tolerances work on paper3d, "
        f"unlike paper2d's atol ≥ 1e-10). Their difference: **{_e(ref['difference'])}** "
        f"(max over the state, largest in {ref['difference_state']}); all the candidates "
        f"below but outliers agree to {_e(spread)}, the floor below which errors are not "
        "resolved. Error measure: raw state difference, max over the 33 "
        "components (the quaternion included: same start, no sign flips). Pairwise max-norm "
        "differences of the candidates (wall ms):",
        "",
        *_table(["run", "wall ms", "steps", *labels], rows),
        "",
        *[n + "\n" for n in notes],
    ]


def _wp_md(res: dict) -> list[str]:
    from benchmarks.report import _e, _ms, _table

    def row(r):
        if "failed" in r:
            return [r["method"], _setting(r), "failed", "", "", "", "∞", "", "", "", "", "",
                    r["failed"][:90].replace("|", "/")]
        st = r["stats"]
        return [r["method"], _setting(r), _ms(r["wall_s"]), _ms(r["wall_min_s"]),
                _ms(r["first_call_s"]), r["repeats"], _e(r["error"]), st["n_steps"],
                st["n_rhs"], st.get("n_jac", "–"), _e(r.get("max_constraint_residual")),
                _e(r.get("energy_drift_J")), _e(r.get("quat_norm_error"))]

    header = ["method", "setting", "wall ms (median)", "min ms", "first call ms", "runs",
              "error", "steps", "rhs evals", "jac evals", "constraint residual m",
              "energy drift J", "‖quat‖ − 1"]
    at_rows = []
    for m, v in res["at_target"].items():
        c, i = v["cheapest"], v["interpolated"]
        at_rows.append([m, "–" if c is None else _setting(c),
                        "–" if c is None else _ms(c["wall_s"]),
                        "–" if c is None else _e(c["error"]),
                        "–" if c is None else _e(c.get("max_constraint_residual")),
                        "–" if c is None else _e(c.get("energy_drift_J")),
                        "–" if i is None else _ms(i["time_s"])])
    bd_rows = [[d["method"], _setting(d), "CasADi's default (central)" if d["fd_method"] ==
                "default" else "`forward` (the package's)", _ms(d["wall_s"]), _e(d["error"]),
                _ms(d["total_s"]), _ms(d["rhs_s"]), _ms(d["jac_s"]), _ms(d["other_s"]),
                d["n_steps"], d["n_rhs"],
                d["n_jac"], f"{d['us_per_jac_call']:.0f}"] for d in res["breakdown"]]
    rd_rows = [[_setting(d), _ms(d["wall_s"]), d["n_steps"], d["n_rhs"], d["n_jac"],
                f"{d['fd_share'] * 100:.0f} %", f"{d['us_per_rhs']:.2f}"]
               for d in res["radau_breakdown"]]
    c_loop = res["rhs"]["paper3d"]["c_loop_ns"] / 1e3
    nx = len(res["reference"]["x_ref"])
    max_ke = max([r.get("max_kinetic_energy_J", 0.0) for r in res["compiled"]] or [math.nan])
    return [
        "## 5. Work-precision, 3 s simulation",
        "",
        "![work-precision](paper3d_work_precision.png)",
        "",
        "**Error** = max over the 33 states of |final state − reference final state| "
        "(section 4). Timed runs: `model.simulate(3.0, method=..., t_eval=[0, 3], "
        "outputs=False, checks=False)`; `wall` = `result.stats['wall_time']` (integration "
        "only), median (and min) over the runs after a first call (which for cvodes/idas also "
        "creates the CasADi integrator, cached in the model afterwards); settings whose first "
        f"call took > {SLOW_S:g} s get half the runs. Constraint residual (max over the run of "
        "the contact gaps, m) and energy drift (max |E(t) − E(0) − ∫ power dt|, E = kinetic + "
        f"potential, Simpson's rule; kinetic energy up to {max_ke:.2e} J) come from one separate "
        "run per setting with dense output every 0.25 ms (RK4: every step when h > 0.25 ms, "
        "so its drift includes the quadrature error of that coarser grid). ‖quat‖ − 1: the "
        "object quaternion's norm at 3 s (not renormalised; R is exact for any norm).",
        "",
        f"### Sweep (one curve per method; adaptive methods: atol = rtol × {ATOL_FACTOR:g})",
        "",
        *_table(header, [row(r) for r in res["compiled"]]),
        "",
        "### Grid near error 1e-8 (markers without lines on the plot)",
        "",
        "Near 1e-8 the error does not fall monotonically with the tolerances (the final state "
        "is nearly at rest; which slow modes are resolved depends on rtol and atol both), so "
        "the cheapest setting is also searched on rtol × atol.",
        "",
        *_table(header, [row(r) for r in res["grid"]]),
        "",
        "### Cheapest setting reaching final-state error ≤ 1e-8",
        "",
        "Over the sweep and the grid; 'interpolated' = wall time on the method's Pareto front "
        "interpolated in log-log at exactly 1e-8 (`work_precision.time_at_error`).",
        "",
        *_table(["method", "cheapest setting ≤ 1e-8", "wall ms (median)", "error",
                 "constraint residual m", "energy drift J", "interpolated at 1e-8 ms"], at_rows),
        "",
        "### Where the time goes",
        "",
        f"No Jacobian is generated for 3D (it would have "
        f"{res['op_counts']['paper3d']['jac_sx_instructions_if_generated']:,} SX instructions); "
        f"the integrators difference the compiled rhs ({c_loop:.2f} µs per evaluation in C). "
        "CVODES/IDAS through CasADi with `record_time`: `wall` = median of several calls; the "
        "split is that of the last call (`recorded run` = rhs + jac + other): `rhs`/`jac` = "
        "time in the rhs callbacks / in CasADi's finite-difference Jacobian of the compiled rhs; "
        "`other` = SUNDIALS and CasADi's linear algebra. The package's `model.external_rhs()` is "
        "`ca.external(..., {'enable_fd': True, 'fd_method': 'forward'})`; for comparison, the "
        "same integrations with CasADi's default scheme (`{'enable_fd': True}`):",
        "",
        *_table(["method", "setting", "finite differences", "wall ms (median)", "error",
                 "recorded run ms", "rhs ms", "jac ms", "other ms", "steps", "rhs calls",
                 "jac calls",
                 "µs / jac call"], bd_rows),
        "",
        f"A forward-difference Jacobian costs {nx} rhs evaluations ≈ {nx * c_loop:.0f} µs in C. "
        "The C Radau IIA differences the rhs itself (forward, "
        f"{nx} calls per Jacobian); share of its rhs calls spent on Jacobians (sweep):",
        "",
        *_table(["setting", "wall ms", "steps", "rhs calls", "jacobians", "in Jacobians",
                 "µs per rhs call (wall / calls)"], rd_rows),
        "",
    ]


def _peers_md(res: dict) -> list[str]:
    from benchmarks.report import equal_error_table, method_choice_md, peer_table, peers_equal_error_md

    return [
        "## 6. Peer: CasADi's own functions, without compilation",
        "",
        "`benchmarks/peers/casadi_uncompiled.py`: the scene's SX graph (the one we generate C "
        "from) as a `casadi.Function` on CasADi's virtual machine, CVODES through "
        "`casadi.integrator` with its Jacobian by AD on the same (interpreted) graph; atol = "
        "rtol × 1e-2, wall time of the integrator call after a setup call, median of 3; tighter "
        "tolerances are skipped once a run exceeds the time budget. Constraint residual and "
        "energy drift: one more run with outputs every 0.25 ms, evaluated by our compiled "
        "outputs (`model.outputs_batch`). (No lambdify or PyDy peer exists for the 3D scene.)",
        "",
        *peer_table(res["peers"]),
        "",
        "### Time to reach final-state error 1e-8",
        "",
        *equal_error_table(res["compiled"] + res["grid"], res["peers"]),
        "",
        *peers_equal_error_md(res["peers_equal_error"], {}),
        *method_choice_md(res["method_choice"], wp.failures(res["compiled"] + res["grid"]),
                          ref_difference=res["reference"]["difference"], section="7", notes=[
            "Over the sweep and the grid near 1e-8 (section 5). The projection curves run "
            "`gs.scenes.paper3d(name='paper3d_proj', gain=0.0)` with `simulate(..., "
            "project=True)`: the stabilisation gain at 0, the state projected onto the "
            "contact constraints after every step.",
            "cvodes and idas difference the compiled rhs for their Jacobian (no Jacobian is "
            "generated for 3D); radau, dopri5 and dop853 run their whole loop in C."]),
    ]


def plot(res: dict, path: Path) -> None:
    from benchmarks.report import plot_work_precision

    plot_work_precision(res, path, title="paper3d, 3 s simulation: work-precision "
                        f"(curves: atol = rtol × {ATOL_FACTOR:g}, labels rtol or h)",
                        target_ms=TARGETS["run_ms"], extra=res["grid"])


def write_all(res: dict, out: Path, log=_log) -> None:
    from benchmarks import report

    out.mkdir(parents=True, exist_ok=True)
    report.write_json(res, out / "paper3d.json")
    write_markdown(res, out / "paper3d.md")
    plot(res, out / "paper3d_work_precision.png")
    log(f"\nwrote {out / 'paper3d.md'}, paper3d.json, paper3d_work_precision.png")
    for row in summary_rows(res):
        log(f"- {row[0]}: target {row[1]}; {row[2]} -> {row[3]}")


def main(argv: list[str] | None = None) -> int:
    from benchmarks.run import private_cache

    ap = argparse.ArgumentParser(prog="python -m benchmarks.paper3d", description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--quick", action="store_true", help="fewer settings and repeats")
    ap.add_argument("--out", type=Path, default=None,
                    help="output directory (default benchmarks/results, or results/quick)")
    args = ap.parse_args(argv)
    out = args.out or (RESULTS / "quick" if args.quick else RESULTS)
    with private_cache():
        res = run(quick=args.quick)
    write_all(res, out)
    return 0


if __name__ == "__main__":
    sys.exit(main())
