"""``gs.export.mjcf``: a 3D grasp as a MuJoCo scene, loaded in real MuJoCo and checked
against the package's own kinematics and dynamics: fingertip frames, joint limits, the
fingers' inertia matrices and gravity torques, the object's pose and mass properties; the
paper's law in MuJoCo's terms holds paper3d's object."""
from __future__ import annotations

import casadi as ca
import numpy as np
import pytest

import grasping_sym as gs
from grasping_sym import export
from grasping_sym.derive.bodies3d import finger_sx
from grasping_sym.errors import InvalidSceneError
from grasping_sym.model.hand_poses import tip_pose

mujoco = pytest.importorskip("mujoco")


def _loaded(model_or_scene):
    m = mujoco.MjModel.from_xml_string(export.mjcf(model_or_scene))
    d = mujoco.MjData(m)
    mujoco.mj_resetDataKeyframe(m, d, 0)
    mujoco.mj_forward(m, d)
    return m, d


def _finger_terms(chain, gravity, q):
    """``G(q)`` and ``dP/dq`` of the package's finger derivation (``derive.bodies3d``)."""
    qs, dqs = ca.SX.sym("q", chain.n), ca.SX.sym("dq", chain.n)
    out = finger_sx(chain, gravity, qs, dqs)
    f = ca.Function("f", [qs, dqs], [out["G"], out["dP"]])
    G, dP = f(q, np.zeros(chain.n))
    return np.asarray(G), np.asarray(dP).ravel()


def test_trifinger_in_mujoco_has_the_derivations_kinematics_inertia_and_gravity():
    """gs.scenes.trifinger() at its guesses: every fingertip site at the fingertip centre and
    frame of ``tip_pose`` (1e-15 m), the joints' ranges their limits, each finger's block of
    MuJoCo's joint-space inertia matrix equal to the derivation's G(q) (1e-12 relative) and
    MuJoCo's gravity compensation equal to dP/dq (1e-12 N m), the object's mass and inertia
    the scene's."""
    scene = gs.scenes.trifinger()
    m, d = _loaded(scene)
    full = np.zeros((m.nv, m.nv))
    for j in range(m.nv):  # M e_j, column by column (mj_mulM: the same in every MuJoCo version)
        e, column = np.zeros(m.nv), np.zeros(m.nv)
        e[j] = 1.0
        mujoco.mj_mulM(m, d, column, e)
        full[:, j] = column
    for i, f in enumerate(scene.fingers, start=1):
        r, Pi = tip_pose(f.chain, f.q0)
        site = m.site(f"tip{i}").id
        np.testing.assert_allclose(d.site_xpos[site], r, rtol=0, atol=1e-15)
        np.testing.assert_allclose(d.site_xmat[site].reshape(3, 3), Pi, rtol=0, atol=1e-15)
        dofs = [m.joint(n).dofadr[0] for n in f.chain.joint_names]
        for name, joint in zip(f.chain.joint_names, f.chain.joints):
            assert tuple(m.jnt_range[m.joint(name).id]) == joint.limits
        G, dP = _finger_terms(f.chain, scene.gravity, np.array(f.q0))
        np.testing.assert_allclose(full[np.ix_(dofs, dofs)], G, rtol=1e-12, atol=1e-12 * np.abs(G).max())
        # MuJoCo's gravity compensation cancels the weight's generalised force -dP/dq
        np.testing.assert_allclose(d.qfrc_gravcomp[dofs], dP, rtol=0, atol=1e-12)
    body = m.body("object").id
    assert m.body_mass[body] == scene.mass
    np.testing.assert_allclose(np.sort(m.body_inertia[body]), np.sort(np.diag(scene.inertia)), rtol=1e-14)


def test_paper3d_in_mujoco_starts_at_the_consistent_start_and_the_paper_law_holds_it(paper3d_model):
    """paper3d built: the fingertips are sphere geoms and the object an ellipsoid geom (their
    surfaces recognised), the object's pose in MuJoCo is the model's start (1e-12), a run's
    rows as qpos replay its fingertips (1e-15 m); under ``paper_law`` for 0.2 s the object is
    held: it moves less than 2 cm, a tenth of a free fall's 0.196 m (MuJoCo's soft contacts
    give way by millimetres: 5.2 mm measured; benchmarks/soft_contact.py)."""
    m, d = _loaded(paper3d_model)
    x0 = paper3d_model.initial_state()
    names = paper3d_model.state_names
    body = m.body("object").id
    np.testing.assert_allclose(d.xpos[body], [x0[names.index(k)] for k in "xyz"], rtol=0, atol=1e-12)
    quat = np.array([x0[names.index(k)] for k in ("qw", "qx", "qy", "qz")])
    np.testing.assert_allclose(d.xquat[body], quat / np.linalg.norm(quat), rtol=0, atol=1e-12)
    assert m.geom("tip1").type == mujoco.mjtGeom.mjGEOM_SPHERE
    assert m.geom("object").type == mujoco.mjtGeom.mjGEOM_ELLIPSOID
    np.testing.assert_allclose(m.geom("object").size, gs.scenes.PAPER3D_SEMI_AXES, rtol=1e-12)
    for i, f in enumerate(paper3d_model.scene.fingers, start=1):
        q = [x0[names.index(n)] for n in f.chain.joint_names]
        np.testing.assert_allclose(d.site_xpos[m.site(f"tip{i}").id], tip_pose(f.chain, q)[0], rtol=0, atol=1e-15)
    # a run replayed in MuJoCo: its rows as qpos put the fingertips where the run has them
    res = paper3d_model.simulate(0.05, t_eval=[0.0, 0.05])
    # the object's rotation along the run, from its quaternion, is MuJoCo's at the start
    np.testing.assert_allclose(res.object_rotations()[0], d.xmat[body].reshape(3, 3), rtol=0, atol=1e-12)
    rows = export.qpos(paper3d_model, res)
    np.testing.assert_allclose(rows[0], d.qpos, rtol=0, atol=1e-12)
    replay = mujoco.MjData(m)
    replay.qpos[:] = rows[-1]
    mujoco.mj_forward(m, replay)
    for i, f in enumerate(paper3d_model.scene.fingers, start=1):
        q = [res.x[-1][names.index(n)] for n in f.chain.joint_names]
        np.testing.assert_allclose(replay.site_xpos[m.site(f"tip{i}").id], tip_pose(f.chain, q)[0], rtol=0,
                                   atol=1e-15)
    law = export.paper_law(paper3d_model)
    start = d.xpos[body].copy()
    for _ in range(200):
        law(m, d)
        mujoco.mj_step(m, d)
    assert d.ncon >= 2 and np.linalg.norm(d.xpos[body] - start) < 0.02


