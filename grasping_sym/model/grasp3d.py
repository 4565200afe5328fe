"""The 3D scene: fingers with smooth fingertips grasp an object with a smooth surface.

What a scene *is* (no derivation here): the finger chains (``model.chains``) with their
fingertip surfaces, the object's surface, mass and inertia, whether the object is free or
turns about a fixed pivot, gravity, the grasp controller's constants, the formulation of the
contact tracking and the outputs to generate. ``derive.grasp3d`` turns it into equations,
``derive.initial3d`` solves its consistent start.

Frames and units: SI; the inertial frame O-xyz; the object frame Om-XYZ has its origin at the
object's mass centre (free) or at the pivot (pivoted); the object's surface, mass centre and
inertia are given in it. The fingertip surface of finger ``i`` is given in the fingertip frame
``Pi_i`` of its chain.

Controller (no object information; ``derive.grasp3d``)::

    u_i = dP_i/dq_i - c q_i' - J_i^T [ (fd / r_ctrl) (r_i - r_j) + (k_center / N) (r_bar - r_bar(0)) ]

``r_i`` the fingertip centres, ``r_bar`` their mean. The first term cancels the finger's own
weight (only when gravity is modelled), the second is joint damping, the third the pull of the
fingertip centres toward each other (the 3D counterpart of the 2D law (32); ONE finger pulls
toward a fixed point: the pivot, as in 2D, or a free object's given ``position``, the object
then held against a plane of the world, ``with_modes``), the last a spring on the grasp's centre. The pull is an
internal force: the two fingertip forces sum to zero, so with gravity alone nothing carries
the object's weight and a grasp under gravity slides down until the fingers are stretched.
The centre spring (N/m) carries it: the object sags by about ``m g / k_center`` and is held.
It uses no object information (only the fingertip centres).
"""
from __future__ import annotations

import math
import numbers
from dataclasses import dataclass, field
from typing import ClassVar

import numpy as np

from grasping_sym.contact import Coulomb, friction_problems
from grasping_sym.errors import InvalidSceneError
from grasping_sym.geometry.atlas import manifest_entry
from grasping_sym.geometry.surfaces import ParametricSurface
from grasping_sym.model.chains import FingerChain, without_limits
from grasping_sym.model.control import PAPER, coefficient_names, control_problems
from grasping_sym.model.control import input_names as _input_names
from grasping_sym.model.inertia import inertia_pattern
from grasping_sym.names import name_problems, names_tuple, output_problems

FORMULATIONS = ("regular", "paper")
SUPPORTS = ("free", "pivot")

#: Parameters that may be kept as run-time inputs (controller and stabilisation only; the
#: bodies fix the initial configuration).
RUNTIME_ALLOWED = ("fd", "c", "k_center", "gain")

#: 1/s, the constraint stabilisation of the paper's formulation by default (``gain`` None);
#: the regular formulation's is 0, its runs projecting instead.
PAPER_GAIN = 300.0

#: Outputs a 3D model can generate; ``{i}`` is the contact (finger) number 1..N.
OUTPUTS: dict[str, str] = {
    "constraint_residual": "m, largest |Qn|, |Qb|, |Qe| over the contacts",
    "f{i}": "N, normal multiplier of contact i (> 0 presses)",
    "lam{i}": "N, tangential multiplier of contact i along x_f",
    "eta{i}": "N, tangential multiplier of contact i along y_f",
    "krel_min{i}": "1/m, smaller eigenvalue of the relative curvature K_f + K~_o at contact i",
    "orthonormality": "max |R^T R - I| of the object's rotation matrix",
    "quat_norm_error": "|quat| - 1",
    "kinetic_energy": "J",
    "potential_energy": "J, gravity of the object and the fingers",
    "power": "W, sum q_i' . u_i (the controller's power) minus the spin friction's dissipation",
    "object_speed": "m/s, |v| of the mass centre (0 for a pivoted object)",
    "object_angular_speed": "rad/s, |omega|",
    "frame_denominator{i}": "rad/s, the paper formulation's omega0.e0 + omega1.e1 (0/0 at rest)",
    "frame_orthonormality": "max |Psi^T Psi - I| of the paper formulation's frames",
}


