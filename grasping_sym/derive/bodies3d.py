"""The bodies of a 3D grasping scene as CasADi SX: finger chains, the object, their surfaces.

SymPy derives each finger's kinematics and Lagrangian dynamics (``derive.spatial``), the
object's rotation from its quaternion, and each surface's point, Montana frame and forms
(``geometry.surfaces``); ``symbolic.translate`` turns them into SX. :func:`bodies` reads a
state ``x`` as a :class:`Bodies` record: what every later stage of the closed loop
(``derive.loop3d``) uses.
"""
from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from functools import lru_cache

import casadi as ca
import numpy as np
import sympy as sp

from grasping_sym.derive.finger_templates import finger_template
from grasping_sym.derive.spatial import (
    finger_dynamics,
    finger_kinematics,
    quaternion_rate,
    quaternion_rate_matrix,
    quaternion_to_matrix,
)
from grasping_sym.geometry.surfaces import CHART, ParametricSurface, U, V
from grasping_sym.model.grasp3d import GraspScene3D
from grasping_sym.symbolic.translate import SympyToCasadi


@lru_cache(maxsize=None)
def _finger_symbolic(chain, gravity):
    kin = finger_kinematics(chain)
    dyn = finger_dynamics(kin, gravity)
    return kin, dyn


def finger_function(chain, gravity) -> ca.Function:
    """``(q, dq) -> r, Pi, J, W, G, h, joints[, dP, P]``: the finger's kinematics and
    dynamics, derived with SymPy (``derive.spatial``) and translated to SX."""
    kin, dyn = _finger_symbolic(chain, gravity)
    q, dq = ca.SX.sym("q", chain.n), ca.SX.sym("dq", chain.n)
    tr = SympyToCasadi({**{kin.q[k]: q[k] for k in range(chain.n)},
                        **{kin.dq[k]: dq[k] for k in range(chain.n)}})
    out = {"r": tr(kin.r), "Pi": tr(kin.Pi), "J": tr(kin.J), "W": tr(kin.W), "G": tr(dyn.G),
           "h": tr(dyn.h), "joints": ca.horzcat(*[tr(p) for p in kin.joint_positions], tr(kin.r))}
    if gravity is not None:
        out["dP"] = tr(dyn.gravity_gradient)
        out["P"] = tr(dyn.potential_energy)
    return ca.Function(f"finger_{chain.name}", [q, dq], list(out.values()), ["q", "dq"], list(out))


def finger_sx(chain, gravity, q: ca.SX, dq: ca.SX) -> dict[str, ca.SX]:
    """The finger's kinematics and dynamics as SX in ``q, dq``: its template (derived with
    SymPy once per chain and gravity, and stored, ``derive.finger_templates``)
    evaluated on ``q, dq``.

    The template is the chain derived in its first joint's fixed frame ``B``
    (``RevoluteJoint.frame``, the identity when it has none: a hand's fingers placed around a
    palm have one), at the origin and under the gravity ``B^T g`` seen there
    (:func:`template_of`); it is turned and moved here: positions ``base + B (.)``, frames and
    Jacobians ``B (.)``, the inertia matrix and Coriolis terms unchanged, the potential energy
    less ``M g . base``. Fingers equal up to their placement (a TriFinger's three) share one
    derivation."""
    g = None if gravity is None else tuple(float(v) for v in gravity)
    template, _ = template_of(chain, g)
    if template != chain:
        return _placed(chain, g, q, dq)
    fn, _ = finger_template(chain, g, lambda: finger_function(chain, g))
    outs = fn.call([q, dq])
    return {fn.name_out(i): outs[i] for i in range(fn.n_out())}


def local_chain(chain):
    """``chain`` in its first joint's fixed frame: that frame the identity, the base at the
    origin, the name ``"0"``, no joint limits (so that fingers equal up to their placement
    are one chain)."""
    joints = tuple(dataclasses.replace(j, limits=None) for j in chain.joints)
    return dataclasses.replace(chain, name="0", base=(0.0, 0.0, 0.0),
                               joints=(dataclasses.replace(joints[0], frame=None), *joints[1:]))


