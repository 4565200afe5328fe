"""Hands read from URDF (``gs.hands.from_urdf``), against models and kinematics computed
without it: the papers' fingers written as URDF give paper3d's equations, TriFinger Pro's
published geometry gives yourdfpy's own forward kinematics, masses and kinetic energy, and
joint limits stop a run by name where the joint crosses them."""
from __future__ import annotations

import dataclasses
import json
from pathlib import Path

import casadi as ca
import numpy as np
import pytest
import yourdfpy

import grasping_sym as gs
from grasping_sym.derive.bodies3d import finger_sx
from grasping_sym.errors import JointLimitError
from grasping_sym.model import chains
from grasping_sym.model.hands import URDFError

DATA = Path(__file__).parent / "data"
PAPER = DATA / "paper_fingers.urdf"
TRIFINGER = gs.hands.TRIFINGER_URDF
TRIFINGER_TIPS = gs.hands.TRIFINGER_TIPS


def _paper3d_from(hand):
    ref = gs.scenes.paper3d()
    fingers = tuple(hand.finger(f.chain.name, f.q0, f.object_contact, f.tip_contact) for f in ref.fingers)
    return dataclasses.replace(ref, name="paper3d_urdf", fingers=fingers)


@pytest.fixture(scope="module")
def paper_models():
    hand = gs.hands.from_urdf(PAPER, tips={"1": "tip1", "2": "tip2"})
    return hand, gs.build(gs.scenes.paper3d()), gs.build(_paper3d_from(hand))


def test_the_papers_fingers_written_as_urdf_load_back_into_paper3ds_model(paper_models):
    """The chains equal the presets but for the joint limits (the rods' inertias, written
    out in the file, read back as rods); the compiled right-hand side equals paper3d's to
    1e-14 relative at random states around its start (the same structure is reused: limits
    are bounds, not equations)."""
    hand, ref, urdf = paper_models
    assert hand.joints == {"q11": "joint11", "q12": "joint12", "q21": "joint21", "q22": "joint22",
                           "q23": "joint23"}
    for chain, preset in zip(hand.chains, (chains.finger1(), chains.finger2())):
        assert chains.without_limits(chain) == preset
    assert hand.chains[0].joints[0].limits == (-1.0, 0.541)
    assert hand.chains[0].joints[1].limits is None
    assert urdf.state_names == ref.state_names
    rng = np.random.default_rng(7)
    x0 = ref.initial_state()
    worst = 0.0
    for _ in range(20):
        x = x0 + 0.02 * rng.standard_normal(x0.size)
        a, b = ref.rhs(x), urdf.rhs(x)
        worst = max(worst, float(np.max(np.abs(a - b)) / np.max(np.abs(a))))
    assert worst < 1e-14, worst


def test_a_joint_limit_stops_the_run_by_name_where_the_joint_crosses_it(paper_models):
    """joint11's upper limit 0.541 rad: paper3d's motion crosses it early (q11 starts at
    0.536 and rises to 0.544 at 0.06 s); the run stops there with ``JointLimitError`` naming q11, at the step where
    the rolling model without limits crosses 0.541."""
    _, ref, urdf = paper_models
    free = ref.simulate(0.2, t_eval=np.linspace(0.0, 0.2, 20001))
    q11 = free["q11"]
    k = int(np.argmax(q11 > 0.541))
    assert k > 0, "the unlimited run must cross 0.541 rad for this test"
    t_cross = free.t[k - 1] + (0.541 - q11[k - 1]) / (q11[k] - q11[k - 1]) * (free.t[k] - free.t[k - 1])
    for method in ("radau", "dop853"):
        with pytest.raises(JointLimitError, match=r"joint q11 reached its limits \[-1, 0\.541\]") as info:
            urdf.simulate(0.2, method=method)
        err = info.value
        i = urdf.state_names.index("q11")
        assert err.x[i] <= 0.541 and err.t <= t_cross + 1e-9
        assert t_cross - err.t < 5e-3, (method, err.t, t_cross)
    x = urdf.initial_state()
    x[urdf.state_names.index("q11")] = 0.6
    with pytest.raises(JointLimitError, match="q11"):
        urdf.simulate(0.01, x0=x)


