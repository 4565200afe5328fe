"""A 3D grasp as a MuJoCo scene (MJCF): the same bodies, masses, inertias, joint limits,
gravity and start (docs/conventions.md section 12).

``gs.export.mjcf(model)`` writes the scene of a built 3D grasp (``gs.build``), started at its
consistent start; ``gs.export.mjcf(scene)`` at the scene's own guesses. Load it with
``mujoco.MjModel.from_xml_string`` and start it with ``mujoco.mj_resetDataKeyframe(m, d, 0)``
(the keyframe ``start``: the joint angles and the object's pose); ``gs.export.qpos(model, res)``
gives a run as MuJoCo ``qpos`` rows, for replay. ``gs.export.paper_law(model)`` gives the paper's grasp
law written in MuJoCo's terms, to call before each ``mj_step`` (MuJoCo has no such
controller).

What is written:

- each finger is nested bodies, one hinge per joint: body ``k`` sits at the previous link's
  ``vector`` (the first at ``base``) turned by the joint's fixed ``frame``; the hinge's axis is
  the joint's; a joint with ``limits`` has ``range`` (radians: ``<compiler angle="radian">``);
- each link's inertial is the chain's (a uniform rod's unless given). MuJoCo needs positive
  principal moments: a rod's zero moment about its own axis is written as ``ROD_EPSILON``;
  a massless coincident joint's link gets ``MASSLESS`` kg;
- each fingertip is a geom in the fingertip frame: a ``sphere`` or an ``ellipsoid`` when its
  surface is one (all sampled points on it to 1e-9), else a ``mesh`` of the surface sampled
  over its chart's domain (MuJoCo collides with its convex hull), with a site ``tip{i}`` at
  the fingertip centre;
- the object is a body with a free joint (``support="free"``) or a ball joint at its pivot,
  the scene's mass and inertia, a geom of its surface as above, at the start's pose;
- gravity is the scene's; finger links carry ``gravcomp="1"``: MuJoCo cancels their weight, as
  the grasp law's gravity term does;
- contacts are fingertip against object only, ``condim=4`` (sliding and torsional friction),
  with the coefficients given.
"""
from __future__ import annotations

import math
from pathlib import Path
from xml.sax.saxutils import quoteattr

import numpy as np

from grasping_sym.errors import InvalidSceneError

#: kg m^2, what a rod's zero moment about its own axis is written as (MuJoCo needs it > 0).
ROD_EPSILON = 1e-10
#: kg, the mass of a massless coincident joint's link (MuJoCo needs a body's mass > 0).
MASSLESS = 1e-9
#: Chart samples per direction of a surface written as a mesh.
MESH_SAMPLES = 24


def mjcf(model_or_scene, path=None, *, timestep: float = 1e-3, friction: float = 1.0,
         torsion: float = 1e-3, margin: float = 0.0, noslip: int = 0, samples: int = MESH_SAMPLES) -> str:
    """The MJCF text of a 3D grasp (module docstring), written to ``path`` too if given.

    Parameters
    ----------
    model_or_scene
        A built 3D grasp (its consistent start is written) or a ``GraspScene3D`` (its guesses).
    timestep
        s, MuJoCo's step.
    friction, torsion
        Sliding friction coefficient and torsional friction (m) of the fingertip contacts.
    margin
        m, MuJoCo's contact ``margin`` and ``gap`` of the fingertips and the object (contacts
        found that far apart, not acting until they touch).
    noslip
        MuJoCo's ``noslip_iterations`` (0: its default, soft friction).
    samples
        Chart samples per direction of a surface written as a mesh.
    """
    scene = getattr(model_or_scene, "scene", None) or model_or_scene
    if getattr(scene, "kind", None) != "grasp3d":
        raise InvalidSceneError([f"gs.export.mjcf writes 3D grasps (kind 'grasp3d'), not "
                                 f"{getattr(scene, 'kind', type(scene).__name__)!r}: give a "
                                 "GraspScene3D or its built model"])
    q, pos, quat = _start(model_or_scene, scene)
    contact = (f'condim="4" friction="{_num(friction)} {_num(torsion)} 0" margin="{_num(margin)}" '
               f'gap="{_num(margin)}"')
    assets, fingers = [], []
    for i, f in enumerate(scene.fingers, start=1):
        fingers.append(_finger(i, f, assets, samples, f'contype="1" conaffinity="2" {contact}'))
    object_geom = _geom("object", scene.object_surface, np.zeros(3), np.eye(3), assets, samples,
                        f'contype="2" conaffinity="1" {contact} rgba=".85 .2 .2 .6"')
    joint = '<freejoint name="object"/>' if scene.free else '<joint name="object" type="ball"/>'
    H = np.asarray(scene.inertia, dtype=float)
    inertia = " ".join(_num(H[i, j]) for i, j in ((0, 0), (1, 1), (2, 2), (0, 1), (0, 2), (1, 2)))
    gravity = " ".join(_num(v) for v in (scene.gravity or (0.0, 0.0, 0.0)))
    qpos = [v for _, v in q] + ([*pos] if scene.free else []) + [*quat]
    text = f"""<mujoco model={quoteattr(scene.name)}>
  <compiler angle="radian"/>
  <option timestep="{_num(timestep)}" gravity="{gravity}" integrator="implicitfast" noslip_iterations="{int(noslip)}"/>
  <asset>{"".join(assets)}</asset>
  <worldbody>
    {"".join(fingers)}
    <body name="object" pos="{_vec(pos)}" quat="{_vec(quat)}">
      {joint}
      <inertial pos="0 0 0" mass="{_num(scene.mass)}" fullinertia="{inertia}"/>
      {object_geom}
    </body>
  </worldbody>
  <keyframe><key name="start" qpos="{_vec(qpos)}"/></keyframe>
</mujoco>
"""
    if path is not None:
        Path(path).write_text(text)
    return text


