"""Run the benchmarks (paper2d, then paper3d) and write ``benchmarks/results/``.

Usage::

    python -m benchmarks.run                  # full run (several minutes), results committed
    python -m benchmarks.run --quick          # smoke test, into results/quick/
    python -m benchmarks.run --only paper3d   # one scene only (paper2d or paper3d)

Every build goes to private temporary caches; the user's cache is not touched.
The paper3d benchmarks live in ``benchmarks.paper3d`` (also runnable on their own).
"""
from __future__ import annotations

import argparse
import contextlib
import os
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

RESULTS = Path(__file__).resolve().parent / "results"


def _log(msg: str) -> None:
    print(msg, flush=True)


SCENES = ("paper2d", "paper3d")


@contextlib.contextmanager
def private_cache():
    """``GRASPING_SYM_CACHE`` points at a new temporary directory inside the block."""
    with tempfile.TemporaryDirectory(prefix="gs-bench-cache-") as cache:
        old = os.environ.get("GRASPING_SYM_CACHE")
        os.environ["GRASPING_SYM_CACHE"] = cache
        try:
            yield Path(cache)
        finally:
            if old is None:
                os.environ.pop("GRASPING_SYM_CACHE", None)
            else:
                os.environ["GRASPING_SYM_CACHE"] = old


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(prog="python -m benchmarks.run", description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--quick", action="store_true",
                    help="fewer settings and repeats (smoke test)")
    ap.add_argument("--only", choices=SCENES, default=None,
                    help="run the benchmarks of one scene only (default: all)")
    ap.add_argument("--out", type=Path, default=None,
                    help="output directory (default benchmarks/results, or results/quick)")
    args = ap.parse_args(argv)
    out = args.out or (RESULTS / "quick" if args.quick else RESULTS)
    out.mkdir(parents=True, exist_ok=True)
    scenes = (args.only,) if args.only else SCENES
    if "paper2d" in scenes:
        with private_cache():
            results = run(quick=args.quick)
        from benchmarks import report

        report.write_json(results, out / "paper2d.json")
        report.write_markdown(results, out / "paper2d.md")
        report.plot_work_precision(results, out / "paper2d_work_precision.png")
        _log(f"\nwrote {out / 'paper2d.md'}, paper2d.json, paper2d_work_precision.png")
        for row in report.summary_rows(results):
            _log(f"- {row[0]}: target {row[1]}; {row[2]} -> {row[3]}")
    if "paper3d" in scenes:
        from benchmarks import paper3d

        with private_cache():
            results3 = paper3d.run(quick=args.quick, log=_log)
        paper3d.write_all(results3, out, log=_log)
    return 0


