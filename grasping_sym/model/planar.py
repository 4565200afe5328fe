"""The 2D scene: planar two-joint fingers rolling on an object pivoted at a point, or free.

Frames and signs follow ``docs/conventions.md`` section 1 (Yoshida, Arimoto, Tahara 2009):

- inertial frame O-xy, ``Rot(a) = [[cos a, -sin a], [sin a, cos a]]``;
- finger joints at the origin, fingertip centre
  ``O01 = (l11 sin q1 + l12 sin(q1+q2), l11 cos q1 + l12 cos(q1+q2))``;
- fingertip contour point ``O01 + Rot(pi/2 - q1 - q2) c0(u0)``;
- object contour point ``Om + Rot(-theta) c1(u1)``, the object pivoted at the fixed ``Om``
  (``support="pivot"``), or free (``support="free"``): ``Om = (x, y)`` is then its mass
  centre, a state like ``theta`` (docs/conventions.md section 13).

The contact is described by one parameter per contour (``u0`` on the fingertip, ``u1`` on the
object). When both contours are unit-speed and the contact starts at equal parameters, the
two coincide for all time (rolling: equal path lengths) and one state ``s`` serves both, as
in the paper.
"""
from __future__ import annotations

import math
import numbers
from dataclasses import dataclass
from functools import cached_property
from typing import ClassVar

import numpy as np

from grasping_sym.contact import Coulomb, friction_problems
from grasping_sym.errors import InvalidCurveError, InvalidSceneError
from grasping_sym.geometry.curves import PlanarCurve
from grasping_sym.model.control import PAPER, coefficient_names, control_problems
from grasping_sym.model.control import input_names as _input_names
from grasping_sym.names import name_problems, names_tuple, output_problems

#: Parameters of the 2D scene, with their units.
PARAMETERS: dict[str, str] = {
    "l11": "m, length of link 1",
    "l12": "m, length of link 2",
    "m11": "kg, mass of link 1 (uniform rod)",
    "m12": "kg, mass of link 2 (uniform rod)",
    "I": "kg m^2, object inertia about the pivot Om (a free object: about its mass centre)",
    "fd": "N, desired internal force",
    "c": "N m s, joint damping",
    "r": "m, control constant of eq (32)",
    "gf": "1/s, CSM damping gain of Q (gamma_f)",
    "gl": "1/s, CSM damping gain of R (gamma_lambda)",
    "wf": "1/s^2, CSM stiffness gain of Q (omega_f)",
    "wl": "1/s^2, CSM stiffness gain of R (omega_lambda)",
}

#: Parameters a free object adds (``support="free"``), with their units. ``I`` is then the
#: inertia about the mass centre ``Om``.
FREE_PARAMETERS: dict[str, str] = {"M": "kg, object mass (support='free')"}

#: What may hold the 2D object: a fixed pivot (the paper's), or nothing (a free object).
SUPPORTS = ("pivot", "free")

#: The constraint-stabilisation gains: 0 is allowed (no stabilisation).
CSM_GAINS = ("gf", "gl", "wf", "wl")

#: Parameters that may be kept as run-time inputs: they change the dynamics but not the
#: initial configuration (which fixes the pivot ``Om``), so a sweep over them needs no rebuild.
RUNTIME_ALLOWED = ("m11", "m12", "I", "fd", "c", "r", "gf", "gl", "wf", "wl")

#: Outputs a 2D model can generate (only the requested ones are derived and compiled).
OUTPUTS: dict[str, str] = {
    "Q": "m, normal contact constraint (14)",
    "R": "m, rolling constraint (24)",
    "f": "N, normal multiplier",
    "lam": "N, tangential multiplier",
    "delta_f": "N, f + (fd/r) Q1",
    "delta_lam": "N, lam + (fd/r) R1",
    "N1": "m^2, ln0 lb1 - lb0 ln1",
    "kappa_sum": "1/m, kappa0 + kappa1 at the contact",
    "constraint_residual": "m, max(|Q|, |R|)",
    "tangency_defect": "rad, angle between the two contour tangents at the contact",
    "kinetic_energy": "J",
    "potential_energy": "J (gravity only)",
    "power": "W, joint power q'.u of the controller",
}
DEFAULT_OUTPUTS = (
    "Q", "R", "f", "lam", "delta_f", "delta_lam", "N1", "kappa_sum", "constraint_residual",
)


