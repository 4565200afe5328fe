"""Small timing helpers: medians, best-of-repeats, and timing inside a fresh interpreter."""
from __future__ import annotations

import json
import os
import statistics
import subprocess
import sys
import tempfile
import time
import timeit
from collections.abc import Callable
from pathlib import Path

REPO = Path(__file__).resolve().parent.parent


def median(values) -> float:
    return float(statistics.median(values))


def best_per_call(fn: Callable[[], object], *, number: int, repeat: int) -> float:
    """Best (smallest) seconds per call over ``repeat`` batches of ``number`` calls."""
    fn()  # warm up (first-call allocations, lazy imports)
    return min(timeit.repeat(fn, number=number, repeat=repeat)) / number


def interleaved(calls: dict, rounds: int) -> dict:
    """The best wall time of each of ``calls`` (name -> a function of no arguments), called in
    turn ``rounds`` times: this machine's speed drifts by 10-30 % over seconds, which
    back-to-back repeats of one case would read as a difference between cases."""
    best = {k: float("inf") for k in calls}
    for _ in range(rounds):
        for k, fn in calls.items():
            t0 = time.perf_counter()
            fn()
            best[k] = min(best[k], time.perf_counter() - t0)
    return best


def timed(fn: Callable[[], object]) -> tuple[float, object]:
    """Seconds taken by one call of ``fn`` and its result."""
    t0 = time.perf_counter()
    out = fn()
    return time.perf_counter() - t0, out


#: Where the fresh interpreters keep the package's compiled bytecode (``in_fresh_process``).
_PYCACHE: Path | None = None


def _bytecode_env(env: dict) -> dict:
    """``env`` for a fresh interpreter that imports the package from compiled bytecode, as a
    user's install does (pip compiles it): the bytecode in a private prefix
    (``PYTHONPYCACHEPREFIX``, outside the repository), compiled once per benchmark run,
    whatever ``PYTHONDONTWRITEBYTECODE`` the machine sets (this one's does: every fresh
    interpreter then compiled the package's ~110 modules again, ~0.2 s a process)."""
    global _PYCACHE
    env = dict(env)
    env.pop("PYTHONDONTWRITEBYTECODE", None)
    if _PYCACHE is None:
        _PYCACHE = Path(tempfile.mkdtemp(prefix="gs-bench-pycache-"))
        subprocess.run([sys.executable, "-m", "compileall", "-q", str(REPO / "grasping_sym"),
                        str(REPO / "benchmarks")], check=True, capture_output=True,
                       env=dict(env, PYTHONPYCACHEPREFIX=str(_PYCACHE)))
    env["PYTHONPYCACHEPREFIX"] = str(_PYCACHE)
    return env


def in_fresh_process(code: str, cache_dir: Path, timeout: float = 300.0) -> dict:
    """Run ``code`` in a new interpreter (cwd = repository, so ``benchmarks`` imports), with
    the package's bytecode compiled beforehand (``_bytecode_env``).

    ``code`` must print one JSON object as its last line of stdout; it is returned.
    ``GRASPING_SYM_CACHE`` is set to ``cache_dir`` for that process only.
    """
    env = _bytecode_env(dict(os.environ, GRASPING_SYM_CACHE=str(cache_dir)))
    proc = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                          cwd=REPO, env=env, timeout=timeout)
    if proc.returncode != 0:
        raise RuntimeError(f"benchmark subprocess failed (exit {proc.returncode}):\n"
                           f"{proc.stderr[-3000:]}")
    return json.loads(proc.stdout.strip().splitlines()[-1])


#: A fixed compile that tells how fast the machine runs gcc during this run (it is shared with
#: other work, and its speed moves by tens of percent): the driver's LU routines for 14
#: states, as the first build of a 2-finger structure compiles them.
_REFERENCE_DEFINES = {"GS_RHS": "r", "GS_NX": 14, "GS_NP": 2, "GS_HAS_OUT": 0, "GS_HAS_JAC": 0,
                      "GS_HAS_CON": 0, "GS_HAS_RHS_LANES": 0, "GS_SZ_ARG": 64, "GS_SZ_RES": 64,
                      "GS_SZ_IW": 64, "GS_SZ_W": 4096}


def reference_compile_s() -> float:
    """The best of 5 wall times of gcc compiling ``c/lu.c`` with ``_REFERENCE_DEFINES``."""
    from grasping_sym.toolchain.compiler import compile_objects  # noqa: PLC0415
    from grasping_sym.toolchain.library import DRIVER_SOURCES  # noqa: PLC0415

    lu = next(s for s in DRIVER_SOURCES if s.name == "lu.c")
    times = []
    with tempfile.TemporaryDirectory() as tmp:
        for _ in range(5):
            t0 = time.perf_counter()
            compile_objects([lu], tmp, _REFERENCE_DEFINES)
            times.append(time.perf_counter() - t0)
    return min(times)
