"""``build(scene)``: derive, generate C, compile, load -- or load from the cache.

One path for every scene: a scene meets one protocol (``name``, ``state_names``,
``outputs``, ``runtime``, ``params``, ``start_param_names``, ``code_key()``, ``key()``,
``hashed_sources``, ``start_sources``, ``casadi_functions()``, ``solve_start()``,
``bounds()``, ``manifest_extra()``, ``sympy_op_counts()``, ``structure_templates()``; and for
the command line ``simulate_defaults``, ``write_figures()``, ``summary_lines()``), and

    scene -> CasADi functions (codegen.scene_functions) -> C (codegen.cwriter) -> library

Layers are cached apart, each under its own hash:

- the runtime: the hand-written C driver (integrators, projection, the CPython front end),
  compiled once per set of model sizes into ``<cache root>/objects/`` (``codegen.objects``);
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

Stages (timed in ``Model.build_info``): hash; load the cached library, else compile the
committed C, else derive and write C, then compile; then the start, from the cache or solved.
"""
from __future__ import annotations

import dataclasses
import hashlib
import logging
import shutil
import time
from collections.abc import Callable
from pathlib import Path

from grasping_sym import __version__
from grasping_sym.codegen import cache, cwriter, lanes, structure_cache
from grasping_sym.codegen.compiler import COMPILER_FLAGS, vector_libm
from grasping_sym.codegen.functions import guarded_rhs
from grasping_sym.codegen.library import compile_model, model_defines, outputs_read_time
from grasping_sym.runtime import safety, stored
from grasping_sym.runtime.loader import library_name
from grasping_sym.runtime.manifest_schema import manifest_problems
from grasping_sym.runtime.model import Model

Progress = Callable[[str], None]
log = logging.getLogger(__name__)

#: The 4-lane rhs (radau's three stage evaluations in one call, ``codegen.lanes``) is made
#: for right-hand sides up to this many instructions: planar scenes (paper2d: ~1.5k); the 3D
#: rhs (14k) is left without, radau is not the 3D method of choice.
LANES_MAX_INSTRUCTIONS = 5000


def _sources(scene) -> tuple[str, ...]:
    return cache.HASHED_SOURCES + tuple(scene.hashed_sources)


def code_hash(scene) -> dict:
    """Content hash of the generated C for ``scene`` and the inputs it covers."""
    return cache.content_hash(scene.code_key(), __version__, COMPILER_FLAGS, _sources(scene))


def start_key(scene) -> str:
    """Hash of what the scene's start depends on: its whole definition and the sources."""
    text = "\n".join([scene.key(), cache.sources_digest(_sources(scene) + tuple(scene.start_sources)),
                       __version__])
    return hashlib.sha256(text.encode()).hexdigest()


def solve_start(scene) -> dict:
    """The scene's start record (``runtime.stored.start_record``), solved now."""
    x0, values, info = scene.solve_start()
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
    fns = scene.casadi_functions(say)
    cm, timings = fns.model, dict(fns.timings)
    lower, upper = scene.bounds()
    guarded = guarded_rhs(cm, lower, upper, scene.name)
    cm.helpers = (*cm.helpers, *guarded)
    say(f"writing C into {directory}")
    t0 = time.perf_counter()
    if fns.lanes is not None:
        lane_c, lanes_status = fns.lanes
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
        ops.update(scene.sympy_op_counts())
    outputs_time = outputs_read_time(cm, len(scene.p_names))
    from grasping_sym.codegen.controller import controller_function  # noqa: PLC0415

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
        "driver_defines": model_defines(cm, len(scene.p_names), lanes=bool(lane_c)),
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
        # compiled outputs the user did not ask for: only the run-time checks read them
        **({"check_outputs": list(hidden)} if hidden else {}),
        **scene.manifest_extra(),
    }
    stored.write_manifest(directory, manifest)
    manifest["timings"] = timings
    return manifest


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
    return {"names": list(info["names"]),
            "position_states": [state_names[i] for i in info["position_states"]],
            "velocity_states": [state_names[i] for i in info["velocity_states"]]}


def compile_library(directory: Path, manifest: dict) -> Path:
    """Compile the model's C files and link them with the driver (and the CPython fast-call
    extension) and, for a model in layers, its structure's objects."""
    from grasping_sym.codegen import structure_cache  # noqa: PLC0415

    sources = [directory / f for f in manifest["files"] if f.endswith(".c")]
    linked = []
    if "structure" in manifest:
        linked = structure_cache.link_objects(*structure_cache.locate(manifest["structure"]))
    return compile_model(sources, directory / library_name(manifest["name"]),
                         manifest["driver_defines"], objects=linked)


