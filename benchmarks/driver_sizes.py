"""What the driver's run-time sizes cost (issue 26, part 6).

The driver (``grasping_sym/c``: the integrators, the projection, the batch loop and the
CPython front end) used to be compiled into object files once per set of model sizes
(``GS_NX``, ``GS_NP``, ``GS_NY``, ``GS_NC``, ``GS_RADAU_M`` preprocessor constants). It now
reads the sizes at run time (``gs_nx``, ... hidden ``const int`` globals the library's link
file defines, ``toolchain.objects.links_c``), so its objects depend on the model's features
alone and are compiled once per set of them (since issue 28 the features are read at run time
too, and the objects are compiled once per set of work sizes). Here every model is linked twice, with the same
CasADi-generated objects, flags and link line:

* **A, per size**: the driver's C of the revision before the change (``BEFORE``, read with
  ``git show`` into a temporary directory), compiled with the model's sizes as macros, as
  that revision's ``objects.object_defines`` did (names aliased, work sizes bucketed);
* **B, run-time sizes**: the package's driver as it is compiled now
  (``objects.object_defines``, which leaves the sizes out).

Measured per model: ``simulate(3.0)`` with two methods and the bare C loop of the same
integrator (``model.library.<method>``, output every ms), the two libraries interleaved in
one process (A B B A ...), min and median of repeated samples; the results of A and B are
compared bit for bit (these runs, and rk4, a projected radau run and a batch of radau runs);
and the serial gcc seconds of the driver's objects (the files one after another), which A
pays for every new set of sizes and B once per set of work sizes.

    python -m benchmarks.driver_sizes   ->  benchmarks/results/driver_sizes.md (GS_BENCH_SAMPLES: samples)
"""
from __future__ import annotations

import os
import statistics
import subprocess
import sys
import tempfile
import time
from functools import partial
from pathlib import Path

import numpy as np

from benchmarks.machine import machine_info

RESULTS = Path(__file__).resolve().parent / "results"

#: Decision rule of issue 26: keep the per-size compile only where it buys this much run time.
THRESHOLD = 0.05
#: The revision whose driver is A: the last one compiled per set of sizes.
BEFORE = "1bded56^"
#: The git checkout ``BEFORE`` is read from (GS_BENCH_REPO: another clone of the repository).
REPO = Path(os.environ.get("GS_BENCH_REPO", Path(__file__).resolve().parent.parent))

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


def before_sources(dest: Path, rev: str = BEFORE) -> list[Path]:
    """The driver's C of ``rev`` written to ``dest``; its sources in that revision's order
    (``DRIVER_SOURCES`` + ``pyfast.c`` then)."""
    names = subprocess.run(["git", "ls-tree", "--name-only", rev, "grasping_sym/c/"], cwd=REPO,
                           check=True, capture_output=True, text=True).stdout.split()
    for name in names:
        text = subprocess.run(["git", "show", f"{rev}:{name}"], cwd=REPO, check=True,
                              capture_output=True, text=True).stdout
        (dest / Path(name).name).write_text(text)
    order = ("driver.c", "project.c", "rk4.c", "radau5.c", "jac.c", "lu.c", "dopri5.c", "dop853.c",
             "stop.c", "batch.c", "budget.c", "pyfast.c")
    return [dest / n for n in order]


