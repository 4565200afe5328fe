"""Built-in scenes. Each is a plain function returning a scene; every value is a keyword."""
from __future__ import annotations

import math
from typing import TYPE_CHECKING

import numpy as np

from grasping_sym.errors import InvalidSceneError
from grasping_sym.geometry import library, surface_library
from grasping_sym.geometry.curves import PlanarCurve
from grasping_sym.model import chains
from grasping_sym.model.body import BodyScene
from grasping_sym.model.body_line import LineBodyScene
from grasping_sym.model.grasp3d import Finger3D, GraspScene3D
from grasping_sym.model.grasp3d_modes import GraspModesScene, WorldPlane
from grasping_sym.model.inertia import solid_ellipsoid_inertia, solid_superquadric_inertia  # noqa: F401 - gs.scenes.*
from grasping_sym.model.planar import DEFAULT_OUTPUTS, ExtraFinger, PlanarFingerScene
from grasping_sym.model.planar_modes import PlanarModesScene, WorldLine

__all__ = ["BUILTIN", "GraspModesScene", "LineBodyScene", "PlanarModesScene", "WorldPlane", "body_on_line",
           "body_on_plane", "disk_on_incline", "paper2d", "world_line",
           "paper3d", "pinch2d", "pivot3d", "planar_finger", "sphere_on_incline", "trifinger", "with_modes",
           "world_plane"]

if TYPE_CHECKING:  # the 3D modules are imported only when a 3D scene is made
    from grasping_sym.model.grasp3d import GraspScene3D

#: Paper Tables 1 and 2 plus the choices of docs/conventions.md section 1 (SI units).
PAPER2D_PARAMS: dict[str, float] = {
    "l11": 0.065, "l12": 0.065, "m11": 0.045, "m12": 0.040,
    "I": 0.040 * 0.02**2 / 2,          # M r^2 / 2 with M = 0.040 kg, r = 0.02 m
    "fd": 0.5, "c": 0.006, "r": 0.010,
    "gf": 1500.0, "gl": 3000.0, "wf": 225.0e4, "wl": 900.0e4,
}


def planar_finger(
    fingertip: PlanarCurve,
    object: PlanarCurve,  # noqa: A002 - the paper's word
    *,
    name: str = "planar",
    runtime: tuple[str, ...] = (),
    outputs: tuple[str, ...] = DEFAULT_OUTPUTS,
    gravity: tuple[float, float] | None = None,
    q1_0: float = math.pi / 6,
    theta_0: float = 0.0,
    u0_0: float = 0.0,
    u1_0: float = 0.0,
    extra_fingers: tuple = (),
    controller="paper",
    inputs: str | None = None,
    friction=None,
    support: str = "pivot",
    **params: float,
) -> PlanarFingerScene:
    """The general 2D scene with any two contours; unspecified parameters from the paper.

    ``extra_fingers``: further fingers on the same object (``model.planar.ExtraFinger``);
    ``controller``, ``inputs``: the control (``model.control``; default the paper's law (32),
    no inputs); ``friction``: Coulomb friction at the contacts (``gs.contact.coulomb``);
    ``support``: ``"pivot"`` or ``"free"`` (give the object's mass ``M`` then; ``I`` is about
    its mass centre)."""
    values = dict(PAPER2D_PARAMS)
    values.update(params)
    return PlanarFingerScene(
        name=name, fingertip=fingertip, object=object, params=values, runtime=runtime,
        outputs=outputs, gravity=gravity, q1_0=q1_0, theta_0=theta_0, u0_0=u0_0, u1_0=u1_0,
        extra_fingers=tuple(extra_fingers), controller=controller, inputs=inputs,
        friction=friction, support=support,
    )


def paper2d(**overrides) -> PlanarFingerScene:
    """Yoshida-Arimoto-Tahara 2009: the paper's catenary fingertip and object (docs/conventions.md section 1).

    Any argument of ``planar_finger`` (contours, parameters, initial state, ``runtime``,
    ``outputs``) may be overridden by keyword.
    """
    kwargs = {"fingertip": library.paper_fingertip(), "object": library.paper_object(),
              "name": "paper2d"}
    kwargs.update(overrides)
    return planar_finger(**kwargs)