def _start(scene, directory: Path, say: Progress) -> tuple[dict, str]:
    """The scene's start record: from the cache, from the committed files, or solved."""
    key = start_key(scene)
    shape = {"state_names": list(scene.state_names), "start_param_names": list(scene.start_param_names)}
    cached = stored.read_json(directory / stored.STARTS_DIR / f"{key[:16]}.json")
    if cached is not None and cached.get("key") == key and not stored.start_problems(cached, shape):
        return cached, "cache"
    committed = stored.read_json(cache.committed_dir(scene.name) / stored.START)
    if committed is not None and committed.get("key") == key and not stored.start_problems(committed, shape):
        return committed, "committed"
    say(f"solving a consistent start for {scene.name}")
    return solve_start(scene), "solved"


def build(scene, *, progress: Progress | None = None, force: bool = False) -> Model:
    """Build (or load from the cache) the compiled model of ``scene``.

    Parameters
    ----------
    scene
        A scene, e.g. ``grasping_sym.scenes.paper2d()``.
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
    import errno  # noqa: PLC0415

    from grasping_sym.errors import CacheWriteError, GraspingSymError  # noqa: PLC0415
    try:
        return _build(scene, progress=progress, force=force)
    except OSError as exc:
        if isinstance(exc, GraspingSymError) or exc.errno not in (
                errno.ENOSPC, errno.EDQUOT, errno.EROFS, errno.EACCES, errno.EPERM):
            raise
        raise CacheWriteError(exc.filename or cache.cache_root(), exc) from exc


def _build(scene, *, progress: Progress | None = None, force: bool = False) -> Model:
    """``build`` without the translation of cache write failures."""
    say = progress or (lambda msg: None)
    t0 = time.perf_counter()
    digest = code_hash(scene)["hash"]
    root = cache.cache_root()
    directory = safety.ensure_dir(cache.cache_dir(scene.name, digest), root=root)
    lib = directory / library_name(scene.name)
    safety.check_tree(directory, (stored.MANIFEST, stored.START, lib.name))
    manifest = stored.read_manifest(directory)
    info: dict = {"source": "cache"}
    why = _stale(manifest, digest, lib) if not force else "force=True"
    if why:
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
        manifest = {**manifest, "libraries": {**manifest.get("libraries", {}),
                                              lib.name: safety.sha256_file(lib)}}
        stored.write_manifest(directory, manifest)
        info["compile"] = time.perf_counter() - t_c
    t_s = time.perf_counter()
    start, info["start_source"] = _start(scene, directory, say)
    if info["start_source"] != "cache" or stored.read_json(directory / stored.START) != start:
        write_start(directory, start)
    info["start"] = time.perf_counter() - t_s
    info["rewrites"] = {**manifest.get("rewrites", {}), "vector_libm": bool(vector_libm())}
    model = Model(directory, manifest, lib, start)
    model.scene = scene
    info["total"] = time.perf_counter() - t0
    model.build_info = info
    return model


def _stale(manifest: dict | None, digest: str, lib: Path) -> str | None:
    """Why the cached model cannot be used as it is (None: it can)."""
    if manifest is None:
        return "no manifest"
    if problems := manifest_problems(manifest):
        return "invalid manifest: " + "; ".join(problems)
    if manifest.get("hash") != digest:
        return "another code hash"
    return safety.library_problem(lib, manifest)


def _text_diff(old: Path, new: Path, label: str) -> str:
    """A unified diff of two text files (empty when byte-identical), at most 60 lines."""
    import difflib  # noqa: PLC0415

    a = old.read_bytes() if old.exists() else b""
    b = new.read_bytes()
    if a == b:
        return ""
    lines = list(difflib.unified_diff(a.decode(errors="replace").splitlines(),
                                      b.decode(errors="replace").splitlines(),
                                      f"committed/{label}", f"fresh/{label}", lineterm="", n=1))
    more = f"\n... ({len(lines) - 60} more diff lines)" if len(lines) > 60 else ""
    return "\n".join(lines[:60]) + more if lines else f"{label}: bytes differ (line endings?)"


def generate_committed(names=None, *, check: bool = False,
                       root: Path | None = None) -> dict[str, dict[str, str]]:
    """Regenerate ``generated/<name>/`` for built-in scenes (all by default) and
    ``generated/templates/`` for every planar structure.

    The C, header and manifest of a scene are functions of exact inputs and must match byte
    for byte; its ``start.json`` holds solved numbers and must match to
    ``runtime.stored.START_RTOL``. Returns, per scene (and ``"templates"``), each file that
    differs from a fresh generation with a unified diff (or the entries beyond tolerance);
    empty when up to date. With ``check=True`` nothing is written.
    """
    import tempfile  # noqa: PLC0415

    from grasping_sym.codegen import templates  # noqa: PLC0415
    from grasping_sym.scenes import BUILTIN  # noqa: PLC0415

    if root is None:
        checkout = cache.source_checkout()
        if checkout is None and not check:
            raise RuntimeError(
                f"generate writes the committed code into a source checkout, and this package is an "
                f"installed copy ({cache.PACKAGE_DIR}): run it in a clone of the repository "
                "(pip install -e .), or pass root= a directory of your own")
        root = checkout / "generated" if checkout is not None else cache.generated_dir()
    root = Path(root)
    differ: dict[str, dict[str, str]] = {"templates": {}}
    def template(file_name: str, write) -> None:
        """Write a template with ``write(path)``; note and (unless ``check``) replace the
        committed one when it differs."""
        with tempfile.TemporaryDirectory() as tmp:
            fresh = Path(tmp) / file_name
            write(fresh)
            target = root / "templates" / file_name
            if not target.exists() or target.read_bytes() != fresh.read_bytes():
                differ["templates"][file_name] = f"{file_name}: differs (serialized CasADi functions)"
                if not check:
                    target.parent.mkdir(parents=True, exist_ok=True)
                    shutil.copyfile(fresh, target)

    for shared, gravity in templates.PLANAR_STRUCTURES:
        template(f"{templates.template_name(shared, gravity)}.json",
                 lambda path, s=shared, g=gravity: templates.write_template(
                     path, templates.derive_and_build(s, g), templates.template_key(s, g)))
    finger_files: set[str] = set()
    differ["structures"] = {}
    structures: set[str] = set()
    with tempfile.TemporaryDirectory() as private, cache.root_override(Path(private)), \
            structure_cache.derive_afresh():
        for name in names or sorted(BUILTIN):
            _generate_scene(BUILTIN[name](), root, check, differ, structures, finger_files, template)
    if set(names or BUILTIN) == set(BUILTIN):  # structures no built-in scene uses are stale
        for old in sorted((root / structure_cache.DIR).glob("*/")):
            if old.name not in structures:
                differ["structures"][old.name] = f"{old.name}: no longer used by a built-in scene"
                if not check:
                    shutil.rmtree(old)
    if set(names or BUILTIN) == set(BUILTIN):  # finger templates no built-in scene uses are stale
        for old in sorted((root / "templates").glob("finger-*.json")):
            if old.name not in finger_files:
                differ["templates"][old.name] = f"{old.name}: no longer used by a built-in scene"
                if not check:
                    old.unlink()
    return differ


def _generate_scene(scene, root: Path, check: bool, differ: dict, structures: set,
                    finger_files: set, template) -> None:
    """``generate_committed`` for one built-in scene: its finger templates, its C and
    manifest, its start and (for a model in layers) its structure."""
    import tempfile  # noqa: PLC0415

    from grasping_sym.codegen import templates  # noqa: PLC0415

    name = scene.name

    for file_name, key, build in scene.structure_templates():
        finger_files.add(file_name)
        template(file_name, lambda path, b=build, k=key: templates.write_finger_template(path, b(), k))
    target = root / name
    with tempfile.TemporaryDirectory() as tmp:
        fresh = Path(tmp)
        manifest = generate(scene, fresh, count_ops=True)
        record = solve_start(scene)
        stored.write_json(fresh / stored.START, record)
        files = [*manifest["files"], stored.MANIFEST]
        differ[name] = {f: d for f in files if (d := _text_diff(target / f, fresh / f, f"{name}/{f}"))}
        stale = sorted(f.name for f in target.glob("*.[ch]") if f.name not in files)
        differ[name].update({f: f"{name}/{f}: no longer generated" for f in stale})
        old = stored.read_json(target / stored.START)
        if old is None or old.get("key") != record["key"]:
            differ[name][stored.START] = "start.json: missing, or solved for another scene definition"
        elif bad := stored.starts_agree(old, record):
            differ[name][stored.START] = (f"start.json: {len(bad)} entries differ beyond "
                                          f"rtol {stored.START_RTOL:g}: " + "; ".join(bad[:5]))
        if not check:
            target.mkdir(parents=True, exist_ok=True)
            for f in files:
                shutil.copyfile(fresh / f, target / f)
            for f in stale:
                (target / f).unlink()
            if stored.START in differ[name]:  # keep the committed start when it agrees
                shutil.copyfile(fresh / stored.START, target / stored.START)
    if "structure" in manifest:
        entry = manifest["structure"]
        structures.add(entry["name"])
        meta, sdir = structure_cache.locate(entry)
        target = root / structure_cache.DIR / entry["name"]
        files = [*meta["files"], structure_cache.META]
        for f in files:
            if d := _text_diff(target / f, sdir / f, f"structures/{entry['name']}/{f}"):
                differ["structures"][f"{entry['name']}/{f}"] = d
                if not check:
                    target.mkdir(parents=True, exist_ok=True)
                    shutil.copyfile(sdir / f, target / f)