def _positions(names) -> int:
    """The leading states whose speeds ``d<name>`` follow them: the Jacobian's second-order
    rows, the ``GS_RADAU_M`` the per-size build compiled in (the models here are built with
    the naming rule of ``model.names``)."""
    for m in range(len(names) // 2, 0, -1):
        if all(names[m + i] == "d" + names[i] for i in range(m)):
            return m
    return 0


def per_size_defines(model) -> dict:
    """A's macros: the model's driver macros as the per-size revision compiled them."""
    from grasping_sym.toolchain.objects import ALIASES, object_defines

    d = model.manifest["driver_defines"]
    # the old revision read its features and the functions' names as macros too (they are the
    # link file's now, ``objects.links_c``): the aliased names and the feature flags, as
    # ``object_defines`` gave them before the features went to run time
    out = {k: v for k, v in d.items() if k.startswith("GS_HAS_") or k in ("GS_JAC_NIN", "GS_JAC_NOUT",
                                                                         "GS_JAC_BLOCK")}
    out.update({k: ALIASES[k] for k in ALIASES if k in d})
    out.update(object_defines(d))
    out.update({k: d[k] for k in ("GS_NX", "GS_NP", "GS_NY", "GS_NC") if k in d})
    if d.get("GS_HAS_JAC"):
        out["GS_RADAU_M"] = _positions(model.state_names)
    return out


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


def build_pair(model, work: Path, before_src: list[Path], log=print) -> dict:
    """Link ``model``'s generated code with the per-size driver (A) and the package's run-time
    one (B) in ``work``; the two library paths and the serial compile seconds of each driver."""
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
    for tag, sources, defs in (("A", before_src, per_size_defines(model)),
                               ("B", [*DRIVER_SOURCES, PYFAST_C], object_cache.object_defines(defines))):
        d = work / tag
        d.mkdir()
        drv, seconds = _compile_serial(sources, d, defs, include_dirs)
        links = d / "gs_links.c"
        links.write_text(object_cache.links_c(defines))  # A ignores the size variables
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
        before_dir = tmp / "c_before"
        before_dir.mkdir()
        before_src = before_sources(before_dir)
        variants = {}
        for name, model in models.items():
            d = model.manifest["driver_defines"]
            log(f"{name}: nx {d['GS_NX']}, np {d['GS_NP']}, ny {d.get('GS_NY', 0)}, "
                f"nc {d.get('GS_NC', 0)}")
            work = tmp / name
            work.mkdir()
            pair = build_pair(model, work, before_src, log)
            builds[name] = {"sizes": {k: v for k, v in per_size_defines(model).items()
                                      if k in ("GS_NX", "GS_NP", "GS_NY", "GS_NC", "GS_RADAU_M")},
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
        extra = {}
        for name in variants:
            extra[name] = _bitwise_extras(variants[name]["A"], variants[name]["B"])
            log(f"{name}: rk4, projected radau, batch of radau runs identical: {extra[name]}")
    machine = machine_info()
    if not machine.get("git_commit"):  # run from a copy of the tree: the commit of GS_BENCH_REPO
        machine["git_commit"] = subprocess.run(["git", "rev-parse", "--short", "HEAD"], cwd=REPO,
                                               capture_output=True, text=True).stdout.strip()
    return {"machine": machine, "samples": samples, "builds": builds, "rows": rows,
            "bitwise_extras": extra}


def _bitwise_extras(ma, mb) -> bool:
    """Whether A and B agree bit for bit on rk4 (h = 1e-4, 1 s), radau with the projection
    and a batch of three radau runs (final states)."""
    same = True
    for kw in ({"method": "rk4", "h": 1e-4}, {"method": "radau", "project": True}):
        ra, rb = ma.simulate(1.0, **kw), mb.simulate(1.0, **kw)
        same &= bool(np.array_equal(np.asarray(ra.x), np.asarray(rb.x)))
    x0 = np.tile(ma.initial_state(), (3, 1))
    x0[1] *= 1.0 + 1e-6  # an inconsistent start: its run fails alike in both (NaN final state)
    ba, bb = ma.simulate_many(1.0, x0=x0), mb.simulate_many(1.0, x0=x0)
    return same and bool(np.array_equal(ba.x_final, bb.x_final, equal_nan=True)
                         and np.array_equal(ba.status, bb.status))


_FIRST_BUILD = """
import sys, time
import grasping_sym as gs
from grasping_sym.toolchain import library
from benchmarks.scenes import ellipse2d
if sys.argv[1] == "off":
    library.prefetch_driver = lambda defines, fast=True: None
if sys.argv[2] == "warm":
    gs.build(gs.scenes.paper2d())  # a planar model built before: the driver's objects cached
t0 = time.perf_counter()
gs.build(ellipse2d())
print(time.perf_counter() - t0)
"""


def first_builds(runs: int = 2, log=print) -> dict:
    """Wall seconds of the first build of a new planar shape (``benchmarks.scenes.ellipse2d``),
    each in a fresh process and cache root, with the driver's prefetch (``library.
    prefetch_driver``) on and off: in an empty cache (``cold``) and after paper2d (``warm``)."""
    out: dict = {}
    for _ in range(runs):
        for where in ("cold", "warm"):
            for mode in ("on", "off"):
                with tempfile.TemporaryDirectory(prefix="gs-bench-first-") as root:
                    env = {**os.environ, "GRASPING_SYM_CACHE": root,
                           "PYTHONPATH": str(Path(__file__).resolve().parent.parent)}
                    s = float(subprocess.run([sys.executable, "-c", _FIRST_BUILD, mode, where],
                                             check=True, capture_output=True, text=True, env=env,
                                             cwd=Path(__file__).resolve().parent.parent
                                             ).stdout.split()[-1])
                out.setdefault(where, {}).setdefault(mode, []).append(s)
                log(f"first build of ellipse2d, {where} cache, prefetch {mode}: {s:.2f} s")
    return out


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
        "# The driver's sizes at run time: its cost against the driver compiled per model size",
        "",
        "Generated by `python -m benchmarks.driver_sizes` (issue 26, part 6). **A** = the driver's C of "
        f"`{BEFORE}` (the last revision compiled per set of sizes: `GS_NX`, `GS_NP`, `GS_NY`, `GS_NC`, "
        "`GS_RADAU_M` compile-time constants), compiled with this model's sizes; **B** = the package's "
        "driver as it is now: the sizes are `const int` globals the library's link file defines "
        "(`objects.links_c`, another translation unit, no LTO), stack arrays are VLAs, `gs_radau5`'s "
        "matrices are on the stack up to 256 KiB and on the heap above (no size bound), `lu.c` "
        "dispatches sizes 1-8 to copies compiled for that size. Features, function names and the "
        "(bucketed) CasADi work sizes are compile-time in both. "
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
        "set of features (paper2d and fingers2 have the same features: B's objects are the same files, "
        "the package compiles them once).",
        "",
        "| model | nx | np | ny | nc | radau m | features (out, jac, con, lanes) | A: gcc s per size "
        "| B: gcc s (once) |",
        "|---|---|---|---|---|---|---|---|---|",
    ]
    for name, b in data["builds"].items():
        s, f = b["sizes"], b["features"]
        lines.append(f"| {name} | {s['GS_NX']} | {s['GS_NP']} | {s.get('GS_NY', 0)} | {s.get('GS_NC', 0)} "
                     f"| {s.get('GS_RADAU_M', 0)} "
                     f"| {f['GS_HAS_OUT']}, {f['GS_HAS_JAC']}, {f['GS_HAS_CON']}, {f['GS_HAS_RHS_LANES']} "
                     f"| {b['compile_A_s']:.2f} | {b['compile_B_s']:.2f} |")
    lines += [
        "",
        "Bit for bit, A = B also on rk4 (h = 1e-4), radau with the projection and a batch of three radau "
        "runs: " + ", ".join(f"{k} {'yes' if v else 'NO'}" for k, v in data["bitwise_extras"].items()) + ".",
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
    lines += [
        "",
        "Implemented: the sizes at run time everywhere (B is the package's driver). The driver's objects "
        "are compiled once per set of features (`objects.object_defines` leaves the sizes out).",
    ]
    fb = data.get("first_builds")
    if fb:
        lines += [
            "",
            "## The driver's prefetch",
            "",
            "A build that derives a new structure starts compiling the driver's objects in the background "
            "first (`library.prefetch_driver`, now predicted from the features alone). Wall seconds of the "
            "first build of a new planar shape (`ellipse2d`), each in a fresh process and cache root: "
            "*cold* = an empty cache, *warm* = after paper2d was built (the planar driver objects cached).",
            "",
            "| cache | prefetch on: s (each run) | prefetch off: s (each run) | saved (min) |",
            "|---|---|---|---|",
        ]
        for where, v in fb.items():
            lines.append(f"| {where} | {', '.join(f'{s:.2f}' for s in v['on'])} "
                         f"| {', '.join(f'{s:.2f}' for s in v['off'])} | {min(v['off']) - min(v['on']):+.2f} |")
        cold = min(fb["cold"]["off"]) - min(fb["cold"]["on"])
        lines += ["", f"Kept only if it saves >= 0.2 s: it saves {cold:.2f} s on the first build in an empty "
                  f"cache, so it is {'kept' if cold >= 0.2 else 'to be removed'}; once a model with the same "
                  "features was built its objects are cached and it does nothing."]
    path_md.write_text("\n".join(lines) + "\n")


def main() -> None:
    RESULTS.mkdir(exist_ok=True)
    samples = int(os.environ.get("GS_BENCH_SAMPLES", "25"))
    data = run(samples=samples)
    data["first_builds"] = first_builds()
    data["decision"] = decide(data)
    write_report(data, RESULTS / "driver_sizes.md")
    print((RESULTS / "driver_sizes.md").read_text())


if __name__ == "__main__":
    main()
