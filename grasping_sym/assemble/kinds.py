"""What the derivation and the assembly do with each kind of scene (``model.kinds``): one
table, asked by the build (``pipeline``), never a switch on the dimension.

Each row gives, for its kind:

- ``functions(scene, progress, layers)``: the scene's CasADi functions
  (``assemble.scene_functions``): in layers (what is compiled) or, with ``layers=False``, in
  one piece of SX (CasADi's virtual machine, ``assemble.casadi_api``, the tests' reference);
- ``solve_start(scene)``: ``(x0, start values, info)``, the consistent start and the run-time
  values it fixes (2D: the pivot, from the scene's own tangency solution; 3D: Gauss-Newton,
  ``derive.start3d``);
- ``templates(scene)``: ``(file name, key, build)`` of each finger template the scene's
  structure uses beyond the planar ones (committed for the built-in scenes);
- ``sympy_op_counts(scene)``: operation counts of its SymPy pieces, for the manifest.
"""
from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from grasping_sym import rotations
from grasping_sym.assemble import scene_functions
from grasping_sym.assemble.functions import sympy_op_counts
from grasping_sym.derive import body_line, body_plane, finger_templates, start3d
from grasping_sym.derive.grasp3d import finger_function, template_of
from grasping_sym.derive.planar import derive_planar
from grasping_sym.errors import InvalidSceneError
from grasping_sym.geometry.atlas import LAT as ATLAS_LAT
from grasping_sym.model import kinds
from grasping_sym.runtime.atlas import transition


@dataclass(frozen=True)
class Kind:
    functions: Callable
    solve_start: Callable
    templates: Callable
    sympy_op_counts: Callable


def _planar_rolling_problems(scene) -> None:
    """A free 2D object held by one finger alone is refused by its rolling build (nothing else
    would carry it; with modes a line of the world may: ``with_modes(scene, lines=...)``)."""
    if scene.free and scene.n_fingers == 1:
        raise InvalidSceneError(["support='free' with one finger: nothing else holds the object (its "
                                 "contact would open at once); add extra_fingers, or let a line of the "
                                 "world help it with contact modes: gs.scenes.with_modes(scene, lines="
                                 "[gs.scenes.world_line(point, normal)])"])


def _planar_functions(scene, progress=None, layers: bool = True):
    _planar_rolling_problems(scene)
    if not layers:
        return scene_functions.planar_single_piece(scene)
    return scene_functions.planar_functions(scene, progress)


def _planar_start(scene) -> tuple[np.ndarray, dict[str, float], dict]:
    _planar_rolling_problems(scene)
    scene.validate()
    return scene.initial_state(), scene.start_values(), {}


def _grasp3d_functions(scene, progress=None, layers: bool = True):
    if scene.rolling_problems():
        raise InvalidSceneError(scene.rolling_problems())
    if layers and scene.formulation == "regular":
        return scene_functions.grasp3d_layered(scene, progress)
    return scene_functions.grasp3d_functions(scene, progress)


def _grasp3d_start(scene) -> tuple[np.ndarray, dict[str, float], dict]:
    x0, info = start3d.initial_state(scene)
    values = dict(zip(scene.start_param_names, map(float, info["r_bar0"])))
    x0, charts = _in_charts(scene, x0)
    return x0, values, {"residual": float(info["residual"]), "iterations": int(info["iterations"]),
                        **({"charts": charts} if charts else {})}


def _in_charts(scene, x0: np.ndarray) -> tuple[np.ndarray, dict[str, int]]:
    """``x0`` (solved in chart 0 of every surface with an atlas) with each contact that lies
    beyond chart 0's latitudes (``|v| >= 1.3``, near its pole) carried into chart 1, and each
    contact on a repeating chart taken whole periods toward its domain's middle, as a run
    carries them at a chart's edge (``runtime.atlas.transition``: the same point, ``psi``
    turned by the frames' angle); and the charts the start is then written in."""
    x0 = np.array(x0, dtype=float)
    names = scene.state_names
    charts = {}
    for entry in scene.atlas_manifest().get("atlas", ()):
        iu, iv = names.index(entry["u"]), names.index(entry["v"])
        if entry["param"] is None:
            _, x0[iu], x0[iv], _ = transition(entry, 0, float(x0[iu]), float(x0[iv]))
            continue
        if abs(x0[iv]) < ATLAS_LAT[1]:
            continue
        new, x0[iu], x0[iv], delta = transition(entry, 0, float(x0[iu]), float(x0[iv]))
        if entry["psi"] is not None:
            x0[names.index(entry["psi"])] += delta
        charts[entry["param"]] = new
    return x0, charts


def _grasp3d_rolling_start(scene) -> tuple[np.ndarray, dict[str, float], dict]:
    if scene.rolling_problems():
        raise InvalidSceneError(scene.rolling_problems())
    return _grasp3d_start(scene)


