"""The platform a compiled library is made for and loaded on: the CPU's instruction-set
level and whether glibc's vector libm serves it. Read without a compiler (``/proc/cpuinfo``,
``ctypes``), so that the runtime finds a cached library on a machine with none, and the
toolchain compiles for the same level (``toolchain.compiler.isa_flags``).
"""
from __future__ import annotations

import ctypes
import functools
import hashlib
import os
import platform
import sys

import numpy as np

#: Functions with a 4-lane AVX2 version in glibc's libmvec (since glibc 2.35), by arity: the
#: libm calls generated C makes four at a time (``emit.vecmath`` groups them; ``vector_libm``
#: checks that ``libmvec`` has each).
VECTOR_FUNCTIONS: dict[str, int] = {
    **dict.fromkeys(("sin", "cos", "tan", "asin", "acos", "atan", "sinh", "cosh", "tanh",
                     "asinh", "acosh", "atanh", "exp", "log", "log1p", "expm1", "erf"), 1),
    "atan2": 2, "pow": 2,
}

_X86_64_V3_CPU_FLAGS = frozenset({
    "cx16", "lahf_lm", "popcnt", "sse4_1", "sse4_2", "ssse3",  # x86-64-v2
    "avx", "avx2", "bmi1", "bmi2", "f16c", "fma", "abm", "movbe", "xsave",  # x86-64-v3
})
_ISA_ENV = "GRASPING_SYM_ISA"
_VECMATH_ENV = "GRASPING_SYM_VECMATH"
_OPT_ENV = "GRASPING_SYM_OPT"
#: glibc's vector math library, linked by file name (its ``libmvec.so`` link is optional).
LIBMVEC = "libmvec.so.1"



@functools.lru_cache(maxsize=1)
def _cpu_flags() -> frozenset[str]:
    """The CPU's feature flags from /proc/cpuinfo (empty where there is none); read once per
    process (every ``build`` names its library with the level, cached loads included)."""
    try:
        with open("/proc/cpuinfo", encoding="utf-8", errors="replace") as fh:
            for line in fh:
                if line.startswith("flags"):
                    return frozenset(line.partition(":")[2].split())
    except OSError:
        pass
    return frozenset()



def _setting(env: str, choices: dict[str, str]) -> str:
    """The value of ``$env`` (lower case; unset or empty: the first choice), one of
    ``choices`` (value -> what it means), else a ValueError naming them."""
    choice = os.environ.get(env, "").strip().lower() or next(iter(choices))
    if choice not in choices:
        known = " or ".join(f"{k!r} ({v})" for k, v in choices.items())
        raise ValueError(f"{env}={os.environ[env]!r} is not a known setting; use {known}")
    return choice


def isa_level() -> str:
    """The CPU's instruction-set level that libraries are built for: ``"x86-64-v3"`` or
    ``"baseline"``.

    ``"x86-64-v3"`` when the machine is x86-64 and its CPU has every feature of that level
    (AVX2, FMA, BMI1/2, ...); ``"baseline"`` otherwise or when ``$GRASPING_SYM_ISA`` is
    ``baseline``.  Reads /proc/cpuinfo only (no compiler needed), so a cached library is
    found without a compiler on the machine.

    Raises
    ------
    ValueError
        If ``$GRASPING_SYM_ISA`` is set to something other than ``auto`` or ``baseline``.
    """
    choice = _setting(_ISA_ENV, {"auto": "x86-64-v3 where the CPU has it",
                                 "baseline": "the compiler's default target"})
    if choice == "baseline" or platform.machine().lower() not in ("x86_64", "amd64"):
        return "baseline"
    return "x86-64-v3" if _X86_64_V3_CPU_FLAGS <= _cpu_flags() else "baseline"



def optimization() -> str:
    """How hard gcc optimises the libraries built: ``"full"`` (``-O2``, the default),
    ``"quick"`` (``-Og``) or ``"none"`` (``-O0``), as ``$GRASPING_SYM_OPT`` says.

    ``quick`` is for iterating on shapes and for test suites: the model's C compiles in about
    half the time and runs about 10 % slower (paper3d: compile 1.2 s against 2.9 s, a 3 s run
    2.90 ms against 2.60 ms), with the same results on x86-64, where no level fuses or reorders
    floating-point operations (no ``-ffast-math``; the baseline has no fused multiply-add, and
    x86-64-v3 is compiled with ``-ffp-contract=off``; ``tests/test_compiled_runtime.py`` checks
    it bit for bit). ``none`` is for test suites, whose time goes to gcc and not to the runs:
    a model's C compiles about 4.5 times faster than at ``quick`` (a modes model's largest file:
    2.2 s against 10 s) and runs 2 to 3.5 times slower than at ``full`` (a 3 s run with its
    defaults: paper2d 7.1 ms against 2.8-4.7, paper3d 51 against 16-23), with the same results
    again.
    The libraries of the levels have different names.

    Raises
    ------
    ValueError
        If ``$GRASPING_SYM_OPT`` is set to something other than ``full``, ``quick`` or
        ``none``.
    """
    return _setting(_OPT_ENV, {"full": "gcc -O2, the fastest code",
                               "quick": "gcc -Og, about half the compile time, ~10 % slower code",
                               "none": "gcc -O0, ~4.5 times faster to compile than quick, 2-3.5 times slower "
                                       "code"})


def vector_libm() -> bool:
    """True when libraries are built with glibc's vector libm (see the module's docstring):
    the level is x86-64-v3, ``$GRASPING_SYM_VECMATH`` is not ``off`` and ``libmvec.so.1``
    loads with the 4-lane AVX2 version of every function in ``vecmath.VECTOR_FUNCTIONS``.
    Needs no compiler (a cached library is found without one).

    Raises
    ------
    ValueError
        If ``$GRASPING_SYM_VECMATH`` is set to something other than ``auto`` or ``off``.
    """
    choice = _setting(_VECMATH_ENV, {
        "auto": "glibc's libmvec where the CPU and the C library have it",
        "off": "scalar libm calls"})
    return choice == "auto" and isa_level() == "x86-64-v3" and _libmvec_complete()


@functools.lru_cache(maxsize=1)
def _libmvec_complete() -> bool:
    try:
        lib = ctypes.CDLL(LIBMVEC)
    except OSError:
        return False
    prefix = {1: "_ZGVdN4v_", 2: "_ZGVdN4vv_"}
    return all(hasattr(lib, prefix[n] + f) for f, n in VECTOR_FUNCTIONS.items())


def library_tag() -> str:
    """What ties a compiled library to this interpreter (the fast path is an extension) and
    to the instruction set it was compiled for (``store.platform.isa_level``, with ``-mvec`` when
    it calls glibc's vector libm, ``store.platform.vector_libm``), ``-quick`` or ``-O0`` when
    compiled at the quick level or at none (``optimization``), and ``$CC`` when set (``-cc`` and a hash of it: another
    compiler makes another library)."""
    mvec = "-mvec" if vector_libm() else ""
    mvec += {"full": "", "quick": "-quick", "none": "-O0"}[optimization()]
    cc = os.environ.get("CC", "").strip()
    cc = f"-cc{hashlib.sha256(cc.encode()).hexdigest()[:8]}" if cc else ""
    return f"{sys.implementation.cache_tag}-numpy{np.__version__}-{isa_level()}{mvec}{cc}"


def library_name(name: str) -> str:
    """File name of a model's compiled library for this interpreter and CPU."""
    return f"lib{name}.{library_tag()}.so"
