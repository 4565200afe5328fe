"""``build(scene)``: derive, generate C, compile, load -- or load from the cache.

Stages (timed in ``Model.build_info``):

1. hash the scene definition (``codegen.cache``); a cached library with that hash is
   loaded at once: no derivation, no compilation;
2. else, if ``generated/<name>/`` holds C with the same hash (built-in scenes), that C is
   compiled: no derivation;
3. else compose the scene's contours onto the template of its structure (derived with
   SymPy once per structure and stored, ``codegen.templates``), write C; compile and load.
"""
from __future__ import annotations

import shutil
import sys
import time
from collections.abc import Callable
from pathlib import Path

import numpy as np

from grasping_sym import __version__
from grasping_sym.codegen import cache, cwriter, lanes, templates
from grasping_sym.codegen.compiler import COMPILER_FLAGS, isa_level, vector_libm
from grasping_sym.codegen.functions import compose, sx_model, sympy_op_counts
from grasping_sym.codegen.library import compile_model, driver_defines
from grasping_sym.derive.planar import derive_planar, has_gravity, parameter_values
from grasping_sym.model.planar import PlanarFingerScene
from grasping_sym.runtime.model import Model

Progress = Callable[[str], None]


def _library_tag() -> str:
    """What ties a compiled library to this interpreter (the fast path is an extension) and
    to the instruction set it was compiled for (``compiler.isa_level``, with ``-mvec`` when
    it calls glibc's vector libm, ``compiler.vector_libm``)."""
    mvec = "-mvec" if vector_libm() else ""
    return f"{sys.implementation.cache_tag}-numpy{np.__version__}-{isa_level()}{mvec}"


def _is_3d(scene) -> bool:
    return getattr(scene, "kind", "planar") == "grasp3d"


def code_hash(scene) -> dict:
    """Content hash of the generated C for ``scene`` and the inputs it covers."""
    sources = cache.HASHED_SOURCES + (cache.HASHED_SOURCES_3D if _is_3d(scene) else ())
    return cache.content_hash(scene.key(), __version__, COMPILER_FLAGS, sources)


def generate(scene: PlanarFingerScene, directory: Path, *, count_ops: bool = True,
             progress: Progress | None = None) -> dict:
    """Derive and write the C and manifest of ``scene`` into ``directory``.

    Returns the manifest (also written as ``manifest.json``) and, under ``"timings"``,
    seconds spent deriving and translating (not written: they vary run to run).
    """
    say = progress or (lambda msg: None)
    if _is_3d(scene):
        return _generate_grasp3d(scene, directory, say)
    digest = code_hash(scene)
    cm, timings = planar_casadi(scene, say)
    say(f"writing C into {directory}")
    t0 = time.perf_counter()
    lane_c = lanes.rhs_lanes_c(cm.rhs)  # radau's three stages in one call
    cwriter.write_c(cm, scene.name, directory, digest["hash"], __version__, extra_c=lane_c)
    timings["write_c"] = time.perf_counter() - t0
    ops = dict(cm.op_counts)
    if count_ops:
        ops.update(sympy_op_counts(derive_planar(scene)))
    lower, upper = _bounds(scene)
    manifest = _manifest(scene, digest, cm, scene.initial_state(), lower, upper,
                         rhs_lanes=lanes.lanes_symbol(cm.rhs) if lane_c else None,
                         pivot=list(scene.pivot), op_counts=ops)
    cwriter.write_manifest(directory, manifest)
    manifest["timings"] = timings
    return manifest


def planar_casadi(scene: PlanarFingerScene, progress: Progress | None = None):
    """The CasADi functions of a planar scene (template composed with its contours), uncompiled,
    and the seconds spent: ``validate`` (and the initial configuration), ``template``, ``compose``."""
    say = progress or (lambda msg: None)
    t0 = time.perf_counter()
    values = parameter_values(scene)  # validates the scene, solves the initial configuration
    t1 = time.perf_counter()
    say(f"template for {scene.name}'s structure (derived with SymPy once per structure)")
    template, template_source = templates.planar_template(scene.shared_parameter,
                                                          has_gravity(scene), scene.n_fingers)
    t2 = time.perf_counter()
    say("composing the contours onto the template (CasADi)")
    cm = compose(template, scene.fingertips, scene.object, runtime=scene.runtime,
                 constants={k: v for k, v in values.items() if k not in scene.runtime},
                 outputs=scene.outputs, name=scene.name)
    t3 = time.perf_counter()
    return cm, {"validate": t1 - t0, "template": t2 - t1, "template_source": template_source,
                "compose": t3 - t2}