def test_a_surface_that_is_no_primitive_is_a_mesh_of_its_chart():
    """The rounded cube of gs.scenes.trifinger() (neither a sphere nor an ellipsoid) is a
    mesh of its chart's samples, between the inscribed sphere (radius a) and the cube's
    corners (a sqrt 3): |x/a|^4 + |y/a|^4 + |z/a|^4 = 1 reaches a 3^(1/4) at most."""
    scene = gs.scenes.trifinger()
    m = mujoco.MjModel.from_xml_string(export.mjcf(scene))
    geom = m.geom("object")
    assert geom.type == mujoco.mjtGeom.mjGEOM_MESH
    half = gs.scenes.TRIFINGER_CUBE[0]
    mesh = m.mesh(int(geom.dataid[0]))
    vertices = m.mesh_vert[mesh.vertadr[0]:mesh.vertadr[0] + mesh.vertnum[0]]
    # MuJoCo keeps the mesh in its inertial frame: recentre on the vertices' bounding box
    centred = vertices - 0.5 * (vertices.max(axis=0) + vertices.min(axis=0))
    radius = np.sort(np.linalg.norm(centred, axis=1))
    assert vertices.shape[0] > 100
    assert half * (1 - 1e-6) < radius[0] and radius[-1] < half * 3 ** 0.25 * (1 + 1e-6)


def test_one_fingers_paper_law_pulls_toward_the_scenes_position_as_the_package_law_does():
    """pivot3d (one finger, a pivoted object: a ball joint) under ``paper_law``, the law given
    as the preset ``gs.controllers.paper3d()``: the torques are ``-J^T (fd / r_ctrl)(r_1 -
    position)`` on MuJoCo's own site and Jacobian (the package law's anchor for one finger),
    not the empty sum over other fingers."""
    from dataclasses import replace
    from types import SimpleNamespace

    model = gs.build(gs.scenes.pivot3d())
    m, d = _loaded(model)
    assert m.jnt_type[m.joint("object").id] == mujoco.mjtJoint.mjJNT_BALL
    scene = replace(model.scene, controller=gs.controllers.paper3d())
    export.paper_law(SimpleNamespace(scene=scene, start_params=model.start_params))(m, d)
    site = m.site("tip1").id
    jac = np.zeros((3, m.nv))
    mujoco.mj_jacSite(m, d, jac, None, site)
    pull = (scene.params["fd"] / scene.r_ctrl) * (d.site_xpos[site] - np.asarray(scene.position))
    dofs = [m.joint(n).dofadr[0] for n in scene.fingers[0].chain.joint_names]
    expected = (-jac.T @ pull)[dofs] - scene.params["c"] * d.qvel[dofs]
    assert np.linalg.norm(expected) > 1e-3
    np.testing.assert_allclose(d.qfrc_applied[dofs], expected, rtol=1e-12)


def test_a_cylinders_side_is_no_ellipsoid():
    """The least-squares ellipsoid through a cylinder's side has an axis no sample comes near
    (~1e6 m along its own): refused, so the side is written as a mesh; an ellipsoid's chart
    samples to latitude 1.3 give its semi-axes."""
    u, v = np.meshgrid(np.linspace(-np.pi, np.pi, 24), np.linspace(-0.015, 0.015, 24))
    side = np.stack([0.008 * np.cos(u), 0.008 * np.sin(u), v], axis=-1).reshape(-1, 3)
    assert export._ellipsoid_fit(side) is None
    lat = np.linspace(-1.3, 1.3, 24)[:, None]
    shell = np.stack([0.02 * np.cos(lat) * np.cos(u), 0.025 * np.cos(lat) * np.sin(u),
                      0.03 * np.sin(lat) * np.ones_like(u)], axis=-1).reshape(-1, 3)
    np.testing.assert_allclose(export._ellipsoid_fit(shell), (0.02, 0.025, 0.03), rtol=1e-9)


def test_what_cannot_be_exported_is_refused_by_name():
    with pytest.raises(InvalidSceneError, match="writes 3D grasps"):
        export.mjcf(gs.scenes.paper2d())
    flat = gs.SimulationResult(t=np.zeros(1), x=np.zeros((1, 2)), state_names=("theta", "omega"), outputs={},
                               method="radau")
    with pytest.raises(KeyError, match="no object quaternion"):
        flat.object_rotations()
    np.testing.assert_allclose(export.quaternion(np.diag([1.0, -1.0, -1.0])), [0.0, 1.0, 0.0, 0.0])
