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

A free object (``support="free"``) may also touch fixed lines of the world (``WorldLine``: a
table, an incline, a wall; ``docs/conventions.md`` section 14): their contacts come after the
fingers', numbered like them, and each adds the contour parameter ``u_w{m}`` of the object's
support point on line ``m`` (where its outward normal is minus the line's) to the state.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import ClassVar

import numpy as np
import sympy as sp

from grasping_sym.errors import InvalidSceneError
from grasping_sym.model.body import translation_of_time
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


def fingers_outputs(k: int, nv: int | None = None) -> tuple[str, ...]:
    """Every output of a scene of ``k > 1`` contacts: each contact's, the energies and power,
    ``W = A M^-1 A^T`` (``W_r_c``, ``r <= c``, rows ``(Q_i, R_i)`` of contact ``i`` at
    ``2i - 2, 2i - 1``) and ``M^-1 A^T`` (``MinvAT_s_r``, speed ``s`` of ``nv``: the object's
    first, 1 pivoted, 3 free, then the joints'; default a pivoted object and ``k`` fingers)."""
    n, nv = 2 * k, 1 + 2 * k if nv is None else nv
    return (*(f"{o}{i}" for i in range(1, k + 1) for o in CONTACT_OUTPUTS),
            "kinetic_energy", "potential_energy", "power",
            *(f"W_{r}_{c}" for r in range(n) for c in range(r, n)),
            *(f"MinvAT_{s}_{r}" for s in range(nv) for r in range(n)))


@dataclass(frozen=True)
class WorldLine:
    """A fixed line of the world: a point on it and its unit normal (into the free half-plane)
    (m, world); ``support``: a guess of the object contour's parameter facing it at the start."""

    point: tuple[float, float]
    normal: tuple[float, float]
    support: float = 0.0
    #: the line's translation ``d(t)`` (two expressions of ``t``, ``d(0) = 0``, as
    #: ``model.body_line.LineBodyScene.line_motion``); None: fixed
    motion: tuple | None = None

    def __post_init__(self) -> None:
        try:
            point = tuple(float(v) for v in np.ravel(self.point))
            normal = tuple(float(v) for v in np.ravel(self.normal))
            support = float(self.support)
        except (TypeError, ValueError):
            raise InvalidSceneError([f"a world line takes a point and a normal (two numbers each) and "
                                     f"a support (a number), not {self.point!r}, {self.normal!r}, "
                                     f"{self.support!r}"]) from None
        object.__setattr__(self, "point", point)
        object.__setattr__(self, "normal", normal)
        object.__setattr__(self, "support", support)
        p = []
        if len(point) != 2 or not all(math.isfinite(v) for v in point):
            p.append(f"line point {point} must be two finite numbers (m)")
        if len(normal) != 2 or not abs(math.hypot(*normal) - 1) < 1e-12:
            p.append(f"line normal {normal} must be a unit vector (to 1e-12)")
        if not math.isfinite(support):
            p.append(f"support {support} must be a finite number (a guess of the contour parameter)")
        motion, problems = translation_of_time(self.motion, "line motion", dims=2)
        object.__setattr__(self, "motion", motion)
        p += problems
        if p:
            raise InvalidSceneError(p)


@dataclass(frozen=True, eq=False)
class PlanarModesScene(WithModes):
    """``base`` with its contact's modes and the world's ``lines`` (module docstring)."""

    base: PlanarFingerScene
    lines: tuple[WorldLine, ...] = field(default=())

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
        object.__setattr__(self, "lines", tuple(self.lines))
        if any(not isinstance(w, WorldLine) for w in self.lines):
            problems.append("lines must be gs.scenes.world_line(point, normal) values")
        if self.lines and not b.free:
            problems.append("lines of the world touch a free object: give the scene support='free' "
                            "(a pivoted object is held by its pivot)")
        if b.free and b.n_fingers == 1 and not self.lines:
            problems.append("support='free' with one finger and no line of the world: nothing else "
                            "holds the object; add extra_fingers, a line (with_modes(scene, "
                            "lines=[gs.scenes.world_line(point, normal)])), or hold it by a pivot")
        if self.lines and b.friction is not None and isinstance(b.friction.mu, tuple) \
                and len(b.friction.mu) != 1:
            problems.append(f"the scene's friction law has one mu per finger ({len(b.friction.mu)}) and "
                            f"there are {self.n_contacts} contacts with the lines: give one mu for all in "
                            "the scene, or every contact's at run time, the fingers' then the lines' "
                            "(simulate(mu=(...)))")
        if b.runtime:
            problems.append(f"runtime = {b.runtime}: a scene with contact modes takes its parameters "
                            "as constants (give their values in the scene); its run-time inputs "
                            "are mu and e")
        problems += output_problems(self.outputs, OUTPUTS if not self.numbered else self.outputs)
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
        return self.base.n_fingers + len(self.lines)

    @property
    def numbered(self) -> bool:
        """Whether the contacts are numbered (several, or one finger and a line): the model of
        several contacts (``derive.planar_modes.derive_planar_fingers_modes``)."""
        return self.n_contacts > 1

    @property
    def runtime(self) -> tuple[str, ...]:
        """``mode, slip, mu`` (one finger), or ``mode1, slip1, mu1, mode2, ...``."""
        if not self.numbered:
            return RUNTIME
        return tuple(f"{k}{i}" for i in range(1, self.n_contacts + 1) for k in RUNTIME)

    @property
    def outputs(self) -> tuple[str, ...]:
        return OUTPUTS if not self.numbered else fingers_outputs(self.n_contacts, self.n_speeds)

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
        k = self.n_contacts
        mus = self.friction.per_contact(k) if self.friction is not None else (math.inf,) * k
        own = dict(zip(self.runtime, [v for mu in mus for v in (0.0, 1.0, min(float(mu), 1e300))]))
        return {**self.base.params, **own}

    # ------------------------------------------------------------------ names
    @property
    def state_names(self) -> tuple[str, ...]:
        lines = tuple(f"u_w{m}" for m in range(1, len(self.lines) + 1))
        if self.n_fingers > 1:
            return (*self.base.state_names, *lines)
        obj = self.base.object_coordinates
        return (*obj, "q1", "q2", *["d" + k for k in obj], "dq1", "dq2", "u0", "u1", *lines)

    @property
    def input_names(self) -> tuple[str, ...]:
        """The base scene's inputs (joint torques ``u1, u2``, held or tabled by ``simulate(u=)``)."""
        return self.base.input_names

    @property
    def p_names(self) -> tuple[str, ...]:
        return (*self.runtime, *self.start_param_names, *coefficient_names(self.input_names))

    def check_outputs(self) -> tuple[str, ...]:
        return self.outputs

    def internal_outputs(self) -> tuple[str, ...]:
        """The outputs only a switch reads (the impulse's ``W = A M^-1 A^T`` and ``M^-1 A^T``,
        or its rows ``M^-1 g``): compiled, not shown (``pipeline.with_check_outputs``)."""
        return tuple(k for k in self.outputs if k.startswith(("W_", "MinvAT_", "Minv_g")))

    def validate(self) -> None:
        self.base.validate()

    def start_values(self) -> dict[str, float]:
        return self.base.start_values()

    def initial_state(self) -> np.ndarray:
        """The base's start (at rest, in contact), with both contact parameters (the lines'
        support points are solved with the model, ``assemble.kinds``)."""
        x = self.base.initial_state()
        n = 2 * self.n_speeds
        return np.concatenate([x[:n], [x[n], x[n]]]) if self.base.shared_parameter else x

    def code_key(self) -> str:
        return "\n".join(["planar-modes-v1", self.base.code_key(), *[_line_key(w) for w in self.lines]])

    def key(self) -> str:
        return "\n".join(["planar-modes-v1", self.base.key(),
                          *[f"{_line_key(w)}|{w.support!r}" for w in self.lines]])

    def rolling_map(self) -> dict | None:
        """``WithModes.rolling_map``; a base with one contact parameter ``s`` for both contours
        (``shared_parameter``) is the rolling model of the states with ``u0 = u1 = s``."""
        if self.lines:
            return None                    # the rolling model has no gap to a line to watch
        if self.n_fingers > 1 or not self.base.shared_parameter:
            return super().rolling_map()
        return {"to": [0, 1, 2, 3, 4, 5, 6], "from": [0, 1, 2, 3, 4, 5, 6, 6]}

    def manifest_extra(self) -> dict:
        """The kind, and that ``simulate`` runs the modes (``runtime.modes``); with several
        fingers their number and where the speeds start and how many (``planar_fingers``);
        how the base's rolling model runs the stretches where every contact rolls
        (``rolling_map``)."""
        extra = {"kind": self.kind, "modes": list(MODES), "n_contacts": self.n_contacts,
                 "rolling_map": self.rolling_map(), "folded_modes": list(self.folded_modes()),
                 "param_rules": {m: "nonnegative" for m in self.runtime if m.startswith("mu")}}
        if self.numbered:
            extra["planar_fingers"] = {
                "fingers": self.n_fingers, "speeds": [self.n_speeds, self.n_speeds],
                "driven": [self.n_fingers + m for m, w in enumerate(self.lines, start=1) if w.motion is not None]}
        return extra

    def bounds(self) -> tuple[list, list]:
        n = len(self.state_names)
        lower: list = [None] * n
        upper: list = [None] * n
        for i, tip in enumerate(self.fingertips):  # (u0_i, u1_i) after q and v
            j = 2 * self.n_speeds + 2 * i
            lower[j], upper[j] = tip.domain
            lower[j + 1], upper[j + 1] = self.base.object.domain
        for m in range(len(self.lines)):
            j = 2 * self.n_speeds + 2 * self.n_fingers + m
            lower[j], upper[j] = self.base.object.domain
        return lower, upper


def _line_key(w: WorldLine) -> str:
    motion = None if w.motion is None else tuple(map(sp.srepr, w.motion))
    return repr((w.point, w.normal, motion))


def with_modes(scene: PlanarFingerScene, lines=()) -> PlanarModesScene:
    """``scene`` whose contact rolls, slides or separates, with the world's ``lines`` (module
    docstring)."""
    return PlanarModesScene(scene, tuple(lines))
