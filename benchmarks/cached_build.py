"""What a build of a scene already on disk costs, in a new process: the scene keyed by its
definition (``pipeline.stages.definition_key``: the scene's keys and the law's definition,
read without running it) against the same build keyed by the law's expressions, as every
cached build was before (the law run on CasADi symbols, serialised and hashed; a 2D scene's
contours sampled for its state names), measured in the same run.

    python -m benchmarks.cached_build     # writes benchmarks/results/cached_build.md and .json

Each row: a fresh interpreter with the package and its build pipeline imported (the import
is reported apart), the scene constructed, then ``gs.build(scene)`` timed, with the cache the
first build of the row filled. Medians of ``RUNS`` processes.

Then a script's whole wait, as a user's ``python script.py`` meets it: ``import grasping_sym``,
the scene, ``gs.build`` and ``simulate(3.0)`` in a new process, the cache filled; against the
same script with the floors that derive, write and compile imported first
(``pipeline.making``: what every cached build imported before a build that finds its model
stopped importing them), in the same run. And what the scene's SymPy costs: ``import sympy``
alone in a new process.
"""
from __future__ import annotations

import json
import os
import platform
import sys
import tempfile
from pathlib import Path

from benchmarks.timing import in_fresh_process, median

RESULTS = Path(__file__).resolve().parent / "results"
RUNS = 7

SCENES = {
    "paper2d (the paper's law)": "gs.scenes.paper2d()",
    "paper3d (the paper's law)": "gs.scenes.paper3d()",
    "paper2d, a law of the user's (gain in a closure)":
        "gs.scenes.paper2d(controller=gs.controllers.paper2d() + gs.controllers.law("
        "(lambda c: lambda m: [-c * dq for dq in m.dq])(0.004), name='extra'))",
}

_CODE = """
import json, os, sys, time
t0 = time.perf_counter()
import grasping_sym as gs
from grasping_sym.pipeline import stages
if os.environ.get("BENCH_BY_EXPRESSIONS"):
    from grasping_sym.pipeline import making  # the expressions' key needs it: imported with the rest
t1 = time.perf_counter()
if os.environ.get("BENCH_BY_EXPRESSIONS"):
    stages.definition_key = lambda scene: None
scene = {scene}
t2 = time.perf_counter()
model = gs.build(scene)
t3 = time.perf_counter()
print(json.dumps({{"import_s": t1 - t0, "scene_s": t2 - t1, "build_s": t3 - t2,
                  "key": model.build_info.get("key"), "source": model.build_info["source"]}}))
"""


_SCRIPT = """
import json, os, sys, time
t0 = time.perf_counter()
import grasping_sym as gs
if os.environ.get("BENCH_MAKING_FIRST"):  # what a cached build imported before
    import grasping_sym.assemble.casadi_api
    import grasping_sym.pipeline.making
scene = {scene}
t1 = time.perf_counter()
model = gs.build(scene)
t2 = time.perf_counter()
model.simulate(3.0)
t3 = time.perf_counter()
print(json.dumps({{"scene_s": t1 - t0, "build_s": t2 - t1, "simulate_s": t3 - t2, "total_s": t3 - t0,
                  "casadi": "casadi" in sys.modules, "source": model.build_info["source"]}}))
"""

_SYMPY = """
import json, time
t0 = time.perf_counter()
import numpy
t1 = time.perf_counter()
import sympy
t2 = time.perf_counter()
print(json.dumps({"numpy_s": t1 - t0, "sympy_s": t2 - t1}))
"""


def _script(scene: str, making_first: bool, cache: Path) -> list[dict]:
    if making_first:
        os.environ["BENCH_MAKING_FIRST"] = "1"
    try:
        runs = [in_fresh_process(_SCRIPT.format(scene=scene), cache) for _ in range(RUNS)]
    finally:
        os.environ.pop("BENCH_MAKING_FIRST", None)
    assert {r["source"] for r in runs} == {"cache"}
    return runs


def _whole_wait(scene: str, cache: Path) -> dict:
    """The script, then the script with ``pipeline.making`` imported first, interleaved."""
    in_fresh_process(_SCRIPT.format(scene=scene), cache)  # fills the cache
    now, before = [], []
    for _ in range(2):
        now += _script(scene, False, cache)
        before += _script(scene, True, cache)
    keys = ("scene_s", "build_s", "simulate_s", "total_s")
    return {"now": {k: median(r[k] for r in now) for k in keys} | {"casadi": any(r["casadi"] for r in now)},
            "before": {k: median(r[k] for r in before) for k in keys}}


