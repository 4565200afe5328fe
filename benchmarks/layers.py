"""The figures of the layered pipeline: build times by layer, the rhs cost against the code
before the start became a layer of its own, loading a built model, and whether generated/ is
the same on another CPU.

    python -m benchmarks.layers          # writes benchmarks/results/layers.md and layers.json

Every build runs in a fresh interpreter (``import grasping_sym`` not counted) with a private
cache, importing the package beside this file (``PYTHONPATH``), so a worktree benchmarks its
own code. The rhs baseline is commit ``BASELINE`` (checked out into a temporary git worktree),
built and timed in the same run, in the same way, as the current code.
"""
from __future__ import annotations

import argparse
import json
import os
import platform
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from benchmarks.timing import REPO, in_fresh_process, median, reference_compile_s

RESULTS = Path(__file__).resolve().parent / "results"
#: The last commit before the start was split from the code (solved numbers were constants).
BASELINE = "982b02a"

_BUILD = """
import json, time
import grasping_sym as gs
build = gs.build  # the package imports lazily: import the build stack before the clock starts
{imports}
scene = {scene}
t0 = time.perf_counter()
model = gs.build(scene)
t1 = time.perf_counter()
print(json.dumps({{"build_s": t1 - t0, "info": model.build_info}}))
"""

_RHS = """
import json
import grasping_sym as gs
from benchmarks.rhs_loop import rhs_loop_ns
model = gs.build({scene})
x = model.initial_state()
n = {n}
print(json.dumps({{"ns": min(rhs_loop_ns(model, x, n) for _ in range(7))}}))
"""

_LOAD = """
import time, sys, json
t0 = time.perf_counter()
import grasping_sym as gs
model = gs.load(sys.argv[1])
t1 = time.perf_counter()
print(json.dumps({"load_s": t1 - t0, "sympy": "sympy" in sys.modules, "casadi": "casadi" in sys.modules}))
"""

SCENES_2D = {
    # a structure whose template is not committed: derived with SymPy on the first build
    "first build of a structure (2-finger template derived)":
        ("from benchmarks.scenes import fingers2d", "fingers2d(2)"),
    "new 2D shape on that structure (other tip radii)":
        ("from benchmarks.scenes import fingers2d; from grasping_sym.geometry import library; "
         "from grasping_sym.model.planar import ExtraFinger; import dataclasses",
         "fingers2d(2, name='fingers2b', fingertip=library.circle(0.011, name='tip'))"),
    "first build of a structure (template committed: ellipse object)":
        ("from benchmarks.scenes import ellipse2d", "ellipse2d()"),
    "new 2D shape on that structure (another ellipse)":
        ("from benchmarks.scenes import ellipse2d; from grasping_sym.geometry import library; "
         "import math",
         "ellipse2d(name='ellipse2b', object=library.ellipse(0.022, 0.028, start=math.pi, "
         "span=1.0, clockwise=True, name='other ellipse'))"),
}
SCENES_3D = {
    "paper3d cold (new name: no cache, no committed model C; its structure's C is committed)":
        ("", "gs.scenes.paper3d(name='paper3d_cold')"),
    "new 3D surface pair on that structure (ellipsoid 22x25x28 mm, tips 9 mm)":
        ("from grasping_sym.geometry import surface_library as sl; import dataclasses",
         "gs.scenes.paper3d(name='paper3d_pair', object_surface=sl.ellipsoid(0.022, 0.025, 0.028, "
         "lon=(-1.5707963267948966, 4.71238898038469), name='object'), fingers=tuple("
         "dataclasses.replace(f, tip=sl.sphere(0.009, name=f'tip{i}')) for i, f in "
         "enumerate(gs.scenes.paper3d().fingers)))"),
    # another torsional friction is folded into the code: a structure neither cached nor
    # committed (fd, a run-time parameter now, no longer makes one)
    "first build of a 3D structure (derived: paper3d with spin damping 3e-5 N m s folded in)":
        ("", "gs.scenes.paper3d(name='paper3d_new', spin_damping=3e-5)"),
}


