"""The runtime layer: the hand-written C driver compiled once into object files that every
model library links, whatever its sizes and features.

A model's driver macros (``library.driver_defines``) hold its sizes (states, parameters,
outputs, constraints), the names of its CasADi functions, its features (outputs, Jacobian,
constraints, 4-lane rhs) and CasADi's work sizes. The driver's objects are compiled with the
work sizes alone, rounded up to powers of two: a small file per library (:func:`links_c`,
compiled with the model's own C) forwards fixed names (``gs_model_rhs``, ...) to the model's
functions, with a stub that fails for each function the model lacks, and defines the sizes
and features the driver reads at run time (``gs_nx``, ``gs_has_out``, ... in
``c/gs_driver.h``). The objects are compiled once per set of work sizes, into
``<cache root>/objects/driver-<hash16>/``: a model of a new size, shape, start, name or set
of features compiles only its own C.

The hash covers the driver's C text, the macros, every compile flag (instruction set
included), the compiler's version and, for the CPython front end, the include directories
(the interpreter's and NumPy's).
"""
from __future__ import annotations

import contextvars
import functools
import hashlib
import os
import tempfile
import threading
from collections.abc import Mapping, Sequence
from concurrent.futures import Future, ThreadPoolExecutor
from pathlib import Path

from grasping_sym.store import paths as cache
from grasping_sym.store import safety
from grasping_sym.toolchain.compiler import (
    BASE_FLAGS,
    CASADI_FILE_FLAGS,
    compile_objects,
    compiler_command,
    compiler_version,
    isa_flags,
    level_flags,
)

__all__ = ["ALIASES", "FEATURES", "SIZES", "cached_objects", "driver_objects", "flags_digest", "links_c",
           "object_defines", "prefetch_driver_objects"]

#: The model's sizes among the driver's macros, and the run-time variable each one defines in
#: the link file (``c/gs_driver.h``).
SIZES: dict[str, str] = {"GS_NX": "gs_nx", "GS_NP": "gs_np", "GS_NY": "gs_ny", "GS_NC": "gs_nc",
                         "GS_OUT_TIME": "gs_out_time"}
#: The model's features among the driver's macros, and the run-time variable of each (0 when
#: the macro is absent); the Jacobian's block index is 1 unless given.
FEATURES: dict[str, str] = {
    "GS_HAS_OUT": "gs_has_out", "GS_HAS_JAC": "gs_has_jac", "GS_HAS_CON": "gs_has_con",
    "GS_HAS_RHS_LANES": "gs_has_lanes", "GS_JAC_NIN": "gs_jac_nin", "GS_JAC_NOUT": "gs_jac_nout",
    "GS_JAC_BLOCK": "gs_jac_block",
}
#: The driver's macros that name a model function, and the fixed name each one gets.
ALIASES: dict[str, str] = {
    "GS_RHS": "gs_model_rhs", "GS_OUT": "gs_model_outputs", "GS_JAC": "gs_model_jac",
    "GS_CON": "gs_model_constraints", "GS_RHS_LANES": "gs_model_rhs_lanes",
}
#: The work sizes and the least each is rounded up to: most models' sizes are below these, so
#: that nearly every model links the same driver objects. Unused stack costs nothing.
_WORK_SIZES = {"GS_SZ_ARG": 64, "GS_SZ_RES": 64, "GS_SZ_IW": 64, "GS_SZ_W": 4096}
_CASADI_SIG = "(const double** arg, double** res, long long int* iw, double* w, int mem)"
_LANES_SIG = "(const double* t, const double* const* x, const double* p, double* const* xdot)"
_SPARSITY_SIG = "(long long int i)"


def _bucket(n: int, least: int) -> int:
    """``n`` rounded up to a power of two, at least ``least``."""
    return max(least, 1 << max(0, int(n) - 1).bit_length())


def object_defines(defines: Mapping[str, str | int]) -> dict[str, str | int]:
    """The macros the driver's objects are compiled with: the work sizes alone, each rounded
    up to a power of two (at least ``_WORK_SIZES``'); the sizes, features and names are the
    link file's (:func:`links_c`)."""
    return {k: _bucket(int(defines[k]), least) for k, least in _WORK_SIZES.items()}


