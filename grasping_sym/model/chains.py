"""Declarative spatial finger chains: revolute joints given by their axes (3D model, issue 3).

Frames (all right-handed, SI units):

- inertial frame O-xyz; gravity of the 3D scene along -y (docs/conventions.md section 2);
- link ``k`` (k = 1..n) of a chain has the frame ``R_k = R_(k-1) F_k Rot(a_k, q_k)`` with
  ``R_0 = I`` (the base frame is parallel to O-xyz), ``F_k`` the joint's fixed ``frame``
  (identity unless given: a URDF joint origin's rotation) and ``Rot(a, q)`` the right-handed
  rotation by the angle ``q`` about the unit axis ``a`` (Rodrigues). The joint axis ``a_k`` is
  given in the joint's frame ``R_(k-1) F_k``, which is the same as in link ``k``'s own frame
  since a rotation leaves its axis fixed;
- joint 1 sits at ``base``; joint ``k+1`` at ``p_(k+1) = p_k + R_k vector_k``; the fingertip
  centre is ``r = p_(n+1) + R_n tip_offset`` and the fingertip frame is
  ``Pi = R_n tip_rotation`` (the frame in which the fingertip surface is given).

Joint-angle sign, a choice forced by the papers. The 2D paper writes the fingertip centre as
``O01 = (l11 sin q1 + l12 sin(q1+q2), l11 cos q1 + l12 cos(q1+q2))``: positive angles turn the
finger *clockwise* seen from +z, i.e. about the axis ``-z``. The 3D paper's eq (8) agrees
(``Pi1' = Pi1 Omega1`` with ``Omega1 = [[0, p1', 0], [-p1', 0, 0], [0, 0, 0]]`` is a rotation
about -z at the rate ``p1' = q11' + q12'``). The presets therefore use the axes ``-z`` (finger 1)
and ``-x`` then ``-z`` (finger 2). With them the true world-frame angular-velocity Jacobians are
exactly the negatives of the paper's eq (39): ``W1 = -W1_paper`` and ``W2 = -W2_paper``. The
paper's W2 (first column ``+x``, next columns ``(0, sin q21, cos q21)``) cannot be the angular
velocity Jacobian of any rigid chain with right-handed joint rotations: ``(0, sin q21, cos q21)``
is z turned by ``-q21`` about x, while ``+x`` in the first column says joint 1 turns by ``+q21``.
Both paper matrices are consistent with the sign of eq (8), i.e. with the paper's finger
angular velocity being the negative of ours; ``derive.spatial`` uses the true one.

Links are uniform rods by default: the centre of mass at mid-length and the inertia about it
``m l^2/12 (I - d d^T)`` (d the unit link direction), i.e. ``m l^2/12`` about every axis
perpendicular to the rod and 0 along it, as in the 2D model. A link of zero length and zero mass
is a *coincident* joint (finger 2's joints 21 and 22 share one point, as in the paper's Fig. 1).
"""
from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass, field

import numpy as np

from grasping_sym.errors import InvalidBodyError

Vec3 = tuple[float, float, float]
Mat3 = tuple[Vec3, Vec3, Vec3]

IDENTITY: Mat3 = ((1.0, 0.0, 0.0), (0.0, 1.0, 0.0), (0.0, 0.0, 1.0))
#: Rotation by +pi/2 about z: the fingertip frame of the presets has X along the last link
#: and Z along world z at zero angles, as the 2D fingertip frame ``Rot(pi/2 - q1 - q2)``.
ROT_Z_HALF_PI: Mat3 = ((0.0, -1.0, 0.0), (1.0, 0.0, 0.0), (0.0, 0.0, 1.0))

#: Preset link lengths (m) and masses (kg): the 2D paper's Table 1 (l11 = l12 = 0.065 m,
#: m11 = 0.045 kg, m12 = 0.040 kg), used for both fingers.
LINK_LENGTHS: tuple[float, float] = (0.065, 0.065)
LINK_MASSES: tuple[float, float] = (0.045, 0.040)
#: Half the distance between the two finger bases along x (m). With the opposed
#: configurations below the fingertip centres are at (-0.03, 0.0563, 0) and (0.03, 0.0563, 0):
#: 0.06 m apart, room for an object of ~0.04 m between fingertips of radius ~0.01 m.
BASE_HALF_SPACING: float = 0.1275  # = 0.03 + 0.065 (sin 30 deg + 1)
#: Joint angles (rad) of the opposed configuration: link 1 at 30 degrees from +y, link 2
#: horizontal, the two fingertips facing each other across x = 0 at height 0.0563 m.
FINGER1_Q_OPPOSED: tuple[float, float] = (math.pi / 6, math.pi / 3)
FINGER2_Q_OPPOSED: tuple[float, float, float] = (0.0, -math.pi / 6, -math.pi / 3)