#: Built-in scenes by name, for the CLI.
BUILTIN = {"paper2d": paper2d}

#: The object of ``pinch2d``: an ellipse with semi-axes (0.020, 0.025) m, 0.040 kg: the
#: section through the mass centre of ``paper3d``'s ellipsoid, with its inertia about z.
PINCH2D_SEMI_AXES: tuple[float, float] = (0.020, 0.025)


def pinch2d(**overrides) -> PlanarFingerScene:
    """Two of the paper's fingers pinch a free ellipse against gravity in the plane: the 2D
    counterpart of the 3D model kept in its plane (docs/conventions.md section 13).

    Every value (SI units):

    - finger 1 as in ``paper2d`` (joints at the origin), finger 2 its mirror image based at
      (0.255, 0) m (the 3D fingers' bases, 0.255 m apart);
    - circular fingertips of radius 0.010 m (``paper3d``'s spheres; arcs of 1.5 rad either
      side of their tip-frame X point, where they touch at the start);
    - the object: an ellipse with semi-axes (0.020, 0.025) m (``paper3d``'s ellipsoid cut at
      z = 0), 0.040 kg, ``I = M (a^2 + b^2) / 5`` about its mass centre (the ellipsoid's
      about z), touched at the ends of its X axis; the start ``q1 = pi/6``, at rest;
    - gravity 9.81 m/s^2 along -y;
    - the paper's law (32) pulls each fingertip centre toward the object's start centre with
      ``fd / r = 50 N/m`` and holds the finger's weight: the pair sags by 5.3 mm and holds.

    Any argument of ``planar_finger`` may be overridden.
    """
    a, b = PINCH2D_SEMI_AXES
    mass = PAPER3D_MASS
    kwargs = dict(
        fingertip=library.circle(PAPER3D_TIP_RADIUS, span=1.5, name="fingertip 1"),
        object=library.ellipse(a, b, start=math.pi / 2, span=math.pi, clockwise=True,
                               name="object ellipse"),
        name="pinch2d", support="free", M=mass, I=mass * (a * a + b * b) / 5,
        gravity=(0.0, -9.81), q1_0=math.pi / 6, u0_0=0.0, u1_0=math.pi,
        extra_fingers=(ExtraFinger(library.circle(PAPER3D_TIP_RADIUS, span=1.5, name="fingertip 2"),
                                   base=(2 * chains.BASE_HALF_SPACING, 0.0), u1_0=0.0),),
    )
    kwargs.update(overrides)
    return planar_finger(**kwargs)


# ---------------------------------------------------------------------- 3D
#: The object of ``paper3d``: a solid ellipsoid with three different semi-axes (m), 0.040 kg
#: (docs/conventions.md section 2), touched at the ends of its X axis.
PAPER3D_SEMI_AXES: tuple[float, float, float] = (0.020, 0.025, 0.030)
PAPER3D_MASS: float = 0.040
#: m, radius of the hemispherical fingertips (the 2D paper's fingertip scale).
PAPER3D_TIP_RADIUS: float = 0.010


