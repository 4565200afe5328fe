"""A free 2D body on a line of the world (a table, an incline seen edge-on): contact modes in 2D.

A body of mass ``mass`` and inertia ``inertia`` (about its mass centre, kg m^2) whose smooth
strictly convex contour ``contour`` (body frame, mass centre at the origin, running clockwise
like a 2D object's: ``docs/conventions.md`` section 1) meets a fixed line of the world
(``line_point``, unit ``line_normal`` into the free half-plane) under gravity. Its one contact
rolls, slides or is separated (``docs/conventions.md`` section 14; MODELS.md section 5): the
model is compiled once with the mode a run-time parameter, and ``Model.simulate`` switches
between the modes at the events (``runtime.modes``), as for a body on a plane in 3D
(``model.body``).

Frames as for a 2D object (section 1): a body point is ``Om + Rot(-theta) c(u)``, so
``theta`` grows clockwise. State: ``x, y`` (mass centre, world), ``theta``, their rates
``dx, dy, dtheta``, and ``u``: the contour parameter of the body's support point, where its
outward normal is ``-line_normal`` (the contact point in contact, the closest point to the
line in flight).
"""
from __future__ import annotations

import math
import numbers
from dataclasses import dataclass, field
from typing import ClassVar

import numpy as np
import sympy as sp

from grasping_sym.contact import Coulomb, friction_problems
from grasping_sym.errors import InvalidCurveError, InvalidSceneError
from grasping_sym.geometry.curves import PlanarCurve
from grasping_sym.model.body import translation_of_time
from grasping_sym.names import name_problems, names_tuple, output_problems

#: The contact's modes, by the number the compiled model takes as its parameter ``mode``.
MODES = ("rolling", "sliding", "separated")
#: The run-time parameters: the mode, the friction coefficient, the slip's sign along the
#: line's tangent ``t = (-n_y, n_x)`` at the start of a slide (used while the slip speed is 0).
RUNTIME = ("mode", "mu", "slip")
#: Every output a body on a line has (``tangential_force``, ``slip_speed``: magnitudes;
#: ``Ft``, ``vt``: signed along ``t``).
OUTPUTS = ("gap", "normal_speed", "normal_force", "tangential_force", "Ft", "cone_ratio",
           "slip_speed", "vt", "rolling_normal_force", "rolling_tangential_force", "rolling_Ft",
           "painleve", "kinetic_energy", "potential_energy", "energy",
           "rc_x", "rc_y", "vc_x", "vc_y", "K_00", "K_01", "K_10", "K_11")


def _number(v) -> bool:
    return isinstance(v, numbers.Real) and not isinstance(v, (bool, np.bool_)) and math.isfinite(v)


def _pair(v) -> tuple[float, ...]:
    try:
        return tuple(float(a) for a in np.asarray(v, dtype=float).ravel())
    except (TypeError, ValueError):
        return (math.nan,)