def _vec(value, n: int = 3) -> tuple[float, ...] | None:
    """``value`` as ``n`` finite floats, or None."""
    try:
        arr = np.asarray(value, dtype=float)
    except (TypeError, ValueError):
        return None
    if arr.shape != (n,) or not np.all(np.isfinite(arr)):
        return None
    return tuple(float(x) for x in arr)


def _mat3(value) -> Mat3 | None:
    try:
        arr = np.asarray(value, dtype=float)
    except (TypeError, ValueError):
        return None
    if arr.shape != (3, 3):
        return None
    return tuple(tuple(float(x) for x in row) for row in arr)  # type: ignore[return-value]


@dataclass(frozen=True)
class RevoluteJoint:
    """A revolute joint and the link it drives.

    Parameters
    ----------
    axis
        Joint axis in the previous link's frame (dimensionless); normalised by the derivation,
        so it need only be non-zero.
    vector
        m, from this joint to the next joint (or to the fingertip frame origin for the last
        link), in this link's frame.
    mass
        kg, mass of the link. 0 only for a massless coincident joint (``vector`` zero).
    com
        m, centre of mass in this link's frame; ``None`` for mid-length (uniform rod).
    inertia
        kg m^2, 3x3 inertia about the centre of mass in this link's frame; ``None`` for the
        uniform rod ``mass |vector|^2 / 12 (I - d d^T)``.
    frame
        The fixed rotation from the previous link's frame to the frame in which this joint
        turns (a URDF joint origin's ``rpy``): link ``k``'s frame is
        ``R_k = R_(k-1) frame_k Rot(a_k, q_k)``; ``axis``, ``vector``, ``com`` and ``inertia``
        are then in link ``k``'s frame. ``None``: the identity.
    limits
        rad, ``(lower, upper)``: the joint's range; a run that reaches either end stops with
        ``JointLimitError`` at the step where it happens. ``None``: no limit (a continuous
        joint).
    """

    axis: Vec3
    vector: Vec3
    mass: float
    com: Vec3 | None = None
    inertia: Mat3 | None = None
    limits: tuple[float, float] | None = None
    frame: Mat3 | None = None

    @property
    def length(self) -> float:
        """m, the link length |vector|."""
        return float(np.linalg.norm(self.vector))

    @property
    def com_local(self) -> Vec3:
        """m, the centre of mass in the link frame (mid-length unless given)."""
        if self.com is not None:
            return self.com
        return tuple(0.5 * x for x in self.vector)  # type: ignore[return-value]

    @property
    def is_rod(self) -> bool:
        """Whether the inertia is the uniform rod's (no explicit ``inertia``)."""
        return self.inertia is None


@dataclass(frozen=True)
class FingerChain:
    """A serial finger of revolute joints from a fixed base to a fingertip frame.

    Parameters
    ----------
    name
        Finger index or name, alphanumeric; the joint symbols are ``q{name}{k}`` (k from 1),
        e.g. ``q11, q12`` for finger ``"1"`` as in the paper.
    base
        m, position of joint 1 in the inertial frame O-xyz.
    joints
        The joints from the base outward (at least one).
    tip_offset
        m, fingertip frame origin (the fingertip centre ``O_i`` of the paper) in the last link's
        frame, relative to the end of the last link.
    tip_rotation
        Rotation from the fingertip frame to the last link's frame (orthonormal, det +1).

    Raises
    ------
    InvalidBodyError
        Listing every problem at once.
    """

    name: str
    base: Vec3
    joints: tuple[RevoluteJoint, ...]
    tip_offset: Vec3 = (0.0, 0.0, 0.0)
    tip_rotation: Mat3 = field(default=IDENTITY)

    def __post_init__(self) -> None:
        problems: list[str] = []
        if not (isinstance(self.name, str) and self.name.isalnum()):
            problems.append(f"name {self.name!r} must be a non-empty alphanumeric string "
                            "(it names the joint symbols q{name}{k})")
        base = _vec(self.base)
        if base is None:
            problems.append(f"base {self.base!r} must be 3 finite numbers (m)")
        else:
            object.__setattr__(self, "base", base)
        offset = _vec(self.tip_offset)
        if offset is None:
            problems.append(f"tip_offset {self.tip_offset!r} must be 3 finite numbers (m)")
        else:
            object.__setattr__(self, "tip_offset", offset)
        rot = _mat3(self.tip_rotation)
        if rot is None or not np.all(np.isfinite(rot)):
            problems.append(f"tip_rotation {self.tip_rotation!r} must be a finite 3x3 matrix")
        else:
            arr = np.array(rot)
            err = float(np.max(np.abs(arr.T @ arr - np.eye(3))))
            if err > 1e-9 or np.linalg.det(arr) < 0:
                problems.append(f"tip_rotation must be a rotation (R^T R = I, det +1); "
                                f"orthonormality error {err:.3g}, det {np.linalg.det(arr):.6g}")
            object.__setattr__(self, "tip_rotation", rot)
        joints = tuple(self.joints) if isinstance(self.joints, (list, tuple)) else ()
        if not joints:
            problems.append(f"joints {self.joints!r} must be a non-empty sequence of RevoluteJoint")
        checked = []
        for k, joint in enumerate(joints, start=1):
            label = f"joint {k} (q{self.name}{k})"
            if not isinstance(joint, RevoluteJoint):
                problems.append(f"{label}: {joint!r} is not a RevoluteJoint")
                continue
            checked.append(_check_joint(joint, label, problems))
        if checked and all(j is not None for j in checked):
            if sum(j.mass for j in checked) <= 0:
                problems.append("total mass is 0 kg: at least one link needs a positive mass")
            object.__setattr__(self, "joints", tuple(checked))
        if problems:
            raise InvalidBodyError(f"finger {self.name}", problems)

    @property
    def n(self) -> int:
        """Number of joints (degrees of freedom)."""
        return len(self.joints)

    @property
    def joint_names(self) -> tuple[str, ...]:
        """Joint symbol names ``q{name}{k}``, k = 1..n."""
        return tuple(f"q{self.name}{k}" for k in range(1, self.n + 1))

    @property
    def total_mass(self) -> float:
        """kg, sum of the link masses."""
        return sum(j.mass for j in self.joints)