def paper3d(**overrides) -> "GraspScene3D":
    """Arimoto-Yoshida 2011: two fingers grasp a free ellipsoid under gravity (docs/conventions.md section 2).

    Every value, chosen because the paper gives no numbers (SI units):

    - finger 1: ``chains.finger1()`` (two joints about z, links 0.065 m, 0.045/0.040 kg, base
      (-0.1275, 0, 0)); finger 2: ``chains.finger2()`` (joint about x, then two about the
      turned z; base (0.1275, 0, 0)); guesses ``q1 = (pi/6, pi/3)``, ``q2 = (0.15, -pi/6,
      -pi/3)``: finger 2 tilted out of the xy plane so that the grasp is truly 3D;
    - fingertips: spheres of radius 0.010 m (hemispherical ends), touching at their +X point
      (the tip frame's X runs along the last link);
    - object: ellipsoid with semi-axes (0.020, 0.025, 0.030) m, 0.040 kg, the inertia of the
      solid body ``m/5 (b^2 + c^2, a^2 + c^2, a^2 + b^2)``; its surface chart has longitude in
      (-pi/2, 3pi/2) so that both contacts, near the ends of the X axis (u = 0 and u = pi, on
      the equator), lie well inside it; pose guess: centre (0, 0.0563, 0), turned by 0.2 rad
      about (1, 1, 1) (a generic pose);
    - gravity 9.81 m/s^2 along -y, on the object and on the fingers (compensated by the
      controller);
    - controller: ``fd = 0.5 N``, ``r_ctrl = 0.010 m`` (the pull (fd / r_ctrl)(r_1 - r_2), about
      3 N at the start), ``c = 0.006 N m s`` (the 2D paper's), ``k_center = 200 N/m`` (carries
      the weight: sag about 2 mm); no stabilisation gain (``gain = 0``): the runs project onto
      the constraints after every step (``simulate``'s default for it), 3.4 times faster than
      the gain 300 1/s it had (``benchmarks/results/defaults3d.md``);
    - contacts: rolling without slip, with a torsional friction of ``spin_damping = 2e-5
      N m s`` (a soft fingertip's twist resistance). With the paper's rigid contacts
      (``spin_damping=0``) nothing resists a spin of the object about the line through the two
      contacts, and it never settles: its angular speed still swings between 0.03 and 0.17
      rad/s at 5 s (peak 1.8 rad/s); with 2e-5 it falls below 1e-3 rad/s;
    - start: the consistent configuration nearest the guesses (``derive.initial3d``) with the
      admissible motion nearest the joint speeds ``dq0 = (1.0, -0.5, 1.5, -0.5, 0.5)`` rad/s,
      so that both contacts roll at first (the paper's formulation needs moving contacts) and
      the grasp then comes to rest.

    Any field of ``GraspScene3D`` may be overridden by keyword (e.g. ``formulation='paper'``).
    """

    a, b, c = PAPER3D_SEMI_AXES
    rot = _axis_angle((1.0, 1.0, 1.0), 0.2)
    fingers = (
        Finger3D(chain=chains.finger1(), tip=surface_library.sphere(PAPER3D_TIP_RADIUS, name="fingertip 1"),
                 q0=chains.FINGER1_Q_OPPOSED, tip_contact=(0.0, 0.0), object_contact=(math.pi, 0.0)),
        Finger3D(chain=chains.finger2(), tip=surface_library.sphere(PAPER3D_TIP_RADIUS, name="fingertip 2"),
                 q0=(0.15, *chains.FINGER2_Q_OPPOSED[1:]), tip_contact=(0.0, 0.0), object_contact=(0.0, 0.0)),
    )
    kwargs = dict(
        name="paper3d", fingers=fingers,
        object_surface=surface_library.ellipsoid(a, b, c, lon=(-math.pi / 2, 3 * math.pi / 2),
                                                 name="object ellipsoid"),
        mass=PAPER3D_MASS, inertia=solid_ellipsoid_inertia(PAPER3D_MASS, a, b, c),
        support="free", position=(0.0, 0.0563, 0.0), rotation=rot, gravity=(0.0, -9.81, 0.0),
        fd=0.5, c=0.006, r_ctrl=0.010, k_center=200.0, spin_damping=2e-5,
        dq0=(1.0, -0.5, 1.5, -0.5, 0.5), outputs=PAPER3D_OUTPUTS,
    )
    if overrides.get("formulation") == "paper" and "outputs" not in overrides:
        kwargs["outputs"] = PAPER3D_OUTPUTS + ("frame_denominator1", "frame_denominator2", "frame_orthonormality")
    kwargs.update(overrides)
    return GraspScene3D(**kwargs)


#: Outputs of the built-in 3D scenes (what the checks, the figures and the tests use).
PAPER3D_OUTPUTS = ("constraint_residual", "f1", "lam1", "eta1", "f2", "lam2", "eta2",
                   "krel_min1", "krel_min2", "orthonormality", "kinetic_energy",
                   "potential_energy", "power", "object_speed", "object_angular_speed")