def _manifest(scene, digest: dict, cm, x0, lower: list, upper: list,
              rhs_lanes: str | None = None, **extra) -> dict:
    """What every manifest records: names, sizes, start, domains and how to compile it.
    ``rhs_lanes``: the C name of the 4-lane rhs when the C file has one (planar scenes; the
    3D rhs, 14k instructions, is left without: radau is not the 3D method of choice)."""
    return {
        "name": scene.name,
        "hash": digest["hash"],
        "hash_inputs": digest["inputs"],
        "state_names": list(scene.state_names),
        "output_names": list(cm.output_names),
        "param_names": list(scene.runtime),
        "param_values": [float(scene.params[k]) for k in scene.runtime],
        "initial_state": [float(v) for v in x0],
        "lower": lower,
        "upper": upper,
        "driver_defines": driver_defines(cm.rhs, cm.outputs, jac_fn=cm.jac,
                                         constraints_fn=cm.constraints, rhs_lanes=rhs_lanes),
        "c_symbols": [f.name() for f in cm.functions()],
        "constraints": _constraints_entry(cm, scene.state_names),
        **extra,
    }


def _generate_grasp3d(scene, directory: Path, say: Progress) -> dict:
    """``generate`` for a 3D grasping scene (``model.grasp3d``): start, derive, C, manifest."""
    from grasping_sym.derive import initial3d  # noqa: PLC0415
    from grasping_sym.derive.grasp3d import derive_grasp3d  # noqa: PLC0415

    digest = code_hash(scene)
    t0 = time.perf_counter()
    say(f"solving a consistent start for {scene.name} (Gauss-Newton)")
    x0, info = initial3d.initial_state(scene)
    t1 = time.perf_counter()
    say(f"deriving {scene.name} ({scene.formulation} formulation; SymPy, then CasADi AD)")
    system = derive_grasp3d(scene, info["r_bar0"])
    t2 = time.perf_counter()
    # no generated Jacobian: 250k SX instructions that gcc needs minutes for; the integrators
    # difference the compiled rhs instead (33 calls of 14k instructions, rarely needed)
    names = tuple(f"{q}{i}" for i in range(1, scene.n_contacts + 1) for q in ("Qn", "Qb", "Qe"))
    cm = sx_model(system.x, system.p, system.xdot, {k: system.outputs[k] for k in scene.outputs},
                  scene.name, jacobian=False, constraints=system.pieces["C"],
                  constraint_names=names)
    t3 = time.perf_counter()
    say(f"writing C into {directory}")
    cwriter.write_c(cm, scene.name, directory, digest["hash"], __version__)
    t4 = time.perf_counter()
    lower: list = [None] * len(scene.state_names)
    upper: list = [None] * len(scene.state_names)
    for i, f in enumerate(scene.fingers, start=1):
        for name, (lo, hi) in ((f"u_f{i}", f.tip.domain[0]), (f"v_f{i}", f.tip.domain[1]),
                               (f"u_o{i}", scene.object_surface.domain[0]),
                               (f"v_o{i}", scene.object_surface.domain[1])):
            k = scene.state_names.index(name)
            lower[k], upper[k] = lo, hi
    checks = {}
    if scene.formulation == "paper":
        fn = system.function("d0", "outputs")
        d0 = fn(x=x0, p=[scene.params[k] for k in scene.runtime])
        checks["frame_denominators"] = [float(d0[f"frame_denominator{i}"])
                                        for i in range(1, scene.n_contacts + 1)]
    manifest = _manifest(
        scene, digest, cm, x0, lower, upper, kind="grasp3d", formulation=scene.formulation,
        start={"residual": info["residual"], "iterations": info["iterations"],
               "r_bar0": [float(v) for v in info["r_bar0"]]},
        checks=checks, op_counts=dict(cm.op_counts))
    cwriter.write_manifest(directory, manifest)
    manifest["timings"] = {"initial_state": t1 - t0, "derive": t2 - t1, "casadi": t3 - t2,
                           "write_c": t4 - t3}
    return manifest


def _constraints_entry(cm, state_names) -> dict:
    """The manifest's ``constraints``: the names of C and the states the projection changes."""
    info = cm.constraint_info
    return {"names": list(info["names"]),
            "position_states": [state_names[i] for i in info["position_states"]],
            "velocity_states": [state_names[i] for i in info["velocity_states"]]}