@dataclass(frozen=True, eq=False)
class ExtraFinger:
    """A further two-joint finger on the same object (finger ``i >= 2`` of a scene).

    Its joints sit at ``base`` (m); its links are uniform rods like finger 1's; its fingertip
    contour is in its own fingertip frame. At the start it touches the object at the object
    parameter ``u1_0``; the fingertip parameter, ``q1`` and ``q2`` are solved from contact and
    tangency (``u0_0`` is the guess).
    """

    fingertip: PlanarCurve
    base: tuple[float, float]
    u1_0: float
    u0_0: float = 0.0
    lengths: tuple[float, float] = (0.065, 0.065)
    masses: tuple[float, float] = (0.045, 0.040)

    def code_key(self) -> str:
        """What the generated code depends on (not the start contact ``u1_0``, ``u0_0``)."""
        return "|".join([self.fingertip.key(), repr((tuple(map(float, self.base)),
                                                     tuple(map(float, self.lengths)),
                                                     tuple(map(float, self.masses))))])


@dataclass(frozen=True, eq=False)
class PlanarFingerScene:
    """Two-joint planar fingers rolling on an object pivoted at a fixed point, or free.

    Parameters
    ----------
    name
        Scene name; also the prefix of the generated C symbols (``{name}_rhs``).
    fingertip, object
        Contours in the fingertip frame O01-X0Y0 and the object frame Om-XY.
    params
        Values of every key of ``PARAMETERS`` (SI units).
    runtime
        Parameters kept as run-time inputs of the compiled functions (see
        ``RUNTIME_ALLOWED``); all others are folded in as constants.
    outputs
        Names from ``OUTPUTS`` to generate.
    gravity
        ``(gx, gy)`` in m/s^2, or ``None`` for a horizontal scene (no gravity terms at all).
        A pivoted object's centre of mass is at its pivot; a free object's weight ``M g``
        acts at its mass centre ``Om``; finger gravity is compensated by the controller.
    q1_0, theta_0, u0_0, u1_0
        Initial joint angle q1 (rad), object angle (rad) and contact parameters on the
        fingertip and object contours. The initial state is at rest; tangency fixes ``q2``
        and contact fixes the pivot ``Om``.
    extra_fingers
        Fingers 2, 3, ... (:class:`ExtraFinger`) on the same object. Each runs the same
        controller (32) toward the pivot; the multi-finger states and outputs carry the
        finger's number (``q21``, ``u0_2``, ``f2``, ...).
    controller
        ``"paper"`` (the law (32), ``controllers.paper2d``), ``None`` (no law) or a
        ``grasping_sym.model.controllers.Controller`` (``model.control``).
    inputs
        ``None`` or ``"torques"``: joint torques ``u1, u2, ...`` added to the controller's.
    friction
        Coulomb friction at the contacts (``gs.contact.coulomb``), checked at run time.
    support
        ``"pivot"`` (the paper's: the object turns about the fixed ``Om``) or ``"free"``: the
        object's mass centre ``Om = (x, y)`` moves too (three degrees of freedom; ``params``
        then also holds its mass ``M``, and ``I`` is about ``Om``). The start puts ``Om``
        where finger 1's contact puts it, as it puts the pivot; the paper's law (32) pulls
        each fingertip toward that start point (``m.pivot``).
    """

    name: str
    fingertip: PlanarCurve
    object: PlanarCurve
    params: dict[str, float]
    runtime: tuple[str, ...] = ()
    outputs: tuple[str, ...] = DEFAULT_OUTPUTS
    gravity: tuple[float, float] | None = None
    q1_0: float = math.pi / 6
    theta_0: float = 0.0
    u0_0: float = 0.0
    u1_0: float = 0.0
    extra_fingers: tuple[ExtraFinger, ...] = ()
    controller: object = PAPER
    inputs: str | None = None
    #: Coulomb friction at the contacts (``gs.contact.coulomb``): read at run time only, so it
    #: is in no cache key; None: no friction limit
    friction: Coulomb | None = None
    support: str = "pivot"

    #: The scene's kind (``model.kinds``: every floor above asks it, never the dimension).
    kind: ClassVar[str] = "planar"
    #: The scene's dimension: 2 or 3 (what a drawing of it has).
    dimension: ClassVar[int] = 2

    def __post_init__(self) -> None:
        object.__setattr__(self, "extra_fingers", tuple(self.extra_fingers))
        object.__setattr__(self, "runtime", tuple(self.runtime))
        object.__setattr__(self, "outputs", names_tuple(self.outputs))
        if self.extra_fingers and self.outputs == DEFAULT_OUTPUTS:
            object.__setattr__(self, "outputs", self.default_outputs())
        problems = self._parameter_problems()
        if problems:
            # the error path: add the contour checks too, so every problem is named at once
            geometry = [] if self._type_problems() else self._geometry_problems(problems)
            raise InvalidSceneError(problems + geometry)

    @cached_property
    def _initial(self) -> tuple[float, tuple[float, float]]:
        self.validate()
        return initial_configuration(self)

    @cached_property
    def _extra_initial(self) -> list[tuple[float, float, float]]:
        """``(q1, q2, u0)`` of each extra finger at the start."""
        return [extra_finger_configuration(self, f) for f in self.extra_fingers]

    @property
    def n_fingers(self) -> int:
        return 1 + len(self.extra_fingers)

    @property
    def free(self) -> bool:
        """Whether the object is free (``support="free"``): its mass centre is a state."""
        return self.support == "free"

    @property
    def parameter_names(self) -> tuple[str, ...]:
        """Every key ``params`` must hold: ``PARAMETERS``, and ``M`` for a free object."""
        return (*PARAMETERS, *(FREE_PARAMETERS if self.free else ()))

    @property
    def fingertips(self) -> tuple[PlanarCurve, ...]:
        """Every finger's fingertip contour, finger 1 first."""
        return (self.fingertip, *(f.fingertip for f in self.extra_fingers))

    def output_names(self) -> tuple[str, ...]:
        """Every output name this scene can generate."""
        if self.n_fingers == 1:
            return tuple(OUTPUTS)
        per = ("Q", "R", "f", "lam", "delta_f", "delta_lam", "kappa_sum", "tangency_defect")
        names = [f"{k}{i}" for i in range(1, self.n_fingers + 1) for k in per]
        names += [f"N1_{i}" for i in range(1, self.n_fingers + 1)]
        return (*names, "constraint_residual", "kinetic_energy", "potential_energy", "power")

    def check_outputs(self) -> tuple[str, ...]:
        """The outputs ``runtime.checks`` reads, compiled whatever ``outputs`` asks for (the
        model does not show those the user did not ask for): the constraints at the start
        (``Q``, ``R``; with several fingers ``constraint_residual``), every contact's normal
        force, tangential force (its friction cone, ``runtime.friction``) and relative
        curvature (``f``, ``lam``, ``kappa_sum``; with several fingers ``f1``, ``lam1``,
        ``kappa_sum1``, ...)."""
        if self.n_fingers == 1:
            return ("Q", "R", "f", "lam", "kappa_sum")
        n = range(1, self.n_fingers + 1)
        return ("constraint_residual", *[f"f{i}" for i in n], *[f"lam{i}" for i in n],
                *[f"kappa_sum{i}" for i in n])

    def default_outputs(self) -> tuple[str, ...]:
        """``DEFAULT_OUTPUTS`` for this scene: with several fingers, each per-contact output once
        per finger (``Q1, Q2, ...``, ``N1_1, N1_2, ...``)."""
        known = self.output_names()
        out: list[str] = []
        for k in DEFAULT_OUTPUTS:
            if k in known:
                out.append(k)
                continue
            for i in range(1, self.n_fingers + 1):
                out += [n for n in (f"{k}{i}", f"{k}_{i}") if n in known]
        return tuple(out)

    @property
    def q2_0(self) -> float:
        """Initial q2 (rad), fixed by tangency at the initial contact."""
        return self._initial[0]

    @property
    def pivot(self) -> tuple[float, float]:
        """The pivot ``Om`` (m), fixed by contact at the initial state; for a free object, its
        mass centre at the start (the point the paper's law pulls toward)."""
        return self._initial[1]

    @property
    def shared_parameter(self) -> bool:
        """True when one state ``s`` serves both contours (unit speed, equal start)."""
        return (
            not self.extra_fingers
            and self.fingertip.unit_speed and self.object.unit_speed and self.u0_0 == self.u1_0
        )

    @property
    def object_coordinates(self) -> tuple[str, ...]:
        """The object's position states: ``theta``, after ``x, y`` for a free object."""
        return ("x", "y", "theta") if self.free else ("theta",)

    @property
    def state_names(self) -> tuple[str, ...]:
        obj = self.object_coordinates
        if self.extra_fingers:
            n = range(1, self.n_fingers + 1)
            q = [f"q{i}{j}" for i in n for j in (1, 2)]
            return (*obj, *q, *["d" + k for k in obj], *["d" + k for k in q],
                    *[f"u{k}_{i}" for i in n for k in (0, 1)])
        tail = ("s",) if self.shared_parameter else ("u0", "u1")
        return (*obj, "q1", "q2", *["d" + k for k in obj], "dq1", "dq2", *tail)

    def validate(self) -> None:
        """Check every parameter, both contours and the initial contact; raise listing all.

        Construction runs only the cheap parameter checks; this full check (which samples
        the contours) runs when the scene is derived or its initial configuration is first
        needed. A scene served from the build cache has the content hash of one that passed.
        """
        problems = self._parameter_problems()
        problems += self._geometry_problems(problems)
        if problems:
            raise InvalidSceneError(problems)

    def _geometry_problems(self, known: list[str]) -> list[str]:
        """Contour regularity, the direction each contour runs, and (when all else is valid)
        the relative curvature at the initial contact."""
        problems: list[str] = []
        directions: list[str] = []
        curves = [("fingertip", self.fingertip, 1), ("object", self.object, -1)]
        curves += [(f"finger {i}'s fingertip", f.fingertip, 1)
                   for i, f in enumerate(self.extra_fingers, start=2)]
        for label, curve, sense in curves:
            try:
                curve.check()
            except InvalidCurveError as exc:
                problems.append(f"{label} contour: {exc}")
                continue
            wrong = _direction_problem(label, curve, sense)
            if wrong:
                directions.append(wrong)
        if not (known or problems) and all(_finite(u) for u in (self.u0_0, self.u1_0)):
            k0 = float(self.fingertip.evaluate(self.u0_0)["curvature"])
            k1 = -float(self.object.evaluate(self.u1_0)["curvature"])
            if not k0 + k1 > 0:
                problems.append(
                    f"relative curvature kappa0 + kappa1 = {k0 + k1:.6g} 1/m <= 0 at the initial "
                    "contact: the contours do not touch from outside there; the fingertip "
                    "contour must run counterclockwise and the object contour clockwise about "
                    "their bodies (e.g. clockwise=True for a library object contour)"
                )
        return directions + problems

    def _type_problems(self) -> list[str]:
        """The types the other checks rely on (each named with the fix)."""
        problems = []
        for label, curve in (("fingertip", self.fingertip), ("object", self.object)):
            if not isinstance(curve, PlanarCurve):
                problems.append(f"{label} is {type(curve).__name__}: give a PlanarCurve "
                                "(e.g. gs.curves.circle(0.01) or gs.PlanarCurve(x, y, domain=...))")
        if not isinstance(self.params, dict):
            problems.append(f"params is {type(self.params).__name__}: give a dict of values by name")
        for i, f in enumerate(self.extra_fingers, start=2):
            if not isinstance(f, ExtraFinger):
                problems.append(f"extra finger {i} is {type(f).__name__}: give an ExtraFinger")
            elif not isinstance(f.fingertip, PlanarCurve):
                problems.append(f"finger {i}'s fingertip is {type(f.fingertip).__name__}: give a "
                                "PlanarCurve")
        return problems

    def _parameter_problems(self) -> list[str]:
        """Checks that need no numeric evaluation of the contours."""
        problems = self._type_problems()
        if problems:
            return problems + name_problems(self.name)
        problems += name_problems(self.name)
        problems += control_problems(self.controller, self.inputs)
        if self.support not in SUPPORTS:
            problems.append(f"support = {self.support!r}: use 'pivot' (the object turns about a "
                            "fixed point) or 'free' (it moves in the plane)")
        known = {**PARAMETERS, **(FREE_PARAMETERS if self.free else {})}
        missing = [k for k in known if k not in self.params]
        unknown = [k for k in self.params if k not in known]
        if missing:
            problems.append(f"missing parameters {missing}: give a value for each"
                            + (" (a free object needs its mass M, kg)" if "M" in missing else ""))
        if unknown:
            hint = (" (M, the object's mass, is a parameter of a free object: support='free')"
                    if "M" in unknown else "")
            problems.append(f"unknown parameters {unknown}: known ones are {list(known)}{hint}")
        for k, v in self.params.items():
            if k in CSM_GAINS:  # 0 turns the stabilisation off (e.g. with projection)
                if not (_finite(v) and v >= 0):
                    problems.append(f"{k} = {v!r} ({PARAMETERS[k]}) must be finite and >= 0")
            elif k in known and not _finite_positive(v):
                problems.append(f"{k} = {v!r} ({known[k]}) must be finite and > 0")
        allowed = (*RUNTIME_ALLOWED, *(FREE_PARAMETERS if self.free else ()))
        for k in self.runtime:
            if k not in allowed:
                problems.append(
                    f"runtime parameter {k!r} cannot vary at run time: allowed are "
                    f"{list(allowed)} (geometry fixes the initial configuration)"
                )
        problems += output_problems(self.outputs, self.output_names())
        problems += friction_problems(self.friction, 1 + len(self.extra_fingers))
        for i, f in enumerate(self.extra_fingers, start=2):
            if not isinstance(f, ExtraFinger):
                problems.append(f"extra finger {i} is {type(f).__name__}: give an ExtraFinger")
                continue
            vals = [*f.base, f.u1_0, f.u0_0]
            if not all(_finite(v) for v in vals):
                problems.append(f"finger {i}: base, u1_0 and u0_0 must be finite numbers")
            if not all(_finite_positive(v) for v in (*f.lengths, *f.masses)) or len(f.lengths) != 2 \
                    or len(f.masses) != 2:
                problems.append(f"finger {i}: lengths {f.lengths} and masses {f.masses} must be two "
                                "finite numbers > 0 each")
            if _finite(f.u1_0) and not self.object.in_domain(f.u1_0):
                problems.append(f"finger {i}: u1_0 = {f.u1_0!r} is outside the object's domain "
                                f"{self.object.domain}")
        if self.gravity is not None and (
            len(self.gravity) != 2 or not all(_finite(g) for g in self.gravity)
        ):
            problems.append(f"gravity = {self.gravity!r} must be None or two finite numbers")
        for k in ("q1_0", "theta_0", "u0_0", "u1_0"):
            if not _finite(getattr(self, k)):
                problems.append(f"{k} = {getattr(self, k)!r} must be a finite number")
        for label, curve, u in (("fingertip", self.fingertip, self.u0_0),
                                ("object", self.object, self.u1_0)):
            if _finite(u) and not curve.in_domain(u):
                problems.append(
                    f"initial contact parameter on the {label} ({u!r}) is outside the "
                    f"contour's domain {curve.domain}: choose a value inside it"
                )
        return problems

    def code_key(self) -> str:
        """Canonical text of everything that determines the generated code.

        The start (``q1_0``, ``theta_0``, ``u0_0``, ``u1_0``, the extra fingers' contacts) is
        not in it: it enters the code only through the run-time pivot (``start_param_names``),
        so a new start reuses the compiled model. Whether one state ``s`` serves both contours
        is: the contours' keys and whether the start's two contact parameters are equal.
        """
        params = ";".join(f"{k}={float(self.params[k])!r}" for k in sorted(self.params))
        return "|".join([
            "planar-finger-v2", self.name, self.fingertip.key(), self.object.key(), params,
            ",".join(self.runtime), ",".join(self.outputs), repr(self.gravity),
            # with the contours' keys this fixes shared_parameter (which samples the contours)
            f"equal_start_parameters={self.u0_0 == self.u1_0}",
            *[f.code_key() for f in self.extra_fingers],
            f"inputs={self.inputs}", *(["support=free"] if self.free else []),
        ])

    def key(self) -> str:
        """Canonical text of the whole definition: the code's and the start's."""
        start = repr((self.q1_0, self.theta_0, self.u0_0, self.u1_0,
                      *[(f.u1_0, f.u0_0) for f in self.extra_fingers]))
        return f"{self.code_key()}|start={start}"

    #: Run-time parameters that the start fixes: the pivot ``Om`` (m); for a free object, its
    #: mass centre at the start, which the paper's law (32) pulls the fingertips toward.
    start_param_names: ClassVar[tuple[str, ...]] = ("xm", "ym")

    @property
    def input_names(self) -> tuple[str, ...]:
        """The control inputs (``model.control``): ``u1, u2, ...`` per joint, or none."""
        return _input_names(self.inputs, 2 * self.n_fingers)

    @property
    def p_names(self) -> tuple[str, ...]:
        """Every entry of the compiled functions' ``p``: the run-time parameters, the start's
        values, the inputs' coefficients."""
        return (*self.runtime, *self.start_param_names, *coefficient_names(self.input_names))

    def start_values(self) -> dict[str, float]:
        """Values of ``start_param_names``: the pivot solved from the initial contact."""
        xm, ym = self.pivot
        return {"xm": float(xm), "ym": float(ym)}

    # ------------------------------------------------------------------ scene protocol
    #: What ``grasping-sym simulate`` does by default: simulated time (s), integrator and
    #: its tolerances (none given: the integrator's own defaults).
    simulate_defaults: ClassVar[dict] = {"t_final": 3.0, "method": "radau", "tolerances": {}}

    def manifest_extra(self) -> dict:
        """What this kind of scene adds to its manifest: a start solved at run time
        (``runtime.start``) holds the object's angle unless it is given or must move; the
        rule each run-time parameter's value must meet (``Model.params`` checks it)."""
        return {"start_hold": list(self.object_coordinates),
                **({"start_implied": {"xm": "x", "ym": "y"}} if self.free else {}),
                "param_rules": {k: "nonnegative" if k in CSM_GAINS else "positive"
                                for k in self.runtime}}

    def bounds(self) -> tuple[list, list]:
        """Per-state bounds (None: unbounded): each contact parameter stays inside its
        contours' domains."""
        n = len(self.state_names)
        lower: list = [None] * n
        upper: list = [None] * n
        if self.shared_parameter:
            lower[-1] = max(self.fingertip.domain[0], self.object.domain[0])
            upper[-1] = min(self.fingertip.domain[1], self.object.domain[1])
            return lower, upper
        for i, tip in enumerate(self.fingertips, start=1):
            tag = "" if self.n_fingers == 1 else f"_{i}"
            k0, k1 = self.state_names.index(f"u0{tag}"), self.state_names.index(f"u1{tag}")
            lower[k0], upper[k0] = tip.domain
            lower[k1], upper[k1] = self.object.domain
        return lower, upper

    def initial_state(self) -> np.ndarray:
        """The consistent initial state at rest, ordered as ``state_names``."""
        obj = [*(self.pivot if self.free else ()), self.theta_0]
        rest = [0.0] * len(obj)
        if self.extra_fingers:
            extra = self._extra_initial
            q = [self.q1_0, self.q2_0, *[v for q1, q2, _ in extra for v in (q1, q2)]]
            u = [self.u0_0, self.u1_0, *[v for (_, _, u0), f in zip(extra, self.extra_fingers)
                                         for v in (u0, f.u1_0)]]
            return np.array([*obj, *q, *rest, *[0.0] * len(q), *u], dtype=float)
        x = [*obj, self.q1_0, self.q2_0, *rest, 0.0, 0.0]
        x += [self.u0_0] if self.shared_parameter else [self.u0_0, self.u1_0]
        return np.array(x, dtype=float)


