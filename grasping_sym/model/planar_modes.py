"""A 2D scene whose finger contact rolls, slides or separates: the planar scene with modes.

``with_modes(scene)`` takes a one-finger ``model.planar.PlanarFingerScene`` (its contours,
links, pivot, gravity and controller) and gives the scene of kind ``"planar_modes"``: the
same bodies, compiled once with the contact's mode a run-time parameter
(``derive.planar_modes``), run by ``runtime.modes`` (switches at located events, impacts
with restitution and Coulomb friction on the impulse; ``docs/conventions.md`` section 8).

State: ``theta, q1, q2, dtheta, dq1, dq2, u0, u1`` (the contact parameters are always two:
the contours' points on their common normal, which move apart while the contact slides).
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import ClassVar

import numpy as np

from grasping_sym.errors import InvalidSceneError
from grasping_sym.model.control import coefficient_names
from grasping_sym.model.planar import PlanarFingerScene
from grasping_sym.model.with_modes import WithModes
from grasping_sym.names import output_problems

#: The contact's modes, by the number the compiled model takes as its parameter ``mode``.
MODES = ("rolling", "sliding", "separated")
#: The run-time parameters: the mode, the slip's sign at the start of a slide, the friction
#: coefficient.
RUNTIME = ("mode", "slip", "mu")
#: Every output (all compiled: the modes' events and maps read them).
OUTPUTS = ("gap", "normal_speed", "normal_force", "lam", "tangential_force", "cone_ratio", "vt",
           "slip_speed", "vt_rate", "rolling_normal_force", "rolling_lam",
           "rolling_tangential_force", "painleve", "free_normal_acceleration", "Q", "R",
           "tangency_defect", "kinetic_energy", "potential_energy", "power", "vn_fixed",
           "W_nn", "W_nt", "W_tt", *(f"Minv_g{k}_{i}" for k in "QR" for i in range(3)))


@dataclass(frozen=True, eq=False)
class PlanarModesScene(WithModes):
    """``base`` with its contact's modes (module docstring)."""

    base: PlanarFingerScene

    kind: ClassVar[str] = "planar_modes"
    dimension: ClassVar[int] = 2
    start_param_names: ClassVar[tuple[str, ...]] = ("xm", "ym")
    extra_fingers: ClassVar[tuple] = ()
    n_fingers: ClassVar[int] = 1
    n_contacts: ClassVar[int] = 1
    shared_parameter: ClassVar[bool] = False
    runtime: ClassVar[tuple[str, ...]] = RUNTIME
    outputs: ClassVar[tuple[str, ...]] = OUTPUTS
    simulate_defaults: ClassVar[dict] = {"t_final": 1.0, "method": "radau",
                                         "tolerances": {"radau": (1e-10, 1e-12)}}

    def __post_init__(self) -> None:
        b = self.base
        problems = []
        if not isinstance(b, PlanarFingerScene):
            raise InvalidSceneError([f"with_modes takes a 2D finger scene (gs.scenes.paper2d(), "
                                     f"gs.scenes.planar_finger(...)), not {type(b).__name__}"])
        if b.extra_fingers:
            problems.append(f"{b.name} has {b.n_fingers} fingers: contact modes in 2D are built for one "
                            "finger (one contact); several contacts need impacts solved jointly")
        if b.runtime:
            problems.append(f"runtime = {b.runtime}: a scene with contact modes takes its parameters "
                            "as constants (give their values in the scene); its run-time inputs "
                            "are mu and e")
        problems += output_problems(self.outputs, OUTPUTS)
        if problems:
            raise InvalidSceneError(problems)

    # ------------------------------------------------------------------ the base's parts

    @property
    def fingertip(self):
        return self.base.fingertip

    @property
    def object(self):  # noqa: A003 - the paper's word
        return self.base.object

    @property
    def fingertips(self) -> tuple:
        return (self.base.fingertip,)


    @property
    def pivot(self) -> tuple[float, float]:
        return self.base.pivot


    @property
    def params(self) -> dict[str, float]:
        mu = self.friction.per_contact(1)[0] if self.friction is not None else math.inf
        return {**self.base.params, "mode": 0.0, "slip": 1.0, "mu": min(mu, 1e300)}

    # ------------------------------------------------------------------ names
    @property
    def state_names(self) -> tuple[str, ...]:
        return ("theta", "q1", "q2", "dtheta", "dq1", "dq2", "u0", "u1")

    @property
    def input_names(self) -> tuple[str, ...]:
        """The base scene's inputs (joint torques ``u1, u2``, held or tabled by ``simulate(u=)``)."""
        return self.base.input_names

    @property
    def p_names(self) -> tuple[str, ...]:
        return (*self.runtime, *self.start_param_names, *coefficient_names(self.input_names))

    def check_outputs(self) -> tuple[str, ...]:
        return OUTPUTS

    def validate(self) -> None:
        self.base.validate()

    def start_values(self) -> dict[str, float]:
        return self.base.start_values()

    def initial_state(self) -> np.ndarray:
        """The base's start (at rest, in contact), with both contact parameters."""
        x = self.base.initial_state()
        return np.concatenate([x[:6], [x[6], x[6]]]) if self.base.shared_parameter else x

    def code_key(self) -> str:
        return "\n".join(["planar-modes-v1", self.base.code_key()])

    def key(self) -> str:
        return "\n".join(["planar-modes-v1", self.base.key()])

    def manifest_extra(self) -> dict:
        """The kind, and that ``simulate`` runs the modes (``runtime.modes``)."""
        return {"kind": self.kind, "modes": list(MODES), "param_rules": {"mu": "nonnegative"}}

    def bounds(self) -> tuple[list, list]:
        lower: list = [None] * 8
        upper: list = [None] * 8
        lower[6], upper[6] = self.base.fingertip.domain
        lower[7], upper[7] = self.base.object.domain
        return lower, upper


def with_modes(scene: PlanarFingerScene) -> PlanarModesScene:
    """``scene`` whose contact rolls, slides or separates (module docstring)."""
    return PlanarModesScene(scene)
