"""What compiling the C driver per model size buys (issue 26, part 6).

The driver (``grasping_sym/c``: the integrators, the projection, the batch loop and the
CPython front end) is compiled into object files once per set of model sizes: ``GS_NX``,
``GS_NP``, ``GS_NY``, ``GS_NC`` and ``GS_RADAU_M`` are preprocessor constants
(``toolchain.library.model_defines``, ``toolchain.objects``). Here every model is linked
twice, with the same CasADi-generated objects, flags and link line:

* **per-size**: the driver as the package compiles it (``objects.object_defines``);
* **run-time sizes**: one build of the same C whose sizes are variables. The five size
  macros are defined to ``gs_rt_nx`` ... ``gs_rt_m``, ``const int`` globals defined by the
  library's small link file (another translation unit, no LTO: the driver's code cannot see
  their values). A handful of textual edits make the C accept that (``_RUNTIME_EDITS``):
  ``enum { n = GS_NX }`` becomes ``const int n = GS_NX``, so the stack arrays become
  variable-length arrays; ``gs_radau5``'s matrix struct gets a fixed bound
  (``GS_NX_MAX`` = 64 rows); the ``lu.c`` unrolling for ``GS_NX <= 8`` is off (it needs the
  size known) and the reduced-system size is a variable (``GS_RADAU_M`` reads 0 in ``#if``).
  The features (``GS_HAS_OUT/JAC/CON/RHS_LANES``), the function names and CasADi's work
  sizes (rounded to the same power-of-two buckets) stay compile-time, as the package has them:
  one run-time build therefore serves every model with the same features (paper2d and the
  2-finger model get the very same objects here).

Measured per model: ``simulate(3.0)`` with two methods and the bare C loop of the same
integrator (``model.library.<method>``, output every ms), the two libraries interleaved in
one process (A B B A ...), min and median of repeated samples; the results of A and B are
compared (they should be bit-identical: the arithmetic is the same, ``-ffp-contract=off``);
and the serial gcc seconds of the driver's objects (the 12 files one after another), which
the per-size scheme pays for every new set of sizes and the run-time one once.

    python -m benchmarks.driver_sizes   ->  benchmarks/results/driver_sizes.md (GS_BENCH_SAMPLES: samples)
"""
from __future__ import annotations

import os
import re
import shutil
import statistics
import tempfile
import time
from functools import partial
from pathlib import Path

import numpy as np

from benchmarks.machine import machine_info

RESULTS = Path(__file__).resolve().parent / "results"

#: Decision rule of issue 26: keep the per-size compile only where it buys this much run time.
THRESHOLD = 0.05
#: Stack bound of gs_radau5's matrices in the run-time build (rows).
NX_MAX = 64
#: The size macros and the globals that replace them in the run-time build.
SIZE_VARS = {"GS_NX": "gs_rt_nx", "GS_NP": "gs_rt_np", "GS_NY": "gs_rt_ny", "GS_NC": "gs_rt_nc",
             "GS_RADAU_M": "gs_rt_m"}

_DECLS = ("\n/* benchmarks.driver_sizes: the sizes as run-time variables (defined by the link file) */\n"
          + "".join(f'extern __attribute__((visibility("hidden"))) const int {v};\n'
                    for v in SIZE_VARS.values())
          + f"#define GS_NX_MAX {NX_MAX}\n")
