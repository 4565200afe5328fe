"""Build stages: validate, structure (a 2D scene's closed loop: from the cache, the committed
code, or written and compiled once per structure, its template derived with SymPy once),
compose (CasADi), write C, compile, load from the cache.

Cold builds and cached loads each run in a fresh interpreter, after ``import grasping_sym``
(the import is not counted), with ``GRASPING_SYM_CACHE`` pointing at a private temporary
directory, so nothing the benchmark process has already derived or imported helps them.
"""
from __future__ import annotations

import tempfile
import time
from pathlib import Path

from benchmarks.timing import in_fresh_process, median

_COLD = """
import json, time
import grasping_sym as gs
build = gs.build  # the package imports lazily: import the build stack before the clock starts
{imports}
t0 = time.perf_counter()
scene = {scene}
t1 = time.perf_counter()
model = gs.build(scene, force={force})
t2 = time.perf_counter()
print(json.dumps({{"scene_s": t1 - t0, "build_s": t2 - t1, "info": model.build_info}}))
"""

SCENES = {
    "paper2d": ("", "gs.scenes.paper2d()"),
    "ellipse2d": ("from benchmarks.scenes import ellipse2d", "ellipse2d()"),
    **{f"fingers{n}": ("from benchmarks.scenes import fingers2d", f"fingers2d({n})") for n in (1, 2, 3)},
}


def _run(scene: str, cache: Path, force: bool) -> dict:
    imports, expr = SCENES[scene]
    return in_fresh_process(_COLD.format(imports=imports, scene=expr, force=force), cache)


def _summarise(runs: list[dict]) -> dict:
    """Median of every timing over the runs (the runs themselves are kept too)."""
    keys = ["validate", "structure", "structure_compile", "compose", "write_c", "compile", "total"]
    out = {"runs": runs, "n": len(runs), "source": runs[0]["info"].get("source"),
           "structure_source": runs[0]["info"].get("structure_source"),
           "scene_s": median([r["scene_s"] for r in runs]),
           "build_s": median([r["build_s"] for r in runs])}
    for k in keys:
        vals = [r["info"][k] for r in runs if k in r["info"]]
        if vals:
            out[k + "_s"] = median(vals)
    return out


def cold_and_cached(scene: str, *, cold_runs: int, cached_runs: int, force: bool = True,
                    log=print) -> dict:
    """``cold_runs`` cold builds (each into a fresh cache) then ``cached_runs`` cached loads."""
    cold = []
    with tempfile.TemporaryDirectory(prefix=f"gs-bench-{scene}-") as tmp:
        for i in range(cold_runs):
            cache = Path(tmp) / f"cold{i}"
            cold.append(_run(scene, cache, force))
            log(f"  cold build {scene} #{i + 1}: {cold[-1]['build_s']:.2f} s "
                f"({cold[-1]['info'].get('source')})")
        warm = [_run(scene, Path(tmp) / "cold0", False) for _ in range(cached_runs)]
        for w in warm:
            if w["info"].get("source") != "cache":
                raise RuntimeError(f"expected a cached load of {scene}, got {w['info']}")
    res = {"cold": _summarise(cold), "cached": _summarise(warm)}
    log(f"  cached load {scene}: median gs.build {res['cached']['build_s'] * 1e3:.1f} ms, "
        f"scene construction {res['cached']['scene_s'] * 1e3:.1f} ms")
    return res


def committed_c_build(scene: str = "paper2d") -> dict:
    """First build on a fresh cache without ``force``: the committed C is compiled, no SymPy."""
    with tempfile.TemporaryDirectory(prefix=f"gs-bench-{scene}-committed-") as tmp:
        return _summarise([_run(scene, Path(tmp), False)])


def in_process_stages(scene_obj) -> dict:
    """Derive + translate in this process, for operation counts (and their timings).

    Returns the timings, SymPy op counts before/after CSE, CasADi SX instruction counts,
    and the objects (``system``, ``casadi_model``) for later use (not serialised).
    """
    from grasping_sym.assemble.functions import build_casadi, sympy_op_counts
    from grasping_sym.derive.planar import derive_planar

    t0 = time.perf_counter()
    system = derive_planar(scene_obj)
    t1 = time.perf_counter()
    cm = build_casadi(system, scene_obj.fingertip, scene_obj.object, scene_obj.name)
    t2 = time.perf_counter()
    ops = sympy_op_counts(system)
    t3 = time.perf_counter()
    return {
        "derive_s": t1 - t0, "translate_s": t2 - t1, "sympy_count_s": t3 - t2,
        "op_counts": {**ops, **cm.op_counts},
        "_system": system, "_casadi_model": cm,
    }