def _frame(urdf_robot, link):
    return urdf_robot.get_transform(frame_to=link, frame_from=urdf_robot.base_link)


def test_trifinger_pro_gives_yourdfpys_kinematics_masses_and_kinetic_energy():
    """At random joint angles inside the limits: each fingertip's centre and frame from the
    derivation equal yourdfpy's forward kinematics (1e-13 m); each finger's mass is its
    links' (the tip link fixed to the lower link included); the potential energy and the
    kinetic energy equal sums over yourdfpy's link frames (velocities by central
    differences of its forward kinematics)."""
    hand = gs.hands.from_urdf(TRIFINGER, tips=TRIFINGER_TIPS)
    robot = yourdfpy.URDF.load(str(TRIFINGER), load_meshes=False, build_collision_scene_graph=False)
    assert len(hand.chains) == 3 and all(c.n == 3 for c in hand.chains)
    for c in hand.chains:
        assert c.total_mass == pytest.approx(0.26 + 0.25 + 0.021 + 0.031, rel=1e-15)
        assert [j.limits for j in c.joints] == [(-0.33, 1.0), (0.0, 1.57), (-2.7, 0.0)]
    g = (0.0, 0.0, -9.81)
    rng = np.random.default_rng(3)
    links = {}  # finger -> [(link, mass, com, inertia in the link frame)], from the file
    for finger, chain in zip("123", hand.chains):
        # the derivation the build uses: the finger's template, placed (derive.bodies3d)
        qs, dqs = ca.SX.sym("q", chain.n), ca.SX.sym("dq", chain.n)
        out = finger_sx(chain, g, qs, dqs)
        fn = ca.Function("finger", [qs, dqs], [out["r"], out["Pi"], out["G"], out["P"]])
        names = [hand.joints[n] for n in chain.joint_names]
        links[finger] = [(robot.link_map[ln].name, robot.link_map[ln].inertial)
                         for ln in (robot.joint_map[n].child for n in names)] + \
            [(TRIFINGER_TIPS[finger], robot.link_map[TRIFINGER_TIPS[finger]].inertial)]
        for _ in range(5):
            q = np.array([rng.uniform(*j.limits) for j in chain.joints])
            dq = rng.uniform(-2, 2, 3)
            cfg = dict(zip(names, q))
            robot.update_cfg(cfg)
            T = _frame(robot, TRIFINGER_TIPS[finger])
            r, Pi, G, P = (np.asarray(v) for v in fn(q, dq))
            np.testing.assert_allclose(r.ravel(), T[:3, 3], rtol=0, atol=1e-13)
            np.testing.assert_allclose(Pi, T[:3, :3], rtol=0, atol=1e-13)

            h = 1e-6
            plus, minus, here = (_bodies(robot, names, links[finger], qq) for qq in (q + h * dq, q - h * dq, q))
            kinetic = potential = 0.0
            for (m, cp, Rp, _), (_, cm, Rm, _), (_, c0, R0, inertia) in zip(plus, minus, here):
                v = (cp - cm) / (2 * h)
                W = (Rp - Rm) / (2 * h) @ R0.T
                w = np.array([W[2, 1], W[0, 2], W[1, 0]])
                kinetic += 0.5 * m * v @ v + 0.5 * w @ (R0 @ inertia @ R0.T) @ w
                potential -= m * np.dot(g, c0)
            assert 0.5 * dq @ G @ dq == pytest.approx(kinetic, rel=1e-8)
            assert P.item() == pytest.approx(potential, rel=1e-12, abs=1e-15)


@pytest.fixture(scope="module")
def trifinger():
    return gs.build(gs.scenes.trifinger())


