"""Hands read from URDF: the finger chains from a base link to each fingertip link
(docs/conventions.md section 11).

``from_urdf(path, tips={"1": "tip_link_a", "2": "tip_link_b"})`` parses the file with
yourdfpy (no meshes loaded) and gives a :class:`Hand`: one ``FingerChain`` per tip, its
fingertip surface, and the names of the URDF joints behind each joint state.

How a URDF chain becomes a ``FingerChain``. URDF composes, from the base link outward, each
joint's fixed origin ``(E_j, t_j)`` and, for a moving joint, the rotation ``Rot(a_j, q_j)``
about its axis ``a_j`` (in the joint's frame). A ``FingerChain`` link ``k`` has the frame
``R_k = R_(k-1) F_k Rot(a_k, q_k)``: ``F_k`` is the product of the fixed rotations from link
``k-1``'s frame to moving joint ``k`` (its own origin's and those of any fixed joints
between), the axis is the URDF's, the link's ``vector`` is the position of the next moving
joint (or of the fingertip frame) in its frame through the fixed joints between, and its
centre of mass and inertia are the URDF's, in the same frame. The chain's ``base`` is joint
1's position in the base link's frame. Every link fixed to link ``k`` (by fixed joints only)
is one rigid body with it: masses add, inertias move to the common centre of mass (parallel
axes). The fingertip frame is the tip link's frame composed with the origin of its collision
sphere or cylinder; the sphere is centred there, the cylinder runs along its z axis. Entries
of a fixed rotation within 4 ulp of 0 or +-1 (``cos(pi/2)`` in an ``rpy``) are taken as exact,
so that a frame turned by a multiple of pi/2 stays an exact permutation in the derivation; a
fixed rotation equal to the identity is left out (``frame=None``), and a link whose centre of
mass and inertia are a uniform rod's along it to 4 ulp is read as the rod (``com`` and
``inertia`` None, as ``RevoluteJoint`` writes one), so that it is the same chain as one typed
in.

The file is parsed once: what the reading below uses of it (the robot's name, its links'
inertials and collision geometries, its joints) is kept as a JSON record in the cache
(``<cache root>/urdf/<hash>.json``, keyed by the file's bytes and yourdfpy's version), so that a
later process reads the same hand without importing yourdfpy and trimesh (0.7 s). Only data
is kept; a missing, unreadable or malformed record is parsed again.

Joint limits: a ``revolute`` joint's ``<limit lower upper>`` becomes ``RevoluteJoint.limits``
(a run stops at them with ``JointLimitError``); a ``continuous`` joint has none. Prismatic,
floating and planar joints, mimic joints, a joint shared by two fingers and a moving joint
that hangs off a finger without leading to a tip are refused by name.
"""
from __future__ import annotations

import hashlib
import io
import os
from collections.abc import Mapping
from dataclasses import dataclass
from importlib import metadata, resources
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import sympy as sp

from grasping_sym.errors import InvalidBodyError, UnsafeCacheError, URDFError  # noqa: F401 - gs.hands.URDFError
from grasping_sym.geometry import surface_library
from grasping_sym.geometry.curves import PlanarCurve, T
from grasping_sym.geometry.surfaces import ParametricSurface
from grasping_sym.model.chains import FingerChain, RevoluteJoint
from grasping_sym.model.grasp3d import Finger3D
from grasping_sym.model.hand_poses import facing, tip_pose  # noqa: F401 - gs.hands.tip_pose, .facing
from grasping_sym.store import files as stored
from grasping_sym.store import paths as cache
from grasping_sym.store import safety

#: TriFinger Pro as published (``grasping_sym/data/trifinger_pro.urdf``: our URDF of the
#: published geometry, with a 0.01 m collision sphere as its fingertip) and its tip links.
TRIFINGER_URDF = resources.files("grasping_sym") / "data" / "trifinger_pro.urdf"
TRIFINGER_TIPS = {"1": "finger_tip_link_0", "2": "finger_tip_link_120", "3": "finger_tip_link_240"}
#: Joint types a finger chain can hold (``continuous``: a revolute joint without limits).
MOVING = ("revolute", "continuous")
#: A fixed rotation's entry this close to 0 or +-1 is taken as exact (4 ulp of 1).
_SNAP = 4 * np.finfo(float).eps