def pivot3d(**overrides) -> "GraspScene3D":
    """One finger (``chains.finger1``, spherical tip of 0.010 m) rolling on an ellipsoid
    (0.020, 0.025, 0.030) m that turns about its centre, fixed; no gravity. The controller pulls
    the fingertip centre toward the pivot (the 2D law (32)). The smallest 3D scene."""

    a, b, c = PAPER3D_SEMI_AXES
    fingers = (Finger3D(chain=chains.finger1(), tip=surface_library.sphere(PAPER3D_TIP_RADIUS, name="fingertip"),
                        q0=chains.FINGER1_Q_OPPOSED, tip_contact=(0.0, 0.1), object_contact=(2.7, 0.25)),)
    kwargs = dict(name="pivot3d", fingers=fingers,
                  object_surface=surface_library.ellipsoid(a, b, c, name="object ellipsoid"),
                  mass=PAPER3D_MASS, inertia=solid_ellipsoid_inertia(PAPER3D_MASS, a, b, c),
                  support="pivot", position=(0.0, 0.0563, 0.0), gravity=None,
                  outputs=("constraint_residual", "f1", "lam1", "eta1", "krel_min1",
                           "orthonormality", "kinetic_energy", "power"))
    kwargs.update(overrides)
    return GraspScene3D(**kwargs)


def _axis_angle(axis, angle: float) -> tuple:
    """The rotation matrix of ``angle`` (rad) about ``axis`` (Rodrigues' formula; SciPy's
    spatial module would cost 0.2-0.4 s to import for it)."""
    a = np.asarray(axis, float)
    a = a / np.linalg.norm(a)
    k = np.array([[0.0, -a[2], a[1]], [a[2], 0.0, -a[0]], [-a[1], a[0], 0.0]])
    r = np.eye(3) + math.sin(angle) * k + (1.0 - math.cos(angle)) * (k @ k)
    return tuple(map(tuple, r))


#: The rounded cube of ``trifinger``: a superquadric of exponent 4 and half-side 0.035 m
#: (0.07 m across; TriFinger's cubes are 0.065 m), 0.08 kg.
TRIFINGER_CUBE: tuple[float, int, float] = (0.035, 4, 0.08)
#: rad, the start guess of every TriFinger finger: TriFinger's own initial position.
TRIFINGER_Q0: tuple[float, float, float] = (0.0, 0.9, -1.7)


def trifinger(object_surface=None, *, mass: float | None = None, inertia=None, **overrides) -> "GraspScene3D":
    """TriFinger Pro (the published geometry: ``gs.hands.TRIFINGER_URDF``) holding a free
    object under gravity, its three fingertips on it.

    Every value, chosen because a hand's URDF says nothing of a grasp (SI units):

    - the hand: ``gs.hands.from_urdf(TRIFINGER_URDF, tips=TRIFINGER_TIPS)``, three fingers of
      three joints 120 degrees apart about z, with their published soft joint limits (a run
      that reaches one stops with ``JointLimitError``) and fingertip spheres of 0.010 m;
    - the object: by default a rounded cube, ``superquadric(0.035, 0.035, 0.035, n=4)``,
      0.08 kg, the inertia of the solid (``solid_superquadric_inertia``); another surface,
      ``mass`` and ``inertia`` may be given (an inertia is needed with another surface);
    - the start: every finger near ``TRIFINGER_Q0`` (TriFinger's initial position), the
      object's centre guessed at the fingertips' mean there, each contact guessed where the
      line between that centre and the fingertip centre meets the surfaces (``hands.facing``);
    - gravity 9.81 m/s^2 along -z (the URDF's world: z up), compensated by the controller;
    - controller: ``fd = 0.5 N``, ``r_ctrl = 0.035 m``, ``c = 0.02 N m s``,
      ``k_center = 200 N/m``; torsional friction ``spin_damping = 2e-5 N m s``;
    - no stabilisation gain (``gain = 0``): the runs project each step onto the constraints
      (``simulate``'s default for it): 1 s at rtol 1e-8 in 41 steps and 2.5 ms, the final
      state 9e-10 from a reference at 1e-12, where the gain of 100 1/s it had took 107 steps
      and 5.7 ms (measured; ``benchmarks/urdf_hand.py``).

    Any field of ``GraspScene3D`` may be overridden by keyword.
    """
    from grasping_sym.model import hand_poses, hands  # noqa: PLC0415 - yourdfpy only for a hand

    hand = hands.from_urdf(hands.TRIFINGER_URDF, tips=hands.TRIFINGER_TIPS)
    if object_surface is None:
        half, n, default_mass = TRIFINGER_CUBE
        object_surface = surface_library.superquadric(half, half, half, n=n, name="rounded cube")
        mass = default_mass if mass is None else mass
        inertia = solid_superquadric_inertia(mass, half, half, half, n) if inertia is None else inertia
    elif mass is None or inertia is None:
        raise InvalidSceneError([f"trifinger(object_surface={getattr(object_surface, 'name', object_surface)!r}): "
                                 "give its mass= (kg) and inertia= (kg m^2, about its centre, "
                                 "e.g. gs.scenes.solid_ellipsoid_inertia(...))"])
    tips = [hand_poses.tip_pose(chain, TRIFINGER_Q0) for chain in hand.chains]
    centre = np.mean([r for r, _ in tips], axis=0)
    fingers = tuple(
        hand.finger(chain.name, TRIFINGER_Q0,
                    object_contact=hand_poses.facing(r - centre),
                    tip_contact=hand_poses.facing(Pi.T @ (centre - r)))
        for chain, (r, Pi) in zip(hand.chains, tips))
    kwargs = dict(
        name="trifinger", fingers=fingers, object_surface=object_surface, mass=mass,
        inertia=inertia, support="free", position=tuple(float(v) for v in centre),
        gravity=(0.0, 0.0, -9.81), fd=0.5, c=0.02, r_ctrl=0.035, k_center=200.0,
        spin_damping=2e-5, outputs=TRIFINGER_OUTPUTS)
    kwargs.update(overrides)
    return GraspScene3D(**kwargs)


