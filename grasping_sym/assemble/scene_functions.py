"""Scene -> CasADi functions, for each kind of scene (called through the scene protocol).

Each function returns a ``SceneFunctions``: the scene's ``CasadiModel`` (rhs, Jacobian,
outputs, constraints; ``p`` = the scene's run-time parameters, then its start parameters),
the seconds spent by stage, and the operation counts. No solved number enters these
functions: what the start fixes is an input (``scene.start_param_names``).
"""
from __future__ import annotations

import re
import time
from collections.abc import Callable
from dataclasses import dataclass, field

import casadi as ca

from grasping_sym.assemble import structure_cache, templates
from grasping_sym.assemble.controller import controller_function, controller_torques
from grasping_sym.assemble.functions import FUNCTION_OPTIONS, compose, sx_model
from grasping_sym.assemble.layered import (
    compose_layered,
    contour_functions,
    contour_leaves,
    jets_functions,
    lanes_glue,
)
from grasping_sym.assemble.structure import (
    PlanarStructureSpec,
    StructureSpec,
    fold_pattern,
    structure_functions,
)
from grasping_sym.assemble.structure3d import Grasp3DStructureSpec, body_values, structure3d_functions
from grasping_sym.assemble.structure_cache import StructureRecord
from grasping_sym.derive.body_line import derive_body_line
from grasping_sym.derive.body_plane import derive_body_plane
from grasping_sym.derive.grasp3d import derive_grasp3d
from grasping_sym.derive.grasp3d_modes import derive_grasp3d_modes
from grasping_sym.derive.planar import has_gravity, parameter_values
from grasping_sym.derive.planar_modes import derive_planar_modes
from grasping_sym.emit.casadi_model import CasadiModel
from grasping_sym.toolchain import library

Progress = Callable[[str], None]


@dataclass
class SceneFunctions:
    model: CasadiModel
    timings: dict = field(default_factory=dict)
    #: the structure layer the model links (``{"name", "hash"}``), if any
    structure: dict | None = None
    #: the C of the model's 4-lane rhs and what was done (None: made from ``model.rhs``)
    lanes: tuple[str | None, str] | None = None


def planar_functions(scene, progress: Progress | None = None) -> SceneFunctions:
    """A planar scene in layers: its structure (the closed loop of its template, derived with
    SymPy once per structure, ``assemble.templates``; compiled once,
    ``assemble.structure_cache``) called by the scene's own contour functions
    (``assemble.layered``). The pivot ``(xm, ym)`` is a run-time input, after the scene's
    run-time parameters."""
    say = progress or (lambda msg: None)
    t0 = time.perf_counter()
    scene.validate()
    ctrl = controller_function(scene, scene.name)
    spec, leaves = planar_structure(scene)
    t1 = time.perf_counter()

    def make(name):
        _prefetch_driver()
        template, source = templates.planar_template(spec.shared, spec.gravity, scene.n_fingers,
                                                     spec.free)
        return structure_functions(template, spec, name), f"template: {source}"

    def contours(record):
        return contour_functions(leaves, record.slots, record.reads, len(scene.state_names),
                                 scene.name)

    cm, own, record, timings = _in_layers(scene, spec, make, contours, ctrl, say,
                                          "composing the contours with the structure (CasADi)")
    rhs_reads = record.reads["rhs"]
    glue = lanes_glue(scene.name, own["rhs"], record.rhs_lanes, len(rhs_reads["L"]),
                      ctrl.function, list(rhs_reads.get("tau", ())))
    return SceneFunctions(cm, {"validate": t1 - t0, **timings}, structure=record.entry(),
                          lanes=glue)