#: rad: a contour whose tangent turns the wrong way by more than this over one traversal
#: (and that sweeps the wrong way about its frame's origin) runs the wrong way about its body.
DIRECTION_TURNING_TOL = 1e-6


def _direction_problem(label: str, curve: PlanarCurve, sense: int) -> str | None:
    """The contour runs the wrong way about its body, by name with the fix, else None.

    The fingertip contour must run counterclockwise about the fingertip (``sense = +1``:
    outward normal on the right of the direction of travel, material on the left), the object
    contour clockwise about the object (``sense = -1``: outward normal on the left), as the
    paper's contours and ``clockwise=True`` library object contours do (docs/guide.md,
    "Direction of travel"). Listed the other way, the package reads the body's material on the
    contour's other side: the fingertip is put inside the object and the run fails later.

    Refused when both measures of :attr:`PlanarCurve.orientation` say so: the tangent turns
    the wrong way over one traversal (beyond ``DIRECTION_TURNING_TOL``) and the contour sweeps
    the wrong way about its frame's origin (the fingertip centre O01, the object's pivot Om).
    For a closed contour both are the sign of the area it encloses. An open contour bent the
    other way on purpose (a concave hollow) passes when its frame's origin is on the body's
    side of it; a straight one always passes.
    """
    o = curve.orientation
    if not (sense * o.turning < -DIRECTION_TURNING_TOL and sense * o.area < -1e-9 * o.length * o.reach):
        return None
    body, origin = (("fingertip", "the fingertip centre O01") if sense > 0
                    else ("object", "the object's pivot Om"))
    runs, should = ("clockwise", "counterclockwise") if sense > 0 else ("counterclockwise", "clockwise")
    material, normal = ("left", "right") if sense > 0 else ("right", "left")
    if o.closed:
        measured = f"the area it encloses is {o.area:+.4g} m^2 (positive counterclockwise)"
    else:
        measured = (f"its tangent turns by {o.turning:+.4g} rad and it sweeps {o.area:+.4g} m^2 "
                    f"about its frame's origin, {origin} (positive counterclockwise)")
    fix = ("list its points the other way round (gs.curves.spline(points[::-1], ...)) or use "
           f"clockwise={sense < 0} for a library contour (e.g. gs.curves.ellipse(a, b, ..., "
           f"clockwise={sense < 0}))")
    article = "An" if sense < 0 else "A"
    inside = ("object would be put inside the fingertip" if sense > 0
              else "fingertip would be put inside the object")
    return (f"{label} contour '{curve.name}' runs {runs} about the {body}: {measured}. {article} {body} "
            f"contour must run {should} about its body (the {body}'s material on the {material} of "
            f"the direction of travel, the outward normal on the {normal}); as given, the {inside} "
            f"and the run would fail on the relative curvature. Fix: {fix}")