def _builds(scenes: dict, runs: int, log) -> list[dict]:
    """Each scene built ``runs`` times, each run into a fresh cache holding what the scenes
    before it in the dict built (a structure built before is in the cache)."""
    rows = []
    per_run: list[list[dict]] = [[] for _ in scenes]
    for _ in range(runs):
        with tempfile.TemporaryDirectory(prefix="gs-bench-layers-") as cache:
            for k, (imports, expr) in enumerate(scenes.values()):
                per_run[k].append(in_fresh_process(_BUILD.format(imports=imports, scene=expr), Path(cache)))
    for (label, _), res in zip(scenes.items(), per_run):
        info = res[0]["info"]
        row = {"what": label, "runs": len(res), "build_s": median([x["build_s"] for x in res]),
               "source": info.get("source"), "structure_source": info.get("structure_source"),
               **{f"{k}_s": median([x["info"].get(k, 0.0) for x in res])
                  for k in ("validate", "structure", "structure_compile", "derive", "compose",
                            "write_c", "compile", "start")
                  if k in info}}
        rows.append(row)
        log(f"{label}: {row['build_s']:.3f} s ({row})")
    return rows


def _worktree(commit: str) -> Path:
    path = Path(tempfile.mkdtemp(prefix="gs-bench-base-")) / "base"
    subprocess.run(["git", "worktree", "add", "--detach", "-q", str(path), commit], cwd=REPO, check=True)
    return path


def _rhs_costs(log) -> list[dict]:
    base = _worktree(BASELINE)
    rows = []
    try:
        for name, n in (("paper2d", 2_000_000), ("paper3d", 100_000)):
            got = {}
            for label, pythonpath in (("baseline", str(base)), ("current", str(REPO))):
                env_code = _RHS.format(scene=f"gs.scenes.{name}()", n=n)
                with tempfile.TemporaryDirectory(prefix="gs-bench-rhs-") as cache:
                    old = os.environ.get("PYTHONPATH")
                    os.environ["PYTHONPATH"] = pythonpath
                    try:
                        got[label] = in_fresh_process(env_code, Path(cache), timeout=600)["ns"]
                    finally:
                        if old is None:
                            os.environ.pop("PYTHONPATH", None)
                        else:
                            os.environ["PYTHONPATH"] = old
            rows.append({"scene": name, "baseline_ns": got["baseline"], "current_ns": got["current"],
                         "ratio": got["current"] / got["baseline"]})
            log(f"rhs {name}: {rows[-1]}")
    finally:
        subprocess.run(["git", "worktree", "remove", "--force", str(base)], cwd=REPO, check=False)
    return rows


def _load(log) -> dict:
    with tempfile.TemporaryDirectory(prefix="gs-bench-load-") as cache:
        env = dict(os.environ, GRASPING_SYM_CACHE=cache)
        code = "import grasping_sym as gs, json; print(json.dumps(str(gs.build(gs.scenes.paper2d()).path)))"
        path = json.loads(subprocess.run([sys.executable, "-c", code], cwd=REPO, env=env, check=True,
                                         capture_output=True, text=True).stdout)
        inner, wall, empty = [], [], []
        for _ in range(7):
            t0 = time.perf_counter()
            out = subprocess.run([sys.executable, "-c", _LOAD, path], cwd=REPO, env=env, check=True,
                                 capture_output=True, text=True).stdout
            wall.append(time.perf_counter() - t0)
            inner.append(json.loads(out))
            t0 = time.perf_counter()
            subprocess.run([sys.executable, "-c", "pass"], check=True)
            empty.append(time.perf_counter() - t0)
    row = {"import_and_load_s": median([x["load_s"] for x in inner]), "process_wall_s": median(wall),
           "empty_interpreter_s": median(empty), "sympy_imported": any(x["sympy"] for x in inner),
           "casadi_imported": any(x["casadi"] for x in inner)}
    log(f"load: {row}")
    return row


CHECK_ENVS = {"OPENBLAS_CORETYPE=Haswell": {"OPENBLAS_CORETYPE": "Haswell"},
              "OPENBLAS_CORETYPE=SkylakeX": {"OPENBLAS_CORETYPE": "SkylakeX"},
              "NPY_DISABLE_CPU_FEATURES=AVX512F,AVX512_SKX,AVX2,FMA3":
                  {"NPY_DISABLE_CPU_FEATURES": "AVX512F,AVX512_SKX,AVX2,FMA3"}}


def _generate_check(log) -> list[dict]:
    rows = []
    for label, extra in CHECK_ENVS.items():
        proc = subprocess.run([sys.executable, "-m", "grasping_sym.cli", "generate", "--all",
                               "--check"], cwd=REPO, capture_output=True,
                              text=True, env={**os.environ, **extra})
        rows.append({"environment": label, "exit": proc.returncode,
                     "lines": [ln for ln in proc.stdout.splitlines() if ln.strip()][:8]})
        log(f"generate --check under {label}: exit {proc.returncode}")
    return rows


