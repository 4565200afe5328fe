"""A free rigid body on a surface of the world (a table, an incline): the scene of contact modes.

A body of mass ``mass`` and inertia ``inertia`` (about its centre of mass, body frame) whose
smooth strictly convex surface ``surface`` (body frame, centre of mass at the origin) meets
a fixed plane of the world (``plane_point``, unit ``plane_normal`` pointing into the free
half-space) under gravity. Its one contact rolls, slides or is separated
(``docs/conventions.md`` section 7; MODELS.md section 5): the model is compiled once with the
mode a run-time parameter, and ``Model.simulate`` switches between the modes at the events
(``runtime.modes``).

State: ``x, y, z`` (centre of mass, world), ``qw, qx, qy, qz`` (orientation), ``vx, vy, vz``,
``omegaX, omegaY, omegaZ`` (body frame), and ``u, v``: the surface coordinates of the body's
support point, where its outward normal is ``-plane_normal`` (the contact point in contact, the
closest point to the plane in flight).
"""
from __future__ import annotations

import math
import numbers
from dataclasses import dataclass, field
from typing import ClassVar

import numpy as np
import sympy as sp

from grasping_sym.contact import Coulomb, friction_problems
from grasping_sym.errors import InvalidSceneError
from grasping_sym.geometry.atlas import manifest_entry
from grasping_sym.geometry.expressions import ExpressionError, to_expression
from grasping_sym.geometry.surfaces import ParametricSurface
from grasping_sym.names import name_problems, names_tuple, output_problems

#: The time in ``plane_motion``'s expressions.
TIME = sp.Symbol("t", real=True)
#: The contact's modes, by the number the compiled model takes as its parameter ``mode``.
MODES = ("rolling", "sliding", "separated")
#: The run-time parameters every body model takes: the mode, the friction coefficient, the
#: slip direction at the start of a slide (world, used while the slip speed is 0), and the
#: slip's scale of a slide's onset at the cone's edge (m/s; 0: none; ``derive.body_plane``).
RUNTIME = ("mode", "mu", "slip_x", "slip_y", "slip_z", "slip_onset")
#: Every output a body scene has.
OUTPUTS = ("gap", "normal_speed", "normal_force", "tangential_force", "cone_ratio", "slip_speed",
           "rolling_normal_force", "rolling_tangential_force", "painleve",
           "kinetic_energy", "potential_energy", "energy",
           "vt_x", "vt_y", "vt_z", "Ft_x", "Ft_y", "Ft_z", "rolling_Ft_x", "rolling_Ft_y",
           "rolling_Ft_z", "rc_x", "rc_y", "rc_z", "vc_x", "vc_y", "vc_z",
           *(f"K_{i}{j}" for i in range(3) for j in range(3)), "onset_left")


def _number(v) -> bool:
    return isinstance(v, numbers.Real) and not isinstance(v, (bool, np.bool_)) and math.isfinite(v)


def _vec(v) -> tuple[float, ...]:
    return tuple(float(a) for a in np.asarray(v, dtype=float).ravel())


