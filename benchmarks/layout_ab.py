"""The package's reorganisation into floors (issue 26) against the code before it, in the same run.

    python -m benchmarks.layout_ab       # writes benchmarks/results/layout_ab.md and .json

The commit before the reorganisation (``BASELINE``) is checked out into a temporary git
worktree; each figure is measured in fresh interpreters that import either that tree or this
one (``PYTHONPATH``), each with its own private cache, alternating A B A B ... so that the
machine's drift touches both alike. The figures are the paths a user takes:

- a cached build of paper2d (``gs.build`` with everything on disk; the package imported first);
- a cold build of paper2d in an empty cache (its committed C compiled, the driver's objects
  too), then, in that cache, paper2d with ``fd`` at run time: a model of other sizes (one
  parameter more), whose structure is new in both trees and whose driver objects only the
  per-size driver (before) compiles again;
- the first build of a new planar shape (derive, write and compile its own C; structures and
  the driver already cached);
- paper2d ``simulate(3.0)`` with every default (outputs every ms, checks);
- ``simulate``'s Python around the C loop on the short and the full way (the batch
  benchmark's case);
- paper3d ``simulate(3.0, method="dop853")``;
- ``simulate_many`` of 256 paper2d runs on one thread (runs/s).

Ratio = B / A (after / before): above 1 is slower, for the times; the rate is inverted so that
above 1 is slower too.
"""
from __future__ import annotations

import json
import os
import subprocess
import sys
import tempfile
from pathlib import Path

from benchmarks.machine import machine_info
from benchmarks.timing import REPO, median

RESULTS = Path(__file__).resolve().parent / "results"
#: The last commit before the reorganisation into floors.
BASELINE = "3d965a0"
#: Fresh-process samples per figure and tree.
ROUNDS = int(os.environ.get("GS_BENCH_ROUNDS", "9"))

_PRELUDE = """
import json, time, statistics
import numpy as np
import grasping_sym as gs
gs.build  # the package imports lazily: the build stack before any clock starts
"""

CASES = {
    "cached build of paper2d (ms)": _PRELUDE + """
scene = gs.scenes.paper2d()
gs.build(scene)  # the cache is warm after this process's first call too
t0 = time.perf_counter(); gs.build(gs.scenes.paper2d()); t1 = time.perf_counter()
print(json.dumps({"v": (t1 - t0) * 1e3}))
""",
    "first build of a new planar shape (s)": _PRELUDE + """
import random
gs.build(gs.scenes.paper2d())  # structures and driver cached, as a user's second shape finds them
a = 0.012 + random.random() * 1e-4
scene = gs.scenes.planar_finger(gs.curves.paper_fingertip(),
                                gs.curves.ellipse(a, 0.008, clockwise=True), name="ab_shape")
t0 = time.perf_counter(); gs.build(scene); t1 = time.perf_counter()
print(json.dumps({"v": t1 - t0}))
""",
    "cold build of paper2d in an empty cache, from its committed C (s)": _PRELUDE + """
import os, tempfile
os.environ["GRASPING_SYM_CACHE"] = tempfile.mkdtemp()  # nothing cached: the driver compiled too
t0 = time.perf_counter(); gs.build(gs.scenes.paper2d()); t1 = time.perf_counter()
print(json.dumps({"v": t1 - t0}))
""",
    "then paper2d with fd at run time: other sizes (s)": _PRELUDE + """
import os, tempfile
os.environ["GRASPING_SYM_CACHE"] = tempfile.mkdtemp()
gs.build(gs.scenes.paper2d())  # the driver's objects for paper2d's sizes are cached
scene = gs.scenes.paper2d(name="ab_runtime_fd", runtime=("fd",))  # one parameter more: GS_NP
t0 = time.perf_counter(); gs.build(scene); t1 = time.perf_counter()
print(json.dumps({"v": t1 - t0}))
""",
    "paper2d simulate(3.0), defaults (ms)": _PRELUDE + """
m = gs.build(gs.scenes.paper2d())
m.simulate(3.0)
ts = []
for _ in range(30):
    t0 = time.perf_counter(); m.simulate(3.0); ts.append(time.perf_counter() - t0)
print(json.dumps({"v": statistics.median(ts) * 1e3}))
""",
    "simulate() short way, Python around the C loop (us)": _PRELUDE + """
m = gs.build(gs.scenes.paper2d(name="paper2d_proj", gf=0, gl=0, wf=0, wl=0))
kw = dict(method="radau", rtol=1e-3, atol=1e-7, project=True, t_eval=[0.0, 3.0], outputs=False)
calls, inner = [], []
for _ in range(2000):
    t0 = time.perf_counter(); r = m.simulate(3.0, **kw); calls.append(time.perf_counter() - t0)
    inner.append(r.stats["wall_time"])
print(json.dumps({"v": (statistics.median(calls) - statistics.median(inner)) * 1e6}))
""",
    "simulate() full way, Python around the C loop (us)": _PRELUDE + """
from grasping_sym.runtime import fastpath
forget = getattr(fastpath, "forget", None) or (lambda m: m._plans.clear())  # before: no forget()
m = gs.build(gs.scenes.paper2d(name="paper2d_proj", gf=0, gl=0, wf=0, wl=0))
kw = dict(method="radau", rtol=1e-3, atol=1e-7, project=True, t_eval=[0.0, 3.0], outputs=False)
calls, inner = [], []
for i in range(1000):
    forget(m)  # no plan: every call takes the full way
    t0 = time.perf_counter(); r = m.simulate(3.0, **kw); calls.append(time.perf_counter() - t0)
    inner.append(r.stats["wall_time"])
print(json.dumps({"v": (statistics.median(calls) - statistics.median(inner)) * 1e6}))
""",
    "paper3d simulate(3.0, dop853) (ms)": _PRELUDE + """
m = gs.build(gs.scenes.paper3d())
m.simulate(3.0, method="dop853")
ts = []
for _ in range(15):
    t0 = time.perf_counter(); m.simulate(3.0, method="dop853"); ts.append(time.perf_counter() - t0)
print(json.dumps({"v": statistics.median(ts) * 1e3}))
""",
    "simulate_many, 256 paper2d runs, 1 thread (runs/s)": _PRELUDE + """
m = gs.build(gs.scenes.paper2d(runtime=("fd",)))
P = {"fd": np.linspace(0.4, 0.6, 256)}
m.simulate_many(3.0, params=P, threads=1)
ts = []
for _ in range(5):
    t0 = time.perf_counter(); m.simulate_many(3.0, params=P, threads=1); ts.append(time.perf_counter() - t0)
print(json.dumps({"v": 256 / statistics.median(ts)}))
""",
}
RATES = {"simulate_many, 256 paper2d runs, 1 thread (runs/s)"}