def _finite(v) -> bool:
    """A finite real number (Python, NumPy; ``True`` is not one)."""
    return isinstance(v, numbers.Real) and not isinstance(v, (bool, np.bool_)) and math.isfinite(v)


def _finite_positive(v) -> bool:
    return _finite(v) and v > 0


def _rot(a: float, v: np.ndarray) -> np.ndarray:
    c, s = math.cos(a), math.sin(a)
    return np.array([c * v[0] - s * v[1], s * v[0] + c * v[1]])


def initial_configuration(scene: PlanarFingerScene) -> tuple[float, tuple[float, float]]:
    """Solve tangency for ``q2`` and contact for the pivot ``Om``.

    Tangency: the unit tangents of both contours coincide in the inertial frame, i.e.
    ``q1 + q2 = pi/2 + theta + theta1(u1) - psi0(u0)`` with ``theta1 = atan2(X', Y')`` and
    ``psi0 = atan2(X0', Y0')``. Contact: ``Om = O01 + Rot(pi/2-q1-q2) c0 - Rot(-theta) c1``.
    """
    p = scene.params
    f0 = scene.fingertip.evaluate(scene.u0_0)
    f1 = scene.object.evaluate(scene.u1_0)
    theta1 = math.atan2(float(f1["dx"]), float(f1["dy"]))
    psi0 = math.atan2(float(f0["dx"]), float(f0["dy"]))
    q1, th = scene.q1_0, scene.theta_0
    q2 = math.pi / 2 + th + theta1 - psi0 - q1
    o01 = np.array([
        p["l11"] * math.sin(q1) + p["l12"] * math.sin(q1 + q2),
        p["l11"] * math.cos(q1) + p["l12"] * math.cos(q1 + q2),
    ])
    c0 = np.array([float(f0["x"]), float(f0["y"])])
    c1 = np.array([float(f1["x"]), float(f1["y"])])
    om = o01 + _rot(math.pi / 2 - q1 - q2, c0) - _rot(-th, c1)
    return q2, (float(om[0]), float(om[1]))