#: (file, old text, new text, expected count): the edits of the run-time build.
_RUNTIME_EDITS = [
    ("gs_driver.h", "#define GS_DRIVER_H\n", "#define GS_DRIVER_H\n" + _DECLS, 1),
    ("dopri5.c", "enum { n = GS_NX };", "const int n = GS_NX;", 1),
    ("dop853.c", "enum { n = GS_NX };", "const int n = GS_NX;", 1),
    ("project.c", "enum { m = GS_NC };", "const int m = GS_NC;", 1),
    ("radau5.c", "enum { n = GS_NX, nit = GS_RADAU_NIT };",
     "const int n = GS_NX;\n  enum { nit = GS_RADAU_NIT };", 1),
    ("radau5.c", "double J[GS_NX * GS_NX];", "double J[GS_NX_MAX * GS_NX_MAX];", 1),
    ("radau5.c", "double LUr[GS_NX * GS_NX];", "double LUr[GS_NX_MAX * GS_NX_MAX];", 1),
    ("radau5.c", "double LUcr[GS_NX * GS_NX];", "double LUcr[GS_NX_MAX * GS_NX_MAX];", 1),
    ("radau5.c", "double LUci[GS_NX * GS_NX];", "double LUci[GS_NX_MAX * GS_NX_MAX];", 1),
    ("radau5.c", "int pr[GS_NX], pc[GS_NX];", "int pr[GS_NX_MAX], pc[GS_NX_MAX];", 1),
    ("radau5.c", "(8L * 4L * GS_NX * GS_NX + 8L * GS_NX)",
     "(8L * 4L * GS_NX_MAX * GS_NX_MAX + 8L * GS_NX_MAX)", 1),
    ("lu.c", "!defined(__clang__) && GS_NX <= 8", "!defined(__clang__) && 0", 1),
]

#: (model, method, tolerances) of the simulations timed.
CASES = [
    ("paper2d", "radau", {}),
    ("paper2d", "dopri5", {"rtol": 1e-10, "atol": 1e-12}),
    ("paper3d", "radau", {}),
    ("paper3d", "dop853", {}),
    ("fingers2", "radau", {}),
    ("fingers2", "dopri5", {"rtol": 1e-10, "atol": 1e-12}),
]
_C_METHOD = {"radau": "radau5", "dopri5": "dopri5", "dop853": "dop853"}
_DEFAULT_TOL = {"radau": (1e-6, 1e-9), "dopri5": (1e-8, 1e-10), "dop853": (1e-8, 1e-10)}


def _scenes() -> dict:
    import grasping_sym as gs
    from benchmarks.scenes import fingers2d

    return {"paper2d": gs.scenes.paper2d(), "paper3d": gs.scenes.paper3d(), "fingers2": fingers2d(2)}


def runtime_sources(dest: Path) -> list[Path]:
    """The driver's C copied to ``dest`` with :data:`_RUNTIME_EDITS` applied; its sources in the
    package's order (``DRIVER_SOURCES`` + ``pyfast.c``)."""
    from grasping_sym.toolchain.library import DRIVER_SOURCES, PYFAST_C

    c_dir = PYFAST_C.parent
    for f in c_dir.iterdir():
        if f.suffix in (".c", ".h"):
            shutil.copy2(f, dest / f.name)
    for name, old, new, count in _RUNTIME_EDITS:
        path = dest / name
        text = path.read_text()
        if text.count(old) != count:
            raise RuntimeError(f"{name}: expected {count} x {old!r}, found {text.count(old)}: "
                               "the driver's C changed, update _RUNTIME_EDITS")
        path.write_text(text.replace(old, new))
    for f in dest.glob("*.[ch]"):  # any size left in a constant-only place would be an #if
        for line in f.read_text().splitlines():
            if re.match(r"\s*#\s*(if|elif)\s", line) and re.search(
                    r"\bGS_N[XPYC]\b", re.sub(r"defined\s*\(?\s*\w+\s*\)?", "", line)):
                raise RuntimeError(f"{f.name}: a size in a preprocessor test: {line.strip()}")
    return [dest / s.name for s in (*DRIVER_SOURCES, PYFAST_C)]


def runtime_defines(defines: dict) -> dict:
    """The run-time build's macros: ``object_defines`` with the sizes named as variables."""
    from grasping_sym.toolchain.objects import object_defines

    out = object_defines(defines)
    for k, var in SIZE_VARS.items():
        out[k] = var
    return out


def sizes_c(defines: dict) -> str:
    """The definitions of the size variables for one model (linked into its library)."""
    values = {"GS_NX": defines["GS_NX"], "GS_NP": defines["GS_NP"],
              "GS_NY": defines.get("GS_NY", 0) if defines.get("GS_HAS_OUT") else 0,
              "GS_NC": defines.get("GS_NC", 0), "GS_RADAU_M": defines.get("GS_RADAU_M", 0)}
    return "".join(f'__attribute__((visibility("hidden"))) const int {SIZE_VARS[k]} = {int(v)};\n'
                   for k, v in values.items())