def test_a_sweep_measures_the_least_grasp_quality_of_each_run(trifinger, tmp_path):
    """``gs.sweep(..., measures=["min:epsilon"])`` over mu: each point's value is the least
    lower bound of epsilon along that run's samples, as ``grasp_quality`` of the same run gives
    it; more friction, a larger epsilon. Without mu the measure is refused by name."""
    ds = gs.sweep(trifinger, {"mu": [0.3, 0.6]}, 0.2, store=tmp_path / "quality.zarr",
                  measures=["min:epsilon"], samples=5, progress=False)
    values = np.asarray(ds["min_epsilon"]).ravel()
    for mu, value in zip((0.3, 0.6), values):
        res = trifinger.simulate(0.2, t_eval=np.linspace(0.0, 0.2, 5))
        direct = float(np.min(trifinger.grasp_quality(res, mu=mu)["epsilon_lower"]))
        assert value == pytest.approx(direct, rel=1e-6)
    assert 0 < values[0] < values[1]
    here = {"r_bar0_x": [trifinger.start_params["r_bar0_x"]]}
    with pytest.raises(ValueError, match="'min:epsilon' \\(with mu, for a 3D grasp or a free 2D object"):
        gs.sweep(trifinger, here, 0.1, store=tmp_path / "no_mu.zarr", measures=["min:epsilon"],
                 progress=False)


def test_the_trifinger_scene_holds_its_rounded_cube_in_force_closure(trifinger):
    """``gs.scenes.trifinger()``: three fingertips on a free rounded cube under gravity. Along
    0.3 s: every contact pushes (f > 0.5 N), no joint reaches its limits, the object's
    momentum changes by the contact forces and its weight (m v' = F1 + F2 + F3 + m g, 1e-9 N
    at the output times, with v' from the run's own rhs), and with mu = 0.5 the three
    contacts are in force closure with a positive epsilon, as three inward pushes 120
    degrees apart are."""
    from grasping_sym.pipeline.quality_along import contact_forces

    model = trifinger
    # at rtol 1e-9: the contact frames carry the run's error (the gaps C alone are projected,
    # docs/conventions.md section 2), 1.1e-9 N at the default rtol 1e-7
    res = model.simulate(0.3, t_eval=np.linspace(0.0, 0.3, 7), rtol=1e-9, atol=1e-11)
    for i in (1, 2, 3):
        assert res[f"f{i}"].min() > 0.5
    names = model.state_names
    for name, (lo, hi) in model.scene.joint_limits().items():
        assert lo < res[name].min() and res[name].max() < hi, name
    forces = contact_forces(model, res)  # (rows, contacts, 3)
    m, g = model.scene.mass, np.array(model.scene.gravity)
    k_v = [names.index(k) for k in ("vx", "vy", "vz")]
    for row, x in enumerate(res.x):
        np.testing.assert_allclose(m * model.rhs(x)[k_v], forces[row].sum(axis=0) + m * g, rtol=0, atol=1e-9)
    quality = model.grasp_quality(res, mu=0.5)
    assert np.all(quality["force_closure"]) and np.all(quality["epsilon_lower"] > 0)


def test_the_solid_superquadrics_inertia_is_the_ellipsoids_at_n_2_and_a_sampled_bodys_at_n_4():
    from grasping_sym.model.inertia import solid_ellipsoid_inertia, solid_superquadric_inertia

    np.testing.assert_allclose(solid_superquadric_inertia(0.3, 0.02, 0.03, 0.04, 2),
                               solid_ellipsoid_inertia(0.3, 0.02, 0.03, 0.04), rtol=1e-14)
    a, b, c, n, mass = 0.02, 0.03, 0.05, 4, 0.7
    rng = np.random.default_rng(11)
    p = rng.uniform(-1.0, 1.0, (2_000_000, 3)) * (a, b, c)
    p = p[np.sum((p / (a, b, c)) ** n, axis=1) <= 1.0]
    sampled = mass * np.array([np.mean(p[:, 1] ** 2 + p[:, 2] ** 2), np.mean(p[:, 0] ** 2 + p[:, 2] ** 2),
                               np.mean(p[:, 0] ** 2 + p[:, 1] ** 2)])
    np.testing.assert_allclose(np.diag(solid_superquadric_inertia(mass, a, b, c, n)), sampled, rtol=2e-3)