def run(*, quick: bool) -> dict:
    import grasping_sym as gs
    from benchmarks import build_stages, rhs_cost
    from benchmarks import work_precision as wp
    from benchmarks.machine import machine_info
    from grasping_sym.model.planar import DEFAULT_OUTPUTS
    from tests.oracles.reference import ReferenceModel

    t_start = time.perf_counter()
    res: dict = {"quick": quick, "machine": machine_info()}
    _log(f"machine: {res['machine']['cpu']}, {res['machine']['logical_cores']} cores, "
         f"load {res['machine']['load_average_1_5_15']}")

    _log("1. build stages (fresh processes, private caches)")
    cold_n, cached_n = (1, 2) if quick else (3, 5)
    res["build"] = {
        "paper2d": build_stages.cold_and_cached("paper2d", cold_runs=cold_n,
                                                cached_runs=cached_n, force=True, log=_log),
        "paper2d_committed_c": build_stages.committed_c_build("paper2d"),
        "ellipse2d": build_stages.cold_and_cached("ellipse2d", cold_runs=cold_n,
                                                  cached_runs=cached_n, force=False, log=_log),
    }
    scene = gs.scenes.paper2d()
    stages = build_stages.in_process_stages(scene)
    res["build"]["in_process"] = stages
    _log(f"  op counts: {stages['op_counts']}")

    model = gs.build(scene)
    energy_outputs = tuple(dict.fromkeys(
        DEFAULT_OUTPUTS + ("kinetic_energy", "potential_energy", "power")))
    energy_model = gs.build(gs.scenes.paper2d(outputs=energy_outputs))
    t0 = time.perf_counter()
    reference_model = ReferenceModel(scene, system=stages["_system"])
    res["reference_model_s"] = time.perf_counter() - t0

    _log("3. reference solution")
    res["reference"] = wp.reference(model, quick=quick, log=_log)
    x_ref = np.array(res["reference"]["x_ref"])

    _log("2. right-hand side cost")
    traj = model.simulate(wp.T_FINAL, rtol=1e-10, atol=1e-12,
                          t_eval=np.linspace(0.0, wp.T_FINAL, 31), outputs=False).x
    res["rhs"] = rhs_cost.rhs_costs(model, stages["_casadi_model"], reference_model, traj,
                                    quick=quick, log=_log)

    _log("3. work-precision, compiled methods")
    # the same scene without Baumgarte stabilisation, for the curves with projection
    nb_scene = gs.scenes.paper2d(name="paper2d_proj", gf=0.0, gl=0.0, wf=0.0, wl=0.0,
                                 outputs=energy_outputs)
    proj_model = gs.build(nb_scene)
    res["compiled"] = wp.compiled_methods(model, energy_model, x_ref, quick=quick,
                                          proj_model=proj_model, log=_log)
    _log("3b. (rtol, atol) grid near error 1e-8, compiled methods")
    res["grid"] = wp.compiled_grid(model, energy_model, x_ref, res["compiled"], quick=quick,
                                   proj_model=proj_model, log=_log)
    res["breakdown"] = wp.sundials_breakdown(model, stages["_casadi_model"], res["compiled"],
                                             quick=quick)

    _log("4. baseline: lambdify + solve_ivp, the paper's equations and without Baumgarte")
    x0 = model.initial_state()
    nb_reference = ReferenceModel(nb_scene)   # the lambdify baseline without Baumgarte
    if not np.allclose(proj_model.initial_state(), x0, rtol=0.0, atol=1e-15):
        raise RuntimeError("the scene without Baumgarte terms starts elsewhere")
    res["baseline"] = wp.baseline(reference_model, x0, x_ref, quick=quick,
                                  energy_model=energy_model, log=_log)
    res["baseline"] += wp.baseline(nb_reference, x0, x_ref, quick=quick,
                                   energy_model=energy_model, methods=wp.BASELINE_NB_METHODS,
                                   suffix=wp.NO_BAUMGARTE, log=_log)
    _log("4a. baseline on the (rtol, atol) grid near error 1e-8")
    for suffix, methods in wp.BASELINE_GRID_METHODS.items():
        res["baseline"] += wp.baseline_grid(
            nb_reference if suffix else reference_model, x0, x_ref, res["baseline"],
            quick=quick, energy_model=energy_model, methods=methods, suffix=suffix, log=_log)
    ours = res["compiled"] + res["grid"]
    res["equal_error"] = wp.equal_error_comparison(ours, res["baseline"])

    _log("4b. peers: CasADi without compilation, PyDy Cython")
    from benchmarks import peer_curves
    rtols = wp.QUICK_SUNDIALS_RTOLS if quick else wp.SUNDIALS_RTOLS   # as our cvodes curve
    res["peers"] = peer_curves.casadi_rows(scene, model, energy_model, x_ref, rtols,
                                           quick=quick, log=_log)
    pydy, res["pydy_build"] = peer_curves.pydy_rows(energy_model, x_ref, quick=quick, log=_log)
    res["peers"] += pydy
    res["peers_equal_error"] = wp.peers_at_equal_error(ours, {
        "SymPy lambdify + solve_ivp": res["baseline"],
        wp.PAPER_EQUATIONS_ONLY: [r for r in res["baseline"]
                                  if not r["method"].endswith(wp.NO_BAUMGARTE)],
        peer_curves.CASADI: [r for r in res["peers"] if r.get("peer") == peer_curves.CASADI],
        peer_curves.PYDY: [r for r in res["peers"] if r.get("peer") == peer_curves.PYDY]})
    res["method_choice"] = wp.method_choice(ours)
    res["same_formulation"] = wp.same_formulation(ours, res["baseline"])

    _log("5. folding constants vs run-time parameters")
    from benchmarks.folding import folding
    res["folding"] = folding(quick, log=_log)
    res["load_average_end"] = [round(v, 2) for v in os.getloadavg()]
    res["total_s"] = time.perf_counter() - t_start
    return res


if __name__ == "__main__":
    sys.exit(main())