def _compile_serial(sources: list[Path], out_dir: Path, defines: dict, include_dirs) -> tuple[list[Path], float]:
    """Objects of ``sources`` compiled one after another; their total gcc wall seconds."""
    from grasping_sym.toolchain.compiler import compile_objects

    objs, total = [], 0.0
    for k, src in enumerate(sources):
        sub = out_dir / f"{k}"
        sub.mkdir()
        t0 = time.perf_counter()
        objs += compile_objects([src], sub, defines, include_dirs)
        total += time.perf_counter() - t0
    return objs, total


def build_pair(model, work: Path, rt_src: list[Path], log=print) -> dict:
    """Link ``model``'s generated code with the per-size driver (A) and the run-time-size one
    (B) in ``work``; the two library paths and the serial compile seconds of each driver."""
    from grasping_sym.assemble import structure_cache
    from grasping_sym.toolchain import objects as object_cache
    from grasping_sym.toolchain.compiler import compile_objects, compile_shared
    from grasping_sym.toolchain.library import DRIVER_SOURCES, PYFAST_C, _driver_inputs

    defines = model.manifest["driver_defines"]
    _, include_dirs = _driver_inputs(True)
    gen = [model.directory / f for f in model.manifest["files"] if f.endswith(".c")]
    linked = []
    if "structure" in model.manifest:
        linked = structure_cache.link_objects(*structure_cache.locate(model.manifest["structure"]))
    (work / "gen").mkdir()
    gen_objs = compile_objects(gen, work / "gen")  # once, linked into both
    out = {}
    for tag, sources, defs, extra in (
            ("A", [*DRIVER_SOURCES, PYFAST_C], object_cache.object_defines(defines), ""),
            ("B", rt_src, runtime_defines(defines), sizes_c(defines))):
        d = work / tag
        d.mkdir()
        drv, seconds = _compile_serial(sources, d, defs, include_dirs)
        links = d / "gs_links.c"
        links.write_text(object_cache.links_c(defines) + extra)
        lib = compile_shared([links], d / "lib" / f"lib{model.name}_{tag}.so",
                             objects=[*gen_objs, *linked, *drv])
        out[tag] = {"library": lib, "compile_s": seconds}
        log(f"  {model.name} {tag}: driver objects {seconds:.2f} s of gcc (serial)")
    return out


def _time_pair(fa, fb, *, samples: int, target_s: float = 0.03) -> tuple[list[float], list[float]]:
    """Seconds per call of ``fa`` and ``fb``, ``samples`` samples each, interleaved A B B A."""
    fa(), fb()
    t0 = time.perf_counter()
    fa()
    one = max(time.perf_counter() - t0, 1e-6)
    k = max(1, int(target_s / one))
    ta, tb = [], []

    def sample(f) -> float:
        t = time.perf_counter()
        for _ in range(k):
            f()
        return (time.perf_counter() - t) / k

    for i in range(samples):
        if i % 2 == 0:
            ta.append(sample(fa))
            tb.append(sample(fb))
        else:
            tb.append(sample(fb))
            ta.append(sample(fa))
    return ta, tb


def _stats(ta, tb) -> dict:
    return {"A_min_ms": min(ta) * 1e3, "A_median_ms": statistics.median(ta) * 1e3,
            "B_min_ms": min(tb) * 1e3, "B_median_ms": statistics.median(tb) * 1e3,
            "ratio_min": min(tb) / min(ta), "ratio_median": statistics.median(tb) / statistics.median(ta),
            # median of the per-pair ratios: each pair ran back to back
            "ratio_pairs": statistics.median(b / a for a, b in zip(ta, tb))}