def _in_layers(scene, spec: StructureSpec, make, own_functions, ctrl, say: Progress, saying: str
               ) -> tuple[CasadiModel, dict, StructureRecord, dict]:
    """A scene's model in layers (``layered.compose_layered``): its structure ``spec`` from
    the cache (``make(name)`` derives it when the cache lacks it), compiled, and the scene's
    own functions of its contact values (``own_functions(record)``, by kind), with the
    controller ``ctrl``. Returns the model, the own functions, the structure's record and
    the seconds by stage."""
    t0 = time.perf_counter()
    say(f"structure of {scene.name} (compiled once per structure)")
    record, directory, source = structure_cache.ensure(spec, make, say)
    t1 = time.perf_counter()
    so = structure_cache.library(record, directory)
    t2 = time.perf_counter()
    say(saying)
    own = own_functions(record)
    n_structure_p = len(scene.runtime) + len(scene.start_param_names)
    cm = compose_layered(structure_cache.externals(record, so), record, own,
                         len(scene.state_names), len(scene.p_names), scene.name, ctrl,
                         n_structure_p)
    t3 = time.perf_counter()
    return cm, own, record, {"structure": t1 - t0, "structure_source": source,
                             "structure_compile": t2 - t1, "compose": t3 - t2}


def _prefetch_driver() -> None:
    """Start compiling the driver's objects (``library.predicted_defines``) while a new
    structure is derived and compiled: in a cache that has none yet (they depend on the work
    sizes alone, not on the model's sizes or features), the first model then waits for them
    no longer than for its own C."""
    library.prefetch_driver(library.predicted_defines())


def planar_single_piece(scene) -> SceneFunctions:
    """A planar scene's functions in one piece of SX: its template composed with its contours
    (``functions.compose``), every derivative by CasADi's AD through the concrete contours.
    Not what is compiled (``planar_functions``), but the same closed loop: CasADi's virtual
    machine evaluates it with nothing compiled, and tests check the layers against it."""
    scene.validate()
    inputs = (*scene.runtime, *scene.start_param_names)
    values = parameter_values(scene)
    template, _ = templates.planar_template(scene.shared_parameter, has_gravity(scene),
                                            scene.n_fingers, scene.free)
    ctrl = controller_function(scene, scene.name)
    return SceneFunctions(compose(template, list(scene.fingertips), scene.object, runtime=inputs,
                                  constants={k: v for k, v in values.items() if k not in inputs},
                                  outputs=scene.outputs, name=scene.name, controller=ctrl))


def planar_structure(scene) -> tuple[PlanarStructureSpec, list[list]]:
    """The structure of a planar scene (``structure.PlanarStructureSpec``) and its contours'
    leaves (``layered.contour_leaves``)."""
    values = parameter_values(scene)
    inputs = (*scene.runtime, *scene.start_param_names)
    leaves = contour_leaves([(tip, scene.object) for tip in scene.fingertips], scene.n_fingers)
    spec = PlanarStructureSpec(shared=scene.shared_parameter, gravity=has_gravity(scene),
                               n_fingers=scene.n_fingers, inputs=inputs,
                               constants=tuple(sorted((k, float(v)) for k, v in values.items()
                                                      if k not in inputs)),
                               folded=fold_pattern(leaves), outputs=tuple(scene.outputs),
                               free=scene.free)
    return spec, leaves


def grasp3d_layered(scene, progress: Progress | None = None) -> SceneFunctions:
    """A 3D scene (regular formulation) in layers: its structure (``assemble.structure3d``:
    derived, written and compiled once per structure, ``assemble.structure_cache``) called by
    the scene's own jets of its surfaces (``assemble.layered.jets_functions``)."""
    say = progress or (lambda msg: None)
    ctrl = controller_function(scene, scene.name)
    spec = Grasp3DStructureSpec(scene.structure_key())

    def make(name):
        _prefetch_driver()
        return structure3d_functions(scene, name), "SymPy and CasADi's AD"

    surfaces = [s for f in scene.fingers for s in (f.tip, scene.object_surface)]

    charts = {slot: scene.p_names.index(name) for slot, name, _ in scene.chart_slots()}

    def jets(record):
        return jets_functions(surfaces, record.slots, record.reads, len(scene.state_names),
                              scene.name, body=tuple(body_values(scene.mass, scene.inertia)),
                              charts=charts, np_=len(scene.p_names))

    cm, _, record, timings = _in_layers(scene, spec, make, jets, ctrl, say,
                                        "the surfaces' jets (SymPy forms, CasADi AD)")
    return SceneFunctions(cm, timings, structure=record.entry(),
                          lanes=(None, "not made: a 3D rhs is too large for the 4-lane copy "
                                       "(radau is not the 3D method of choice)"))


