"""Small timing helpers: medians, best-of-repeats, and timing inside a fresh interpreter."""
from __future__ import annotations

import json
import os
import statistics
import subprocess
import sys
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


def timed(fn: Callable[[], object]) -> tuple[float, object]:
    """Seconds taken by one call of ``fn`` and its result."""
    t0 = time.perf_counter()
    out = fn()
    return time.perf_counter() - t0, out


def in_fresh_process(code: str, cache_dir: Path, timeout: float = 300.0) -> dict:
    """Run ``code`` in a new interpreter (cwd = repository, so ``benchmarks`` imports).

    ``code`` must print one JSON object as its last line of stdout; it is returned.
    ``GRASPING_SYM_CACHE`` is set to ``cache_dir`` for that process only.
    """
    env = dict(os.environ, GRASPING_SYM_CACHE=str(cache_dir))
    proc = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                          cwd=REPO, env=env, timeout=timeout)
    if proc.returncode != 0:
        raise RuntimeError(f"benchmark subprocess failed (exit {proc.returncode}):\n"
                           f"{proc.stderr[-3000:]}")
    return json.loads(proc.stdout.strip().splitlines()[-1])