@dataclass(frozen=True)
class LineBodyScene:
    """A free 2D body on a line of the world (module docstring). ``position``, ``theta``: its
    start (moved along the line's normal onto the line when ``start="contact"``);
    ``velocity``, ``dtheta``: its speeds at the start (in contact, the contact point's normal
    speed is removed); ``support``: a guess of the contour parameter that faces the line;
    ``gain`` (1/s): the critically damped stabilisation of the contact constraints and of the
    support point's tracking."""

    name: str
    contour: PlanarCurve
    mass: float
    inertia: float
    line_point: tuple[float, float] = (0.0, 0.0)
    line_normal: tuple[float, float] = (0.0, 1.0)
    #: the line's translation ``d(t)`` (m, world; two expressions of ``t``, text, numbers or
    #: SymPy with the symbol ``t``; ``d(0) = 0``): a conveyor, a rising or shaking table
    line_motion: tuple | None = None
    gravity: tuple[float, float] = (0.0, -9.81)
    position: tuple[float, float] = (0.0, 0.0)
    theta: float = 0.0
    velocity: tuple[float, float] = (0.0, 0.0)
    dtheta: float = 0.0
    support: float = 0.0
    start: str = "contact"
    gain: float = 200.0
    friction: Coulomb | None = None
    outputs: tuple[str, ...] = OUTPUTS
    controller: object = None
    inputs: str | None = None
    runtime: tuple[str, ...] = field(default=RUNTIME, init=False)

    kind: ClassVar[str] = "body2d"
    dimension: ClassVar[int] = 2
    start_param_names: ClassVar[tuple[str, ...]] = ()
    input_names: ClassVar[tuple[str, ...]] = ()
    simulate_defaults: ClassVar[dict] = {"t_final": 1.0, "method": "radau", "tolerances": {}}

    def __post_init__(self) -> None:
        for k in ("line_point", "line_normal", "gravity", "position", "velocity"):
            object.__setattr__(self, k, _pair(getattr(self, k)))
        object.__setattr__(self, "outputs", names_tuple(self.outputs))
        motion, motion_problems = translation_of_time(self.line_motion, "line_motion", dims=2)
        object.__setattr__(self, "line_motion", motion)
        problems = motion_problems + self._problems()
        if problems:
            raise InvalidSceneError(problems)

    def _problems(self) -> list[str]:
        p = name_problems(self.name)
        if not isinstance(self.contour, PlanarCurve):
            p.append(f"contour is {type(self.contour).__name__}: give a PlanarCurve (gs.curves...)")
        else:
            try:
                self.contour.check()
            except InvalidCurveError as exc:
                p.append(f"contour: {exc}")
            else:
                o = self.contour.orientation
                if o.closed and o.area > 0:
                    p.append(f"contour '{self.contour.name}' runs counterclockwise (it encloses "
                             f"{o.area:+.4g} m^2): a body's contour runs clockwise about it, like a 2D "
                             "object's (clockwise=True for a library contour)")
        if not (_number(self.mass) and self.mass > 0):
            p.append(f"mass = {self.mass!r} must be a finite number > 0 (kg)")
        if not (_number(self.inertia) and self.inertia > 0):
            p.append(f"inertia = {self.inertia!r} must be a finite number > 0 (kg m^2, about the "
                     "mass centre)")
        for k in ("line_point", "line_normal", "gravity", "position", "velocity"):
            v = getattr(self, k)
            if len(v) != 2 or not all(math.isfinite(a) for a in v):
                p.append(f"{k} = {v!r} must be two finite numbers")
        if len(self.line_normal) == 2 and not abs(np.linalg.norm(self.line_normal) - 1) < 1e-12:
            p.append(f"line_normal = {self.line_normal} must be a unit vector (to 1e-12)")
        for k in ("theta", "dtheta", "support"):
            if not _number(getattr(self, k)):
                p.append(f"{k} = {getattr(self, k)!r} must be a finite number")
        if self.start not in ("contact", "as given"):
            p.append(f"start = {self.start!r}: choose 'contact' (the body put on the line) or "
                     "'as given' (where position says, e.g. above the line)")
        if not (_number(self.gain) and self.gain > 0):
            p.append(f"gain = {self.gain!r} must be a finite number > 0 (1/s)")
        if self.controller is not None or self.inputs is not None:
            p.append("a body on a line has no joints: controller and inputs must be None")
        p += friction_problems(self.friction, 1)
        p += output_problems(self.outputs, OUTPUTS)
        return p

    # ------------------------------------------------------------------ names
    @property
    def state_names(self) -> tuple[str, ...]:
        return ("x", "y", "theta", "dx", "dy", "dtheta", "u")

    @property
    def params(self) -> dict[str, float]:
        mu = self.friction.per_contact(1)[0] if self.friction is not None else math.inf
        return {"mode": 0.0, "mu": min(mu, 1e300), "slip": 1.0}

    @property
    def p_names(self) -> tuple[str, ...]:
        return self.runtime

    @property
    def n_contacts(self) -> int:
        return 1

    @property
    def tangent(self) -> tuple[float, float]:
        """The line's tangent ``t = (-n_y, n_x)``: the direction of positive ``vt``, ``Ft``."""
        return (-self.line_normal[1], self.line_normal[0])

    def check_outputs(self) -> tuple[str, ...]:
        """Every output: the modes' events and maps read all of them."""
        return OUTPUTS

    def code_key(self) -> str:
        return "\n".join(["body2d-v1", self.name, self.contour.key(), repr(float(self.mass)),
                          repr(float(self.inertia)), repr(self.line_point), repr(self.line_normal),
                          repr(self.gravity), repr(float(self.gain)), ",".join(self.outputs),
                          *([] if self.line_motion is None
                            else [f"motion={tuple(map(sp.srepr, self.line_motion))}"])])

    def key(self) -> str:
        return "\n".join([self.code_key(), repr(self.position), repr(float(self.theta)),
                          repr(self.velocity), repr(float(self.dtheta)), repr(float(self.support)),
                          self.start])

    def manifest_extra(self) -> dict:
        """The kind, and that ``simulate`` runs the modes (``runtime.modes``)."""
        return {"kind": "body2d", "modes": list(MODES),
                "body2d": {"mass": float(self.mass), "inertia": float(self.inertia),
                           "line_normal": list(self.line_normal), "gain": float(self.gain)},
                "param_rules": {"mu": "nonnegative"}}

    def bounds(self) -> tuple[list, list]:
        lower: list = [None] * 7
        upper: list = [None] * 7
        lower[6], upper[6] = self.contour.domain
        return lower, upper