def template_of(chain, gravity) -> tuple:
    """The chain and gravity of the finger template that ``finger_sx`` uses for ``chain``
    under ``gravity``: the local chain (:func:`local_chain`) and the gravity ``B^T g`` seen
    in its first joint's fixed frame ``B`` (the identity when it has none)."""
    g = None if gravity is None else tuple(float(v) for v in gravity)
    frame = chain.joints[0].frame
    if frame is not None and g is not None:
        g = tuple(float(v) + 0.0 for v in np.array(frame, dtype=float).T @ np.array(g))
    return local_chain(chain), g


def _placed(chain, g, q: ca.SX, dq: ca.SX) -> dict[str, ca.SX]:
    """``finger_sx`` of a chain that is not its own template (``finger_sx``'s docstring)."""
    B = np.eye(3) if chain.joints[0].frame is None else np.array(chain.joints[0].frame, dtype=float)
    base = np.array(chain.base, dtype=float)
    out = finger_sx(*template_of(chain, g), q, dq)
    Bm, bm = ca.DM(B), ca.DM(base)
    placed = {"r": bm + ca.mtimes(Bm, out["r"]), "Pi": ca.mtimes(Bm, out["Pi"]),
              "J": ca.mtimes(Bm, out["J"]), "W": ca.mtimes(Bm, out["W"]),
              "joints": ca.repmat(bm, 1, out["joints"].size2()) + ca.mtimes(Bm, out["joints"])}
    if "P" in out:  # -sum m g . (base + B c) = P_local - M g . base
        mass = sum(j.mass for j in chain.joints)
        placed["P"] = out["P"] - mass * float(np.dot(g, base))
    return {**out, **placed}


def surface_sx(surface: ParametricSurface, u, v, extra: bool = False, chart=None) -> dict[str, ca.SX]:
    """Point, Montana frame and forms of ``surface`` at ``(u, v)`` as SX: ``S``, ``x``,
    ``y``, ``n``, ``M``, ``K``, ``T``; with ``extra`` also the tangent map ``Tm = [S_u S_v]``
    and the second fundamental form ``II`` (surface frame). ``chart``: for a surface with an
    atlas (``geometry.atlas``), the chart (an SX, 0 or 1 at run time) at which its blended
    surface is written; None (or a surface without one): the surface itself."""
    if chart is not None and surface.atlas is not None and surface.atlas.turned is not None:
        # chart 1 is chart 0 turned by Q about the centre: S + c (Q - I)(S - centre), each
        # vector v + c (Q - I) v (the frame's forms are the same): exact at c = 0
        out = surface_sx(surface, u, v, extra)
        turn = chart * (ca.DM(surface.atlas.turned) - ca.DM.eye(3))
        out["S"] = out["S"] + turn @ (out["S"] - ca.DM(surface.atlas.center))
        for k in ("x", "y", "n", *(("Tm",) if extra else ())):
            out[k] = out[k] + turn @ out[k]
        return out
    if chart is not None and surface.atlas is not None:
        surface = surface.atlas.blended
        tr = SympyToCasadi({U: u, V: v, CHART: chart})
    else:
        tr = SympyToCasadi({U: u, V: v})
    x, y, n = surface.frame
    out = {"S": tr(surface.S), "x": tr(x), "y": tr(y), "n": tr(n),
           "M": tr(surface.montana_metric), "K": tr(surface.curvature_form),
           "T": tr(surface.torsion_form)}
    if extra:
        out["Tm"] = ca.horzcat(tr(surface.S_u), tr(surface.S_v))
        out["II"] = tr(surface.second_fundamental_form)
    return out


def object_rotation(quat: ca.SX, om: ca.SX) -> tuple[ca.SX, ca.SX, ca.SX]:
    """``(R, quat', N)``: the rotation of a (not necessarily unit) quaternion, its rate at
    the body angular velocity ``om`` and the matrix ``N`` of ``quat' = N om``."""
    qs, ws = sp.Matrix(sp.symbols("qw qx qy qz", real=True)), sp.Matrix(sp.symbols("wX wY wZ", real=True))
    tr = SympyToCasadi({**{qs[i]: quat[i] for i in range(4)}, **{ws[i]: om[i] for i in range(3)}})
    return tr(quaternion_to_matrix(qs, unit=False)), tr(quaternion_rate(qs, ws)), tr(quaternion_rate_matrix(qs))


