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
"""
from __future__ import annotations

import dataclasses
import errno
import hashlib
import logging
import re
import time
from collections.abc import Callable
from pathlib import Path

from grasping_sym import __version__
from grasping_sym.assemble import kinds
from grasping_sym.assemble.controller import controller_function, controller_key
from grasping_sym.assemble.functions import guarded_rhs
from grasping_sym.emit import cwriter, lanes
from grasping_sym.errors import CacheWriteError, GraspingSymError
from grasping_sym.model.control import PAPER
from grasping_sym.pipeline.built import BuiltModel, compile_library, compiled_manifest
from grasping_sym.store import files as stored
from grasping_sym.store import paths as cache
from grasping_sym.store import safety
from grasping_sym.store.manifest_schema import manifest_problems
from grasping_sym.store.platform import library_name
from grasping_sym.toolchain.compiler import toolchain_id, vector_libm
from grasping_sym.toolchain.library import model_defines, outputs_read_time

Progress = Callable[[str], None]
log = logging.getLogger(__name__)

#: The shared directory of the definition keys (``store.paths.SHARED_DIRS``).
DEFINITIONS = "definitions"
#: The lock file in a model's cache entry that one build at a time holds while it writes it.
BUILD_LOCK = ".build.lock"
_HEX64 = re.compile(r"[0-9a-f]{64}")

#: The 4-lane rhs (radau's three stage evaluations in one call, ``codegen.lanes``) is made
#: for right-hand sides up to this many instructions: planar scenes (paper2d: ~1.5k); the 3D
#: rhs (14k) is left without, radau is not the 3D method of choice.
LANES_MAX_INSTRUCTIONS = 5000


def _code_key(scene) -> str:
    """The scene's code key with its controller's (the hash of the law's expressions)."""
    return f"{scene.code_key()}|controller={controller_key(scene)}"


def definition_key(scene) -> str | None:
    """The hash of the scene's whole definition (its name, ``code_key()`` and ``key()``: its
    code's and its start's)
    with its controller's definition (``Controller.definition``: a preset's name and
    parameters, a law's code), the package's sources and version: computed without running the
    law or deriving anything, so that a cached scene is found at the cost of a lookup
    (``definitions/<key>.json`` maps it to the code hash and the start key). None for a law
    whose definition cannot be read (then the law's expressions key the build)."""
    law = scene.controller
    text = "none" if law is None else "paper" if law == PAPER else law.definition
    if text is None:
        return None
    parts = ["definition", type(scene).__name__, scene.name, scene.code_key(), scene.key(),
             f"controller={text}"]
    return cache.content_hash("\n".join(parts), __version__)["hash"]


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


def code_hash(scene) -> dict:
    """Content hash of the generated C for ``scene`` and the inputs it covers."""
    return cache.content_hash(_code_key(scene), __version__)


def start_key(scene) -> str:
    """Hash of what the scene's start depends on: its whole definition and the sources."""
    text = "\n".join([scene.key(), controller_key(scene), cache.tree_digest(), __version__])
    return hashlib.sha256(text.encode()).hexdigest()


def solve_start(scene) -> dict:
    """The scene's start record (``runtime.stored.start_record``), solved now."""
    x0, values, info = kinds.kind(scene).solve_start(scene)
    missing = [k for k in scene.start_param_names if k not in values]
    if missing:
        raise RuntimeError(f"{type(scene).__name__}.solve_start gave no value for {missing}")
    return stored.start_record(x0, {k: values[k] for k in scene.start_param_names},
                               start_key(scene), info)


def generate(scene, directory: Path, *, count_ops: bool = True,
             progress: Progress | None = None) -> dict:
    """Derive and write the C and manifest of ``scene`` into ``directory``.

    Returns the manifest (also written as ``manifest.json``) and, under ``"timings"``,
    seconds spent deriving and translating (not written: they vary run to run). The manifest
    is a function of exact inputs only; the start is written apart (``write_start``).
    """
    say = progress or (lambda msg: None)
    digest = code_hash(scene)
    scene, hidden = with_check_outputs(scene)
    fns = kinds.casadi_functions(scene, say)
    cm, timings = fns.model, dict(fns.timings)
    lower, upper = scene.bounds()
    guarded = guarded_rhs(cm, lower, upper, scene.name)
    cm.helpers = (*cm.helpers, *guarded)
    say(f"writing C into {directory}")
    t0 = time.perf_counter()
    if fns.lanes is not None:
        lane_c, lanes_status = fns.lanes
    elif not cm.rhs.is_a("SXFunction"):
        lane_c, lanes_status = None, "not made: the rhs is not one piece of SX (a choice of branches by mode)"
    elif cm.rhs.n_instructions() <= LANES_MAX_INSTRUCTIONS:
        lane_c, lanes_status = lanes.rhs_lanes(cm.rhs)
    else:
        lane_c, lanes_status = None, (f"not made: the rhs has {cm.rhs.n_instructions()} > "
                                      f"{LANES_MAX_INSTRUCTIONS} instructions")
    files, grouped = cwriter.write_c(cm, scene.name, directory, digest["hash"], __version__,
                                     extra_c=lane_c,
                                     groups=cwriter.layered_groups(cm) if fns.structure else None)
    timings["write_c"] = time.perf_counter() - t0
    ops = dict(cm.op_counts)
    if count_ops:
        ops.update(kinds.kind(scene).sympy_op_counts(scene))
    outputs_time = outputs_read_time(cm, len(scene.p_names))
    ctrl = controller_function(scene, "c")
    law = scene.controller
    manifest = {
        "name": scene.name,
        "hash": digest["hash"],
        "hash_inputs": digest["inputs"],
        "state_names": list(scene.state_names),
        "output_names": list(cm.output_names),
        "param_names": list(scene.runtime),
        "param_values": [float(scene.params[k]) for k in scene.runtime],
        "start_param_names": list(scene.start_param_names),
        "input_names": list(scene.input_names),
        "lower": lower,
        "upper": upper,
        "outputs_time": outputs_time,
        # the control layer: the law (its name), whether it reads the object's state and the time
        "controller": {"law": law if isinstance(law, str) or law is None else law.name,
                       "uses_object": ctrl.uses_object, "reads_time": ctrl.reads_time},
        "driver_defines": model_defines(cm, lanes=bool(lane_c)),
        "c_symbols": [f.name() for f in cm.functions()],
        "files": files,
        "constraints": _constraints_entry(cm, scene.state_names),
        "start_conditions": list(cm.start_names),
        # what the rewrites of the C did: the 4-lane rhs ("applied" or why not) and, per
        # function, the libm calls grouped for the vector libm (codegen.lanes, .vecmath)
        "rewrites": {"rhs_lanes": lanes_status, "vecmath_grouped_calls": grouped},
        "op_counts": ops,
        **({"structure": fns.structure} if fns.structure else {}),
        **({"rhs_guarded": guarded[0].name()} if guarded else {}),
        # a model with modes: the outputs in its folded modes (the manifest's folded_modes), for
        # the rows of the stretches in those modes (runtime.modes)
        **({"outputs_folded": f"{scene.name}_outputs_folded"}
           if any(f.name() == f"{scene.name}_outputs_folded" for f in cm.helpers) else {}),
        # outputs only a switch reads, in a function of their own (``Model.internal``)
        **({"internal_outputs": {"function": f"{scene.name}_internal", "names": list(cm.internal_names)}}
           if cm.internal_names else {}),
        # compiled outputs the user did not ask for: only the run-time checks read them
        **({"check_outputs": list(hidden)} if hidden else {}),
        "defaults": _run_defaults(scene),
        **scene.manifest_extra(),
    }
    stored.write_manifest(directory, manifest)
    manifest["timings"] = timings
    return manifest


def _run_defaults(scene) -> dict:
    """The method, tolerances and projection ``simulate``, ``simulate_many``, sweeps and the
    command line take when given none (the scene's ``simulate_defaults``; tolerances None: the
    method's own, ``runtime.settings.DEFAULT_TOLERANCES``; ``project``: whether the C loops
    project onto the constraints when ``project`` is not given, ``runtime.projection``)."""
    d = getattr(scene, "simulate_defaults", {})
    method = d.get("method", "radau")
    rtol, atol = d.get("tolerances", {}).get(method, (None, None))
    return {"method": method, "rtol": rtol, "atol": atol, "project": bool(d.get("project", False))}


def with_check_outputs(scene) -> tuple[object, tuple[str, ...]]:
    """The scene whose code is generated, and the outputs it adds: ``scene`` with, after its
    own outputs, every output the run-time checks read (``scene.check_outputs()``,
    ``runtime.checks``) that it does not list. A model checks every contact and every
    constraint whatever outputs it shows; the manifest's ``check_outputs`` names the added
    ones, which the model does not show (``Model.output_names``). The code hash is the
    scene's own: the added outputs are a function of it."""
    hidden = tuple(k for k in scene.check_outputs() if k not in scene.outputs)
    if not hidden:
        return scene, ()
    return dataclasses.replace(scene, outputs=(*scene.outputs, *hidden)), hidden


def write_start(directory: Path, record: dict) -> None:
    """Store a start record under ``starts/<key>.json`` and as the directory's default."""
    starts = safety.ensure_dir(directory / stored.STARTS_DIR, root=directory)
    stored.write_json(starts / f"{record['key'][:16]}.json", record)
    stored.write_json(directory / stored.START, record)


def _constraints_entry(cm, state_names) -> dict:
    """The manifest's ``constraints``: the names of C and the states the projection changes."""
    info = cm.constraint_info
    if not info:  # a model with no constraints (a body on a plane: its modes have their own)
        return {"names": [], "position_states": [], "velocity_states": []}
    return {"names": list(info["names"]),
            "position_states": [state_names[i] for i in info["position_states"]],
            "velocity_states": [state_names[i] for i in info["velocity_states"]]}


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
    return solve_start(scene), "solved"


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
    digest = known["hash"] if known else code_hash(scene)["hash"]
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
                manifest, info, lib = _make(scene, directory, manifest, why, digest, force, say, progress)
    t_s = time.perf_counter()
    skey = known["start_key"] if known else start_key(scene)
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


def _make(scene, directory: Path, manifest, why: str, digest: str, force: bool, say, progress):
    """``(manifest, info, library)``: the model's C (committed, or derived now) compiled into
    ``directory``, whose cached entry is stale (``why``)."""
    if manifest is not None:
        log.info("rebuilding %s: %s", scene.name, why)
    safety.clean_stale(directory)
    committed = cache.committed_dir(scene.name)
    cm = stored.read_manifest(committed)
    if not force and cm is not None and cm.get("hash") == digest:
        say(f"using committed C from {committed}")
        for f in cm["files"]:
            safety.write_bytes(directory / f, (committed / f).read_bytes())
        manifest, info = cm, {"source": "committed C"}
    else:
        manifest = generate(scene, directory, count_ops=False, progress=progress)
        info = {"source": "derived", **manifest.pop("timings")}
    if not force and why != "no manifest":
        info["rebuilt_because"] = why
    say(f"compiling {scene.name} with gcc")
    t_c = time.perf_counter()
    lib = compile_library(directory, manifest)
    manifest = compiled_manifest(manifest, lib)
    stored.write_manifest(directory, manifest)
    info["compile"] = time.perf_counter() - t_c
    return manifest, info, lib


def _stale(manifest: dict | None, digest: str, lib: Path) -> str | None:
    """Why the cached model cannot be used as it is (None: it can)."""
    if manifest is None:
        return "no manifest"
    if problems := manifest_problems(manifest):
        return "invalid manifest: " + "; ".join(problems)
    if manifest.get("hash") != digest:
        return "another code hash"
    if manifest.get("compiled_with") != toolchain_id():
        return f"compiled with {manifest.get('compiled_with')!r}, not {toolchain_id()!r}"
    return safety.library_problem(lib, manifest)