@dataclass(frozen=True)
class BodyScene:
    """A free body on a plane of the world (module docstring). ``plane_spin`` (rad/s): the
    plane turns about its normal through ``plane_point`` (a turntable). ``rotation``: the body's
    orientation at the start (world from body); ``position``: its centre's start, moved along
    the plane's normal onto the plane when ``start="contact"``; ``velocity``, ``omega`` (body
    frame): its speeds at the start (in contact, the normal speed of the contact point is
    removed). ``gain`` (1/s): the critically damped stabilisation of the contact constraints
    and of the support point's tracking."""

    name: str
    surface: ParametricSurface
    mass: float
    inertia: tuple
    plane_point: tuple[float, float, float] = (0.0, 0.0, 0.0)
    plane_normal: tuple[float, float, float] = (0.0, 0.0, 1.0)
    plane_spin: float = 0.0
    #: the plane's translation ``d(t)`` (m, world; three expressions of ``t``, text, numbers or
    #: SymPy with the symbol ``t``; ``d(0) = 0``): a conveyor, a rising or shaking table
    plane_motion: tuple | None = None
    gravity: tuple[float, float, float] = (0.0, 0.0, -9.81)
    position: tuple[float, float, float] = (0.0, 0.0, 0.0)
    rotation: tuple = ((1.0, 0.0, 0.0), (0.0, 1.0, 0.0), (0.0, 0.0, 1.0))
    velocity: tuple[float, float, float] = (0.0, 0.0, 0.0)
    omega: tuple[float, float, float] = (0.0, 0.0, 0.0)
    support: tuple[float, float] = (0.0, 0.0)
    start: str = "contact"
    gain: float = 200.0
    friction: Coulomb | None = None
    outputs: tuple[str, ...] = OUTPUTS
    controller: object = None
    inputs: str | None = None
    runtime: tuple[str, ...] = field(default=RUNTIME, init=False)

    kind: ClassVar[str] = "body"
    dimension: ClassVar[int] = 3
    start_param_names: ClassVar[tuple[str, ...]] = ()
    input_names: ClassVar[tuple[str, ...]] = ()
    simulate_defaults: ClassVar[dict] = {"t_final": 1.0, "method": "radau",
                                         "tolerances": {}}

    def __post_init__(self) -> None:
        for k in ("plane_point", "plane_normal", "gravity", "position", "velocity", "omega", "support"):
            object.__setattr__(self, k, _vec(getattr(self, k)))
        H = np.asarray(self.inertia, float)
        if H.shape == (3,):
            H = np.diag(H)
        object.__setattr__(self, "inertia", tuple(map(tuple, H.tolist())))
        object.__setattr__(self, "rotation", tuple(map(tuple, np.asarray(self.rotation, float).tolist())))
        object.__setattr__(self, "outputs", names_tuple(self.outputs))
        motion, motion_problems = translation_of_time(self.plane_motion, "plane_motion")
        object.__setattr__(self, "plane_motion", motion)
        problems = motion_problems + self._problems()
        if problems:
            raise InvalidSceneError(problems)

    def _problems(self) -> list[str]:
        p = name_problems(self.name)
        if not isinstance(self.surface, ParametricSurface):
            p.append(f"surface is {type(self.surface).__name__}: give a ParametricSurface (gs.surfaces...)")
        if not (_number(self.mass) and self.mass > 0):
            p.append(f"mass = {self.mass!r} must be a finite number > 0 (kg)")
        H = np.asarray(self.inertia, float)
        if H.shape != (3, 3) or not np.all(np.isfinite(H)) or not np.allclose(H, H.T) \
                or np.linalg.eigvalsh(0.5 * (H + H.T)).min() <= 0:
            p.append(f"inertia {self.inertia} must be a symmetric positive definite 3x3 matrix (kg m^2)")
        for k in ("plane_point", "plane_normal", "gravity", "position", "velocity", "omega"):
            v = getattr(self, k)
            if len(v) != 3 or not all(math.isfinite(a) for a in v):
                p.append(f"{k} = {v!r} must be three finite numbers")
        if len(self.plane_normal) == 3 and not abs(np.linalg.norm(self.plane_normal) - 1) < 1e-12:
            p.append(f"plane_normal = {self.plane_normal} must be a unit vector (to 1e-12)")
        R = np.asarray(self.rotation, float)
        if R.shape != (3, 3) or not np.allclose(R.T @ R, np.eye(3), atol=1e-12) or np.linalg.det(R) < 0:
            p.append("rotation must be a proper rotation matrix (R^T R = I to 1e-12, det +1)")
        if len(self.support) != 2 or not all(math.isfinite(a) for a in self.support):
            p.append(f"support = {self.support!r} must be two finite numbers (the guess of (u, v))")
        if self.start not in ("contact", "as given"):
            p.append(f"start = {self.start!r}: choose 'contact' (the body put on the plane) or "
                     "'as given' (where position says, e.g. above the plane)")
        if not _number(self.plane_spin):
            p.append(f"plane_spin = {self.plane_spin!r} must be a finite number (rad/s; 0: a fixed plane)")
        if self.plane_motion is not None and self.plane_spin:
            p.append("plane_motion and plane_spin together are not built: a plane translates or turns")
        if not (_number(self.gain) and self.gain > 0):
            p.append(f"gain = {self.gain!r} must be a finite number > 0 (1/s)")
        if self.controller is not None or self.inputs is not None:
            p.append("a body on a plane has no joints: controller and inputs must be None")
        p += friction_problems(self.friction, 1)
        p += output_problems(self.outputs, (*OUTPUTS, "support_facing"))
        return p

    # ------------------------------------------------------------------ names
    @property
    def state_names(self) -> tuple[str, ...]:
        return ("x", "y", "z", "qw", "qx", "qy", "qz", "vx", "vy", "vz",
                "omegaX", "omegaY", "omegaZ", "u", "v")

    @property
    def params(self) -> dict[str, float]:
        mu = self.friction.per_contact(1)[0] if self.friction is not None else math.inf
        return {"mode": 0.0, "mu": min(mu, 1e300), "slip_x": 0.0, "slip_y": 0.0, "slip_z": 0.0,
                "slip_onset": 0.0}

    @property
    def chart_names(self) -> tuple[str, ...]:
        """The chart of the body's surface when it has an atlas (``geometry.atlas``): a
        parameter the run sets (``runtime.atlas``), after every other in ``p``."""
        return ("chart",) if getattr(self.surface, "atlas", None) is not None else ()

    @property
    def p_names(self) -> tuple[str, ...]:
        return (*self.runtime, *self.chart_names)

    @property
    def n_contacts(self) -> int:
        return 1

    def check_outputs(self) -> tuple[str, ...]:
        """Every output: the modes' events and maps read all of them, and a run's start reads
        whether its support point faces the plane (``support_facing``, not shown)."""
        return (*OUTPUTS, "support_facing")

    def code_key(self) -> str:
        return "\n".join(["body-v3", self.name, self.surface.key(), repr(self.mass),
                          repr(self.inertia), repr(self.plane_point), repr(self.plane_normal),
                          repr(self.gravity), repr(self.gain), ",".join(self.outputs),
                          f"spin={self.plane_spin!r}",
                          *([] if self.plane_motion is None
                            else [f"motion={tuple(map(sp.srepr, self.plane_motion))}"])])

    def key(self) -> str:
        return "\n".join([self.code_key(), repr(self.position), repr(self.rotation),
                          repr(self.velocity), repr(self.omega), repr(self.support), self.start])

    def manifest_extra(self) -> dict:
        """The kind, and that ``simulate`` runs the modes (``runtime.modes``)."""
        return {"kind": "body", "modes": list(MODES),
                "body": {"mass": float(self.mass), "inertia": [list(r) for r in self.inertia],
                         "plane_normal": list(self.plane_normal), "gain": float(self.gain)},
                "param_rules": {"mu": "nonnegative"},
                **self.atlas_manifest()}

    def atlas_manifest(self) -> dict:
        """The surface's atlas (``geometry.atlas``) as the run time reads it, if it has one."""
        entry = manifest_entry(self.surface, "chart", "u", "v", None)
        if entry is None:
            return {}
        return {**({"chart_param_names": list(self.chart_names)} if self.chart_names else {}), "atlas": [entry]}

    def bounds(self) -> tuple[list, list]:
        lower: list = [None] * 15
        upper: list = [None] * 15
        (u0, u1), (v0, v1) = self.surface.domain
        lower[13], upper[13], lower[14], upper[14] = u0, u1, v0, v1
        return lower, upper