def _bodies(robot, names, links, q):
    """``(mass, centre of mass, inertial frame, inertia)`` of each link, from yourdfpy's
    forward kinematics at the joint angles ``q``."""
    robot.update_cfg(dict(zip(names, q)))
    out = []
    for link, inertial in links:
        T = _frame(robot, link) @ inertial.origin
        out.append((inertial.mass, T[:3, 3], T[:3, :3], inertial.inertia))
    return out


def _write(tmp_path, body: str, name="hand.urdf") -> Path:
    path = tmp_path / name
    path.write_text(f'<?xml version="1.0"?>\n<robot name="bad">\n{body}\n</robot>\n')
    return path


FINGER = """
  <link name="base"/>
  <link name="a"><inertial><mass value="0.1"/><origin xyz="0 0.05 0"/>
    <inertia ixx="1e-5" iyy="1e-6" izz="1e-5" ixy="0" ixz="0" iyz="0"/></inertial></link>
  <link name="tip">{tip}</link>
  <joint name="j1" type="{kind}"><parent link="base"/><child link="a"/><axis xyz="0 0 1"/>{limit}</joint>
  <joint name="j2" type="fixed"><parent link="a"/><child link="tip"/><origin xyz="0 0.1 0"/></joint>
"""
SPHERE = '<collision><geometry><sphere radius="0.01"/></geometry></collision>'
LIMIT = '<limit lower="-1" upper="1" effort="1" velocity="1"/>'


def test_what_cannot_be_read_as_a_hand_is_refused_by_name(tmp_path):
    """Each bad file or argument names the problem and its fix; nothing is guessed."""
    ok = _write(tmp_path, FINGER.format(tip=SPHERE, kind="revolute", limit=LIMIT))
    assert gs.hands.from_urdf(ok, tips={"1": "tip"}).chains[0].joints[0].limits == (-1.0, 1.0)
    cases = {
        "cannot be read as URDF": _write(tmp_path, "<link", "broken.urdf"),
        "is prismatic": _write(tmp_path, FINGER.format(tip=SPHERE, kind="prismatic", limit=LIMIT), "p.urdf"),
        "has no <limit lower upper>": _write(tmp_path, FINGER.format(tip=SPHERE, kind="revolute", limit=""),
                                             "l.urdf"),
        r"exactly one collision sphere or cylinder .*it has: box": _write(
            tmp_path, FINGER.format(tip='<collision><geometry><box size="1 1 1"/></geometry></collision>',
                                    kind="continuous", limit=""), "b.urdf"),
    }
    for message, path in cases.items():
        with pytest.raises(URDFError, match=message):
            gs.hands.from_urdf(path, tips={"1": "tip"})
    loop = ('<link name="base"/><link name="a"/><link name="b"/>'
            '<joint name="ab" type="fixed"><parent link="a"/><child link="b"/></joint>'
            '<joint name="ba" type="fixed"><parent link="b"/><child link="a"/></joint>')
    with pytest.raises(URDFError, match="loop back to link"):
        gs.hands.from_urdf(_write(tmp_path, loop, "loop.urdf"), tips={"1": "a"}, base="base")
    with pytest.raises(URDFError, match="tip link 'nowhere' of finger '1' is not in the file"):
        gs.hands.from_urdf(ok, tips={"1": "nowhere"})
    with pytest.raises(URDFError, match="must be alphanumeric"):
        gs.hands.from_urdf(ok, tips={"f-1": "tip"})
    with pytest.raises(URDFError, match="moves both finger '1' and finger '2'"):
        gs.hands.from_urdf(ok, tips={"1": "tip", "2": "a"})
    # a collision cylinder (radius 8 mm, length 30 mm, turned by its origin) is its side, in
    # the fingertip frame at the collision's origin: every point 8 mm from its z axis
    cylinder = ('<collision><origin xyz="0 0.01 0" rpy="1.5707963267948966 0 0"/>'
                '<geometry><cylinder radius="0.008" length="0.03"/></geometry></collision>')
    hand = gs.hands.from_urdf(_write(tmp_path, FINGER.format(tip=cylinder, kind="revolute", limit=LIMIT),
                                     "cyl.urdf"), tips={"1": "tip"})
    (u0, u1), (v0, v1) = hand.tips[0].domain
    uu, vv = np.meshgrid(np.linspace(u0, u1, 7), np.linspace(v0, v1, 5))
    points = hand.tips[0].evaluate(uu, vv)["point"]
    np.testing.assert_allclose(np.hypot(points[..., 0], points[..., 1]), 0.008, rtol=1e-14)
    assert (v0, v1) == (-0.015, 0.015)
    chain = hand.chains[0]
    np.testing.assert_allclose(chain.joints[-1].vector, (0.0, 0.11, 0.0), atol=1e-16)  # 0.1 + 0.01
    np.testing.assert_allclose(np.asarray(chain.tip_rotation) @ (0.0, 0.0, 1.0), (0.0, -1.0, 0.0), atol=1e-16)
    # a tip without a usable collision takes the surface the user gives
    boxed = cases[r"exactly one collision sphere or cylinder .*it has: box"]
    hand = gs.hands.from_urdf(boxed, tips={"1": "tip"},
                              surfaces={"1": gs.scenes.surface_library.sphere(0.02)})
    assert hand.tips[0].name == "sphere" and hand.chains[0].joints[0].limits is None