def links_c(defines: Mapping[str, str | int]) -> str:
    """C source forwarding each fixed name of :data:`ALIASES` to the model's function (and,
    for the Jacobian, its sparsity pattern), or to a stub that fails (returns 1; the
    sparsity NULL) for a function ``defines`` does not name, and defining the model's sizes
    (:data:`SIZES`; outputs and constraints 0 when the driver has none) and features
    (:data:`FEATURES`) the driver reads.

    Raises ``ValueError`` when the rhs or a feature's function is not named, or the
    Jacobian's inputs or outputs exceed the work sizes the driver's objects are compiled with
    (``object_defines``), as the driver's ``#error``s did when they were macros."""
    work = object_defines(defines)
    has = {"GS_NY": bool(defines.get("GS_HAS_OUT")), "GS_NC": bool(defines.get("GS_HAS_CON"))}
    values = {k: int(defines.get(k, 0)) for k in FEATURES}
    values["GS_JAC_BLOCK"] = int(defines.get("GS_JAC_BLOCK", 1))
    if values["GS_HAS_JAC"] and not (5 <= values["GS_JAC_NIN"] <= int(work["GS_SZ_ARG"])
                                     and values["GS_JAC_BLOCK"] < values["GS_JAC_NOUT"]
                                     <= int(work["GS_SZ_RES"])):
        raise ValueError(f"the Jacobian's GS_JAC_NIN / GS_JAC_NOUT / GS_JAC_BLOCK {values} are "
                         f"inconsistent with each other or with the work sizes {work}")
    named = {"GS_HAS_OUT": "GS_OUT", "GS_HAS_JAC": "GS_JAC", "GS_HAS_CON": "GS_CON",
             "GS_HAS_RHS_LANES": "GS_RHS_LANES"}
    unnamed = [flag for flag, name in named.items() if values[flag] and name not in defines]
    if "GS_RHS" not in defines or unnamed:
        raise ValueError(f"the driver's macros {dict(defines)!r:.300} name no function for "
                         f"{['GS_RHS'] if 'GS_RHS' not in defines else unnamed}: give each "
                         "feature's function (library.driver_defines makes them)")
    lines = ["/* grasping_sym: this model's sizes, features and functions, for the driver "
             "(toolchain.objects) */"]
    for k, var in SIZES.items():
        value = int(defines.get(k, 0)) if has.get(k, True) else 0
        lines.append(f'__attribute__((visibility("hidden"))) const int {var} = {value};')
    for k, var in FEATURES.items():
        lines.append(f'__attribute__((visibility("hidden"))) const int {var} = {values[k]};')
    for k, alias in ALIASES.items():
        sig = _LANES_SIG if k == "GS_RHS_LANES" else _CASADI_SIG
        target = defines.get(k)
        if target is None:  # a stub the driver never calls (its feature is 0), failing if it did
            lines.append(f"int {alias}{sig} {{ return 1; }}")
            if k == "GS_JAC":
                lines.append(f"const long long int* {alias}_sparsity_out{_SPARSITY_SIG} "
                             "{ return 0; }")
            continue
        args = "t, x, p, xdot" if k == "GS_RHS_LANES" else "arg, res, iw, w, mem"
        lines += [f"int {target}{sig};", f"int {alias}{sig} {{ return {target}({args}); }}"]
        if k == "GS_JAC":
            lines += [f"const long long int* {target}_sparsity_out{_SPARSITY_SIG};",
                      f"const long long int* {alias}_sparsity_out{_SPARSITY_SIG} "
                      f"{{ return {target}_sparsity_out(i); }}"]
    return "\n".join(lines) + "\n"


@functools.lru_cache(maxsize=8)
def _flags_digest(cc: tuple[str, ...], isa: tuple[str, ...], level: tuple[str, ...]) -> str:
    text = "\0".join([" ".join(cc), compiler_version(), " ".join(BASE_FLAGS + level),
                      " ".join(CASADI_FILE_FLAGS), " ".join(isa)])
    return hashlib.sha256(text.encode()).hexdigest()


def flags_digest() -> str:
    """Hash of what an object file depends on besides its source: the compiler and its
    version, the flags (the optimisation level's included) and the instruction set."""
    return _flags_digest(tuple(compiler_command()), tuple(isa_flags()), level_flags())


def _digest(sources: Sequence[Path], defines: Mapping, include_dirs: Sequence[str]) -> str:
    h = hashlib.sha256()
    for part in (flags_digest(), repr(sorted(defines.items())), repr(list(include_dirs))):
        h.update(part.encode() + b"\0")
    c_dir = sources[0].parent
    for f in sorted({*sources, *c_dir.glob("*.h")}):
        h.update(f.name.encode() + b"\0" + f.read_bytes())
    return h.hexdigest()