def _run(code: str, tree: Path, cache: Path) -> float:
    env = dict(os.environ, GRASPING_SYM_CACHE=str(cache), PYTHONPATH=str(tree))
    proc = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, cwd=tree,
                          env=env, timeout=900)
    if proc.returncode != 0:
        raise RuntimeError(f"{tree}: benchmark subprocess failed:\n{proc.stderr[-3000:]}")
    return float(json.loads(proc.stdout.strip().splitlines()[-1])["v"])


def measure(log=print) -> dict:
    with tempfile.TemporaryDirectory() as tmp:
        base = Path(tmp) / "baseline"
        subprocess.run(["git", "worktree", "add", "--detach", "-q", str(base), BASELINE], cwd=REPO,
                       check=True)
        # the baseline's committed code as its package data (``grasping_sym.generated``), not
        # this tree's (which the editable install maps it to)
        (base / "grasping_sym" / "generated").symlink_to(base / "generated")
        try:
            trees = {"before": base, "after": REPO}
            caches = {k: Path(tmp) / f"cache-{k}" for k in trees}
            out = {}
            for name, code in CASES.items():
                samples = {k: [] for k in trees}
                for _ in range(ROUNDS):
                    for k, tree in trees.items():
                        samples[k].append(_run(code, tree, caches[k]))
                a, b = median(samples["before"]), median(samples["after"])
                ratio = a / b if name in RATES else b / a
                out[name] = {"before": a, "after": b, "ratio": ratio, "samples": samples}
                log(f"{name}: before {a:.4g}, after {b:.4g}, ratio {ratio:.3f}")
        finally:
            subprocess.run(["git", "worktree", "remove", "--force", str(base)], cwd=REPO, check=False)
    return out


def write(out: dict) -> None:
    lines = ["# The reorganisation into floors (issue 26) against the code before it",
             "",
             f"Generated by `python -m benchmarks.layout_ab`: before = `{BASELINE}` (a git worktree), "
             "after = this tree, each figure the median of "
             f"{ROUNDS} fresh interpreters per tree, run alternately in one run, each tree with its own "
             "private cache. Ratio = after / before (a rate inverted): above 1 is slower.",
             "",
             "Machine: {cpu}, {logical_cores} logical cores, load average {load_average_1_5_15} at "
             "the end; {gcc}; commit {git_commit}, {date_utc} UTC.".format(**machine_info()),
             "",
             "| figure | before | after | ratio |",
             "|---|---|---|---|",
             *[f"| {k} | {v['before']:.4g} | {v['after']:.4g} | {v['ratio']:.3f} |" for k, v in out.items()],
             ""]
    RESULTS.mkdir(exist_ok=True)
    (RESULTS / "layout_ab.md").write_text("\n".join(lines))
    (RESULTS / "layout_ab.json").write_text(json.dumps(out, indent=1) + "\n")


if __name__ == "__main__":
    write(measure())