#: Outputs of ``trifinger``.
TRIFINGER_OUTPUTS = ("constraint_residual", "f1", "lam1", "eta1", "f2", "lam2", "eta2", "f3", "lam3",
                     "eta3", "kinetic_energy", "potential_energy", "power", "object_speed",
                     "object_angular_speed")


BUILTIN.update({"paper3d": paper3d, "pivot3d": pivot3d})


def body_on_plane(surface, *, mass: float, inertia, name: str = "body", **kwargs) -> "BodyScene":
    """A free rigid body with ``surface`` (body frame, centre of mass at its origin) on a fixed
    plane of the world (``model.body.BodyScene``: ``plane_point``, ``plane_normal``,
    ``plane_spin`` (a turntable), ``plane_motion`` (a translation of time: a conveyor, a lift),
    ``gravity``, the start ``position``, ``rotation``, ``velocity``, ``omega``, ``support``,
    ``start``, ``gain``, ``friction``)."""
    return BodyScene(name=name, surface=surface, mass=mass, inertia=inertia, **kwargs)


def body_on_line(contour, *, mass: float, inertia: float, name: str = "body2d", **kwargs) -> LineBodyScene:
    """A free 2D body with ``contour`` (body frame, mass centre at its origin, running clockwise
    like a 2D object's) on a line of the world (``model.body_line.LineBodyScene``:
    ``line_point``, ``line_normal``, ``line_motion`` (its translation, two expressions of
    ``t``: a conveyor, a rising table), ``gravity``, the start ``position``, ``theta``,
    ``velocity``, ``dtheta``, ``support``, ``start``, ``gain``, ``friction``)."""
    return LineBodyScene(name=name, contour=contour, mass=mass, inertia=inertia, **kwargs)


def disk_on_incline(radius: float = 0.05, mass: float = 0.1, incline: float = 0.3, *,
                    name: str = "disk_incline", **kwargs) -> LineBodyScene:
    """A uniform disk (``I = m r^2 / 2``) on a line inclined by ``incline`` rad, rising to the
    left (its normal ``(sin b, cos b)``; downhill is ``(cos b, -sin b)``, along the line's
    tangent ``t = (-cos b, sin b)`` reversed), gravity ``-y``: the 2D counterpart of
    ``sphere_on_incline``. Its contour is a clockwise circle by angle over ten turns either
    way (a roll of up to 10 turns each way stays inside its domain: 1 s at the default incline
    is 2.1 turns); the contact starts at ``u = 0``, the contour's point ``(r, 0)`` turned to
    face the line."""
    b = float(incline)
    n = (math.sin(b), math.cos(b))
    # the contour's point at u = 0, (r, 0) with outward normal (1, 0), faces -n when the body
    # is turned by theta with Rot(-theta) (1, 0) = -n: theta = pi/2 + b
    defaults = dict(line_normal=n, gravity=(0.0, -9.81), theta=math.pi / 2 + b, support=0.0)
    defaults.update(kwargs)
    return LineBodyScene(name=name, contour=library.circle(radius, by="angle", span=20 * math.pi,
                                                           clockwise=True, name="disk"),
                         mass=mass, inertia=0.5 * mass * radius**2, **defaults)


