"""Nanoseconds per right-hand-side evaluation of a built model, in a C loop.

The loop (``benchmarks/c/rhs_loop.c``) is compiled once per process into a temporary
directory and calls the model library's ``gs_rhs`` through a function pointer: models carry
no timing code of their own.
"""
from __future__ import annotations

import ctypes
import tempfile
from functools import lru_cache
from pathlib import Path

import numpy as np

from grasping_sym.toolchain.compiler import compile_shared

SOURCE = Path(__file__).resolve().parent / "c" / "rhs_loop.c"
_dp = ctypes.c_void_p


@lru_cache(maxsize=1)
def _loop():
    out = Path(tempfile.mkdtemp(prefix="gs-bench-loop-")) / "rhs_loop.so"
    lib = ctypes.CDLL(str(compile_shared([SOURCE], out)))
    fn = lib.bench_rhs_loop_ns
    fn.argtypes = [_dp, ctypes.c_long, ctypes.c_long, _dp, _dp, _dp]
    fn.restype = ctypes.c_double
    return fn


def rhs_loop_ns(model, x, n: int = 100_000, p=None) -> float:
    """ns per call of ``model``'s compiled rhs at ``x`` (``p``: default the model's)."""
    lib = model.library
    x = np.ascontiguousarray(x, dtype=float)
    if x.shape != (lib.nx,):
        raise ValueError(f"x has shape {x.shape}; the model has nx = {lib.nx}")
    pa = lib._p(p) if p is not None or lib.np else None
    pa = None if pa is None else np.ascontiguousarray(pa, dtype=float)
    xdot = np.empty(lib.nx)
    rhs = ctypes.cast(lib._lib.gs_rhs, _dp).value
    return float(_loop()(rhs, int(n), lib.nx, x.ctypes.data,
                         None if pa is None or pa.size == 0 else pa.ctypes.data, xdot.ctypes.data))
