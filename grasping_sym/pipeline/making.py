"""What a build does when the cache does not hold the scene's model: derive it, write its C,
compile it, solve its start; and the keys that need the scene's expressions (the code hash,
which runs the law; the start key).

A build that finds its model (``pipeline.stages``) never imports this module, nor SymPy,
CasADi, the derivation or the emitter through it: a cached build costs what a lookup costs.
"""
from __future__ import annotations

import dataclasses
import hashlib
import logging
import time
from collections.abc import Callable
from pathlib import Path

from grasping_sym import __version__
from grasping_sym.assemble import kinds, structure_cache
from grasping_sym.assemble.controller import controller_function, controller_key
from grasping_sym.assemble.functions import guarded_rhs
from grasping_sym.emit import cwriter, lanes
from grasping_sym.store import files as stored
from grasping_sym.store import paths as cache
from grasping_sym.store import safety
from grasping_sym.store.platform import library_name
from grasping_sym.toolchain.compiler import compiler_stamp, toolchain_id
from grasping_sym.toolchain.library import compile_model, model_defines, outputs_read_time

Progress = Callable[[str], None]
log = logging.getLogger(__name__)

#: The 4-lane rhs (radau's three stage evaluations in one call, ``codegen.lanes``) is made
#: for right-hand sides up to this many instructions: planar scenes (paper2d: ~1.5k); the 3D
#: rhs (14k) is left without, radau is not the 3D method of choice.
LANES_MAX_INSTRUCTIONS = 5000


def code_key(scene) -> str:
    """The scene's code key with its controller's (the hash of the law's expressions)."""
    return f"{scene.code_key()}|controller={controller_key(scene)}"


def code_hash(scene) -> dict:
    """Content hash of the generated C for ``scene`` and the inputs it covers."""
    return cache.content_hash(code_key(scene), __version__)


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


def _constraints_entry(cm, state_names) -> dict:
    """The manifest's ``constraints``: the names of C and the states the projection changes."""
    info = cm.constraint_info
    if not info:  # a model with no constraints (a body on a plane: its modes have their own)
        return {"names": [], "position_states": [], "velocity_states": []}
    return {"names": list(info["names"]),
            "position_states": [state_names[i] for i in info["position_states"]],
            "velocity_states": [state_names[i] for i in info["velocity_states"]]}


def make(scene, directory: Path, manifest, why: str, digest: str, force: bool, say, progress):
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
    stamp = compiler_stamp()
    lib = compile_library(directory, manifest)
    manifest = compiled_manifest(manifest, lib, stamp)
    stored.write_manifest(directory, manifest)
    info["compile"] = time.perf_counter() - t_c
    return manifest, info, lib


def compile_here(directory: Path, manifest: dict, data: dict) -> dict:
    """A model's library compiled from the C sent, with its structure's files first; returns
    the manifest with the library's record."""
    if data.get("structure"):
        structure_cache.install_files(data["structure"]["entry"], data["structure"]["files"])
    stamp = compiler_stamp()
    return compiled_manifest(manifest, compile_library(directory, manifest), stamp)


def compiled_manifest(manifest: dict, lib: Path, stamp: str | None) -> dict:
    """``manifest`` with the record of a library just compiled: its checksum and what
    compiled it (``toolchain.compiler.toolchain_id``, checked before a cached one is used),
    with the compiler's stamp taken before the compile (``toolchain_matches``; a stamp from
    another machine, as a portable model carries, matches nothing there)."""
    return {**manifest, "compiled_with": toolchain_id(), "compiler_stamp": stamp,
            "libraries": {**manifest.get("libraries", {}), lib.name: safety.sha256_file(lib)}}


def compile_library(directory: Path, manifest: dict) -> Path:
    """Compile the model's C files and link them with the driver (and the CPython fast-call
    extension) and, for a model in layers, its structure's objects."""
    sources = [directory / f for f in manifest["files"] if f.endswith(".c")]
    linked = []
    if "structure" in manifest:
        linked = structure_cache.link_objects(*structure_cache.locate(manifest["structure"]))
    return compile_model(sources, directory / library_name(manifest["name"]),
                         manifest["driver_defines"], objects=linked)