def extra_finger_configuration(scene: PlanarFingerScene, finger: ExtraFinger) -> tuple[float, float, float]:
    """``(q1, q2, u0)`` of an extra finger touching the object at ``finger.u1_0`` at the start.

    Tangency fixes ``q1 + q2 = pi/2 + theta + theta1(u1) - psi0(u0)`` (as for finger 1); the
    fingertip centre is then ``O = P - Rot(pi/2 - q1 - q2) c0(u0)`` with ``P`` the object's
    contact point, and the arm reaches it iff ``|O - base - l2 d(q1 + q2)| = l1``: one equation
    in ``u0``: every root on the fingertip's domain is bracketed, the one nearest ``u0_0`` is
    taken; ``q1`` follows.
    """
    om = np.array(scene.pivot)
    th = scene.theta_0
    f1 = scene.object.evaluate(finger.u1_0)
    theta1 = math.atan2(float(f1["dx"]), float(f1["dy"]))
    P = om + _rot(-th, np.array([float(f1["x"]), float(f1["y"])]))
    l1, l2 = finger.lengths
    base = np.array(finger.base, float)

    def reach(u0: float):
        f0 = finger.fingertip.evaluate(u0)
        phi = math.pi / 2 + th + theta1 - math.atan2(float(f0["dx"]), float(f0["dy"]))
        o_tip = P - _rot(math.pi / 2 - phi, np.array([float(f0["x"]), float(f0["y"])]))
        w = o_tip - base - l2 * np.array([math.sin(phi), math.cos(phi)])
        return w, phi

    def gap(u0: float) -> float:
        w, _ = reach(u0)
        return float(np.hypot(*w) - l1)

    # every root of the reach equation on the fingertip's domain; the one nearest u0_0
    lo, hi = finger.fingertip.domain
    grid = np.linspace(lo, hi, 721)
    vals = np.array([gap(u) for u in grid])
    roots = [_bisect(gap, a, b, fa) for a, b, fa, fb in zip(grid[:-1], grid[1:], vals[:-1], vals[1:])
             if fa * fb <= 0]
    if not roots:
        raise InvalidSceneError([
            f"an extra finger based at {finger.base} cannot touch the object at u1 = {finger.u1_0} "
            f"with any point of its fingertip (the arm's reach misses by at least {np.min(np.abs(vals)):.3g} m): "
            "move its base or the contact point"])
    u0 = min(roots, key=lambda u: abs(u - finger.u0_0))
    w, phi = reach(u0)
    q1 = math.atan2(w[0], w[1])
    return q1, phi - q1, u0


def _bisect(f, a: float, b: float, fa: float) -> float:
    """The root of ``f`` bracketed by ``[a, b]`` (``f(a) = fa``), by bisection to the last
    representable midpoint (at most ~60 halvings): no SciPy import (0.15 s) on a build's path."""
    if fa == 0.0:
        return a
    while True:
        m = 0.5 * (a + b)
        if m <= a or m >= b:
            return m
        fm = f(m)
        if fm == 0.0:
            return m
        if (fm < 0) == (fa < 0):
            a, fa = m, fm
        else:
            b = m