def state_slices(scene: GraspScene3D) -> dict[str, slice]:
    """Where the state's parts lie: ``q``, ``pos`` (free objects), ``quat``, ``dq``, ``vel``
    (free objects), ``om``, then the contacts' states."""
    nQ = sum(f.chain.n for f in scene.fingers)
    sizes = [("q", nQ), ("pos", 3 if scene.free else 0), ("quat", 4), ("dq", nQ),
             ("vel", 3 if scene.free else 0), ("om", 3)]
    out, k = {}, 0
    for key, n in sizes:
        out[key] = slice(k, k + n)
        k += n
    return out


@dataclass
class Finger:
    """One finger chain at ``(q, dq)`` (world frame, m): its tip centre ``r``, tip rotation
    ``Pi``, Jacobians ``J`` (linear) and ``W`` (angular), mass matrix ``G``, bias ``h``,
    joint positions ``joints`` (3 x (n + 1)), and with gravity the potential's gradient
    ``dP`` and the potential ``P``."""

    dq: ca.SX
    r: ca.SX
    Pi: ca.SX
    J: ca.SX
    W: ca.SX
    G: ca.SX
    h: ca.SX
    joints: ca.SX
    dP: ca.SX | None = None
    P: ca.SX | None = None


@dataclass
class Bodies:
    """A state ``x`` read as the scene's bodies.

    ``zb``, ``Vs``: the bodies' positions ``(q, [pos], quat)`` and speeds ``(dq, [vel], om)``;
    ``zb_dot``: the positions' rates (the quaternion's exact rate), ``zb_dot_lin``: the
    same written ``N om`` (linear in the speeds); ``etas``: each contact's states.
    """

    x: ca.SX
    fingers: list[Finger]
    quat: ca.SX
    om: ca.SX
    pos: ca.SX | ca.DM
    vel: ca.SX | None
    R: ca.SX
    etas: list[ca.SX]
    gravity: tuple[float, ...] | None
    zb: ca.SX
    zb_dot: ca.SX
    zb_dot_lin: ca.SX
    Vs: ca.SX
    #: kg and kg m^2 (object frame): the object's mass and inertia, numbers or, in a
    #: structure (``assemble.structure3d``), inputs
    mass: ca.SX | float = 0.0
    inertia: ca.SX | ca.DM | None = None


def bodies(scene: GraspScene3D, x: ca.SX, n_eta: int, mass_properties=None) -> Bodies:
    """The bodies at state ``x``, whose contacts have ``n_eta`` states each; the object's
    ``(mass, inertia)`` are ``mass_properties`` when given (SX inputs), else the scene's."""
    free = scene.free
    sl = state_slices(scene)
    q, quat, dq, om = x[sl["q"]], x[sl["quat"]], x[sl["dq"]], x[sl["om"]]
    pos = x[sl["pos"]] if free else ca.DM(scene.position)
    vel = x[sl["vel"]] if free else None
    k = sl["om"].stop
    etas = [x[k + i * n_eta:k + (i + 1) * n_eta] for i in range(scene.n_contacts)]
    g = None if scene.gravity is None else tuple(float(v) for v in scene.gravity)
    R, quat_dot, Eq = object_rotation(quat, om)
    fingers, off = [], 0
    for f in scene.fingers:
        n = f.chain.n
        fingers.append(Finger(dq=dq[off:off + n], **finger_sx(f.chain, g, q[off:off + n], dq[off:off + n])))
        off += n
    zb = ca.vertcat(q, pos, quat) if free else ca.vertcat(q, quat)
    zb_dot_lin = ca.vertcat(dq, vel, Eq @ om) if free else ca.vertcat(dq, Eq @ om)
    zb_dot = ca.vertcat(dq, vel, quat_dot) if free else ca.vertcat(dq, quat_dot)
    Vs = ca.vertcat(dq, vel, om) if free else ca.vertcat(dq, om)
    mass, inertia = mass_properties or (float(scene.mass), ca.DM(np.asarray(scene.inertia)))
    return Bodies(x=x, fingers=fingers, quat=quat, om=om, pos=pos, vel=vel, R=R, etas=etas,
                  gravity=g, zb=zb, zb_dot=zb_dot, zb_dot_lin=zb_dot_lin, Vs=Vs, mass=mass,
                  inertia=inertia)
