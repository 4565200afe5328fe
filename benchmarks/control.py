"""The figures of control inputs, controllers and optimal control (issue 14).

    python -m benchmarks.control         # writes benchmarks/results/control.md and control.json

- what inputs cost: paper2d's compiled rhs with and without ``inputs="torques"`` (ns per call,
  C loop), and a 3 s radau run closed loop, with a constant input and with a table input;
- what a new law costs: building paper2d with a controller of its own (the structure cached);
- the optimal-control example (examples/ocp_paper2d.py): IPOPT's iterations and wall time,
  the re-simulated error.

Every ratio's baseline is measured in the same run.
"""
from __future__ import annotations

import importlib.util
import json
import platform
import shutil
import time
from pathlib import Path

import numpy as np

import grasping_sym as gs
from benchmarks.rhs_loop import rhs_loop_ns
from benchmarks.timing import REPO, best_per_call, median

RESULTS = Path(__file__).resolve().parent / "results"
RUN = {"method": "radau", "rtol": 1e-8, "atol": 1e-10, "outputs": False, "checks": False,
       "t_eval": [0.0, 3.0]}


def _ocp(name: str = "ocp_paper2d"):
    spec = importlib.util.spec_from_file_location(name, REPO / "examples" / f"{name}.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def measure() -> dict:
    out: dict = {"machine": platform.processor() or platform.machine()}
    closed = gs.build(gs.scenes.paper2d())
    inputs = gs.build(gs.scenes.paper2d(inputs="torques"))
    x = closed.initial_state()
    ns_closed = min(rhs_loop_ns(closed, x, 200_000) for _ in range(7))
    ns_inputs = min(rhs_loop_ns(inputs, x, 200_000) for _ in range(7))
    out["rhs_ns"] = {"closed_loop": ns_closed, "inputs": ns_inputs, "ratio": ns_inputs / ns_closed}
    # the same motion three ways (inputs at zero): what the inputs and a table's restarts cost
    table = gs.inputs.piecewise_linear([0.0, 1.0, 2.0, 3.0], np.zeros((4, 2)))
    runs = {
        "closed_loop": lambda: closed.simulate(3.0, **RUN),
        "constant_input": lambda: inputs.simulate(3.0, u=[0.0, 0.0], **RUN),
        "table_input": lambda: inputs.simulate(3.0, u=table, **RUN),
    }
    t_run = {k: best_per_call(f, number=3, repeat=7) for k, f in runs.items()}
    steps = {k: int(f().stats["n_steps"]) for k, f in runs.items()}
    out["run_s"] = {k: {"s": v, "steps": steps[k], "ratio": v / t_run["closed_loop"]}
                    for k, v in t_run.items()}
    # a controller of one's own: the structure is cached, the law compiles with the shape
    builds, rng = [], np.random.default_rng()
    for _ in range(3):
        law = gs.controllers.paper2d() + gs.controllers.damping(float(rng.uniform(1e-4, 2e-4)))
        t0 = time.perf_counter()
        model = gs.build(gs.scenes.paper2d(controller=law))
        builds.append(time.perf_counter() - t0)
        assert model.build_info["source"] == "derived"
    out["new_law_build_s"] = median(builds)
    ocp = _ocp()
    model = gs.build(ocp.scene())
    shutil.rmtree(model.directory / "casadi_api", ignore_errors=True)  # their first build
    t0 = time.perf_counter()
    for which in ("ode", "outputs"):
        model.casadi_function(which, compiled=True)
    compile_s = time.perf_counter() - t0
    solves = [ocp.solve(model, compiled=True) for _ in range(3)]
    vm = [ocp.solve(model, compiled=False) for _ in range(2)]
    res = ocp.resimulate(model, solves[-1])
    out["ocp"] = {"intervals": ocp.N_INTERVALS, "degree": ocp.DEGREE, "compile_s": compile_s,
                  "iterations": [r["iterations"] for r in solves],
                  "wall_s": [r["wall_time"] for r in solves], "status": solves[-1]["status"],
                  "vm_iterations": [r["iterations"] for r in vm], "vm_wall_s": [r["wall_time"] for r in vm],
                  "theta_error": float(res["theta"][-1] - ocp.THETA_TARGET),
                  "f_min_points": float(solves[-1]["f_points"].min()),
                  "f_min_resimulated": float(res["f"].min()), "cost": solves[-1]["cost"]}
    ocp3 = _ocp("ocp_paper3d")
    model3 = gs.build(ocp3.scene())
    r3 = ocp3.solve(model3)
    res3 = ocp3.resimulate(model3, r3)
    phi = ocp3.turn(model3, res3, r3["R0"])
    omega = [model3.state_names.index(k) for k in ("omegaX", "omegaY", "omegaZ")]
    out["ocp3d"] = {"intervals": ocp3.N_INTERVALS, "degree": ocp3.DEGREE, "hessian": ocp3.HESSIAN,
                    "iterations": r3["iterations"], "wall_s": r3["wall_time"], "status": r3["status"],
                    "turn_error": float(phi[-1] - ocp3.ANGLE),
                    "omega_end": float(np.linalg.norm(res3.x[-1, omega])),
                    "f_min_resimulated": float(min(res3["f1"].min(), res3["f2"].min()))}
    return out


def report(r: dict) -> str:
    rhs, run, ocp = r["rhs_ns"], r["run_s"], r["ocp"]
    lines = [
        "# Control inputs, controllers, optimal control",
        "",
        f"Machine: {r['machine']}. `python -m benchmarks.control`.",
        "",
        "## What inputs cost (paper2d)",
        "",
        "| | closed loop | with `inputs=\"torques\"` | ratio (goal <= 1.10) |",
        "|---|---|---|---|",
        f"| compiled rhs, ns per call (C loop) | {rhs['closed_loop']:.0f} | {rhs['inputs']:.0f} | "
        f"{rhs['ratio']:.3f} |",
        "",
        "| 3 s radau run (rtol 1e-8, atol 1e-10, no outputs), the same motion | ms | steps | "
        "ratio to closed loop (goal <= 1.2) |",
        "|---|---|---|---|",
    ]
    for k, v in run.items():
        lines.append(f"| {k.replace('_', ' ')} | {v['s'] * 1e3:.3f} | {v['steps']} | {v['ratio']:.3f} |")
    lines += [
        "",
        "The inputs are zero, so the three runs follow one motion: the constant input costs the "
        "extra entries of p; the table (piecewise linear, knots at 1 and 2 s) costs the restarts "
        "of the integration there (three segments, each starting with a small step).",
        "",
        f"A controller of one's own (paper2d's structure cached): build {r['new_law_build_s']:.2f} s "
        "(median of 3; the law's C compiled with the contours, nothing derived).",
        "",
        "## Optimal control (examples/ocp_paper2d.py)",
        "",
        f"Legendre collocation, {ocp['intervals']} intervals of degree {ocp['degree']}, IPOPT with "
        "exact Hessians (MUMPS).",
        "",
        f"- status: {ocp['status']}; iterations {ocp['iterations']}",
        f"- the closed loop and its derivatives in compiled C (`casadi_function(compiled=True)`): "
        f"wall time of the solve (NLP built and solved) {', '.join(f'{w:.2f}' for w in ocp['wall_s'])} s "
        f"(goal <= 5 s), after compiling them once in {ocp['compile_s']:.1f} s (kept with the model)",
        f"- the same in CasADi's virtual machine (SX expanded into the NLP): "
        f"{', '.join(f'{w:.2f}' for w in ocp['vm_wall_s'])} s, {ocp['vm_iterations']} iterations",
        f"- re-simulated by the compiled model: theta(1 s) - 0.3 = {ocp['theta_error']:.2e} rad (goal < 1e-4)",
        f"- normal force: min {ocp['f_min_points']:.4f} N at the collocation points (>= 0.1 imposed), "
        f"{ocp['f_min_resimulated']:.4f} N along the re-simulated motion",
        "",
        "## Optimal control in 3D (examples/ocp_paper3d.py)",
        "",
        f"paper3d's held ellipsoid turned by 0.2 rad about z in 1 s, least added torque, normal "
        f"forces >= 1 N: {r['ocp3d']['intervals']} intervals of degree {r['ocp3d']['degree']}, "
        f"{r['ocp3d']['hessian']} Hessians.",
        "",
        f"- status: {r['ocp3d']['status']}; {r['ocp3d']['iterations']} iterations, "
        f"{r['ocp3d']['wall_s']:.1f} s in CasADi's virtual machine (the functions called once "
        "per collocation point, differentiated through their symbolic Jacobians, "
        "`casadi_api.DERIVATIVE_OPTIONS`; the Hessian of the Lagrangian, 24 symbolic Jacobians "
        "of the reverse derivatives of 1.1M instructions each, is 0.2 s of every iteration)",
        f"- re-simulated: turn error {r['ocp3d']['turn_error']:.1e} rad, |omega| at 1 s "
        f"{r['ocp3d']['omega_end']:.2e} rad/s (the coarse mesh), normal forces >= "
        f"{r['ocp3d']['f_min_resimulated']:.2f} N",
        "",
    ]
    return "\n".join(lines)


def main() -> None:
    r = measure()
    RESULTS.mkdir(exist_ok=True)
    (RESULTS / "control.json").write_text(json.dumps(r, indent=1) + "\n")
    (RESULTS / "control.md").write_text(report(r))
    print(report(r))


if __name__ == "__main__":
    main()