def grasp3d_functions(scene, progress: Progress | None = None) -> SceneFunctions:
    """A 3D grasping scene: SymPy for the pieces, CasADi's AD for the constraint derivatives
    (``derive.grasp3d``). No generated Jacobian: 250k SX instructions that gcc needs minutes
    for; the integrators difference the compiled rhs instead."""
    say = progress or (lambda msg: None)
    t0 = time.perf_counter()
    say(f"deriving {scene.name} ({scene.formulation} formulation; SymPy, then CasADi AD)")
    system = derive_grasp3d(scene, torques=controller_torques)
    t1 = time.perf_counter()
    names = tuple(f"{q}{i}" for i in range(1, scene.n_contacts + 1) for q in ("Qn", "Qb", "Qe"))
    G = system.start_conditions
    implied = system.start_values if G and scene.start_param_names else None
    cm = sx_model(system.x, system.p, system.xdot, {k: system.outputs[k] for k in scene.outputs},
                  scene.name, jacobian=False, constraints=system.constraint,
                  constraint_names=names, start_conditions=ca.vertcat(*G.values()) if G else None,
                  start_names=tuple(G), start_values=implied, t=system.t,
                  outputs_time=system.reads_time)
    t2 = time.perf_counter()
    return SceneFunctions(cm, {"derive": t1 - t0, "casadi": t2 - t1})


def body_functions(scene, progress: Progress | None = None) -> SceneFunctions:
    """A body on a plane (``model.body``) or on a line (``model.body_line``): its three modes in
    one piece of SX (``derive.body_plane``, ``derive.body_line``), the mode a run-time
    parameter; with the generated Jacobian."""
    say = progress or (lambda msg: None)
    t0 = time.perf_counter()
    line = scene.kind == "body2d"
    say(f"deriving {scene.name} (a body on a {'line' if line else 'plane'}, three contact modes; CasADi)")
    d = derive_body_line(scene) if line else derive_body_plane(scene)
    t1 = time.perf_counter()
    cm = sx_model(d["x"], d["p"], d["xdot"], {k: d["outputs"][k] for k in scene.outputs},
                  scene.name, jacobian=True, t=d["t"], outputs_time=d["reads_time"])
    return SceneFunctions(cm, {"derive": t1 - t0, "casadi": time.perf_counter() - t1})


def modes_functions(scene, progress: Progress | None = None) -> SceneFunctions:
    """A scene with contact modes (``model.planar_modes``, ``model.grasp3d_modes``): every
    contact's modes in one piece of SX (``derive.planar_modes``, ``derive.grasp3d_modes``),
    the modes run-time parameters. No generated Jacobian: the 2D one's 17 869 SX instructions
    take gcc 19 s (its rhs 0.4 s); the integrators difference the rhs."""
    say = progress or (lambda msg: None)
    t0 = time.perf_counter()
    say(f"deriving {scene.name} (contact modes; SymPy, then CasADi)")
    derive = derive_planar_modes if scene.kind == "planar_modes" else derive_grasp3d_modes
    d = derive(scene, controller_torques)
    t1 = time.perf_counter()
    internal = set(scene.internal_outputs())  # an impact's terms: read at switches only
    cm = sx_model(d["x"], d["p"], d["xdot"], {k: d["outputs"][k] for k in scene.outputs if k not in internal},
                  scene.name, jacobian=False, t=d["t"], outputs_time=d["reads_time"],
                  internal={k: d["outputs"][k] for k in scene.outputs if k in internal})
    modes = [i for i, k in enumerate(scene.p_names) if re.fullmatch(r"mode\d*", k)]
    folded = dict(zip(modes, scene.folded_modes(), strict=True))
    # (outputs that read the time take no folded function: runtime.modes would not call it)
    rolling = None if d["reads_time"] else _folded_outputs(cm, folded)
    if rolling is not None:
        cm.helpers = (*cm.helpers, rolling)
    branches = [dict(zip(modes, b, strict=True)) for b in scene.rhs_branches()]
    if branches:
        _fold_rhs(cm, branches)
    return SceneFunctions(cm, {"derive": t1 - t0, "casadi": time.perf_counter() - t1})