@dataclass(frozen=True)
class Hand:
    """Finger chains and fingertip surfaces read from a URDF (``from_urdf``).

    Attributes
    ----------
    name
        The URDF robot's name.
    chains
        One ``FingerChain`` per tip, in the order of ``tips``; joint states ``q{finger}{k}``.
    tips
        Each finger's fingertip surface, in its fingertip frame.
    tip_links
        The URDF link of each fingertip.
    joints
        ``{joint state: URDF joint name}``, e.g. ``{"q11": "finger_base_to_upper_joint_0"}``.
    """

    name: str
    chains: tuple[FingerChain, ...]
    tips: tuple[ParametricSurface, ...]
    tip_links: tuple[str, ...]
    joints: dict[str, str]

    def finger(self, which, q0, object_contact, tip_contact=(0.0, 0.0)) -> Finger3D:
        """The ``Finger3D`` of finger ``which`` (its name, e.g. ``"1"``) for a scene: its chain
        and fingertip, the start guesses ``q0`` (rad), ``object_contact`` and ``tip_contact``
        (surface coordinates)."""
        names = [c.name for c in self.chains]
        if which not in names:
            raise KeyError(f"hand {self.name!r} has no finger {which!r}; its fingers are {names}")
        i = names.index(which)
        return Finger3D(chain=self.chains[i], tip=self.tips[i], q0=tuple(q0),
                        tip_contact=tuple(tip_contact), object_contact=tuple(object_contact))


def from_urdf(path, tips: Mapping[str, str], *, surfaces: Mapping[str, ParametricSurface] | None = None,
              base: str | None = None) -> Hand:
    """Read the fingers of a hand from the URDF file ``path``.

    Parameters
    ----------
    path
        The URDF file (meshes are never loaded).
    tips
        ``{finger name: tip link}``: one finger per entry, from ``base`` to that link. Finger
        names are alphanumeric (they name the joint states ``q{finger}{k}``).
    surfaces
        ``{finger name: surface}``: the fingertip surface in the tip link's frame, for a tip
        whose collision geometry is not one sphere or cylinder (or to replace it).
    base
        The link fixed in the world, whose frame is the inertial frame O-xyz; default the
        URDF's root link.

    Raises
    ------
    URDFError
        Listing every problem (unreadable file, unknown links, joint types a finger cannot
        hold, tips without a usable surface, ...) with its fix.
    """
    path = Path(path)
    robot = _as_namespace(_robot_record(path))
    surfaces = dict(surfaces or {})
    links = {link.name: link for link in robot.links}
    by_child = {j.child: j for j in robot.joints}
    children: dict[str, list] = {}
    for j in robot.joints:
        children.setdefault(j.parent, []).append(j)
    problems = _tree_problems(robot, links)
    if problems:
        raise URDFError(path, problems)
    roots = [name for name in links if name not in by_child]
    if base is None:
        if len(roots) != 1:
            raise URDFError(path, [f"has {len(roots)} root links {roots}; name the one fixed in "
                                   "the world: from_urdf(..., base='link')"])
        base = roots[0]
    if base not in links:
        problems.append(f"base link {base!r} is not in the file; its links are {sorted(links)}")
    if not isinstance(tips, Mapping) or not tips:
        problems.append(f"tips={tips!r} must be a non-empty mapping {{finger name: tip link}}")
        tips = {}
    for finger, link in tips.items():
        if not (isinstance(finger, str) and finger.isalnum()):
            problems.append(f"finger name {finger!r} must be alphanumeric (it names the joint "
                            f"states q{{finger}}{{k}})")
        if link not in links:
            problems.append(f"tip link {link!r} of finger {finger!r} is not in the file")
    unknown = set(surfaces) - set(tips)
    if unknown:
        problems.append(f"surfaces given for {sorted(unknown)}, which are not fingers of tips={dict(tips)}")
    if problems:
        raise URDFError(path, problems)

    paths = {finger: _path(by_child, base, link) for finger, link in tips.items()}
    owner: dict[str, str] = {}
    for finger, joints in paths.items():
        if joints is None:
            problems.append(f"tip link {tips[finger]!r} of finger {finger!r} does not hang from "
                            f"the base link {base!r}")
            continue
        for j in joints:
            if j.type in MOVING and j.name in owner:
                problems.append(f"joint {j.name!r} moves both finger {owner[j.name]!r} and finger "
                                f"{finger!r}: fingers are independent chains from a fixed base; "
                                "choose a base below the shared joint")
            owner.setdefault(j.name, finger)
    if problems:
        raise URDFError(path, problems)

    chains, surfs, joint_names = [], [], {}
    for finger, joints in paths.items():
        tip = _tip_surface(finger, links[tips[finger]], surfaces.get(finger), problems)
        built = _chain(finger, joints, tip[1] if tip else (np.eye(3), np.zeros(3)), links, children,
                       problems)
        if tip is None or built is None:
            continue
        base_point, moving, names, tip_rotation = built
        try:
            chain = FingerChain(name=finger, base=base_point, joints=moving, tip_rotation=tip_rotation)
        except InvalidBodyError as exc:
            problems += [f"finger {finger!r} (URDF joints {', '.join(names)}): {p}" for p in exc.problems]
            continue
        chains.append(chain)
        surfs.append(tip[0])
        joint_names.update(zip(chain.joint_names, names))
    if problems:
        raise URDFError(path, problems)
    return Hand(name=robot.name, chains=tuple(chains), tips=tuple(surfs),
                tip_links=tuple(tips.values()), joints=joint_names)