def qpos(model, result) -> np.ndarray:
    """The run ``result`` of ``model`` as MuJoCo ``qpos`` rows ``(n, nq)`` of :func:`mjcf`'s
    scene (the joint angles, then the object's position, if free, and quaternion): set
    ``d.qpos[:] = row`` and ``mujoco.mj_forward`` to replay it in MuJoCo's viewer or renderer."""
    scene = model.scene
    names = list(result.state_names)
    cols = [n for f in scene.fingers for n in f.chain.joint_names]
    cols += (["x", "y", "z"] if scene.free else []) + ["qw", "qx", "qy", "qz"]
    X = np.asarray(result.x, dtype=float)
    rows = X[:, [names.index(c) for c in cols]]
    quat = rows[:, -4:]
    rows[:, -4:] = quat / np.linalg.norm(quat, axis=1, keepdims=True)
    return rows


def _start(model_or_scene, scene) -> tuple[list, np.ndarray, np.ndarray]:
    """The joint angles, the object's position and quaternion (w, x, y, z) to write."""
    names = [n for f in scene.fingers for n in f.chain.joint_names]
    if hasattr(model_or_scene, "initial_state"):
        x0 = np.asarray(model_or_scene.initial_state(), dtype=float)
        idx = {k: i for i, k in enumerate(model_or_scene.state_names)}
        q = [(n, float(x0[idx[n]])) for n in names]
        pos = np.array([x0[idx[k]] for k in ("x", "y", "z")]) if scene.free else np.asarray(scene.position)
        quat = np.array([x0[idx[k]] for k in ("qw", "qx", "qy", "qz")])
        return q, pos, quat / np.linalg.norm(quat)
    q = [(n, float(v)) for f in scene.fingers for n, v in zip(f.chain.joint_names, f.q0)]
    return q, np.asarray(scene.position, dtype=float), quaternion(np.asarray(scene.rotation, dtype=float))


def _finger(i: int, f, assets: list, samples: int, contact: str) -> str:
    chain = f.chain
    xml, close, at = [], [], np.asarray(chain.base, dtype=float)
    for k, joint in enumerate(chain.joints, start=1):
        frame = "" if joint.frame is None else f' quat="{_vec(quaternion(np.asarray(joint.frame)))}"'
        limits = "" if joint.limits is None else f' limited="true" range="{_vec(joint.limits)}"'
        xml.append(f'<body name="f{i}l{k}" pos="{_vec(at)}"{frame} gravcomp="1">'
                   f'<joint name="q{chain.name}{k}" type="hinge" axis="{_vec(joint.axis)}"{limits}/>'
                   + _inertial(joint))
        vector = np.asarray(joint.vector, dtype=float)
        if np.linalg.norm(vector) > 0:
            xml.append(f'<geom type="capsule" fromto="0 0 0 {_vec(vector)}" size="0.003" contype="0" '
                       'conaffinity="0" mass="0" rgba=".4 .4 .4 1"/>')
        close.append("</body>")
        at = vector
    tip_pos = at + np.asarray(chain.tip_offset, dtype=float)
    tip_rot = np.asarray(chain.tip_rotation, dtype=float)
    xml.append(_geom(f"tip{i}", f.tip, tip_pos, tip_rot, assets, samples, contact))
    xml.append(f'<site name="tip{i}" pos="{_vec(tip_pos)}" quat="{_vec(quaternion(tip_rot))}"/>')
    return "".join(xml + close[::-1])