def _grasp3d_templates(scene) -> list[tuple[str, str, object]]:
    used = dict.fromkeys(template_of(f.chain, scene.gravity) for f in scene.fingers)
    return [(finger_templates.finger_template_name(chain, g), finger_templates.finger_template_key(chain, g),
             lambda chain=chain, g=g: finger_function(chain, g)) for chain, g in used]


def _body_functions(scene, progress=None, layers: bool = True):
    return scene_functions.body_functions(scene, progress)


def _modes_functions(scene, progress=None, layers: bool = True):
    return scene_functions.modes_functions(scene, progress)


def _planar_modes_start(scene) -> tuple[np.ndarray, dict[str, float], dict]:
    """The base's start, and each line's support point on the object's contour; every line
    must be apart from the object at the start."""
    scene.validate()
    x0 = scene.initial_state()
    if not scene.lines:
        return x0, scene.start_values(), {}
    names = scene.state_names
    pos, theta = x0[[names.index("x"), names.index("y")]], float(x0[names.index("theta")])
    c, s = np.cos(theta), np.sin(theta)
    extra = []
    for m, w in enumerate(scene.lines, start=1):
        u, S = body_line.support_point(scene.base.object, theta, np.array(w.normal), w.support)
        gap = float(np.dot(w.normal, pos + np.array([c * S[0] + s * S[1], -s * S[0] + c * S[1]])
                           - np.array(w.point)))
        if not gap > 0:
            raise InvalidSceneError([f"line {m} cuts the object at the start (gap {gap:.6g} m): put it "
                                     "below the object (its normal into the free side)"])
        extra.append(u)
    return np.concatenate([x0, extra]), scene.start_values(), {}


def _grasp3d_modes_start(scene) -> tuple[np.ndarray, dict[str, float], dict]:
    """The base grasp's start, and each plane's support point on the object; every plane must
    be apart from the object at the start."""
    x0, values, info = _grasp3d_start(scene.base)
    base = scene.base
    names = base.state_names
    quat = x0[[names.index(k) for k in ("qw", "qx", "qy", "qz")]]
    R = rotations.matrices(quat)[0]
    pos = np.array(base.position, float) if not base.free else x0[[names.index(k) for k in "xyz"]]
    extra, charts = [], {}
    for m, w in enumerate(scene.planes, start=1):
        uv, S, chart = body_plane.support_in_a_chart(base.object_surface, R, np.array(w.normal), w.support)
        gap = float(np.dot(w.normal, pos + R @ S - np.array(w.point)))
        if not gap > 0:
            raise InvalidSceneError([f"plane {m} cuts the object at the start (gap {gap:.6g} m): put it "
                                     "below the object (its normal into the free side)"])
        extra += list(uv)
        if f"chart_w{m}" in scene.chart_names:
            charts[f"chart_w{m}"] = chart
    x0, _ = _in_charts(scene, np.concatenate([x0, extra]))     # the planes' on a repeating chart
    charts = {**info.get("charts", {}), **charts}   # the base grasp's contacts', then the planes'
    return x0, values, {**info, **({"charts": charts} if charts else {})}


def _body_start(scene) -> tuple[np.ndarray, dict[str, float], dict]:
    x0, info = body_plane.start_state(scene)
    x0, _ = _in_charts(scene, x0)   # its support point on a repeating chart (an atlas's: solved in its chart)
    return x0, {}, info


def _body_line_start(scene) -> tuple[np.ndarray, dict[str, float], dict]:
    x0, info = body_line.start_state(scene)
    return x0, {}, info


#: kind name -> its row
KINDS: dict[str, Kind] = {
    "planar": Kind(functions=_planar_functions, solve_start=_planar_start,
                   templates=lambda scene: [],
                   sympy_op_counts=lambda scene: sympy_op_counts(derive_planar(scene))),
    "grasp3d": Kind(functions=_grasp3d_functions, solve_start=_grasp3d_rolling_start,
                    templates=_grasp3d_templates, sympy_op_counts=lambda scene: {}),
    "body": Kind(functions=_body_functions, solve_start=_body_start,
                 templates=lambda scene: [], sympy_op_counts=lambda scene: {}),
    "body2d": Kind(functions=_body_functions, solve_start=_body_line_start,
                   templates=lambda scene: [], sympy_op_counts=lambda scene: {}),
    "grasp3d_modes": Kind(functions=_modes_functions,
                          solve_start=_grasp3d_modes_start,
                          templates=lambda scene: [], sympy_op_counts=lambda scene: {}),
    "planar_modes": Kind(functions=_modes_functions, solve_start=_planar_modes_start,
                         templates=lambda scene: [], sympy_op_counts=lambda scene: {}),
}


def kind(scene) -> Kind:
    """The row of ``scene``'s kind (a named error for a scene of no known kind)."""
    return kinds.of(scene, KINDS, "deriving and assembling")


def casadi_functions(scene, progress=None, layers: bool = True):
    """``scene``'s CasADi functions (``Kind.functions``)."""
    return kind(scene).functions(scene, progress, layers)