def without_limits(chain: FingerChain) -> FingerChain:
    """``chain`` with no joint limits: what its equations depend on (limits are bounds a run
    checks, never terms of the equations)."""
    if all(j.limits is None for j in chain.joints):
        return chain
    return dataclasses.replace(chain, joints=tuple(dataclasses.replace(j, limits=None) for j in chain.joints))


def _check_joint(joint: RevoluteJoint, label: str, problems: list[str]) -> RevoluteJoint | None:
    """Validate one joint, append its problems, return it with coerced tuples (or None)."""
    start = len(problems)
    axis = _vec(joint.axis)
    if axis is None:
        problems.append(f"{label}: axis {joint.axis!r} must be 3 finite numbers")
    elif math.hypot(*axis) < 1e-12:
        problems.append(f"{label}: axis {axis} has norm {math.hypot(*axis):.3g}; give a non-zero "
                        "direction (it is normalised)")
    vector = _vec(joint.vector)
    if vector is None:
        problems.append(f"{label}: vector {joint.vector!r} must be 3 finite numbers (m)")
    try:
        mass = float(joint.mass)
    except (TypeError, ValueError):
        mass = math.nan
    if not math.isfinite(mass) or mass < 0:
        problems.append(f"{label}: mass {joint.mass!r} must be finite and >= 0 kg (0 only for "
                        "a massless coincident joint)")
    com = None
    if joint.com is not None:
        com = _vec(joint.com)
        if com is None:
            problems.append(f"{label}: com {joint.com!r} must be 3 finite numbers (m) or None")
    inertia = None
    if joint.inertia is not None:
        inertia = _mat3(joint.inertia)
        if inertia is None or not np.all(np.isfinite(inertia)):
            problems.append(f"{label}: inertia {joint.inertia!r} must be a finite 3x3 matrix "
                            "(kg m^2) or None for a uniform rod")
        else:
            arr = np.array(inertia)
            scale = max(float(np.max(np.abs(arr))), 1e-300)
            if np.max(np.abs(arr - arr.T)) > 1e-12 * scale:
                problems.append(f"{label}: inertia {inertia} is not symmetric")
            elif np.min(np.linalg.eigvalsh(arr)) < -1e-12 * scale:
                problems.append(f"{label}: inertia has a negative principal moment "
                                f"{np.min(np.linalg.eigvalsh(arr)):.3g} kg m^2")
    if vector is not None and math.isfinite(mass):
        length = math.hypot(*vector)
        if mass > 0 and length <= 0 and inertia is None:
            problems.append(f"{label}: link length 0 m with mass {mass} kg; a uniform rod needs a "
                            "positive length (or give com and inertia explicitly)")
        if mass == 0 and (length > 0 or (inertia is not None and np.any(np.array(inertia) != 0))):
            problems.append(f"{label}: mass 0 kg is allowed only for a massless coincident joint "
                            f"(vector 0 and no inertia); got length {length} m; give a positive mass")
    frame = None
    if joint.frame is not None:
        frame = _mat3(joint.frame)
        arr = None if frame is None else np.array(frame)
        if arr is None or not np.all(np.isfinite(arr)) or \
                float(np.max(np.abs(arr.T @ arr - np.eye(3)))) > 1e-9 or np.linalg.det(arr) < 0:
            problems.append(f"{label}: frame {joint.frame!r} must be a rotation (3x3, R^T R = I, "
                            "det +1) or None")
    limits = None
    if joint.limits is not None:
        limits = _vec(joint.limits, 2)
        if limits is None or not limits[0] < limits[1]:
            problems.append(f"{label}: limits {joint.limits!r} must be two finite angles (rad), "
                            "lower < upper, or None for a joint without limits")
    if len(problems) > start:
        return None
    return RevoluteJoint(axis=axis, vector=vector, mass=mass, com=com, inertia=inertia, limits=limits,
                         frame=frame)


