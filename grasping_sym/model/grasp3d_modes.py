"""A 3D grasp whose contacts each roll, slide or separate: the grasp scene with modes.

``with_modes(scene, planes=...)`` on a ``model.grasp3d.GraspScene3D`` (regular formulation)
gives the scene of kind ``"grasp3d_modes"``: the same fingers, object, start and controller,
and planes of the world the object may touch (a table, a wall, fixed, translated or
turned by given functions of time: ``WorldPlane``; one finger and a plane may hold a free
object),
compiled once with every contact's mode a run-time parameter (``derive.grasp3d_modes``), run
by ``runtime.modes`` (``docs/conventions.md`` section 9). Contacts are the fingers' first,
then the planes'. The state is the base scene's, then each plane's support point ``(u, v)``
on the object's surface (where its normal is minus the plane's).
"""
from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass, field
from typing import ClassVar

import numpy as np
import sympy as sp

from grasping_sym.errors import InvalidSceneError
from grasping_sym.geometry.atlas import manifest_entry
from grasping_sym.model.body import rate_of_time, translation_of_time
from grasping_sym.model.grasp3d import GraspScene3D
from grasping_sym.model.with_modes import WithModes

#: The contacts' modes, by the number the compiled model takes as its parameter ``mode{i}``.
MODES = ("rolling", "sliding", "separated")


@dataclass(frozen=True)
class WorldPlane:
    """A fixed plane of the world: a point on it and its unit normal (into the free half-space)
    (m, world); ``support``: a guess of the object's surface coordinates facing it at the start."""

    point: tuple[float, float, float]
    normal: tuple[float, float, float]
    support: tuple[float, float] = (0.0, 0.0)
    #: the plane's translation ``d(t)`` (as ``model.body.BodyScene.plane_motion``); None: fixed
    motion: tuple | None = None
    #: its turning rate ``w(t)`` (rad/s, about its normal through ``point + d(t)``: a
    #: turntable); None: it does not turn
    spin: object = None

    def __post_init__(self) -> None:
        object.__setattr__(self, "point", tuple(float(v) for v in np.ravel(self.point)))
        object.__setattr__(self, "normal", tuple(float(v) for v in np.ravel(self.normal)))
        object.__setattr__(self, "support", tuple(float(v) for v in np.ravel(self.support)))
        p = []
        if len(self.point) != 3 or not all(math.isfinite(v) for v in self.point):
            p.append(f"plane point {self.point} must be three finite numbers (m)")
        if len(self.normal) != 3 or not abs(math.hypot(*self.normal) - 1) < 1e-12:
            p.append(f"plane normal {self.normal} must be a unit vector (to 1e-12)")
        if len(self.support) != 2 or not all(math.isfinite(v) for v in self.support):
            p.append(f"support {self.support} must be two finite numbers (a guess of (u, v))")
        motion, problems = translation_of_time(self.motion, "plane motion")
        object.__setattr__(self, "motion", motion)
        p += problems
        spin, problems = rate_of_time(self.spin, "plane spin")
        object.__setattr__(self, "spin", spin)
        p += problems
        if p:
            raise InvalidSceneError(p)


#: 1/s, the constraint stabilisation of a grasp with modes whose base has none (``gain = 0``,
#: the base's runs project): the runs of a model with modes do not project, so its rolling,
#: sliding and touching contacts are held by ``C'' + 2 g C' + g^2 C = 0`` (paper3d's former gain).
MODES_GAIN = 300.0


