"""What a build of a scene already on disk costs, in a new process: the scene keyed by its
definition (``pipeline.stages.definition_key``: the scene's keys and the law's definition,
read without running it) against the same build keyed by the law's expressions, as every
cached build was before (the law run on CasADi symbols, serialised and hashed; a 2D scene's
contours sampled for its state names), measured in the same run.

    python -m benchmarks.cached_build     # writes benchmarks/results/cached_build.md and .json

Each row: a fresh interpreter with the package and its build pipeline imported (the import
is reported apart), the scene constructed, then ``gs.build(scene)`` timed, with the cache the
first build of the row filled. Medians of ``RUNS`` processes.
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
    (RESULTS / "cached_build.md").write_text("\n".join(lines) + "\n")
    print("\n".join(lines))


if __name__ == "__main__":
    main()