def run(samples: int = 25, log=print) -> dict:
    import grasping_sym as gs

    models = {name: gs.build(scene) for name, scene in _scenes().items()}
    Model = type(models["paper2d"])  # noqa: N806 - runtime.model.Model (its import path is moving)
    rows, builds = [], {}
    with tempfile.TemporaryDirectory(prefix="gs-bench-driver-sizes-") as tmp:
        tmp = Path(tmp)
        rt_dir = tmp / "c_runtime"
        rt_dir.mkdir()
        rt_src = runtime_sources(rt_dir)
        variants = {}
        for name, model in models.items():
            d = model.manifest["driver_defines"]
            log(f"{name}: nx {d['GS_NX']}, np {d['GS_NP']}, ny {d.get('GS_NY', 0)}, "
                f"nc {d.get('GS_NC', 0)}, radau m {d.get('GS_RADAU_M', 0)}")
            work = tmp / name
            work.mkdir()
            pair = build_pair(model, work, rt_src, log)
            builds[name] = {"sizes": {k: d.get(k, 0) for k in SIZE_VARS},
                            "features": {k: d.get(k, 0) for k in ("GS_HAS_OUT", "GS_HAS_JAC", "GS_HAS_CON",
                                                                  "GS_HAS_RHS_LANES")},
                            "compile_A_s": pair["A"]["compile_s"], "compile_B_s": pair["B"]["compile_s"]}
            variants[name] = {tag: Model(model.directory, model.manifest, pair[tag]["library"], model.start)
                              for tag in ("A", "B")}
        for name, method, tol in CASES:
            ma, mb = variants[name]["A"], variants[name]["B"]
            ra = ma.simulate(3.0, method=method, **tol)
            rb = mb.simulate(3.0, method=method, **tol)
            same = bool(np.array_equal(np.asarray(ra.x), np.asarray(rb.x)))
            ta, tb = _time_pair(partial(ma.simulate, 3.0, method=method, **tol),
                                partial(mb.simulate, 3.0, method=method, **tol), samples=samples)
            sim = _stats(ta, tb)
            # the bare C loop of the same integrator, output every ms
            rtol, atol = tol.get("rtol", _DEFAULT_TOL[method][0]), tol.get("atol", _DEFAULT_TOL[method][1])
            x0, t_out = ma.initial_state(), np.linspace(0.0, 3.0, 3001)
            ca_, cb_ = (getattr(m.library, _C_METHOD[method]) for m in (ma, mb))
            c_args = dict(rtol=rtol, atol=atol, max_steps=1_000_000)
            xa, _, st = ca_(x0, t_out, **c_args)
            xb, _, _ = cb_(x0, t_out, **c_args)
            same = same and bool(np.array_equal(xa, xb))
            ta, tb = _time_pair(partial(ca_, x0, t_out, **c_args), partial(cb_, x0, t_out, **c_args),
                                samples=samples)
            loop = _stats(ta, tb)
            rows.append({"model": name, "method": method, "tolerances": tol or "defaults",
                         "steps": int(st["n_steps"]),
                         "bit_identical": same, "simulate": sim, "c_loop": loop})
            log(f"{name} {method}: simulate A {sim['A_min_ms']:.3f} ms, B {sim['B_min_ms']:.3f} ms, "
                f"B/A {sim['ratio_min']:.3f} (min) {sim['ratio_pairs']:.3f} (pairs); C loop B/A "
                f"{loop['ratio_min']:.3f}; identical {same}")
    return {"machine": machine_info(), "samples": samples, "nx_max": NX_MAX, "builds": builds,
            "rows": rows}


def decide(data: dict) -> dict:
    """Per model: the largest gain of the per-size build over the run-time one, in run time of
    ``simulate`` (B / A - 1, from the min and the pair median: the smaller of the two, so that
    noise does not make a gain), and whether it reaches :data:`THRESHOLD`."""
    out = {}
    for r in data["rows"]:
        s = r["simulate"]
        gain = min(s["ratio_min"], s["ratio_pairs"]) - 1.0
        m = out.setdefault(r["model"], {"gain": -1.0, "method": None})
        if gain > m["gain"]:
            m.update(gain=gain, method=r["method"])
    for m in out.values():
        m["keep_per_size"] = m["gain"] >= THRESHOLD
    return out


