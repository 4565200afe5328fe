"""Content hash of a scene's generated code, and where generated code lives.

- Built-in scenes: ``<repository>/generated/<name>/`` (committed C + manifest), installed as
  the package data ``grasping_sym.generated``.
- Every built model: ``<cache root>/<name>-<hash16>/`` with the C, the manifest and the
  compiled library. The cache root is ``$GRASPING_SYM_CACHE`` if set, else
  ``$XDG_CACHE_HOME/grasping_sym`` (default ``~/.cache/grasping_sym``).

The hash covers the scene's canonical text, the package version, CasADi's version, the
compiler flags and the source text of the modules that shape the generated code, so any
change to one of them makes a fresh build.
"""
from __future__ import annotations

import hashlib
import os
from contextlib import contextmanager
from functools import lru_cache
from pathlib import Path

import casadi as ca

PACKAGE_DIR = Path(__file__).resolve().parent.parent


def generated_dir() -> Path:
    """The committed generated code: the package data ``grasping_sym.generated`` (the
    repository's top-level ``generated/`` in a source checkout or an editable install)."""
    from importlib.resources import files  # noqa: PLC0415

    return Path(str(files("grasping_sym.generated")))


def source_checkout() -> Path | None:
    """The repository root when the package runs from a source checkout (``generated/`` and
    ``pyproject.toml`` beside the package), else None (an installed copy)."""
    root = PACKAGE_DIR.parent
    if (root / "pyproject.toml").is_file() and generated_dir().resolve() == (root / "generated").resolve():
        return root
    return None
#: Sources whose text enters the hash of every scene's code: every module that shapes a
#: planar scene's generated code, its manifest or its compiled library, and the ones all
#: scenes share. A scene class adds the modules of its own model (``scene.hashed_sources``),
#: so work on the 3D modules does not invalidate the planar artifacts; list a module here as
#: soon as the planar pipeline imports it.
HASHED_SOURCES = (
    "geometry/curves.py", "model/planar.py", "model/names.py", "derive/system.py",
    "derive/contour_functions.py", "derive/planar.py", "codegen/translate.py",
    "codegen/functions.py", "codegen/cwriter.py", "codegen/templates.py",
    "codegen/scene_functions.py", "codegen/compiler.py", "c/driver.c", "c/project.c", "c/rk4.c",
    "c/radau5.c", "c/radau5.h", "c/jac.c", "c/lu.c", "c/dopri5.c", "c/dop853.c",
    "c/stop.c", "c/batch.c",
    "c/budget.c", "c/gs_internal.h",
    "c/pyfast.c", "c/gs_driver.h", "codegen/library.py", "codegen/lanes.py",
    "codegen/vecmath.py", "codegen/algorithm.py", "codegen/reciprocals.py", "codegen/objects.py",
    "codegen/structure.py",
    "codegen/structure_cache.py", "codegen/layered.py", "pipeline.py", "model/control.py",
    "codegen/controller.py",
)
# Not here: ``controllers.py`` and ``derive/quantities.py``. What they make, the controller's
# expressions, enters a scene's code key itself (``codegen.controller.controller_key``), so
# a new preset or quantity rebuilds the models whose law changed, and no structure.


_ROOT_OVERRIDE: list[Path] = []


@contextmanager
def root_override(path: Path):
    """Use ``path`` as the cache root inside the ``with`` block (``generate_committed``
    derives everything afresh in a private root)."""
    _ROOT_OVERRIDE.append(Path(path))
    try:
        yield Path(path)
    finally:
        _ROOT_OVERRIDE.pop()


def cache_root() -> Path:
    if _ROOT_OVERRIDE:
        return _ROOT_OVERRIDE[-1]
    env = os.environ.get("GRASPING_SYM_CACHE")
    if env:
        return Path(env)
    base = os.environ.get("XDG_CACHE_HOME") or str(Path.home() / ".cache")
    return Path(base) / "grasping_sym"


@lru_cache(maxsize=4)
def sources_digest(sources: tuple[str, ...] = HASHED_SOURCES) -> str:
    """Hash of the source text of the modules that shape generated code."""
    h = hashlib.sha256()
    for rel in sources:
        h.update(rel.encode())
        h.update((PACKAGE_DIR / rel).read_bytes())
    return h.hexdigest()


def content_hash(scene_key: str, version: str, compiler_flags: tuple[str, ...],
                 sources: tuple[str, ...] = HASHED_SOURCES) -> dict:
    """The hash and the inputs it covers (recorded in the manifest)."""
    inputs = {
        "scene": hashlib.sha256(scene_key.encode()).hexdigest(),
        "grasping_sym": version,
        "casadi": ca.__version__,
        "compiler_flags": " ".join(compiler_flags),
        "sources": sources_digest(sources),
    }
    h = hashlib.sha256("\n".join(f"{k}={inputs[k]}" for k in sorted(inputs)).encode())
    return {"hash": h.hexdigest(), "inputs": inputs}


def cache_dir(name: str, digest: str) -> Path:
    return cache_root() / f"{name}-{digest[:16]}"


def committed_dir(name: str) -> Path:
    return generated_dir() / name
