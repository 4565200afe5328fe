"""The stages of ``build(scene)``: derive, generate C, compile, load -- or load from the cache.

One path for every scene: a scene meets one protocol (``name``, ``state_names``,
``outputs``, ``runtime``, ``params``, ``start_param_names``, ``code_key()``, ``key()``,
``casadi_functions()``, ``solve_start()``,
``bounds()``, ``manifest_extra()``, ``sympy_op_counts()``, ``structure_templates()``; and for
the command line ``simulate_defaults``, ``write_figures()``, ``summary_lines()``), and

    scene -> CasADi functions (codegen.scene_functions) -> C (codegen.cwriter) -> library

Layers are cached apart, each under its own hash:

- the runtime: the hand-written C driver (integrators, projection, the CPython front end),
  compiled once per set of work sizes into ``<cache root>/objects/`` (``toolchain.objects``);
- a 2D scene's structure: the closed loop of its template with its constants, as functions of
  the contour values, written and compiled once into ``<cache root>/structures/``
  (``codegen.structure``, ``codegen.structure_cache``; the built-in ones are committed under
  ``generated/structures/``);
- the code: the scene's own C (for a 2D scene only its contours and the glue that calls the
  structure, ``codegen.layered``), its manifest and the compiled library, hashed from the
  exact inputs that shape them (``scene.code_key()``, the package's sources, versions,
  compiler flags); ``generated/<name>/`` holds the committed C of the built-in scenes;
- the start: the numbers solved from the scene's start (the consistent initial state, the
  run-time values the start fixes such as the 2D pivot), under ``starts/<key>.json`` in the
  code's directory (``runtime.stored``). A new start reuses the compiled code.

The hash of the code reads the controller's expressions (the law is run to make them), and a
2D scene's state names sample its contours: a tenth of a second. A build that found a
scene's model keeps what it found under the scene's definition (``definition_key``: the
scene's ``key()`` and its law's definition, no expression made), in
``<cache root>/definitions/``, so that a build of the same definition is a lookup.

Stages (timed in ``Model.build_info``): hash; load the cached library, else compile the
committed C, else derive and write C, then compile; then the start, from the cache or solved.
This module is the lookup; what a build does when it finds nothing is ``pipeline.making``,
imported only then: a build that finds its model imports neither SymPy nor CasADi for it.
"""
from __future__ import annotations

import errno
import re
import time
from collections.abc import Callable
from pathlib import Path

from grasping_sym import __version__
from grasping_sym.errors import CacheWriteError, GraspingSymError
from grasping_sym.model.control import PAPER
from grasping_sym.pipeline.built import BuiltModel
from grasping_sym.store import files as stored
from grasping_sym.store import paths as cache
from grasping_sym.store import safety
from grasping_sym.store.manifest_schema import manifest_problems
from grasping_sym.store.platform import library_name
from grasping_sym.toolchain.compiler import toolchain_id, toolchain_matches, vector_libm

Progress = Callable[[str], None]

#: The shared directory of the definition keys (``store.paths.SHARED_DIRS``).
DEFINITIONS = "definitions"
#: The lock file in a model's cache entry that one build at a time holds while it writes it.
BUILD_LOCK = ".build.lock"
_HEX64 = re.compile(r"[0-9a-f]{64}")


def _making():
    """``pipeline.making``: the derivation, the emitter and the compiler, with SymPy and CasADi,
    imported when a build needs them (its model not in the cache, its law not keyed by its
    definition, its start not stored), not by a build that finds everything."""
    import grasping_sym.pipeline.making as making  # noqa: PLC0415 - lazy: SymPy and CasADi only when the cache misses
    return making


def definition_key(scene) -> str | None:
    """The hash of the scene's whole definition (its name, ``code_key()`` and ``key()``: its
    code's and its start's)
    with its controller's definition (``Controller.definition``: a preset's name and
    parameters, a law's code), the package's sources and version: computed without running the
    law or deriving anything, so that a cached scene is found at the cost of a lookup
    (``definitions/<key>.json`` maps it to the code hash and the start key). The sources enter
    by their files' stat (``store.paths.sources_stamp``), not read whole: an edited source
    misses the lookup, and the build keys its code by the sources read whole. None for a law
    whose definition cannot be read (then the law's expressions key the build)."""
    law = scene.controller
    text = "none" if law is None else "paper" if law == PAPER else law.definition
    if text is None:
        return None
    parts = ["definition", type(scene).__name__, scene.name, scene.code_key(), scene.key(),
             f"controller={text}"]
    return cache.content_hash("\n".join(parts), __version__, "stat:" + cache.sources_stamp())["hash"]


def _definitions(root: Path) -> Path:
    return safety.ensure_dir(root / DEFINITIONS, root=root)


def _known(root: Path, key: str) -> dict | None:
    """What a build of the scene of definition ``key`` recorded (``definition_key``): its
    code hash and start key, or None."""
    path = _definitions(root) / f"{key[:32]}.json"
    if not path.exists():
        return None
    safety.check_file(path)
    known = stored.read_json(path)
    if known is None or known.get("key") != key or not all(
            isinstance(known.get(k), str) and _HEX64.fullmatch(known[k]) for k in ("hash", "start_key")):
        return None
    return known


def _remember(root: Path, key: str, digest: str, start: str) -> None:
    stored.write_json(_definitions(root) / f"{key[:32]}.json",
                      {"key": key, "hash": digest, "start_key": start})