#: The record's layout (``_robot_record``; raise it whenever ``_record_of`` changes): a record
#: of another layout is parsed again.
_RECORD_FORMAT = 1


def _robot_record(path: Path) -> dict:
    """What ``from_urdf`` reads of the URDF file at ``path`` (``_record_of``), from the cache
    when a record of the same bytes and yourdfpy version is there, else parsed with yourdfpy
    and recorded."""
    try:
        data = path.read_bytes()
    except OSError as exc:
        raise URDFError(path, [f"cannot be read: {exc.strerror or exc}; check the path"]) from None
    version = metadata.version("yourdfpy")
    key = hashlib.sha256(b"\0".join([data, version.encode(), str(_RECORD_FORMAT).encode()])).hexdigest()[:32]
    root = cache.cache_root()
    where = root / "urdf" / f"{key}.json"
    kept = None
    try:
        if os.path.lexists(where):
            safety.ensure_dir(where.parent, root=root)  # the directory yours alone, as the file
            safety.check_file(where)
            kept = stored.read_json(where)
    except UnsafeCacheError:
        raise
    except OSError:  # gone meanwhile (a cache clear) or unreadable: parsed again
        kept = None
    if kept is not None and kept.get("key") == key and _is_record(kept.get("robot")):
        return kept["robot"]
    import yourdfpy  # noqa: PLC0415 - lxml and trimesh only for a hand read from a file

    try:  # the very bytes hashed, not the file read again (it may have been saved meanwhile)
        urdf = yourdfpy.URDF.load(io.BytesIO(data), build_scene_graph=False, load_meshes=False,
                                  build_collision_scene_graph=False, load_collision_meshes=False)
    except Exception as exc:  # yourdfpy and lxml raise many types for a bad file
        raise URDFError(path, [f"cannot be read as URDF: {type(exc).__name__}: {exc}; check "
                               "that it is a URDF file (XML, a <robot> element)"]) from None
    record = _record_of(urdf.robot)
    try:
        safety.ensure_dir(where.parent, root=root)
        stored.write_json(where, {"key": key, "robot": record})
    except OSError:  # a full or read-only cache (CacheWriteError included): parsed again next time
        pass
    return record