def test_a_hand_read_again_comes_from_its_parsed_record_without_yourdfpy(tmp_path, monkeypatch):
    """The first read of a URDF file keeps what the reading uses of it in the cache
    (``<root>/urdf/``); a later process reads the same hand from that record without importing
    yourdfpy (and trimesh); a record that does not parse as one is parsed again, and a changed
    file is a new record."""
    import subprocess
    import sys

    monkeypatch.setenv("GRASPING_SYM_CACHE", str(tmp_path / "cache"))
    first = gs.hands.from_urdf(TRIFINGER, tips=TRIFINGER_TIPS)
    (record,) = (tmp_path / "cache" / "urdf").glob("*.json")
    code = ("import sys, pickle; import grasping_sym as gs; "
            "h = gs.hands.from_urdf(gs.hands.TRIFINGER_URDF, tips=gs.hands.TRIFINGER_TIPS); "
            "sys.stdout.buffer.write(pickle.dumps((h.chains, h.joints, h.tip_links, h.name, "
            "[str(t.S) for t in h.tips], 'yourdfpy' in sys.modules, 'trimesh' in sys.modules)))")
    import pickle
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, check=True).stdout
    chains_, joints, tip_links, name, tips, yourdfpy_loaded, trimesh_loaded = pickle.loads(out)
    assert not yourdfpy_loaded and not trimesh_loaded
    assert (chains_, joints, tip_links, name) == (first.chains, first.joints, first.tip_links, first.name)
    assert tips == [str(t.S) for t in first.tips]
    key = json.loads(record.read_text())["key"]
    for damaged in ('{"key": "not this file", "robot": []}', json.dumps({"key": key, "robot": {}}),
                    json.dumps({"key": key, "robot": {"name": "x", "links": [{}], "joints": []}})):
        record.write_text(damaged)
        again = gs.hands.from_urdf(TRIFINGER, tips=TRIFINGER_TIPS)
        assert again.chains == first.chains and '"robot": {' in record.read_text()  # parsed, rewritten
        assert json.loads(record.read_text())["robot"]["links"]
    edited = tmp_path / "edited.urdf"
    edited.write_text(TRIFINGER.read_text().replace('radius="0.01"', 'radius="0.012"', 1))
    other = gs.hands.from_urdf(edited, tips=TRIFINGER_TIPS)
    assert len(list((tmp_path / "cache" / "urdf").glob("*.json"))) == 2 and other.chains == first.chains
    assert other.tips[0].S != first.tips[0].S