def _set(p: ca.SX, values: dict[int, int]) -> ca.SX:
    """The parameters ``p`` with ``p[i] = values[i]`` (numbers) in place of their symbols."""
    return ca.vertcat(*[ca.SX(values[i]) if i in values else p[i] for i in range(p.numel())])


#: A folded outputs function is made where it has at most this share of the general one's
#: instructions (the 3D grasp's with every contact rolling: 58 %; paper2d's one contact: 95 %,
#: not made).
FOLDED_OUTPUTS_SHARE = 0.75


def _folded_outputs(cm, values: dict[int, int]):
    """``{name}_outputs_folded``: the outputs with the parameters ``p[i] = values[i]`` (the
    contacts' modes of ``folded_modes``: every finger rolling, every surface of the world
    apart) in place, the other modes' branches folded away by CasADi, the same arguments and
    numbers; for the rows of the stretches in those modes (``runtime.modes``). None where it
    would save little (``FOLDED_OUTPUTS_SHARE``) or there are no outputs."""
    f = cm.outputs
    if f is None or not values:
        return None
    x, p = ca.SX.sym("x", f.numel_in(0)), ca.SX.sym("p", f.numel_in(1))
    (y,) = f.call([x, _set(p, values)])
    folded = ca.Function(f.name() + "_folded", [x, p], [y], ["x", "p"], ["y"], FUNCTION_OPTIONS)
    if folded.n_instructions() > FOLDED_OUTPUTS_SHARE * f.n_instructions():
        return None
    cm.op_counts["outputs_folded_sx_instructions"] = folded.n_instructions()
    return folded


#: The rhs takes a branch with some contacts' modes folded in where it has at most this share
#: of the general rhs's instructions (the 3D grasp over a table's every finger rolling and the
#: table apart: 51 %; paper2d's finger: rolling 57 %, sliding 64 %, apart 19 %).
FOLDED_RHS_SHARE = 0.75


def _fold_rhs(cm, branches: list[dict[int, int]]) -> None:
    """Make ``cm``'s rhs choose, in the C, between the general rhs (``{name}_rhs_any``) and, for
    each of ``branches`` (the parameters ``p[i] = b[i]``: the contacts' modes of
    ``rhs_branches``), one with those values in place, the other modes' branches folded away
    by CasADi (``{name}_rhs_modes_{m1}{m2}...``), by the mode parameters it is called with (a
    CasADi ``Switch``): the same numbers, each mode's stretches at about the cost of that mode
    alone. A branch that saves little (``FOLDED_RHS_SHARE``) is left out."""
    f = cm.rhs
    name = f.name()
    ins = f.sx_in()
    p = ins[3]
    general = ca.Function(f"{name}_any", ins, f.call(ins), ca.dyn_in(), ca.dyn_out(), FUNCTION_OPTIONS)
    made = []
    for values in branches:
        tag = "".join(str(values[i]) for i in sorted(values))
        folded = ca.Function(f"{name}_modes_{tag}", ins, f.call([*ins[:3], _set(p, values), *ins[4:]]),
                             ca.dyn_in(), ca.dyn_out(), FUNCTION_OPTIONS)
        if folded.n_instructions() <= FOLDED_RHS_SHARE * general.n_instructions():
            made.append((values, folded))
            cm.op_counts[f"rhs_modes_{tag}_sx_instructions"] = folded.n_instructions()
    if not made:
        return
    chosen = ca.Function.conditional(f"{name}_branch", [g for _, g in made], general)
    mx = [ca.MX.sym(f.name_in(i), f.sparsity_in(i)) for i in range(f.n_in())]
    index = ca.MX(len(made))                 # the general rhs unless a branch's modes are given
    for k in reversed(range(len(made))):
        at = ca.MX(1)
        for i, v in made[k][0].items():
            at = ca.logic_and(at, mx[3][i] == v)
        index = ca.if_else(at, k, index)
    cm.rhs = ca.Function(name, mx, chosen.call([index, *mx]), ca.dyn_in(), ca.dyn_out())
    cm.helpers = (general, *(g for _, g in made), *cm.helpers)