def _is_record(robot) -> bool:
    """Whether ``robot`` has the shape ``_record_of`` writes (else the file is parsed again)."""
    link_keys, joint_keys = {"name", "inertial", "collisions"}, {
        "name", "type", "parent", "child", "origin", "axis", "limit", "mimic"}
    return (isinstance(robot, dict) and isinstance(robot.get("name"), str)
            and isinstance(robot.get("links"), list) and isinstance(robot.get("joints"), list)
            and all(isinstance(x, dict) and link_keys <= x.keys() and isinstance(x["collisions"], list)
                    and all(isinstance(c, dict) and {"origin", "geometry"} <= c.keys() for c in x["collisions"])
                    for x in robot["links"])
            and all(isinstance(j, dict) and joint_keys <= j.keys() for j in robot["joints"]))


def _matrix(value) -> list | None:
    return None if value is None else np.asarray(value, dtype=float).tolist()


def _record_of(robot) -> dict:
    """The parts of yourdfpy's ``robot`` that ``from_urdf`` reads, as plain JSON data (floats
    kept exactly: JSON writes their shortest round-tripping repr)."""
    def geometry(g):
        if g is None:
            return None
        return {"sphere": None if g.sphere is None else {"radius": float(g.sphere.radius)},
                "cylinder": None if g.cylinder is None else {"radius": float(g.cylinder.radius),
                                                             "length": float(g.cylinder.length)},
                "box": None if getattr(g, "box", None) is None else {},
                "mesh": None if getattr(g, "mesh", None) is None else {}}

    def inertial(i):
        if i is None:
            return None
        return {"mass": None if i.mass is None else float(i.mass), "origin": _matrix(i.origin),
                "inertia": _matrix(i.inertia)}

    links = [{"name": link.name, "inertial": inertial(link.inertial),
              "collisions": [{"origin": _matrix(c.origin), "geometry": geometry(c.geometry)}
                             for c in link.collisions]} for link in robot.links]
    joints = [{"name": j.name, "type": j.type, "parent": j.parent, "child": j.child,
               "origin": _matrix(j.origin), "axis": _matrix(j.axis),
               "limit": None if j.limit is None else {
                   "lower": None if j.limit.lower is None else float(j.limit.lower),
                   "upper": None if j.limit.upper is None else float(j.limit.upper)},
               "mimic": None if j.mimic is None else {"joint": j.mimic.joint}} for j in robot.joints]
    return {"name": robot.name, "links": links, "joints": joints}


def _as_namespace(value):
    """A record (``_record_of``) as attributes, as yourdfpy's objects have them."""
    if isinstance(value, dict):
        return SimpleNamespace(**{k: _as_namespace(v) for k, v in value.items()})
    if isinstance(value, list) and value and isinstance(value[0], dict):
        return [_as_namespace(v) for v in value]
    return value


def _tree_problems(robot, links) -> list[str]:
    """What keeps the file's links and joints from being a tree: a joint naming a link the
    file lacks, a link with two parent joints, a loop of joints."""
    problems, parents = [], {}
    for j in robot.joints:
        for role, link in (("parent", j.parent), ("child", j.child)):
            if link not in links:
                problems.append(f"joint {j.name!r} names the {role} link {link!r}, which the file lacks")
        parents.setdefault(j.child, []).append(j.name)
    problems += [f"link {child!r} is the child of joints {names}: a URDF's links form a tree, one "
                 "parent joint each" for child, names in parents.items() if len(names) > 1]
    if problems:
        return problems
    up = {j.child: j.parent for j in robot.joints}
    for start in links:
        seen, link = set(), start
        while link in up:
            if link in seen:
                return [f"the joints loop back to link {link!r}: a URDF's links form a tree, without "
                        "loops (close a loop with a constraint of your own, not a joint)"]
            seen.add(link)
            link = up[link]
    return []


def _path(by_child, base: str, tip: str):
    """The joints from ``base`` to ``tip`` (base first), or None if ``tip`` is not below it."""
    joints, link = [], tip
    while link != base:
        j = by_child.get(link)
        if j is None:
            return None
        joints.append(j)
        link = j.parent
    return joints[::-1]