def rate_of_time(value, what: str) -> tuple[sp.Expr | None, list[str]]:
    """``(w, problems)``: a plane's turning rate ``value`` (rad/s: None, a number, or one
    expression of ``t``: text or SymPy with the symbol ``t``) as a SymPy expression, and what is
    wrong with it (not one finite expression of ``t`` alone)."""
    if value is None:
        return None, []
    try:
        w = to_expression(value, {"t": TIME}, what)
    except (ExpressionError, TypeError) as exc:
        return None, [str(exc)]
    w = w.subs({s: TIME for s in w.free_symbols if s.name == "t"})
    if w.free_symbols - {TIME}:
        return None, [f"{what} = {w}: give one expression of t alone (rad/s)"]
    # the rate and its derivative (in the contact's acceleration) real and finite at t = 0
    if _values_at_start((w, sp.diff(w, TIME))) is None:
        return None, [f"{what} = {w}: it and its rate must be real and finite at t = 0 (rad/s)"]
    return w, []


def _values_at_start(exprs) -> list[float] | None:
    """The values of ``exprs`` at ``t = 0``; None if one is not a real finite number there."""
    try:
        at0 = [complex(e.subs(TIME, 0)) for e in exprs]
    except (TypeError, ValueError):
        return None
    if not all(math.isfinite(v.real) and v.imag == 0 for v in at0):
        return None
    return [v.real for v in at0]


def translation_of_time(value, what: str, dims: int = 3) -> tuple[tuple | None, list[str]]:
    """``(d, problems)``: a plane's (``dims = 3``) or a line's (``dims = 2``) translation
    ``value`` (None, or ``dims`` expressions of ``t``: text, numbers or SymPy with the symbol
    ``t``) as SymPy expressions, and what is wrong with it (not ``dims`` expressions of ``t``
    alone, or not 0 at ``t = 0``: the plane starts where its point is)."""
    if value is None:
        return None, []
    try:
        d = tuple(to_expression(e, {"t": TIME}, what) for e in value)
    except (ExpressionError, TypeError) as exc:
        return None, [str(exc)]
    # a SymPy t of the user's (any assumptions) is the time
    d = tuple(e.subs({s: TIME for s in e.free_symbols if s.name == "t"}) for e in d)
    if len(d) != dims or any(e.free_symbols - {TIME} for e in d):
        return None, [f"{what} = {d}: give {('two', 'three')[dims - 2]} expressions of t alone (m)"]
    at0 = _values_at_start((*d, *(sp.diff(e, TIME) for e in d), *(sp.diff(e, TIME, 2) for e in d)))
    if at0 is None:
        return None, [f"{what} = {d}: it, its velocity and acceleration must be real and finite at "
                      "t = 0 (m)"]
    if any(abs(v) > 1e-15 for v in at0[:dims]):
        return None, [f"{what} = {d} is not 0 at t = 0: the plane starts at its point"]
    return d, []