#: Driver compilations started ahead (``prefetch_driver_objects``), by object directory.
_AHEAD: dict[Path, Future] = {}
_AHEAD_LOCK = threading.Lock()


def _driver_directory(sources: Sequence[Path], defs: Mapping, include_dirs: Sequence[str]) -> Path:
    return cache.cache_root() / "objects" / f"driver-{_digest(sources, defs, include_dirs)[:16]}"


def _compile_driver(sources, defs, include_dirs, directory: Path,
                    at_once: int | None = None) -> list[Path]:
    return cached_objects(sources, safety.ensure_dir(directory, root=cache.cache_root()), defs,
                          include_dirs, at_once=at_once)


def driver_objects(sources: Sequence[Path], defines: Mapping[str, str | int],
                   include_dirs: Sequence[str] = ()) -> list[Path]:
    """The object files of the driver ``sources`` compiled with ``object_defines(defines)``:
    from ``<cache root>/objects/`` or compiled there now (in parallel, each installed
    atomically, so concurrent builds agree), or by a compilation started ahead for the same
    macros (``prefetch_driver_objects``), waited for."""
    defs = object_defines(defines)
    directory = _driver_directory(sources, defs, include_dirs)
    with _AHEAD_LOCK:
        ahead = _AHEAD.pop(directory, None)
    if ahead is not None:
        try:
            return ahead.result()
        except Exception:  # noqa: BLE001 - compiled again below, which raises its error
            pass
    return _compile_driver(sources, defs, include_dirs, directory)


def prefetch_driver_objects(sources: Sequence[Path], defines: Mapping[str, str | int],
                            include_dirs: Sequence[str] = ()) -> None:
    """Start compiling the driver's objects for ``defines`` in a background thread, unless
    they are cached or already under way: a build that predicts its model's macros before it
    derives anything (``library.predicted_defines``) compiles them meanwhile, and
    :func:`driver_objects` waits for them. Only a head start: a wrong prediction costs the
    compilation, never a wrong object."""
    defs = object_defines(defines)
    directory = _driver_directory(sources, defs, include_dirs)
    if all(os.path.lexists(directory / f"{Path(src).stem}.o") for src in sources):
        return
    with _AHEAD_LOCK:
        if directory not in _AHEAD:
            pool = ThreadPoolExecutor(max_workers=1, thread_name_prefix="gs-driver")
            # one file at a time: the build's own work keeps the other CPU
            # in this thread's context: its cache root (``store.paths.root_override``)
            _AHEAD[directory] = pool.submit(contextvars.copy_context().run, _compile_driver,
                                            sources, defs, include_dirs, directory, 1)
            pool.shutdown(wait=False)


def cached_objects(sources: Sequence[Path], directory: Path,
                   defines: Mapping[str, str | int] | None = None,
                   include_dirs: Sequence[str] = (), quick: Sequence[Path] = (),
                   at_once: int | None = None) -> list[Path]:
    """The object files ``<directory>/<stem>.o`` of ``sources``: checked (``runtime.safety``)
    when there, else compiled now (in parallel, each installed atomically; one process or
    thread compiles a directory's objects while the others wait for them; ``quick``: sources
    compiled with ``compiler.QUICK_FLAGS`` at the full level; ``at_once``: at most that many compilers at a
    time). ``directory`` must exist and be the caller's to fill."""
    objects = [Path(directory) / f"{Path(src).stem}.o" for src in sources]
    if _present(objects):
        return objects
    # one compiler per directory at a time: a concurrent build of the same code waits and
    # finds the objects done instead of compiling them again
    with safety.exclusive(Path(directory) / ".objects.lock"):
        if _present(objects):
            return objects
        with tempfile.TemporaryDirectory(dir=directory, prefix=".build-") as tmp:
            built = compile_objects(sources, Path(tmp), defines, include_dirs, quick=quick,
                                    at_once=at_once)
            for obj, final in zip(built, objects):
                os.replace(obj, final)
    return objects


def _present(objects: list[Path]) -> bool:
    """Whether every object file is there (each checked, ``store.safety``)."""
    if not all(os.path.lexists(o) for o in objects):
        return False
    for o in objects:
        safety.check_file(o)
    return True