def _inertial(joint) -> str:
    if joint.mass <= 0:
        return f'<inertial pos="0 0 0" mass="{_num(MASSLESS)}" diaginertia="{_vec([MASSLESS * 1e-6] * 3)}"/>'
    vector = np.asarray(joint.vector, dtype=float)
    if joint.inertia is None:
        length = float(np.linalg.norm(vector))
        d = vector / length
        H = joint.mass * length**2 / 12 * (np.eye(3) - np.outer(d, d)) + ROD_EPSILON * np.outer(d, d)
    else:
        H = np.asarray(joint.inertia, dtype=float)
    full = " ".join(_num(H[a, b]) for a, b in ((0, 0), (1, 1), (2, 2), (0, 1), (0, 2), (1, 2)))
    return f'<inertial pos="{_vec(joint.com_local)}" mass="{_num(joint.mass)}" fullinertia="{full}"/>'


def _geom(name: str, surface, pos, rot, assets: list, samples: int, contact: str) -> str:
    """A geom of ``surface`` placed at ``pos``, ``rot`` in its body: a sphere when it is one,
    else a mesh sampled over its chart."""
    (u0, u1), (v0, v1) = surface.domain
    uu, vv = np.meshgrid(np.linspace(u0, u1, samples), np.linspace(v0, v1, samples), indexing="ij")
    points = surface.evaluate(uu, vv)["point"].reshape(-1, 3)
    centre, radius = _sphere_fit(points)
    if radius is not None:
        return (f'<geom name="{name}" type="sphere" pos="{_vec(pos + rot @ centre)}" size="{_num(radius)}" '
                f'{contact}/>')
    axes = _ellipsoid_fit(points)
    if axes is not None:
        return (f'<geom name="{name}" type="ellipsoid" pos="{_vec(pos)}" quat="{_vec(quaternion(rot))}" '
                f'size="{_vec(axes)}" {contact}/>')
    assets.append(f'<mesh name="{name}_mesh" vertex="{" ".join(_num(v) for v in points.ravel())}"/>')
    return (f'<geom name="{name}" type="mesh" mesh="{name}_mesh" pos="{_vec(pos)}" '
            f'quat="{_vec(quaternion(rot))}" {contact}/>')


def _sphere_fit(points: np.ndarray) -> tuple[np.ndarray, float | None]:
    """The centre and radius of the sphere through ``points`` (least squares on
    ``|p|^2 = 2 c . p + r^2 - |c|^2``), the radius None unless every point is on it to 1e-9
    of it."""
    A = np.column_stack([2 * points, np.ones(len(points))])
    b = np.sum(points * points, axis=1)
    sol, *_ = np.linalg.lstsq(A, b, rcond=None)
    centre = sol[:3]
    r2 = sol[3] + centre @ centre
    if r2 <= 0:
        return centre, None
    radius = math.sqrt(r2)
    spread = np.max(np.abs(np.linalg.norm(points - centre, axis=1) - radius))
    return centre, radius if spread <= 1e-9 * radius else None


def _ellipsoid_fit(points: np.ndarray) -> np.ndarray | None:
    """The semi-axes ``(a, b, c)`` of the ellipsoid ``(x/a)^2 + (y/b)^2 + (z/c)^2 = 1`` in the
    surface's own axes through ``points`` (least squares in ``1/a^2, 1/b^2, 1/c^2``), None
    unless every point is on it to 1e-9 and they reach half of every semi-axis."""
    k, *_ = np.linalg.lstsq(points * points, np.ones(len(points)), rcond=None)
    if np.any(k <= 0):
        return None
    residual = np.max(np.abs((points * points) @ k - 1.0))
    axes = 1.0 / np.sqrt(k)
    # the samples must reach half of every semi-axis (a chart stopping short of the poles
    # reaches 0.96 of it at latitude 1.3): a cylinder's side fits an "ellipsoid" with an axis
    # of ~1e6 m along its own (a coefficient ~1e-12), which no sample comes near
    reach = np.max(np.abs(points), axis=0)
    return axes if residual <= 1e-9 and np.all(axes <= 2.0 * reach) else None