def _snap(R: np.ndarray) -> np.ndarray:
    out = np.array(R, dtype=float)
    for target in (0.0, 1.0, -1.0):
        out[np.abs(out - target) <= _SNAP] = target
    return out


def _origin(joint_or_element) -> tuple[np.ndarray, np.ndarray]:
    T = getattr(joint_or_element, "origin", None)
    if T is None:
        return np.eye(3), np.zeros(3)
    T = np.asarray(T, dtype=float)
    return _snap(T[:3, :3]), T[:3, 3].copy()


def _tuple(v) -> tuple[float, float, float]:
    return tuple(float(x) + 0.0 for x in v)  # type: ignore[return-value]


def _chain(finger, joints, tip_origin, links, children, problems):
    """The chain's base point, its ``RevoluteJoint``s, their URDF names and the fingertip
    frame's rotation (module docstring); None after appending its problems."""
    start = len(problems)
    moving = [j for j in joints if j.type != "fixed"]
    for j in moving:
        if j.type not in MOVING:
            problems.append(f"finger {finger!r}: joint {j.name!r} is {j.type}; a finger holds "
                            f"revolute and continuous joints only (fix it: type='fixed')")
        if j.mimic is not None:
            problems.append(f"finger {finger!r}: joint {j.name!r} mimics {j.mimic.joint!r}; "
                            "coupled joints are not modelled: give it its own motor (no <mimic>)")
        if j.type == "revolute" and (j.limit is None or j.limit.lower is None or j.limit.upper is None):
            problems.append(f"finger {finger!r}: revolute joint {j.name!r} has no <limit lower upper>; "
                            "give them, or make it a 'continuous' joint")
    if not moving:
        problems.append(f"finger {finger!r}: no revolute joint between the base and its tip")
    if len(problems) > start:
        return None
    on_path = {j.name for j in joints}
    # (Rc, tc): the current frame in the frame of the last moving link (the base link's before
    # joint 1); pending: the last moving joint, whose vector is still to come
    Rc, tc = np.eye(3), np.zeros(3)
    base_point, out, pending = None, [], None
    for j in joints:
        E, t = _origin(j)
        position = tc + Rc @ t
        Rc = Rc @ E
        if j.type == "fixed":
            tc = position
            continue
        if pending is None:
            base_point = _tuple(position)
        else:
            out.append(_joint(pending, position, finger, links, children, on_path, problems))
        axis = np.asarray(j.axis if j.axis is not None else (1.0, 0.0, 0.0), dtype=float)
        limits = (float(j.limit.lower), float(j.limit.upper)) if j.type == "revolute" else None
        frame = None if np.array_equal(Rc, np.eye(3)) else _tuple_rows(Rc)
        pending = (_tuple(axis), limits, frame, j.child)
        Rc, tc = np.eye(3), np.zeros(3)
    R_tip, t_tip = tip_origin
    out.append(_joint(pending, tc + Rc @ t_tip, finger, links, children, on_path, problems))
    return base_point, tuple(out), tuple(j.name for j in moving), _tuple_rows(Rc @ R_tip)


def _tuple_rows(R) -> tuple:
    return tuple(_tuple(row) for row in _snap(R))


def _joint(pending, vector, finger, links, children, on_path, problems) -> RevoluteJoint:
    """The ``RevoluteJoint`` of a moving joint: its axis, limits and fixed frame, the vector to
    the next joint (or the fingertip frame), and the mass of its link and every link fixed to
    it."""
    axis, limits, frame, child = pending
    mass, com, inertia = _rigid_body(child, links, children, on_path, finger, problems)
    com_k, inertia_k = (_tuple(com), _tuple_rows(inertia)) if mass > 0 else (None, None)
    if mass > 0 and _is_rod(mass, com, inertia, np.asarray(vector, dtype=float)):
        com_k, inertia_k = None, None  # the uniform rod's, as RevoluteJoint writes it
    return RevoluteJoint(axis=axis, vector=_tuple(vector), mass=mass, com=com_k, inertia=inertia_k,
                         limits=limits, frame=frame)