def sphere_on_incline(radius: float = 0.05, mass: float = 0.1, incline: float = 0.3, *,
                      name: str = "sphere_incline", **kwargs) -> "BodyScene":
    """A uniform solid sphere on a plane inclined by ``incline`` rad about the world x axis
    (its normal ``(0, -sin b, cos b)``; downhill is ``-(0, cos b, sin b)``), gravity ``-z``.
    The sphere's chart is turned so that its pole points along the world x axis: the contact
    starts on the chart's equator at ``(u, v) = (0, 0)`` and a roll or slide downhill moves it
    along the equator."""
    b = float(incline)
    n = (0.0, -math.sin(b), math.cos(b))
    # body frame: the chart's equator (v = 0) through the contact, the roll along it
    Rx = np.array([[1.0, 0.0, 0.0], [0.0, math.cos(b), -math.sin(b)], [0.0, math.sin(b), math.cos(b)]])
    Rchart = np.array([[0.0, 0.0, 1.0], [0.0, 1.0, 0.0], [-1.0, 0.0, 0.0]])  # body z (pole) along world x
    rotation = Rx @ Rchart
    inertia = 0.4 * mass * radius**2
    defaults = dict(plane_normal=n, gravity=(0.0, 0.0, -9.81), rotation=rotation,
                    support=(0.0, 0.0))
    defaults.update(kwargs)
    return BodyScene(name=name, surface=surface_library.sphere(radius, lon=(-3 * math.pi, 3 * math.pi)),
                     mass=mass, inertia=(inertia, inertia, inertia), **defaults)


def with_modes(scene, planes=(), lines=()):
    """``scene`` whose contacts roll, slide (Coulomb) or separate, switching at located events
    (``docs/conventions.md`` sections 8, 9 and 14): a 2D scene of one finger or several
    (``model.planar_modes``), whose free object may also touch fixed ``lines`` of the world
    (``world_line``), or a 3D grasp (``model.grasp3d_modes``), whose object may also touch
    fixed or driven ``planes`` of the world (``world_plane``: a table, a wall)."""
    if isinstance(scene, GraspScene3D):
        if lines:
            raise InvalidSceneError(["lines= are the world's surfaces of a 2D scene: a 3D scene takes "
                                     "planes=[gs.scenes.world_plane(point, normal)]"])
        return GraspModesScene(scene, tuple(planes))
    if planes:
        raise InvalidSceneError(["planes= are the world's surfaces of a 3D scene: a 2D scene takes "
                                 "lines=[gs.scenes.world_line(point, normal)]"])
    return PlanarModesScene(scene, tuple(lines))


def world_line(point, normal, support: float = 0.0, motion=None) -> WorldLine:
    """A line of the world through ``point`` with unit ``normal`` (into the free side), for
    ``with_modes(scene, lines=[...])`` of a 2D scene with a free object; ``support``: a guess of
    the object contour's parameter that faces it at the start; ``motion``: its translation
    ``d(t)`` (two expressions of ``t``, ``d(0) = 0``; None: fixed): a conveyor, a rising table."""
    return WorldLine(point, normal, support, motion)


def world_plane(point, normal, support=(0.0, 0.0), motion=None, spin=None) -> WorldPlane:
    """A plane of the world through ``point`` with unit ``normal`` (into the free side), for
    ``with_modes(scene, planes=[...])``; ``support``: a guess of the object's surface
    coordinates that face it at the start; ``motion``: its translation ``d(t)`` (three
    expressions of ``t``, ``d(0) = 0``; None: fixed); ``spin``: its turning rate (rad/s, a
    number or an expression of ``t``) about its normal through ``point + d(t)``: a turntable."""
    return WorldPlane(point, normal, support, motion, spin)