def quaternion(R: np.ndarray) -> np.ndarray:
    """The unit quaternion ``(w, x, y, z)``, ``w >= 0``, of the rotation matrix ``R``
    (Shepperd's method: the largest of the four candidates, then the others from it)."""
    R = np.asarray(R, dtype=float)
    t = np.trace(R)
    cands = [t, R[0, 0], R[1, 1], R[2, 2]]
    k = int(np.argmax(cands))
    if k == 0:
        w = 0.5 * math.sqrt(1 + t)
        q = np.array([w, (R[2, 1] - R[1, 2]) / (4 * w), (R[0, 2] - R[2, 0]) / (4 * w), (R[1, 0] - R[0, 1]) / (4 * w)])
    else:
        i, j, m = k - 1, k % 3, (k + 1) % 3
        s = 0.5 * math.sqrt(max(0.0, 1 + R[i, i] - R[j, j] - R[m, m]))
        q = np.zeros(4)
        q[1 + i] = s
        q[0] = (R[m, j] - R[j, m]) / (4 * s)
        q[1 + j] = (R[j, i] + R[i, j]) / (4 * s)
        q[1 + m] = (R[m, i] + R[i, m]) / (4 * s)
    q = q / np.linalg.norm(q)
    return -q if q[0] < 0 else q


def paper_law(model):
    """The paper's grasp law (``gs.controllers.paper3d``, the scenes' default) in MuJoCo's
    terms, for a MuJoCo model of ``model`` (:func:`mjcf`): ``law(mj_model, mj_data)`` writes
    into ``qfrc_applied`` the joint torques ``-c q' - J_i^T [(fd / r_ctrl) sum_j (r_i - r_j) +
    (k_center / N)(r_bar - r_bar0)]`` (one finger: ``(fd / r_ctrl)(r_1 - position)``, toward
    the scene's ``position``, as the law's) from the fingertip sites ``tip{i}`` and their
    Jacobians (gravity is compensated by ``gravcomp``). Call it before each ``mj_step``."""
    import mujoco  # noqa: PLC0415 - MuJoCo only for a user who runs the export

    scene = model.scene
    law = scene.controller
    preset = law if law is None or isinstance(law, str) else getattr(law, "preset", None)
    if preset not in ("paper", "paper3d", None):
        raise InvalidSceneError([f"paper_law: the scene's law is {getattr(law, 'name', law)!r}; only the "
                                 "paper's law has a MuJoCo form here: write yours on mujoco's sites "
                                 "and Jacobians"])
    anchor = np.asarray(scene.position, dtype=float)  # one finger pulls toward it (the law's)
    fd, c, k_center = (float(scene.params[k]) for k in ("fd", "c", "k_center"))
    r_ctrl = float(scene.r_ctrl)
    start = dict(model.start_params)
    r_bar0 = np.array([start.get(f"r_bar0_{a}", 0.0) for a in "xyz"])
    joints = [n for f in scene.fingers for n in f.chain.joint_names]
    state = {}

    def law_fn(m, d) -> None:
        if not state:
            state["dofs"] = np.array([m.joint(j).dofadr[0] for j in joints])
            state["sites"] = [m.site(f"tip{i}").id for i in range(1, len(scene.fingers) + 1)]
            state["jac"] = np.zeros((3, m.nv))
        sites, jac, dofs = state["sites"], state["jac"], state["dofs"]
        r = [d.site_xpos[s].copy() for s in sites]
        n = len(r)
        r_bar = sum(r) / n
        tau = np.zeros(m.nv)
        for i, s in enumerate(sites):
            mujoco.mj_jacSite(m, d, jac, None, s)
            if n == 1:
                pull = (fd / r_ctrl) * (r[0] - anchor)
            else:
                pull = (fd / r_ctrl) * sum((r[i] - r[j] for j in range(n) if j != i), np.zeros(3))
            if k_center:
                pull = pull + (k_center / n) * (r_bar - r_bar0)
            tau -= jac.T @ pull
        tau[dofs] -= c * d.qvel[dofs]
        d.qfrc_applied[:] = 0.0
        d.qfrc_applied[dofs] = tau[dofs]

    return law_fn


def _num(v) -> str:
    return f"{float(v):.17g}"


def _vec(values) -> str:
    return " ".join(_num(v) for v in values)