def start_note(surface) -> str:
    """What a contact's start may be on ``surface`` beyond its domain (``start_inside``), for
    the messages that refuse one: on an atlas, chart 0 off its poles; else nothing."""
    return "" if surface.atlas is None else (
        " (on a surface with an atlas: chart 0's longitude, and a latitude strictly inside "
        "+-pi/2, off its poles, where chart 0 still has coordinates: the start moves a contact "
        "beyond +-1.3 into chart 1)")


def start_inside(surface, uv) -> bool:
    """Whether a contact's start (its guess, or the solved point) ``uv`` lies where the start
    can take it: the surface's domain; on a surface with an atlas (``geometry.atlas``) chart 0
    anywhere off its poles (``|v| < pi/2``; the start carries a contact beyond its latitudes
    into chart 1)."""
    if surface.atlas is None:
        return surface.in_domain(*uv)
    (u0, u1), _ = surface.domain
    u, v = (float(a) for a in uv)
    return u0 <= u <= u1 and abs(v) < 0.5 * math.pi


@dataclass(frozen=True)
class Finger3D:
    """A finger chain and its fingertip surface (in the chain's fingertip frame)."""

    chain: FingerChain
    tip: ParametricSurface
    q0: tuple[float, ...]                      # rad, joint angles: a guess of the start
    tip_contact: tuple[float, float]           # (u_f, v_f): a guess of the fingertip contact
    object_contact: tuple[float, float]        # (u_o, v_o): the object point to touch