@dataclass(frozen=True, eq=False)
class GraspModesScene(WithModes):
    """``base`` with its contacts' modes and the world's ``planes`` (module docstring)."""

    base: GraspScene3D
    planes: tuple[WorldPlane, ...] = field(default=())

    kind: ClassVar[str] = "grasp3d_modes"
    dimension: ClassVar[int] = 3
    simulate_defaults: ClassVar[dict] = {"t_final": 1.0, "method": "radau",
                                         "tolerances": {}}

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
        if b.gain == 0:  # the modes' runs do not project: their constraints need the gain
            object.__setattr__(self, "base", dataclasses.replace(b, gain=MODES_GAIN))
        object.__setattr__(self, "planes", tuple(self.planes))
        if any(not isinstance(w, WorldPlane) for w in self.planes):
            problems.append("planes must be gs.scenes.world_plane(point, normal) values")
        elif b.friction is not None and isinstance(b.friction.mu, tuple) \
                and len(b.friction.mu) != b.n_contacts + len(self.planes):
            problems.append(f"the friction law has {len(b.friction.mu)} mu for {b.n_contacts + len(self.planes)} "
                            "contacts (the fingers', then the planes'): give one per contact, or one for all")
        if problems:
            raise InvalidSceneError(problems)

    # ------------------------------------------------------------------ the base's parts

    @property
    def n_contacts(self) -> int:
        return self.base.n_contacts + len(self.planes)

    @property
    def n_fingers(self) -> int:
        return self.base.n_contacts


    @property
    def start_param_names(self) -> tuple[str, ...]:
        return self.base.start_param_names

    @property
    def runtime(self) -> tuple[str, ...]:
        n = range(1, self.n_contacts + 1)
        return (*[f"mode{i}" for i in n], *[f"slip_{c}{i}" for i in n for c in ("x", "y", "onset")],
                *[f"mu{i}" for i in n])

    @property
    def params(self) -> dict[str, float]:
        mus = self.friction.per_contact(self.n_contacts) if self.friction is not None \
            else (math.inf,) * self.n_contacts
        out = dict(self.base.params)
        for i, mu in enumerate(mus, start=1):
            out.update({f"mode{i}": 0.0, f"slip_x{i}": 1.0, f"slip_y{i}": 0.0, f"slip_onset{i}": 0.0,
                        f"mu{i}": min(mu, 1e300)})
        return out

    @property
    def state_names(self) -> tuple[str, ...]:
        return (*self.base.state_names,
                *[f"{c}_w{m}" for m in range(1, len(self.planes) + 1) for c in "uv"])

    @property
    def p_names(self) -> tuple[str, ...]:
        return (*self.runtime, *self.start_param_names, *self.chart_names)

    def plane_charts(self) -> tuple[str, ...]:
        """The charts of the planes' support points on an object with an atlas (``chart_w{m}``:
        its ``(u_w{m}, v_w{m})``, no frame angle); 0 at the start unless a support point was
        solved in chart 1; none on an object without one."""
        if getattr(self.base.object_surface, "atlas", None) is None:
            return ()
        return tuple(f"chart_w{m}" for m in range(1, len(self.planes) + 1))

    @property
    def chart_names(self) -> tuple[str, ...]:
        """The base grasp's charts (``GraspScene3D.chart_slots``), then the planes'."""
        return (*self.base.chart_names, *self.plane_charts())

    def atlas_manifest(self) -> dict:
        """The base grasp's (``GraspScene3D.atlas_manifest``), a fingertip's entry naming the
        contact whose slip is in its frame (``slip_frame``: turned with it at a switch), and
        the planes' support points'."""
        entries = [{**e, "slip_frame": int(e["param"][len("chart_f"):])}
                   if (e["param"] or "").startswith("chart_f") else e
                   for e in self.base.atlas_manifest().get("atlas", [])]
        for m in range(1, len(self.planes) + 1):
            entry = manifest_entry(self.base.object_surface, f"chart_w{m}", f"u_w{m}", f"v_w{m}", None)
            entries += [] if entry is None else [entry]
        if not entries:
            return {}
        return {**({"chart_param_names": list(self.chart_names)} if self.chart_names else {}), "atlas": entries}

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
        per = ("f", "lam", "eta", "gap", "normal_speed", "normal_acceleration",
               "normal_force", "tangential_force", "cone_ratio", "vt_x", "vt_y", "slip_speed", "onset_left",
               "painleve", "at_x", "at_y", "vn_fixed")
        return ("constraint_residual", *[f"{q}{i}" for i in n for q in per],
                *[f"krel_min{i}" for i in range(1, self.n_fingers + 1)],
                "orthonormality", "quat_norm_error", "kinetic_energy", "potential_energy", "power",
                "object_speed", "object_angular_speed",
                *[f"W_{r}_{c}" for r in range(3 * k) for c in range(r, 3 * k)],
                *[f"MinvAT_{j}_{r}" for r in range(3 * k) for j in range(self.n_speeds)])

    def check_outputs(self) -> tuple[str, ...]:
        return self.outputs

    def internal_outputs(self) -> tuple[str, ...]:
        """The outputs only a switch reads (the impulse's ``W = A M^-1 A^T`` and ``M^-1 A^T``):
        compiled, not shown (``pipeline.with_check_outputs``)."""
        return tuple(k for k in self.outputs if k.startswith(("W_", "MinvAT_")))

    def code_key(self) -> str:
        return "\n".join(["grasp3d-modes-v2", self.base.code_key(),
                          *[repr((w.point, w.normal, None if w.motion is None else tuple(map(sp.srepr, w.motion)),
                                  None if w.spin is None else sp.srepr(w.spin)))
                            for w in self.planes]])

    def key(self) -> str:
        """The code's key (the planes' motions too: a driven plane's place at the start moves
        the start), the base's whole definition and the planes' supports."""
        return "\n".join([self.code_key(), self.base.key(),
                          *[repr(w.support) for w in self.planes]])

    def rolling_map(self) -> dict | None:
        """``WithModes.rolling_map``: None with planes of the world (the rolling model has no
        gap to them to watch), or with atlases, repeating charts too (a chart switch is the
        model with modes' to make, in its own ``p``)."""
        return None if self.planes or self.base.atlas_manifest() else super().rolling_map()

    def manifest_extra(self) -> dict:
        """The kind, that ``simulate`` runs the modes (``runtime.modes``), where the speeds are,
        how the base's rolling model runs the stretches where every contact rolls."""
        return {"kind": self.kind, "modes": list(MODES), "n_contacts": self.n_contacts,
                "rolling_map": self.rolling_map(), "folded_modes": list(self.folded_modes()),
                "grasp_modes": {"speeds": [self.speeds_offset, self.n_speeds], "fingers": self.n_fingers,
                                "driven": [self.n_fingers + m for m, w in enumerate(self.planes, start=1)
                                           if w.motion is not None or w.spin is not None]},
                "param_rules": {f"mu{i}": "nonnegative" for i in range(1, self.n_contacts + 1)},
                **({"joint_limits": list(self.base.joint_limits())} if self.base.joint_limits() else {}),
                **self.atlas_manifest()}

    def bounds(self) -> tuple[list, list]:
        lower, upper = self.base.bounds()
        (u0, u1), (v0, v1) = self.base.object_surface.domain
        for _ in self.planes:
            lower, upper = [*lower, u0, v0], [*upper, u1, v1]
        return lower, upper


def with_modes(scene: GraspScene3D, planes=()) -> GraspModesScene:
    """``scene`` whose contacts roll, slide or separate, with the world's ``planes`` (module
    docstring)."""
    return GraspModesScene(scene, tuple(planes))

