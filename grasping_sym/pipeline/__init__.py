"""``build(scene)``: derive, generate C, compile, load -- or load from the cache.

- ``stages``: the build's stages and its cache (``build``, ``generate``, the code's hash);
- ``built``: what ``build`` returns, a runtime model with its scene (``BuiltModel``);
- ``committed``: the committed code of the built-in scenes (``generate_committed``).
"""
from __future__ import annotations

from grasping_sym.pipeline.built import BuiltModel, compile_library
from grasping_sym.pipeline.committed import generate_committed
from grasping_sym.pipeline.stages import (
    build,
    code_hash,
    generate,
    solve_start,
    start_key,
    with_check_outputs,
    write_start,
)

__all__ = ["BuiltModel", "build", "code_hash", "compile_library", "generate", "generate_committed",
           "solve_start", "start_key", "with_check_outputs", "write_start"]