def _is_rod(mass: float, com, inertia, vector) -> bool:
    """Whether ``com`` and ``inertia`` are the uniform rod's along ``vector`` (centre at
    mid-length, ``mass |vector|^2 / 12 (I - d d^T)``) to within 4 ulp of their scales."""
    length = float(np.linalg.norm(vector))
    if length == 0.0:
        return False
    d = vector / length
    rod = mass * length**2 / 12 * (np.eye(3) - np.outer(d, d))
    return bool(np.all(np.abs(com - vector / 2) <= _SNAP * length)
                and np.all(np.abs(inertia - rod) <= _SNAP * np.max(np.abs(rod))))


def _rigid_body(link_name, links, children, on_path, finger, problems):
    """kg, m, kg m^2: mass, centre of mass and inertia about it, in ``link_name``'s frame, of
    the link and every link fixed to it (fixed joints only)."""
    parts = []  # (mass, com, inertia) in link_name's frame

    def visit(name, R, t):
        link = links[name]
        inertial = link.inertial
        if inertial is not None and inertial.mass:
            Ri, ti = _origin(inertial)
            inertia_local = np.asarray(inertial.inertia if inertial.inertia is not None else np.zeros((3, 3)), float)
            Ri_full = R @ Ri
            parts.append((float(inertial.mass), t + R @ ti, Ri_full @ inertia_local @ Ri_full.T))
        for j in children.get(name, []):
            if j.type == "fixed":
                E, tj = _origin(j)
                visit(j.child, R @ E, t + R @ tj)
            elif j.name not in on_path:
                problems.append(f"finger {finger!r}: link {j.child!r} hangs from link {name!r} by the "
                                f"moving joint {j.name!r}, which leads to no tip; make it fixed or "
                                "give it a tip")

    visit(link_name, np.eye(3), np.zeros(3))
    mass = sum(m for m, _, _ in parts)
    if mass <= 0:
        return 0.0, np.zeros(3), np.zeros((3, 3))
    com = sum(m * c for m, c, _ in parts) / mass
    inertia = np.zeros((3, 3))
    for m, c, part in parts:
        d = c - com
        inertia += part + m * (d @ d * np.eye(3) - np.outer(d, d))
    return mass, com, inertia


def _tip_surface(finger, link, given, problems):
    """The fingertip surface of ``link`` and its frame ``(R, t)`` in the link's frame."""
    if given is not None:
        if not isinstance(given, ParametricSurface):
            problems.append(f"finger {finger!r}: surfaces[{finger!r}] = {given!r} is not a surface "
                            "(grasping_sym.geometry.surface_library)")
            return None
        return given, (np.eye(3), np.zeros(3))
    usable = [c for c in link.collisions
              if c.geometry is not None and (c.geometry.sphere is not None or c.geometry.cylinder is not None)]
    if len(usable) != 1:
        kinds = [_geometry_kind(c.geometry) for c in link.collisions] or ["none"]
        problems.append(f"finger {finger!r}: tip link {link.name!r} needs exactly one collision "
                        f"sphere or cylinder for its fingertip surface (it has: {', '.join(kinds)}); "
                        f"give one: from_urdf(..., surfaces={{{finger!r}: surface_library.sphere(r)}})")
        return None
    col = usable[0]
    name = f"fingertip {finger}"
    if col.geometry.sphere is not None:
        surface = surface_library.sphere(float(col.geometry.sphere.radius), name=name)
    else:
        r, length = float(col.geometry.cylinder.radius), float(col.geometry.cylinder.length)
        side = PlanarCurve(x=sp.Float(r), y=T, domain=(-length / 2, length / 2), name=f"{name} side")
        surface = surface_library.surface_of_revolution(side, axis="z", name=name)
    return surface, _origin(col)


def _geometry_kind(geometry) -> str:
    if geometry is None:
        return "none"
    for kind in ("box", "cylinder", "sphere", "mesh"):
        if getattr(geometry, kind, None) is not None:
            return kind
    return "unknown"

