"""A 2D scene whose finger contacts roll, slide or separate: the planar scene with modes.

``with_modes(scene)`` takes a ``model.planar.PlanarFingerScene`` (its contours, links, pivot,
gravity and controller; one finger or several) and gives the scene of kind
``"planar_modes"``: the same bodies, compiled once with each contact's mode a run-time
parameter (``derive.planar_modes``), run by ``runtime.modes`` (switches at located events,
impacts with restitution and Coulomb friction on the impulse; ``docs/conventions.md``
section 8).

State: ``theta, q1, q2, dtheta, dq1, dq2, u0, u1`` for one finger (the contact parameters
are always two: the contours' points on their common normal, which move apart while the
contact slides); the base's ``theta, q11, q12, q21, ..., u0_1, u1_1, u0_2, ...`` for several.
A scene of several fingers numbers its run-time parameters and outputs by contact
(``mode1``, ``mu2``, ``gap1``, ...).
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
#: Each contact's outputs in a scene of several fingers (numbered by contact, ``gap1``).
CONTACT_OUTPUTS = ("gap", "normal_speed", "normal_force", "lam", "tangential_force", "cone_ratio",
                   "vt", "slip_speed", "painleve", "normal_acceleration", "Q", "R",
                   "tangency_defect", "vn_fixed")


def fingers_outputs(k: int, n_object: int = 1) -> tuple[str, ...]:
    """Every output of a scene of ``k > 1`` fingers: each contact's, the energies and power,
    ``W = A M^-1 A^T`` (``W_r_c``, ``r <= c``, rows ``(Q_i, R_i)`` of contact ``i`` at
    ``2i - 2, 2i - 1``) and ``M^-1 A^T`` (``MinvAT_s_r``, speed ``s``: the object's
    ``n_object`` first, 1 pivoted, 3 free, then the joints')."""
    n, nv = 2 * k, n_object + 2 * k
    return (*(f"{o}{i}" for i in range(1, k + 1) for o in CONTACT_OUTPUTS),
            "kinetic_energy", "potential_energy", "power",
            *(f"W_{r}_{c}" for r in range(n) for c in range(r, n)),
            *(f"MinvAT_{s}_{r}" for s in range(nv) for r in range(n)))


@dataclass(frozen=True, eq=False)
class PlanarModesScene(WithModes):
    """``base`` with its contact's modes (module docstring)."""

    base: PlanarFingerScene

    kind: ClassVar[str] = "planar_modes"
    dimension: ClassVar[int] = 2
    start_param_names: ClassVar[tuple[str, ...]] = ("xm", "ym")
    shared_parameter: ClassVar[bool] = False
    simulate_defaults: ClassVar[dict] = {"t_final": 1.0, "method": "radau",
                                         "tolerances": {}}

    def __post_init__(self) -> None:
        b = self.base
        problems = []
        if not isinstance(b, PlanarFingerScene):
            raise InvalidSceneError([f"with_modes takes a 2D finger scene (gs.scenes.paper2d(), "
                                     f"gs.scenes.planar_finger(...)), not {type(b).__name__}"])
        if b.free and b.n_fingers == 1:
            problems.append("support='free' with one finger: a free 2D object with contact modes "
                            "needs two fingers or more (a free object held by one finger and a "
                            "surface of the world is not built in 2D); add extra_fingers, or hold "
                            "the object by a pivot (support='pivot')")
        if b.runtime:
            problems.append(f"runtime = {b.runtime}: a scene with contact modes takes its parameters "
                            "as constants (give their values in the scene); its run-time inputs "
                            "are mu and e")
        problems += output_problems(self.outputs, OUTPUTS if self.n_fingers == 1 else self.outputs)
        if problems:
            raise InvalidSceneError(problems)

    # ------------------------------------------------------------------ the base's parts

    @property
    def extra_fingers(self) -> tuple:
        return self.base.extra_fingers

    @property
    def n_fingers(self) -> int:
        return self.base.n_fingers

    @property
    def free(self) -> bool:
        """Whether the base's object is free (its mass centre a state; several fingers)."""
        return self.base.free

    @property
    def n_speeds(self) -> int:
        """The speeds (and coordinates): the object's (1 pivoted, 3 free), then 2 per finger."""
        return len(self.base.object_coordinates) + 2 * self.n_fingers

    @property
    def parameter_names(self) -> tuple[str, ...]:
        return self.base.parameter_names

    @property
    def n_contacts(self) -> int:
        return self.base.n_fingers

    @property
    def runtime(self) -> tuple[str, ...]:
        """``mode, slip, mu`` (one finger), or ``mode1, slip1, mu1, mode2, ...``."""
        if self.n_fingers == 1:
            return RUNTIME
        return tuple(f"{k}{i}" for i in range(1, self.n_fingers + 1) for k in RUNTIME)

    @property
    def outputs(self) -> tuple[str, ...]:
        return OUTPUTS if self.n_fingers == 1 else fingers_outputs(self.n_fingers, self.n_speeds - 2 * self.n_fingers)

    @property
    def fingertip(self):
        return self.base.fingertip

    @property
    def object(self):  # noqa: A003 - the paper's word
        return self.base.object

    @property
    def fingertips(self) -> tuple:
        return self.base.fingertips


    @property
    def pivot(self) -> tuple[float, float]:
        return self.base.pivot


    @property
    def params(self) -> dict[str, float]:
        k = self.n_fingers
        mus = self.friction.per_contact(k) if self.friction is not None else (math.inf,) * k
        own = dict(zip(self.runtime, [v for mu in mus for v in (0.0, 1.0, min(float(mu), 1e300))]))
        return {**self.base.params, **own}

    # ------------------------------------------------------------------ names
    @property
    def state_names(self) -> tuple[str, ...]:
        if self.n_fingers > 1:
            return self.base.state_names
        return ("theta", "q1", "q2", "dtheta", "dq1", "dq2", "u0", "u1")

    @property
    def input_names(self) -> tuple[str, ...]:
        """The base scene's inputs (joint torques ``u1, u2``, held or tabled by ``simulate(u=)``)."""
        return self.base.input_names

    @property
    def p_names(self) -> tuple[str, ...]:
        return (*self.runtime, *self.start_param_names, *coefficient_names(self.input_names))

    def check_outputs(self) -> tuple[str, ...]:
        return self.outputs

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

    def rolling_map(self) -> dict | None:
        """``WithModes.rolling_map``; a base with one contact parameter ``s`` for both contours
        (``shared_parameter``) is the rolling model of the states with ``u0 = u1 = s``."""
        if self.n_fingers > 1 or not self.base.shared_parameter:
            return super().rolling_map()
        return {"to": [0, 1, 2, 3, 4, 5, 6], "from": [0, 1, 2, 3, 4, 5, 6, 6]}

    def manifest_extra(self) -> dict:
        """The kind, and that ``simulate`` runs the modes (``runtime.modes``); with several
        fingers their number and where the speeds start and how many (``planar_fingers``);
        how the base's rolling model runs the stretches where every contact rolls
        (``rolling_map``)."""
        k = self.n_fingers
        extra = {"kind": self.kind, "modes": list(MODES), "n_contacts": k, "rolling_map": self.rolling_map(),
                 "param_rules": {m: "nonnegative" for m in self.runtime if m.startswith("mu")}}
        if k > 1:
            extra["planar_fingers"] = {"fingers": k, "speeds": [self.n_speeds, self.n_speeds]}
        return extra

    def bounds(self) -> tuple[list, list]:
        n = len(self.state_names)
        lower: list = [None] * n
        upper: list = [None] * n
        for i, tip in enumerate(self.fingertips):  # (u0_i, u1_i) after q and v
            j = 2 * self.n_speeds + 2 * i
            lower[j], upper[j] = tip.domain
            lower[j + 1], upper[j + 1] = self.base.object.domain
        return lower, upper


def with_modes(scene: PlanarFingerScene) -> PlanarModesScene:
    """``scene`` whose contact rolls, slides or separates (module docstring)."""
    return PlanarModesScene(scene)
