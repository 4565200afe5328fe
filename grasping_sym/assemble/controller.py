"""The controller layer: a scene's joint torques as a CasADi function ``(t, x, p) -> tau``.

``tau`` is the law of the scene's controller (``grasping_sym.model.controllers``) at the scene's
quantities (``derive.quantities``), plus its inputs ``u(t) = a + b t`` (``model.control``)
when it has some. The contact dynamics take ``tau`` as an input (2D: the template's torque
symbols; 3D: ``derive.grasp3d``'s ``torques``), so the law is compiled with the scene's own
small C file and a new law derives nothing else.
"""
from __future__ import annotations

import hashlib

import casadi as ca

from grasping_sym.assemble.functions import FUNCTION_OPTIONS
from grasping_sym.derive.quantities import body_quantities, grasp3d_quantities, planar_quantities
from grasping_sym.errors import ControllerError
from grasping_sym.model import kinds
from grasping_sym.model.control import PAPER
from grasping_sym.model.controllers import paper2d, paper3d

__all__ = ["ControllerFunction", "controller_function", "controller_key", "controller_torques",
           "outputs_p"]


#: kind -> (its quantities, ``derive.quantities``; the paper's law of its papers)
_KINDS = {"planar": (planar_quantities, paper2d), "grasp3d": (grasp3d_quantities, paper3d),
          "body": (body_quantities, None), "body2d": (body_quantities, None),
          "planar_modes": (planar_quantities, paper2d),
          "grasp3d_modes": (lambda scene, *a: grasp3d_quantities(scene.base, *a), paper3d)}


def controller_torques(scene, t, x, p) -> tuple[ca.SX, bool, bool]:
    """The torques of every finger joint, in order; whether the law read the object; whether
    it reads the time itself (the inputs' ``a + b t`` aside)."""
    quantities, paper_law = kinds.of(scene, _KINDS, "a controller")
    m = quantities(scene, t, x, p, scene.p_names)
    law = scene.controller
    if law == PAPER:
        law = paper_law()
    cols = law.torques(m) if law is not None else [ca.SX.zeros(dq.numel(), 1) for dq in m.dq]
    tau = ca.vertcat(*cols) if cols else ca.SX(0, 1)
    known = {s.element_hash() for s in ca.symvar(ca.vertcat(t, x, p))}
    free = [s for s in ca.symvar(tau) if s.element_hash() not in known]
    if free:
        raise ControllerError(
            f"controller {law.name!r} uses symbols {sorted(str(s) for s in free)} that are not the "
            "model's quantities: a law may read only m's quantities (m.q, m.dq, m.tip, m.J, "
            "m.param(name), ...); a gain is a number, or a scene parameter read with m.param")
    timed = bool(ca.depends_on(tau, t))
    if scene.input_names:
        n = len(scene.input_names)
        k = scene.p_names.index(scene.input_names[0])
        tau = tau + p[k:k + n] + p[k + n:k + 2 * n] * t
    return tau, m.uses_object, timed


class ControllerFunction:
    """``function``: ``<name>_controller (t, x, p) -> tau`` (SX); ``uses_object``: the law
    reads the object's pose or velocity; ``reads_time``: the law reads the time itself."""

    def __init__(self, function: ca.Function, uses_object: bool, reads_time: bool):
        self.function, self.uses_object, self.reads_time = function, uses_object, reads_time


def controller_function(scene, name: str) -> ControllerFunction:
    """The scene's controller layer (:class:`ControllerFunction`)."""
    t = ca.SX.sym("t")
    x = ca.SX.sym("x", len(scene.state_names))
    p = ca.SX.sym("p", len(scene.p_names))
    tau, uses_object, timed = controller_torques(scene, t, x, p)
    f = ca.Function(f"{name}_controller", [t, x, p], [tau], ["t", "x", "p"], ["tau"],
                    FUNCTION_OPTIONS)
    return ControllerFunction(f, uses_object, timed)


def controller_key(scene) -> str:
    """The hash of the controller's expressions (what a model's code depends on)."""
    return hashlib.sha256(controller_function(scene, "c").function.serialize().encode()).hexdigest()


def outputs_p(p, np_: int, reads_time: bool):
    """``(p of the outputs, their p as the model's, the time of their torques)``: the model's
    ``p`` at time 0, or, when the law reads the time itself, a ``p`` with one more entry,
    the time (a model's outputs take the inputs' value at a time as ``a``, with ``b = 0``)."""
    if not reads_time:
        return p, p, 0
    p_out = type(p).sym("p", np_ + 1)
    return p_out, p_out[:np_], p_out[np_]