def run(*, runs: int = 3, log=print) -> dict:
    os.environ["PYTHONPATH"] = str(REPO)  # the fresh processes import this tree's package
    ref = reference_compile_s()
    log(f"reference compile (c/lu.c, 14 states): {ref:.3f} s")
    return {"machine": {"cpu": platform.processor() or platform.machine(), "python": platform.python_version(),
                        "reference_compile_s": ref},
            "builds_2d": _builds(SCENES_2D, runs, log),
            "builds_3d": _builds(SCENES_3D, max(1, runs - 1), log),
            "rhs": _rhs_costs(log), "load": _load(log), "generate_check": _generate_check(log)}


def _table(header: list[str], rows: list[list]) -> list[str]:
    return ["| " + " | ".join(header) + " |", "|" + "---|" * len(header),
            *["| " + " | ".join(str(c) for c in r) + " |" for r in rows]]


def markdown(res: dict) -> str:
    def ms(v):
        return "" if v is None else f"{1e3 * v:.0f}"

    build_rows = [[r["what"], r["runs"], r["source"], r.get("structure_source") or "",
                   ms(r.get("validate_s")), ms(r.get("structure_s")), ms(r.get("structure_compile_s")),
                   ms(r.get("derive_s")), ms(r.get("compose_s")), ms(r.get("write_c_s")),
                   ms(r.get("compile_s")), ms(r.get("start_s")), f"**{ms(r['build_s'])}**"]
                  for r in res["builds_2d"] + res["builds_3d"]]
    rhs_rows = [[r["scene"], f"{r['baseline_ns']:.1f}", f"{r['current_ns']:.1f}", f"{r['ratio']:.3f}"]
                for r in res["rhs"]]
    ld = res["load"]
    lines = [
        "# The layered pipeline: build, rhs cost, load, reproducibility",
        "",
        f"`python -m benchmarks.layers` on {res['machine']['cpu']}, Python {res['machine']['python']}. "
        "Fresh interpreter and private cache per build; medians, in ms. The machine is shared "
        "and its speed moves by tens of percent: gcc compiled the driver's `c/lu.c` (14 "
        f"states, the best of 5) in {1e3 * res['machine'].get('reference_compile_s', float('nan')):.0f} ms "
        "in this run: compare it between runs before comparing their build times.",
        "",
        "## Builds",
        "",
        "Rows in order, each run into one cache, so a row finds what the rows above it built "
        "(the structure of the row above for a \"new 2D shape\" row). A 2D scene is built in "
        "layers: its structure (the closed loop of its template, with its constants; written "
        "and compiled once: *structure ms*, *structure compile ms*), then its own contour "
        "functions and the glue that calls the structure (*compose*, *write C*, *compile*: the "
        "model's small C, and the driver's objects beside it when this cache has none for the "
        "model's sizes, as in the first row). A 3D scene likewise: its structure (derived with SymPy and "
        "CasADi's AD, with the surfaces' jets as inputs), then its surfaces' jets and the glue. "
        "`gs.build` is the wall time of the call.",
        "",
        *_table(["build", "runs", "code from", "structure from", "validate ms", "structure ms",
                 "structure compile ms", "derive ms", "compose ms", "write C ms", "compile ms",
                 "start ms", "gs.build ms"], build_rows),
        "",
        "## Right-hand side per evaluation (C loop, best of 7)",
        "",
        f"Baseline: commit `{BASELINE}` (pivot and 3D spring rest point folded in as constants), "
        "built and timed in this run the same way.",
        "",
        *_table(["scene", "baseline ns", "current ns", "current / baseline"], rhs_rows),
        "",
        "## Loading a built model in a fresh process",
        "",
        *_table(["import + gs.load ms", "whole process ms", "empty interpreter ms", "SymPy imported",
                 "CasADi imported"],
                [[ms(ld["import_and_load_s"]), ms(ld["process_wall_s"]), ms(ld["empty_interpreter_s"]),
                  ld["sympy_imported"], ld["casadi_imported"]]]),
        "",
        "## `grasping-sym generate --all --check` on other kernels",
        "",
        *_table(["environment", "exit (0: up to date)"],
                [[r["environment"], r["exit"]] for r in res["generate_check"]]),
        "",
    ]
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(prog="python -m benchmarks.layers", description=__doc__)
    ap.add_argument("--runs", type=int, default=3, help="builds per row (default 3)")
    ap.add_argument("--out", type=Path, default=RESULTS)
    args = ap.parse_args(argv)
    res = run(runs=args.runs)
    args.out.mkdir(parents=True, exist_ok=True)
    (args.out / "layers.json").write_text(json.dumps(res, indent=2, sort_keys=True) + "\n")
    (args.out / "layers.md").write_text(markdown(res))
    print(f"wrote {args.out / 'layers.md'}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