def _bounds(scene: PlanarFingerScene) -> tuple[list, list]:
    """Per-state bounds: the contact parameters must stay inside their contours' domains."""
    n = len(scene.state_names)
    lower: list = [None] * n
    upper: list = [None] * n
    if scene.shared_parameter:
        lower[-1] = max(scene.fingertip.domain[0], scene.object.domain[0])
        upper[-1] = min(scene.fingertip.domain[1], scene.object.domain[1])
        return lower, upper
    names = scene.state_names
    tips = scene.fingertips
    for i, tip in enumerate(tips, start=1):
        tag = "" if len(tips) == 1 else f"_{i}"
        k0, k1 = names.index(f"u0{tag}"), names.index(f"u1{tag}")
        lower[k0], upper[k0] = tip.domain
        lower[k1], upper[k1] = scene.object.domain
    return lower, upper


def compile_library(directory: Path, manifest: dict) -> Path:
    """Compile ``{name}.c`` with the driver (and the CPython fast-call extension)."""
    name = manifest["name"]
    out = directory / f"lib{name}.{_library_tag()}.so"
    return compile_model(directory / f"{name}.c", out, manifest["driver_defines"])


def build(scene: PlanarFingerScene, *, progress: Progress | None = None,
          force: bool = False) -> Model:
    """Build (or load from the cache) the compiled model of ``scene``.

    Parameters
    ----------
    scene
        A scene, e.g. ``grasping_sym.scenes.paper2d()``.
    progress
        Called with a short message before each slow stage.
    force
        Rebuild even when the cache holds this scene.
    """
    say = progress or (lambda msg: None)
    t0 = time.perf_counter()
    digest = code_hash(scene)["hash"]
    directory = cache.cache_dir(scene.name, digest)
    lib = directory / f"lib{scene.name}.{_library_tag()}.so"
    manifest = cwriter.read_manifest(directory)
    info: dict = {"source": "cache"}
    if force or manifest is None or manifest.get("hash") != digest or not lib.exists():
        committed = cache.committed_dir(scene.name)
        cm = cwriter.read_manifest(committed)
        if not force and cm is not None and cm.get("hash") == digest:
            say(f"using committed C from {committed}")
            directory.mkdir(parents=True, exist_ok=True)
            for suffix in (".c", ".h"):
                shutil.copyfile(committed / f"{scene.name}{suffix}",
                                directory / f"{scene.name}{suffix}")
            cwriter.write_manifest(directory, cm)
            manifest, info = cm, {"source": "committed C"}
        else:
            manifest = generate(scene, directory, count_ops=False, progress=progress)
            info = {"source": "derived", **manifest.pop("timings")}
        say(f"compiling {scene.name} with gcc")
        t_c = time.perf_counter()
        lib = compile_library(directory, manifest)
        info["compile"] = time.perf_counter() - t_c
    model = Model(directory, manifest, lib)
    info["total"] = time.perf_counter() - t0
    model.build_info = info
    return model


GENERATED_FILES = ("{name}.c", "{name}.h", "manifest.json")


def generate_committed(names=None, *, check: bool = False,
                       root: Path | None = None) -> dict[str, list[str]]:
    """Regenerate ``generated/<name>/`` for built-in scenes (all by default) and
    ``generated/templates/`` for every planar structure.

    With ``check=True`` nothing is written: returns, per scene (and ``"templates"``), the
    files that differ from a fresh generation (empty lists when up to date).
    """
    import tempfile  # noqa: PLC0415

    from grasping_sym.scenes import BUILTIN  # noqa: PLC0415

    root = Path(root) if root is not None else cache.REPO_GENERATED
    differ: dict[str, list[str]] = {"templates": []}
    for shared, gravity in templates.PLANAR_STRUCTURES:
        name = f"{templates.template_name(shared, gravity)}.json"
        with tempfile.TemporaryDirectory() as tmp:
            fresh = Path(tmp) / name
            templates.write_template(fresh, templates.derive_and_build(shared, gravity),
                                     templates.template_key(shared, gravity))
            target = root / "templates" / name
            if not target.exists() or target.read_bytes() != fresh.read_bytes():
                differ["templates"].append(name)
                if not check:
                    target.parent.mkdir(parents=True, exist_ok=True)
                    shutil.copyfile(fresh, target)
    for name in names or sorted(BUILTIN):
        scene = BUILTIN[name]()
        with tempfile.TemporaryDirectory() as tmp:
            fresh = Path(tmp)
            generate(scene, fresh, count_ops=True)
            target = root / name
            files = [f.format(name=name) for f in GENERATED_FILES]
            differ[name] = [
                f for f in files
                if not (target / f).exists() or (target / f).read_bytes() != (fresh / f).read_bytes()
            ]
            if not check:
                target.mkdir(parents=True, exist_ok=True)
                for f in files:
                    shutil.copyfile(fresh / f, target / f)
    return differ