def _row(scene: str, by_expressions: bool, cache: Path) -> dict:
    code = _CODE.format(scene=scene)
    if by_expressions:
        os.environ["BENCH_BY_EXPRESSIONS"] = "1"
    try:
        in_fresh_process(code, cache)  # fills the cache (and the definition's entry)
        runs = [in_fresh_process(code, cache) for _ in range(RUNS)]
    finally:
        os.environ.pop("BENCH_BY_EXPRESSIONS", None)
    keys = {r["key"] for r in runs}
    sources = {r["source"] for r in runs}
    assert sources == {"cache"}, sources
    return {k: median(r[k] for r in runs) for k in ("import_s", "scene_s", "build_s")} | {
        "key": sorted(keys)}


def main() -> None:
    # Python's bytecode cache on, as on a user's machine (this workplace turns it off: each
    # process would compile every module it imports again, ~0.1 s)
    os.environ.pop("PYTHONDONTWRITEBYTECODE", None)
    out: dict = {"python": platform.python_version(), "machine": platform.machine(), "rows": {}}
    with tempfile.TemporaryDirectory() as tmp:
        for label, scene in SCENES.items():
            cache = Path(tmp) / "cache"
            expr = _row(scene, True, cache)
            defn = _row(scene, False, cache)
            out["rows"][label] = {"expressions": expr, "definition": defn}
            print(f"{label}: {expr['build_s'] * 1e3:.1f} ms -> {defn['build_s'] * 1e3:.1f} ms",
                  file=sys.stderr)
        cache = Path(tmp) / "cache"
        out["scripts"] = {label: _whole_wait(SCENES[label], cache) for label in list(SCENES)[:2]}
        out["sympy"] = {k: median(r[k] for r in runs) for k in ("numpy_s", "sympy_s")
                        for runs in [[in_fresh_process(_SYMPY, cache) for _ in range(RUNS)]]}
    RESULTS.mkdir(exist_ok=True)
    (RESULTS / "cached_build.json").write_text(json.dumps(out, indent=2) + "\n")
    lines = [
        "# A build of a scene already on disk, in a new process",
        "",
        f"`python -m benchmarks.cached_build` on {out['machine']}, Python {out['python']}. "
        f"Medians of {RUNS} fresh processes, in ms. *by expressions*: the law run and its "
        "expressions hashed to find the model (every cached build before the definition key); "
        "*by definition*: the scene's keys and the law's definition read without running it, "
        "in the same run. *import*: `import grasping_sym` and the pipeline (SymPy and CasADi "
        "with it); *scene*: constructing the scene object.",
        "",
        "| scene | import ms | scene ms | `gs.build` by expressions ms | `gs.build` by definition ms "
        "| ratio |",
        "|---|---|---|---|---|---|",
    ]
    for label, row in out["rows"].items():
        e, d = row["expressions"], row["definition"]
        lines.append(f"| {label} | {d['import_s'] * 1e3:.0f} | {d['scene_s'] * 1e3:.0f} | "
                     f"{e['build_s'] * 1e3:.1f} | {d['build_s'] * 1e3:.1f} ({', '.join(d['key'])}) | "
                     f"{d['build_s'] / e['build_s']:.3f} |")
    lines += [
        "",
        "## A script's whole wait",
        "",
        "`import grasping_sym`, the scene, `gs.build` (found in the cache) and `simulate(3.0)`, in "
        f"a new process; medians of {2 * RUNS}, in ms. *before*: the same script with "
        "`pipeline.making` and `assemble.casadi_api` (the assembly, the emitter, the derivation, the "
        "compiler's library, CasADi) imported first, as every cached build imported them before a build that finds "
        "its model stopped, interleaved with *now*.",
        "",
        "| scene | scene ms (with the import) | `gs.build` ms before | `gs.build` ms now "
        "| simulate ms | whole script ms before | whole script ms now | ratio |",
        "|---|---|---|---|---|---|---|---|",
    ]
    for label, row in out["scripts"].items():
        b, n = row["before"], row["now"]
        lines.append(f"| {label} | {n['scene_s'] * 1e3:.0f} | {b['build_s'] * 1e3:.0f} | "
                     f"{n['build_s'] * 1e3:.0f} | {n['simulate_s'] * 1e3:.1f} | {b['total_s'] * 1e3:.0f} | "
                     f"{n['total_s'] * 1e3:.0f} | {n['total_s'] / b['total_s']:.2f} |")
    sy = out["sympy"]
    lines += ["", f"- `import numpy` alone: {sy['numpy_s'] * 1e3:.0f} ms; then `import sympy`: "
              f"{sy['sympy_s'] * 1e3:.0f} ms. The scenes are made of SymPy expressions: its import is "
              "the most of what is left of a script's wait."]
    (RESULTS / "cached_build.md").write_text("\n".join(lines) + "\n")
    print("\n".join(lines))


if __name__ == "__main__":
    main()
