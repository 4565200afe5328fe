"""A 3D grasp whose finger contacts each roll, slide or separate: the grasp scene with modes.

``with_modes(scene)`` on a ``model.grasp3d.GraspScene3D`` (regular formulation) gives the
scene of kind ``"grasp3d_modes"``: the same fingers, object, start and controller, compiled
once with every contact's mode a run-time parameter (``derive.grasp3d_modes``), run by
``runtime.modes`` (``docs/conventions.md`` section 9). The state is the base scene's.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import ClassVar

from grasping_sym.errors import InvalidSceneError
from grasping_sym.model.grasp3d import GraspScene3D

#: The contacts' modes, by the number the compiled model takes as its parameter ``mode{i}``.
MODES = ("rolling", "sliding", "separated")


@dataclass(frozen=True, eq=False)
class GraspModesScene:
    """``base`` with its contacts' modes (module docstring)."""

    base: GraspScene3D

    kind: ClassVar[str] = "grasp3d_modes"
    dimension: ClassVar[int] = 3
    input_names: ClassVar[tuple[str, ...]] = ()
    simulate_defaults: ClassVar[dict] = {"t_final": 1.0, "method": "radau",
                                         "tolerances": {"radau": (1e-9, 1e-11)}}

    def __post_init__(self) -> None:
        b = self.base
        if not isinstance(b, GraspScene3D):
            raise InvalidSceneError([f"with_modes takes a grasp scene (gs.scenes.paper3d(), pivot3d(), "
                                     f"or a GraspScene3D), not {type(b).__name__}"])
        problems = []
        if b.formulation != "regular":
            problems.append(f"formulation = {b.formulation!r}: contact modes are built on the regular "
                            "formulation (formulation='regular')")
        if b.runtime:
            problems.append(f"runtime = {b.runtime}: a scene with contact modes takes its parameters as "
                            "constants (give their values in the scene); its run-time inputs are mu and e")
        if b.inputs is not None:
            problems.append("inputs: a scene with contact modes has no control inputs (use a controller)")
        if problems:
            raise InvalidSceneError(problems)

    # ------------------------------------------------------------------ the base's parts
    @property
    def name(self) -> str:
        return f"{self.base.name}_modes"

    @property
    def n_contacts(self) -> int:
        return self.base.n_contacts

    @property
    def controller(self):
        return self.base.controller

    @property
    def friction(self):
        return self.base.friction

    @property
    def gravity(self):
        return self.base.gravity

    @property
    def start_param_names(self) -> tuple[str, ...]:
        return self.base.start_param_names

    @property
    def runtime(self) -> tuple[str, ...]:
        n = range(1, self.n_contacts + 1)
        return (*[f"mode{i}" for i in n], *[f"slip_{c}{i}" for i in n for c in "xy"],
                *[f"mu{i}" for i in n])

    @property
    def params(self) -> dict[str, float]:
        mus = self.friction.per_contact(self.n_contacts) if self.friction is not None \
            else (math.inf,) * self.n_contacts
        out = dict(self.base.params)
        for i, mu in enumerate(mus, start=1):
            out.update({f"mode{i}": 0.0, f"slip_x{i}": 1.0, f"slip_y{i}": 0.0, f"mu{i}": min(mu, 1e300)})
        return out

    @property
    def state_names(self) -> tuple[str, ...]:
        return self.base.state_names

    @property
    def p_names(self) -> tuple[str, ...]:
        return (*self.runtime, *self.start_param_names)

    @property
    def n_speeds(self) -> int:
        return sum(f.chain.n for f in self.base.fingers) + (3 if self.base.free else 0) + 3

    @property
    def speeds_offset(self) -> int:
        return sum(f.chain.n for f in self.base.fingers) + (3 if self.base.free else 0) + 4

    @property
    def outputs(self) -> tuple[str, ...]:
        k = self.n_contacts
        n = range(1, k + 1)
        per = ("f", "lam", "eta", "krel_min", "gap", "normal_speed", "normal_acceleration",
               "normal_force", "tangential_force", "cone_ratio", "vt_x", "vt_y", "slip_speed",
               "painleve", "at_x", "at_y", "vn_fixed")
        return ("constraint_residual", *[f"{q}{i}" for i in n for q in per],
                "orthonormality", "quat_norm_error", "kinetic_energy", "potential_energy", "power",
                "object_speed", "object_angular_speed",
                *[f"W_{r}_{c}" for r in range(3 * k) for c in range(r, 3 * k)],
                *[f"MinvAT_{j}_{r}" for r in range(3 * k) for j in range(self.n_speeds)])

    def check_outputs(self) -> tuple[str, ...]:
        return self.outputs

    def code_key(self) -> str:
        return "\n".join(["grasp3d-modes-v1", self.base.code_key()])

    def key(self) -> str:
        return "\n".join(["grasp3d-modes-v1", self.base.key()])

    def manifest_extra(self) -> dict:
        """The kind, that ``simulate`` runs the modes (``runtime.modes``), where the speeds are."""
        return {"kind": self.kind, "modes": list(MODES), "n_contacts": self.n_contacts,
                "grasp_modes": {"speeds": [self.speeds_offset, self.n_speeds]},
                "param_rules": {f"mu{i}": "nonnegative" for i in range(1, self.n_contacts + 1)}}

    def bounds(self) -> tuple[list, list]:
        return self.base.bounds()


def with_modes(scene: GraspScene3D) -> GraspModesScene:
    """``scene`` whose contacts roll, slide or separate (module docstring)."""
    return GraspModesScene(scene)