def write_report(data: dict, path_md: Path) -> None:
    m = data["machine"]
    verdict = decide(data)
    lines = [
        "# The driver compiled per model size, against one build with the sizes at run time",
        "",
        "Generated by `python -m benchmarks.driver_sizes` (issue 26, part 6). **A** = the driver's objects "
        "as the package compiles them, per set of sizes (`GS_NX`, `GS_NP`, `GS_NY`, `GS_NC`, `GS_RADAU_M` "
        "compile-time constants); **B** = one build of the same C with those five sizes as `const int` "
        "globals defined in another translation unit (the library's link file; no LTO), stack arrays as "
        "VLAs, `gs_radau5`'s matrices bounded at "
        f"{data['nx_max']} rows, the `lu.c` unrolling (n <= 8) and the constant reduced size off. "
        "Features, function names and the (bucketed) CasADi work sizes stay compile-time in both. "
        "Both libraries link the same CasADi-generated objects with the same flags; they are timed in one "
        "process, interleaved (A B B A ...), "
        f"{data['samples']} samples each of back-to-back runs (~30 ms a sample). "
        "Ratio = B / A (above 1: the per-size build is faster); *min* compares the fastest samples, "
        "*pairs* is the median of the ratios of samples run back to back.",
        "",
        f"Machine: {m['cpu']}, {m['logical_cores']} logical cores, load average at the end "
        f"{m['load_average_1_5_15']} (other work was running); {m['gcc']}; commit {m['git_commit']}.",
        "",
        "## Run time",
        "",
        "| model | method | tolerances | steps | A simulate ms (min / med) | B simulate ms (min / med) "
        "| B/A min | B/A pairs | C loop B/A min | C loop B/A pairs | A = B bitwise |",
        "|---|---|---|---|---|---|---|---|---|---|---|",
    ]
    for r in data["rows"]:
        s, c = r["simulate"], r["c_loop"]
        tol = r["tolerances"] if isinstance(r["tolerances"], str) else ", ".join(
            f"{k} {v:g}" for k, v in r["tolerances"].items())
        lines.append(
            f"| {r['model']} | {r['method']} | {tol} | {r['steps']} | {s['A_min_ms']:.3f} / {s['A_median_ms']:.3f} "
            f"| {s['B_min_ms']:.3f} / {s['B_median_ms']:.3f} | {s['ratio_min']:.3f} | {s['ratio_pairs']:.3f} "
            f"| {c['ratio_min']:.3f} | {c['ratio_pairs']:.3f} | {'yes' if r['bit_identical'] else 'NO'} |")
    lines += [
        "",
        "## Compile cost of the driver's objects",
        "",
        "Serial gcc wall seconds for the 12 driver files (11 + `pyfast.c`), one after another, as the "
        "background prefetch compiles them. A is paid once per new set of sizes (and features); B once per "
        "set of features (paper2d and fingers2 have the same features, so B's objects are the same file set).",
        "",
        "| model | nx | np | ny | nc | radau m | features (out, jac, con, lanes) | A: gcc s per size "
        "| B: gcc s (once) |",
        "|---|---|---|---|---|---|---|---|---|",
    ]
    for name, b in data["builds"].items():
        s, f = b["sizes"], b["features"]
        lines.append(f"| {name} | {s['GS_NX']} | {s['GS_NP']} | {s['GS_NY']} | {s['GS_NC']} | {s['GS_RADAU_M']} "
                     f"| {f['GS_HAS_OUT']}, {f['GS_HAS_JAC']}, {f['GS_HAS_CON']}, {f['GS_HAS_RHS_LANES']} "
                     f"| {b['compile_A_s']:.2f} | {b['compile_B_s']:.2f} |")
    lines += [
        "",
        f"## Decision (rule: keep per-size compiles only where they buy >= {THRESHOLD:.0%} of run time)",
        "",
        "Gain = B/A - 1 of `simulate`, the smaller of the min and pairs ratios, the largest over the "
        "model's methods.",
        "",
        "| model | largest gain | method | keep per-size |",
        "|---|---|---|---|",
    ]
    for name, v in verdict.items():
        lines.append(f"| {name} | {v['gain']:+.1%} | {v['method']} | {'yes' if v['keep_per_size'] else 'no'} |")
    path_md.write_text("\n".join(lines) + "\n")


def main() -> None:
    RESULTS.mkdir(exist_ok=True)
    samples = int(os.environ.get("GS_BENCH_SAMPLES", "25"))
    data = run(samples=samples)
    data["decision"] = decide(data)
    write_report(data, RESULTS / "driver_sizes.md")
    print((RESULTS / "driver_sizes.md").read_text())


if __name__ == "__main__":
    main()