def finger1(
    *,
    base: Vec3 = (-BASE_HALF_SPACING, 0.0, 0.0),
    lengths: tuple[float, float] = LINK_LENGTHS,
    masses: tuple[float, float] = LINK_MASSES,
    tip_offset: Vec3 = (0.0, 0.0, 0.0),
    tip_rotation: Mat3 = ROT_Z_HALF_PI,
) -> FingerChain:
    """Finger 1 of the paper: two joints about z, the 2D finger placed in the xy plane.

    Both axes are ``-z`` so that positive angles bend the finger clockwise seen from +z and
    the fingertip centre is the 2D ``O01`` shifted by ``base``:
    ``r1 = base + (l11 sin q11 + l12 sin(q11+q12), l11 cos q11 + l12 cos(q11+q12), 0)``.
    At zero angles the links point along +y. The fingertip frame is ``Rot_z(pi/2 - q11 - q12)``
    (X along the last link, Z = z), the 2D fingertip frame. Defaults: base (-0.1275, 0, 0) m,
    l = (0.065, 0.065) m, m = (0.045, 0.040) kg; at ``FINGER1_Q_OPPOSED`` the fingertip centre
    is at (-0.03, 0.0563, 0) m.
    """
    if len(lengths) != 2 or len(masses) != 2:
        raise InvalidBodyError("finger 1", [f"lengths {lengths!r} and masses {masses!r} must "
                                             "have 2 entries each (links 11 and 12)"])
    joints = tuple(
        RevoluteJoint(axis=(0.0, 0.0, -1.0), vector=(0.0, float(length), 0.0), mass=float(mass))
        for length, mass in zip(lengths, masses)
    )
    return FingerChain(name="1", base=base, joints=joints, tip_offset=tip_offset,
                       tip_rotation=tip_rotation)


def finger2(
    *,
    base: Vec3 = (BASE_HALF_SPACING, 0.0, 0.0),
    lengths: tuple[float, float] = LINK_LENGTHS,
    masses: tuple[float, float] = LINK_MASSES,
    tip_offset: Vec3 = (0.0, 0.0, 0.0),
    tip_rotation: Mat3 = ROT_Z_HALF_PI,
) -> FingerChain:
    """Finger 2 of the paper: joint 21 about x, joints 22 and 23 about z turned by q21.

    Joint 21 (axis ``-x``) and joint 22 share the base point (a massless coincident joint);
    joints 22 and 23 have the axis ``-z`` of link 21's frame, i.e. ``-(0, sin q21, cos q21)``
    in the world: the paper's W2 of eq (39) up to its sign convention (module docstring). At
    zero angles the links point along +y; at ``q21 = 0`` the finger moves in the xy plane like
    finger 1, and negative q22, q23 bend it toward -x, opposing finger 1. Defaults: base
    (0.1275, 0, 0) m, l = (0.065, 0.065) m, m = (0.045, 0.040) kg; at ``FINGER2_Q_OPPOSED``
    the fingertip centre is at (0.03, 0.0563, 0) m.
    """
    if len(lengths) != 2 or len(masses) != 2:
        raise InvalidBodyError("finger 2", [f"lengths {lengths!r} and masses {masses!r} must "
                                             "have 2 entries each (links 22 and 23)"])
    joints = (
        RevoluteJoint(axis=(-1.0, 0.0, 0.0), vector=(0.0, 0.0, 0.0), mass=0.0),
        *(RevoluteJoint(axis=(0.0, 0.0, -1.0), vector=(0.0, float(length), 0.0), mass=float(mass))
          for length, mass in zip(lengths, masses)),
    )
    return FingerChain(name="2", base=base, joints=joints, tip_offset=tip_offset,
                       tip_rotation=tip_rotation)
