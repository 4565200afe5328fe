"""What a scene says about its control: its controller and its inputs (both kinds of scene).

``controller``: ``"paper"`` (the scene's paper law, the default), ``None`` (no law: the
torques are the inputs alone), or a :class:`grasping_sym.model.controllers.Controller`.
``inputs``: ``None`` (none) or ``"torques"``: one joint torque ``u1, u2, ...`` (N m) per finger
joint, in the order of the joints, added to the controller's. On a model an input is
``u(t) = a + b t`` between the knots of its schedule (``grasping_sym.runtime.inputs``): its run-time
coefficients ``u1, ..., u1_rate, ...`` follow the start's values in the compiled ``p``.
"""
from __future__ import annotations

from grasping_sym.model.controllers import Controller

#: The kinds of input a scene may ask for.
INPUT_KINDS = ("torques",)
#: The default controller: the scene's paper law.
PAPER = "paper"


def input_names(inputs: str | None, n_joints: int) -> tuple[str, ...]:
    """``u1, ..., un`` for joint torques, else none."""
    return tuple(f"u{k}" for k in range(1, n_joints + 1)) if inputs == "torques" else ()


def coefficient_names(names: tuple[str, ...]) -> tuple[str, ...]:
    """The run-time coefficients of inputs ``names``: each value ``a``, then each rate ``b``."""
    return (*names, *(f"{k}_rate" for k in names))


def control_problems(controller, inputs) -> list[str]:
    """Named problems of a scene's ``controller`` and ``inputs`` values."""

    problems = []
    if not (controller is None or controller == PAPER or isinstance(controller, Controller)):
        problems.append(f"controller = {controller!r}: give 'paper' (the paper's law), None (no law: "
                        "the torques are the inputs) or a gs.controllers.Controller")
    if inputs is not None and inputs not in INPUT_KINDS:
        problems.append(f"inputs = {inputs!r}: give None or one of {list(INPUT_KINDS)}")
    return problems
