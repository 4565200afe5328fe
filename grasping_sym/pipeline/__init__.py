"""``build(scene)``: derive, generate C, compile, load -- or load from the cache.

- ``stages``: the build's stages and its cache lookup (``build``);
- ``making``: what a build does when the cache misses (``generate``, the code's hash, the
  start solved, the compile), with SymPy and CasADi: imported only then;
- ``built``: what ``build`` returns, a runtime model with its scene (``BuiltModel``);
- ``committed``: the committed code of the built-in scenes (``generate_committed``).

The names of ``making`` and ``committed`` are imported on first use (module ``__getattr__``),
so that ``gs.build`` of a cached scene imports neither.
"""
from __future__ import annotations

import importlib

from grasping_sym.pipeline.built import BuiltModel
from grasping_sym.pipeline.stages import build, write_start

_LAZY = {
    "code_hash": "grasping_sym.pipeline.making",
    "compile_library": "grasping_sym.pipeline.making",
    "generate": "grasping_sym.pipeline.making",
    "solve_start": "grasping_sym.pipeline.making",
    "start_key": "grasping_sym.pipeline.making",
    "with_check_outputs": "grasping_sym.pipeline.making",
    "generate_committed": "grasping_sym.pipeline.committed",
}

__all__ = ["BuiltModel", "build", "code_hash", "compile_library", "generate", "generate_committed",
           "solve_start", "start_key", "with_check_outputs", "write_start"]


def __getattr__(name: str):
    if name not in _LAZY:
        raise AttributeError(f"module 'grasping_sym.pipeline' has no attribute {name!r}")
    value = getattr(importlib.import_module(_LAZY[name]), name)
    globals()[name] = value  # later look-ups skip this function
    return value


def __dir__() -> list[str]:
    return sorted(set(globals()) | set(_LAZY))