@dataclass(frozen=True)
class GraspScene3D:
    """A 3D grasping scene (every value documented by ``scenes.paper3d``).

    Parameters
    ----------
    fingers
        One or more :class:`Finger3D`.
    object_surface
        The object's surface in its frame (m).
    mass, inertia
        kg; kg m^2, the 3x3 inertia about the object frame's origin in its axes.
    support
        ``'free'`` (6 DOF, position of the mass centre and orientation) or ``'pivot'`` (the
        object turns about its frame's origin, fixed at ``position``).
    position, rotation
        m, 3x3: the object's pose at the start (a guess: the consistent start moves it).
    gravity
        m/s^2, world vector, or None for a horizontal scene (no gravity terms generated).
    fd, c, r_ctrl, k_center
        N; N m s; m; N/m: the controller (module docstring).
    spin_damping
        N m s, torsional friction at each contact: a twist torque ``-spin_damping (n . w_rel)``
        about the normal (a soft finger's); 0 is the paper's rigid contact, where a spin of
        the object about the line through two contacts is resisted by nothing.
    gain
        1/s, constraint stabilisation: ``C'' + 2 g C' + g^2 C = 0`` (critically damped); 0:
        none in the equations, the runs project onto the constraints after every step instead
        (``simulate``'s ``project``, on by default for such a scene: the fastest reliable run,
        ``simulate_defaults``; in the paper's formulation the projection onto the velocity
        constraints fails by name, their Jacobian on the speeds singular: at paper3d's start
        already). None (the default): 0 in the regular formulation, ``PAPER_GAIN`` in the
        paper's.
    dq0
        rad/s, joint speeds wished at the start (all fingers, in order); the start uses the
        admissible motion closest to them in kinetic energy (None: rest).
    formulation
        ``'regular'`` (surface coordinates and frame angle, regular at rest: default) or
        ``'paper'`` (the paper's moving frames, (Es), (Efs), (31)-(32)).
    outputs
        Names from :data:`OUTPUTS` (``{i}`` expanded), only those are generated.
    runtime
        Parameters from :data:`RUNTIME_ALLOWED` kept as inputs of the compiled code.
    """

    name: str
    fingers: tuple[Finger3D, ...]
    object_surface: ParametricSurface
    mass: float
    inertia: tuple[tuple[float, float, float], ...]
    support: str = "free"
    position: tuple[float, float, float] = (0.0, 0.0, 0.0)
    rotation: tuple[tuple[float, float, float], ...] = ((1.0, 0.0, 0.0), (0.0, 1.0, 0.0), (0.0, 0.0, 1.0))
    gravity: tuple[float, float, float] | None = None
    fd: float = 0.5
    c: float = 0.006
    r_ctrl: float = 0.010
    k_center: float = 0.0
    gain: float | None = None
    spin_damping: float = 0.0
    formulation: str = "regular"
    dq0: tuple[float, ...] | None = None
    outputs: tuple[str, ...] = ()
    runtime: tuple[str, ...] = ()
    controller: object = PAPER
    inputs: str | None = None
    #: Coulomb friction at the contacts (``gs.contact.coulomb``): read at run time only, so it
    #: is in no cache key; None: no friction limit
    friction: Coulomb | None = None
    problems: tuple[str, ...] = field(default=(), repr=False)

    #: The scene's kind (``model.kinds``: every floor above asks it, never the dimension).
    kind: ClassVar[str] = "grasp3d"
    #: The scene's dimension: 2 or 3 (what a drawing of it has).
    dimension: ClassVar[int] = 3

    def __post_init__(self) -> None:
        if self.gain is None:
            object.__setattr__(self, "gain", 0.0 if self.formulation == "regular" else PAPER_GAIN)
        object.__setattr__(self, "fingers", tuple(self.fingers))
        object.__setattr__(self, "outputs", names_tuple(self.outputs))
        object.__setattr__(self, "runtime", tuple(self.runtime))
        object.__setattr__(self, "inertia", _matrix(self.inertia))
        object.__setattr__(self, "rotation", _matrix(self.rotation))
        problems = self._problems()
        if problems:
            raise InvalidSceneError(problems)

    # ------------------------------------------------------------------ validation
    def _problems(self) -> list[str]:
        p: list[str] = name_problems(self.name) + control_problems(self.controller, self.inputs)
        if not self.fingers:
            p.append("no fingers: give at least one Finger3D")
        for i, f in enumerate(self.fingers, start=1):
            if len(f.q0) != f.chain.n:
                p.append(f"finger {i}: q0 has {len(f.q0)} angles, the chain has {f.chain.n} joints")
            if not start_inside(f.tip, f.tip_contact):
                p.append(f"finger {i}: tip_contact {f.tip_contact} is outside the fingertip's domain "
                         f"{f.tip.domain}{start_note(f.tip)}")
            if not start_inside(self.object_surface, f.object_contact):
                p.append(f"finger {i}: object_contact {f.object_contact} is outside the object's "
                         f"domain {self.object_surface.domain}{start_note(self.object_surface)}")
        for label, values in (("position", self.position), ("dq0", self.dq0 or ()),
                              *[(f"finger {i}: q0", f.q0) for i, f in enumerate(self.fingers, 1)],
                              *[(f"finger {i}: tip_contact", f.tip_contact)
                                for i, f in enumerate(self.fingers, 1)],
                              *[(f"finger {i}: object_contact", f.object_contact)
                                for i, f in enumerate(self.fingers, 1)]):
            if not all(_number(v) for v in values):
                p.append(f"{label} = {tuple(values)!r} must hold finite numbers")
        if self.dq0 is not None and len(self.dq0) != sum(f.chain.n for f in self.fingers):
            p.append(f"dq0 has {len(self.dq0)} speeds; the fingers have "
                     f"{sum(f.chain.n for f in self.fingers)} joints")
        names = [f.chain.name for f in self.fingers]
        if len(set(names)) != len(names):
            p.append(f"finger chains share names {names}: give each a distinct name")
        for k in ("mass", "fd", "c", "r_ctrl"):
            v = getattr(self, k)
            if not (_number(v) and v > 0):
                p.append(f"{k} = {v!r} must be a finite number > 0")
        if not (isinstance(self.gain, (int, float)) and math.isfinite(self.gain) and self.gain >= 0):
            p.append(f"gain = {self.gain!r} must be a finite number >= 0 (1/s; 0: no stabilisation, "
                     "e.g. with simulate(project=True))")
        if not (math.isfinite(self.spin_damping) and self.spin_damping >= 0):
            p.append(f"spin_damping = {self.spin_damping!r} must be finite and >= 0 (N m s)")
        if not (math.isfinite(self.k_center) and self.k_center >= 0):
            p.append(f"k_center = {self.k_center!r} must be finite and >= 0 (N/m)")
        H = np.asarray(self.inertia, float)
        if H.shape != (3, 3) or not np.all(np.isfinite(H)) or not np.allclose(H, H.T) \
                or np.linalg.eigvalsh(0.5 * (H + H.T)).min() <= 0:
            p.append(f"inertia {self.inertia} must be a symmetric positive definite 3x3 matrix (kg m^2)")
        R = np.asarray(self.rotation, float)
        if R.shape != (3, 3) or not np.allclose(R.T @ R, np.eye(3), atol=1e-12) or np.linalg.det(R) < 0:
            p.append("rotation must be a proper rotation matrix (R^T R = I to 1e-12, det +1)")
        if self.support not in SUPPORTS:
            p.append(f"support {self.support!r} unknown: choose one of {SUPPORTS}")
        if self.formulation not in FORMULATIONS:
            p.append(f"formulation {self.formulation!r} unknown: choose one of {FORMULATIONS}")
        elif self.chart_names and self.formulation != "regular":
            p.append("a surface with an atlas (atlas=True) needs formulation='regular': the paper "
                     "formulation's frames have no angle psi to carry across charts")
        if self.gravity is not None and (len(self.gravity) != 3
                                         or not all(math.isfinite(g) for g in self.gravity)):
            p.append(f"gravity {self.gravity!r} must be three finite numbers (m/s^2) or None")
        for k in self.runtime:
            if k not in RUNTIME_ALLOWED:
                p.append(f"runtime parameter {k!r} not allowed: choose from {RUNTIME_ALLOWED}")
        p += output_problems(self.outputs, self.output_catalogue())
        p += friction_problems(self.friction, len(self.fingers))
        return p

    # ------------------------------------------------------------------ names
    @property
    def n_contacts(self) -> int:
        return len(self.fingers)

    def output_catalogue(self) -> tuple[str, ...]:
        """Every output this scene can generate (``{i}`` expanded)."""
        out = []
        for k in OUTPUTS:
            if "{i}" in k:
                if k.startswith("frame_denominator") and self.formulation != "paper":
                    continue
                out += [k.format(i=i) for i in range(1, self.n_contacts + 1)]
            elif k == "frame_orthonormality" and self.formulation != "paper":
                continue
            else:
                out.append(k)
        return tuple(out)

    def check_outputs(self) -> tuple[str, ...]:
        """The outputs ``runtime.checks`` reads, compiled whatever ``outputs`` asks for (the
        model does not show those the user did not ask for): the constraints
        (``constraint_residual``), every contact's normal and tangential forces (its friction
        cone, ``runtime.friction``) and relative curvature (``f{i}``, ``lam{i}``, ``eta{i}``,
        ``krel_min{i}``) and, in the paper formulation, its frame denominator
        (``frame_denominator{i}``)."""
        n = range(1, self.n_contacts + 1)
        paper = [f"frame_denominator{i}" for i in n] if self.formulation == "paper" else []
        return ("constraint_residual", *[f"f{i}" for i in n],
                *[k for i in n for k in (f"lam{i}", f"eta{i}")], *[f"krel_min{i}" for i in n],
                *paper)

    @property
    def free(self) -> bool:
        return self.support == "free"

    @property
    def joint_names(self) -> tuple[str, ...]:
        return tuple(n for f in self.fingers for n in f.chain.joint_names)

    @property
    def state_names(self) -> tuple[str, ...]:
        """Positions, speeds, then the contact states of each contact."""
        q = list(self.joint_names)
        pos = q + (["x", "y", "z"] if self.free else []) + ["qw", "qx", "qy", "qz"]
        vel = ["d" + n for n in q] + (["vx", "vy", "vz"] if self.free else []) + ["omegaX", "omegaY", "omegaZ"]
        return tuple(pos + vel + [n for i in range(1, self.n_contacts + 1) for n in self.contact_state_names(i)])

    def contact_state_names(self, i: int) -> tuple[str, ...]:
        base = (f"u_f{i}", f"v_f{i}", f"u_o{i}", f"v_o{i}")
        if self.formulation == "regular":
            return (*base, f"psi{i}")
        return (*base, f"s{i}", *(f"Psi0{i}_{k}" for k in range(9)), *(f"Psi1{i}_{k}" for k in range(9)))

    @property
    def params(self) -> dict[str, float]:
        return {"fd": self.fd, "c": self.c, "k_center": self.k_center, "gain": self.gain}

    def code_key(self) -> str:
        """Canonical text of what the generated code depends on.

        The start -- the guesses ``rotation``, ``q0``, ``tip_contact``, ``object_contact``,
        ``dq0`` and, for a free object, ``position`` -- is not in it: it enters the code
        through the run-time rest point of the centre spring (``start_param_names``), and
        through the law where the law reads it (one finger's ``position0``: then in the
        controller's key, ``assemble.controller.controller_key``).
        """
        parts = ["grasp3d-v2", self.name, self.support, self.formulation, repr(self.mass),
                 repr(self.inertia), repr(None if self.free else self.position), repr(self.gravity),
                 repr(self.params), repr(self.r_ctrl), repr(self.spin_damping), ",".join(self.outputs),
                 ",".join(self.runtime), self.object_surface.key(), f"inputs={self.inputs}"]
        for f in self.fingers:
            parts += [repr(f.chain), f.tip.key()]
        return "\n".join(parts)

    @property
    def input_names(self) -> tuple[str, ...]:
        """The control inputs (``model.control``): ``u1, u2, ...`` per joint, or none."""
        return _input_names(self.inputs, len(self.joint_names))

    @property
    def p_names(self) -> tuple[str, ...]:
        """Every entry of the compiled functions' ``p``: the run-time parameters, the start's
        values, the inputs' coefficients, the charts (``chart_names``)."""
        return (*self.runtime, *self.start_param_names, *coefficient_names(self.input_names),
                *self.chart_names)

    def chart_slots(self) -> tuple[tuple[int, str, str], ...]:
        """``(slot, parameter, side)`` of each contact surface with an atlas
        (``geometry.atlas``): contact ``i``'s fingertip (slot ``2 (i - 1)``, parameter
        ``chart_f{i}``, side ``f``), the object there (``2 i - 1``, ``chart_o{i}``, ``o``). The
        chart is a parameter the run sets (``runtime.atlas``), 0 at the start unless the contact
        lies beyond chart 0's latitudes (``assemble.kinds``)."""
        out = []
        for i, f in enumerate(self.fingers, 1):
            for slot, side, surface in ((2 * i - 2, "f", f.tip), (2 * i - 1, "o", self.object_surface)):
                if getattr(surface, "atlas", None) is not None:
                    out.append((slot, f"chart_{side}{i}", side))
        return tuple(out)

    @property
    def chart_names(self) -> tuple[str, ...]:
        return tuple(name for _, name, _ in self.chart_slots())

    def atlas_manifest(self) -> dict:
        """The manifest's charts: their parameters' names, and what the run time reads to map
        a contact across them (``runtime.atlas``), a repeating chart's entries (no parameter)
        among them in the same order (contact by contact, fingertip then object)."""
        entries = []
        for i, f in enumerate(self.fingers, 1):
            for side, surface in (("f", f.tip), ("o", self.object_surface)):
                psi = f"psi{i}" if f"psi{i}" in self.state_names else None   # the paper's: none
                entry = manifest_entry(surface, f"chart_{side}{i}", f"u_{side}{i}", f"v_{side}{i}", psi)
                entries += [] if entry is None else [entry]
        if not entries:
            return {}
        return {**({"chart_param_names": list(self.chart_names)} if self.chart_names else {}), "atlas": entries}

    def structure_key(self) -> str:
        """What the code depends on besides the scene's name and its surfaces: the text of
        its structure layer (``codegen.structure3d``). Joint limits are not in it: they are
        bounds the run checks (``bounds``), not equations; nor the object's mass and inertia
        (inputs of the structure: only the inertia's pattern, diagonal or full, is)."""
        parts = ["grasp3d-v4", self.support, self.formulation, inertia_pattern(self.inertia),
                 repr(None if self.free else self.position), repr(self.gravity),
                 repr(self.gain), repr(self.spin_damping), ",".join(self.outputs),
                 ",".join(self.runtime), repr(self.start_param_names),
                 *[repr(without_limits(f.chain)) for f in self.fingers]]
        return "\n".join(parts)

    def key(self) -> str:
        """Canonical text of the whole definition: the code's and the start's."""
        parts = [self.code_key(), repr(self.position), repr(self.rotation), repr(self.dq0)]
        for f in self.fingers:
            parts += [repr(f.q0), repr(f.tip_contact), repr(f.object_contact)]
        return "\n".join(parts)

    @property
    def start_param_names(self) -> tuple[str, ...]:
        """Run-time parameters that the start fixes: the rest point ``r_bar0`` (m, world) of
        the controller's centre spring, when the scene has one."""
        if self.k_center > 0 or "k_center" in self.runtime:
            return ("r_bar0_x", "r_bar0_y", "r_bar0_z")
        return ()


    def rolling_problems(self) -> list[str]:
        """What stops this scene's rolling model (kind ``"grasp3d"``, every contact held):
        one finger alone cannot hold a free object; with a surface of the world it can, as
        contacts that may slide and let go (``with_modes``)."""
        if self.free and len(self.fingers) < 2:
            return ["a free object held by one finger needs a surface of the world to rest on: "
                    "gs.scenes.with_modes(scene, planes=[gs.scenes.world_plane(point, normal)]); "
                    "or use support='pivot' with one finger"]
        return []

    # ------------------------------------------------------------------ scene protocol
    @property
    def simulate_defaults(self) -> dict:
        """dop853 (1.8 to 2.9 times faster than radau at every rtol from 1e-3 to 1e-11 on
        paper3d at the same final-state error, benchmarks/results/tolerances.md; a scene too
        stiff for it falls back to radau, ``Model.simulate``); with ``gain = 0`` (the default)
        the runs project onto the constraints after every step (``project``), which holds
        them without the stiffness the gain brings: paper3d's 3 s run takes 81 steps where
        the gain 300 1/s takes 306 (``benchmarks/results/defaults3d.md``); so do the runs of
        a model whose gain is a run-time parameter (it may be 0 in a run)."""
        # a run-time gain may be 0 in a run: such a model projects too (harmless with a gain)
        return {"t_final": 5.0, "method": "dop853", "project": self.gain == 0 or "gain" in self.runtime,
                "tolerances": {"dop853": (1e-7, 1e-9), "radau": (1e-6, 1e-9)}}

    def manifest_extra(self) -> dict:
        """What a 3D scene adds to its manifest: its formulation; the rule each run-time
        parameter's value must meet (``Model.params`` checks it)."""
        return {"kind": "grasp3d", "formulation": self.formulation,
                "param_rules": {k: "positive" if k in ("fd", "c") else "nonnegative"
                                for k in self.runtime},
                **({"joint_limits": list(self.joint_limits())} if self.joint_limits() else {}),
                **self.atlas_manifest()}

    def joint_limits(self) -> dict[str, tuple[float, float]]:
        """rad, ``{joint state name: (lower, upper)}`` of every joint that has limits."""
        return {name: joint.limits
                for f in self.fingers
                for name, joint in zip(f.chain.joint_names, f.chain.joints)
                if joint.limits is not None}

    def bounds(self) -> tuple[list, list]:
        """Per-state bounds (None: unbounded): the surface coordinates of each contact stay
        inside their surfaces' domains, and each joint with ``limits`` inside them (the
        manifest's ``joint_limits`` names those joints: the run-time checks stop there with
        ``JointLimitError``)."""
        lower: list = [None] * len(self.state_names)
        upper: list = [None] * len(self.state_names)
        for name, (lo, hi) in self.joint_limits().items():
            k = self.state_names.index(name)
            lower[k], upper[k] = lo, hi
        for i, f in enumerate(self.fingers, start=1):
            for name, (lo, hi) in ((f"u_f{i}", f.tip.domain[0]), (f"v_f{i}", f.tip.domain[1]),
                                   (f"u_o{i}", self.object_surface.domain[0]),
                                   (f"v_o{i}", self.object_surface.domain[1])):
                k = self.state_names.index(name)
                lower[k], upper[k] = lo, hi
        return lower, upper


def _matrix(m) -> tuple[tuple[float, float, float], ...]:
    a = np.asarray(m, dtype=float)
    if a.shape == (3,):
        a = np.diag(a)
    return tuple(tuple(float(x) for x in row) for row in a)


def _number(v) -> bool:
    """A finite real number (``True`` is not one)."""
    return isinstance(v, numbers.Real) and not isinstance(v, (bool, np.bool_)) and math.isfinite(v)