def write_start(directory: Path, record: dict) -> None:
    """Store a start record under ``starts/<key>.json`` and as the directory's default."""
    starts = safety.ensure_dir(directory / stored.STARTS_DIR, root=directory)
    stored.write_json(starts / f"{record['key'][:16]}.json", record)
    stored.write_json(directory / stored.START, record)


def _start(scene, directory: Path, say: Progress, key: str,
           state_names: list[str]) -> tuple[dict, str]:
    """The scene's start record of start key ``key``: from the cache, from the committed
    files, or solved."""
    shape = {"state_names": list(state_names), "start_param_names": list(scene.start_param_names)}
    cached = stored.read_json(directory / stored.STARTS_DIR / f"{key[:16]}.json")
    if cached is not None and cached.get("key") == key and not stored.start_problems(cached, shape):
        return cached, "cache"
    committed = stored.read_json(cache.committed_dir(scene.name) / stored.START)
    if committed is not None and committed.get("key") == key and not stored.start_problems(committed, shape):
        return committed, "committed"
    say(f"solving a consistent start for {scene.name}")
    return _making().solve_start(scene), "solved"


def build(scene, *, progress: Progress | None = None, force: bool = False) -> BuiltModel:
    """Build (or load from the cache) the compiled model of ``scene``.

    Parameters
    ----------
    scene
        A scene, e.g. ``grasping_sym.model.scenes.paper2d()``.
    progress
        Called with a short message before each slow stage.
    force
        Rebuild even when the cache holds this scene.

    Raises
    ------
    UnsafeCacheError
        A cache path is a link, another user's, or writable by others.
    CacheWriteError
        The cache is full, read-only or not writable (the path and the fix are named).
    """

    try:
        return _build(scene, progress=progress, force=force)
    except OSError as exc:
        if isinstance(exc, GraspingSymError) or exc.errno not in (
                errno.ENOSPC, errno.EDQUOT, errno.EROFS, errno.EACCES, errno.EPERM):
            raise
        raise CacheWriteError(exc.filename or cache.cache_root(), exc) from exc


def _build(scene, *, progress: Progress | None = None, force: bool = False) -> BuiltModel:
    """``build`` without the translation of cache write failures."""
    say = progress or (lambda msg: None)
    t0 = time.perf_counter()
    called = time.time()
    root = cache.cache_root()
    definition = definition_key(scene)
    known = _known(root, definition) if definition is not None and not force else None
    digest = known["hash"] if known else _making().code_hash(scene)["hash"]
    directory = safety.ensure_dir(cache.cache_dir(scene.name, digest), root=root)
    lib = directory / library_name(scene.name)
    safety.check_tree(directory, (stored.MANIFEST, stored.START, lib.name))
    manifest = stored.read_manifest(directory)
    info: dict = {"source": "cache"}
    why = _stale(manifest, digest, lib) if not force else "force=True"
    if why:
        # one process or thread at a time builds an entry: a concurrent build of the same
        # model (another worker, notebook or thread) waits and finds it done
        with safety.exclusive(directory / BUILD_LOCK):
            # what another build wrote meanwhile; forced: only if written after this call began
            if not force or _written_since(directory, called):
                manifest = stored.read_manifest(directory)
                why = _stale(manifest, digest, lib)
            if why:
                manifest, info, lib = _making().make(scene, directory, manifest, why, digest, force, say, progress)
    t_s = time.perf_counter()
    skey = known["start_key"] if known else _making().start_key(scene)
    start, info["start_source"] = _start(scene, directory, say, skey,
                                         manifest["state_names"] if known else scene.state_names)
    if info["start_source"] != "cache" or stored.read_json(directory / stored.START) != start:
        write_start(directory, start)
    info["start"] = time.perf_counter() - t_s
    if definition is not None and not known:
        _remember(root, definition, digest, skey)
    info["key"] = "definition" if known else "expressions"
    info["rewrites"] = {**manifest.get("rewrites", {}), "vector_libm": bool(vector_libm())}
    model = BuiltModel(directory, manifest, lib, start, scene)
    if manifest.get("rolling_map") is not None:  # a model with modes: its base's rolling model too
        say(f"building {scene.base.name}, the rolling model of the stretches where every contact rolls")
        model.rolling = _build(scene.base, progress=progress, force=force)
        info["rolling_model"] = model.rolling.build_info["total"]
    info["total"] = time.perf_counter() - t0
    model.build_info = info
    return model


def _written_since(directory: Path, when: float) -> bool:
    """Whether the manifest in ``directory`` was written at or after ``when`` (``time.time()``):
    by a build that began after a forced one was asked for, so as new as it would make."""
    try:
        return (directory / stored.MANIFEST).stat().st_mtime >= when
    except OSError:
        return False


def _stale(manifest: dict | None, digest: str, lib: Path) -> str | None:
    """Why the cached model cannot be used as it is (None: it can)."""
    if manifest is None:
        return "no manifest"
    if problems := manifest_problems(manifest):
        return "invalid manifest: " + "; ".join(problems)
    if manifest.get("hash") != digest:
        return "another code hash"
    if not toolchain_matches(manifest.get("compiled_with"), manifest.get("compiler_stamp")):
        return f"compiled with {manifest.get('compiled_with')!r}, not {toolchain_id()!r}"
    return safety.library_problem(lib, manifest)
