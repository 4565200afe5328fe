"""Scene -> CasADi functions, for each kind of scene (called through the scene protocol).

Each function returns a ``SceneFunctions``: the scene's ``CasadiModel`` (rhs, Jacobian,
outputs, constraints; ``p`` = the scene's run-time parameters, then its start parameters),
the seconds spent by stage, and the operation counts. No solved number enters these
functions: what the start fixes is an input (``scene.start_param_names``).
"""
from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass, field

from grasping_sym.codegen.functions import CasadiModel

Progress = Callable[[str], None]


@dataclass
class SceneFunctions:
    model: CasadiModel
    timings: dict = field(default_factory=dict)


def planar_functions(scene, progress: Progress | None = None) -> SceneFunctions:
    """A planar scene: its structure's template (derived with SymPy once per structure and
    stored, ``codegen.templates``) composed with its contours. The pivot ``(xm, ym)`` is a
    run-time input, after the scene's run-time parameters."""
    from grasping_sym.codegen import templates  # noqa: PLC0415
    from grasping_sym.codegen.functions import compose  # noqa: PLC0415
    from grasping_sym.derive.planar import has_gravity, parameter_values  # noqa: PLC0415

    say = progress or (lambda msg: None)
    t0 = time.perf_counter()
    scene.validate()
    values = parameter_values(scene)
    t1 = time.perf_counter()
    say(f"template for {scene.name}'s structure (derived with SymPy once per structure)")
    template, source = templates.planar_template(scene.shared_parameter, has_gravity(scene),
                                                 scene.n_fingers)
    t2 = time.perf_counter()
    say("composing the contours onto the template (CasADi)")
    inputs = (*scene.runtime, *scene.start_param_names)
    cm = compose(template, scene.fingertips, scene.object, runtime=inputs,
                 constants={k: v for k, v in values.items() if k not in inputs},
                 outputs=scene.outputs, name=scene.name)
    t3 = time.perf_counter()
    return SceneFunctions(cm, {"validate": t1 - t0, "template": t2 - t1, "template_source": source,
                               "compose": t3 - t2})


def grasp3d_functions(scene, progress: Progress | None = None) -> SceneFunctions:
    """A 3D grasping scene: SymPy for the pieces, CasADi's AD for the constraint derivatives
    (``derive.grasp3d``). No generated Jacobian: 250k SX instructions that gcc needs minutes
    for; the integrators difference the compiled rhs instead."""
    import casadi as ca  # noqa: PLC0415

    from grasping_sym.codegen.functions import sx_model  # noqa: PLC0415
    from grasping_sym.derive.grasp3d import derive_grasp3d  # noqa: PLC0415

    say = progress or (lambda msg: None)
    t0 = time.perf_counter()
    say(f"deriving {scene.name} ({scene.formulation} formulation; SymPy, then CasADi AD)")
    system = derive_grasp3d(scene)
    t1 = time.perf_counter()
    names = tuple(f"{q}{i}" for i in range(1, scene.n_contacts + 1) for q in ("Qn", "Qb", "Qe"))
    G = system.start_conditions
    implied = system.geometry["r_bar"] if G and scene.start_param_names else None
    cm = sx_model(system.x, system.p, system.xdot, {k: system.outputs[k] for k in scene.outputs},
                  scene.name, jacobian=False, constraints=system.pieces["C"],
                  constraint_names=names, start_conditions=ca.vertcat(*G.values()) if G else None,
                  start_names=tuple(G), start_values=implied)
    t2 = time.perf_counter()
    return SceneFunctions(cm, {"derive": t1 - t0, "casadi": t2 - t1})
