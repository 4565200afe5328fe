"""Free objects in 2D (``support="free"``): the object's mass centre moves in the plane.

Checks against answers derived elsewhere:
- the 3D model (``model.grasp3d``: a different derivation, in quaternions and surface
  coordinates) kept in its plane: two planar fingers with spherical tips pinch an ellipsoid
  whose section is the 2D ellipse, from a start with nothing symmetric; over 5 s the two
  agree on the object's position and angle, every joint angle and both normal forces;
- energy: d/dt (kinetic + potential) = q'.u, the object's translation and weight included;
- the closed loop compiled in layers (structure, contours, controller) against the SymPy
  statement of the whole loop (``derive_planar``) at random states;
- what a free object cannot have yet (contact modes) and a missing mass are refused by name.
"""
from __future__ import annotations

import dataclasses
import math
from types import SimpleNamespace

import casadi as ca
import numpy as np
import pytest
from scipy.integrate import cumulative_simpson

import grasping_sym as gs
from grasping_sym import sweeps
from grasping_sym.assemble.functions import build_casadi
from grasping_sym.derive.planar import derive_planar
from grasping_sym.errors import InvalidSceneError
from grasping_sym.geometry import surface_library
from grasping_sym.model import chains
from grasping_sym.model.grasp3d import Finger3D, GraspScene3D
from grasping_sym.pipeline.quality_along import contact_forces
from grasping_sym.runtime import modes
from grasping_sym.runtime import outputs as outputs_

SHIFT = chains.BASE_HALF_SPACING     # 2D finger 1 sits at the origin, 3D finger 1 at -SHIFT
T_FINAL = 5.0
TIGHT = {"rtol": 1e-12, "atol": 1e-12}


@pytest.fixture(scope="module")
def pinch():
    """pinch2d (its symmetric start) with its contact forces and energies, mu = 0.5."""
    return gs.build(gs.scenes.pinch2d(outputs=("f1", "f2", "lam1", "lam2", "constraint_residual",
                                               "kinetic_energy", "potential_energy", "power"),
                                      friction=gs.contact.coulomb(0.5)))


def _pinch(wide: bool = False, **kw):
    """pinch2d from a start with nothing symmetric: turned object, contacts off its axis;
    ``wide``: its contours over several turns (an open contact's point may go round)."""
    if wide:
        kw.update(fingertip=gs.curves.circle(0.01, span=3 * math.pi),
                  object=gs.curves.ellipse(0.020, 0.025, start=math.pi / 2, span=3 * math.pi,
                                           clockwise=True))
    tip2 = {"fingertip": gs.curves.circle(0.01, span=3 * math.pi)} if wide else {}
    return gs.scenes.pinch2d(theta_0=0.25, u1_0=math.pi + 0.3, u0_0=0.002,
                             extra_fingers=(dataclasses.replace(gs.scenes.pinch2d().extra_fingers[0],
                                                                u1_0=-0.25, **tip2),), **kw)


def _planar_3d(scene2d, low=-math.pi / 2, planes=()):
    """The 3D model of ``scene2d`` kept in its plane: the 2D fingers as chains about -z, the
    fingertip circles as spheres, the ellipse as the section of an ellipsoid (third semi-axis
    0.030 m) with the 2D inertia about z, the 2D start as the 3D guesses (exactly consistent),
    and the 2D law (32) written as a law of the 3D quantities, pulling toward the same point.
    The ellipsoid's chart: longitudes ``(low, low + 2 pi)``, or ``(low, -low)`` for
    ``low < -pi`` (a chart over several turns); ``planes``: with modes and these
    planes of the world (``with_modes``)."""
    x2 = dict(zip(scene2d.state_names, scene2d.initial_state()))
    a, b = gs.scenes.PINCH2D_SEMI_AXES
    mass = scene2d.params["M"]
    inertia = np.array(gs.scenes.solid_ellipsoid_inertia(mass, a, b, 0.030))
    assert inertia[2, 2] == pytest.approx(scene2d.params["I"], rel=1e-15)
    xm, ym = scene2d.pivot
    anchor = ca.DM([xm - SHIFT, ym, 0.0])
    fd, r, c = (scene2d.params[k] for k in ("fd", "r", "c"))

    @gs.controllers.law
    def pull(m):
        return [-c * dq - J.T @ ((fd / r) * (tip - anchor)) + g
                for dq, J, tip, g in zip(m.dq, m.J, m.tip, m.gravity_torque)]

    radius = 0.01
    tip_lon = (-3 * math.pi, 3 * math.pi) if low < -math.pi else (-math.pi, math.pi)

    def finger(i, chain):
        u0, u1 = x2[f"u0_{i}"], x2[f"u1_{i}"]
        lon = (-u1 - low) % (2 * math.pi) + low     # the 3D chart's (low, low + 2 pi)
        return Finger3D(chain=chain, tip=surface_library.sphere(radius, name=f"tip {i}", lon=tip_lon),
                        q0=(x2[f"q{i}1"], x2[f"q{i}2"]), tip_contact=(u0 / radius, 0.0),
                        object_contact=(lon, 0.0))

    base2 = scene2d.extra_fingers[0].base
    fingers = (finger(1, chains.finger1()),
               finger(2, dataclasses.replace(chains.finger1(base=(base2[0] - SHIFT, base2[1], 0.0)),
                                             name="2")))
    th = x2["theta"]
    rot = ((math.cos(th), math.sin(th), 0.0), (-math.sin(th), math.cos(th), 0.0), (0.0, 0.0, 1.0))
    s3 = GraspScene3D(
        name="pinch_in_plane", fingers=fingers,
        object_surface=surface_library.ellipsoid(a, b, 0.030, lon=(low, -low if low < -math.pi
                                                                       else low + 2 * math.pi)),
        mass=mass, inertia=tuple(map(tuple, inertia)), support="free",
        position=(x2["x"] - SHIFT, x2["y"], 0.0), rotation=rot, gravity=(0.0, -9.81, 0.0),
        controller=pull, gain=300.0, dq0=(0.0,) * 4, outputs=("constraint_residual", "f1", "f2"))
    return gs.scenes.with_modes(s3, planes=planes) if planes else s3


def test_a_free_pinch_agrees_with_the_3d_model_kept_in_its_plane():
    # the 2D stabilisation critically damped at the 3D gain: both follow the same exact motion
    scene = _pinch(gf=300.0, gl=300.0, wf=300.0**2, wl=300.0**2,
                   outputs=("constraint_residual", "f1", "f2"))
    s3 = _planar_3d(scene)
    m2, m3 = gs.build(scene), gs.build(s3)
    x3 = dict(zip(m3.state_names, m3.initial_state()))
    x2 = dict(zip(scene.state_names, scene.initial_state()))
    assert abs(x3["x"] + SHIFT - x2["x"]) + abs(x3["y"] - x2["y"]) <= 1e-15   # the same start
    t = np.linspace(0.0, T_FINAL, 101)
    r2 = m2.simulate(T_FINAL, t_eval=t, method="radau", **TIGHT)
    r3 = m3.simulate(T_FINAL, t_eval=t, method="dop853", **TIGHT)
    R = r3.object_rotations()
    theta3 = -np.arctan2(R[:, 1, 0], R[:, 0, 0])        # 2D: Om + Rot(-theta) c
    diff = {"x": r3["x"] + SHIFT - r2["x"], "y": r3["y"] - r2["y"], "theta": theta3 - r2["theta"],
            **{k: r3[k] - r2[k] for k in ("q11", "q12", "q21", "q22")}}
    worst = {k: float(np.max(np.abs(v))) for k, v in diff.items()}
    # measured 1.3e-12 at these tolerances (3.7e-10 at 1e-10); the object moves by 24 mm and
    # turns by 0.44 rad
    assert max(worst.values()) <= 1e-10, worst
    assert np.ptp(r2["theta"]) > 0.02 and np.ptp(r2["y"]) > 1e-3 and np.ptp(r2["x"]) > 1e-3
    for k in ("f1", "f2"):
        assert np.max(np.abs(r3[k] - r2[k])) <= 1e-8 * np.max(np.abs(r2[k])), k
    assert np.max(np.abs(r3["z"])) <= 1e-14                         # the 3D run stays in its plane


def test_a_free_object_balances_energy_with_its_weight(pinch):
    model = pinch
    t = np.linspace(0.0, 1.0, 4001)
    res = model.simulate(1.0, t_eval=t, rtol=1e-11, atol=1e-13)
    o = res.outputs
    energy = o["kinetic_energy"] + o["potential_energy"]
    work = cumulative_simpson(o["power"], x=res.t, initial=0.0)
    drift = np.max(np.abs(energy - energy[0] - work))
    # the object and fingers sag 5 mm (the potential changes by 5e-3 J); an error in its terms
    # would show at that scale; measured 1.7e-12 J
    assert np.ptp(o["potential_energy"]) > 1e-3
    assert drift <= 1e-9, drift
    assert o["constraint_residual"].max() <= 1e-10
    y = res["y"]
    assert y[-1] < y[0] - 4e-3                                       # it sags under its weight


def test_the_layers_compose_the_sympy_closed_loop_of_a_free_object():
    scene = _pinch(runtime=("M",), gravity=(0.5, -9.81))
    model = gs.build(scene)
    # the SymPy path closes the loop with the law's own statement (derive.planar.paper_law)
    direct = build_casadi(derive_planar(scene), list(scene.fingertips), scene.object, "direct")
    assert model.state_names[:3] == ("x", "y", "theta")
    rng = np.random.default_rng(5)
    x0 = scene.initial_state()
    names = list(model.state_names)
    acc = [names.index("dx"), names.index("dy")]
    for mass in (0.03, 0.05):          # M a run-time input of both
        for _ in range(3):
            x = x0 + rng.normal(size=x0.size) * 0.01
            a = np.array(direct.rhs(0, x, [], [mass], [])[0]).ravel()
            b = model.rhs(x, [mass])
            np.testing.assert_allclose(a, b, rtol=1e-12, atol=1e-12 * np.abs(a).max())
            assert np.abs(a[acc]).max() > 1e-2                      # the object accelerates


def test_a_free_object_needs_its_mass_and_two_fingers_for_modes():
    with pytest.raises(InvalidSceneError, match="a free object needs its mass M"):
        gs.scenes.planar_finger(gs.curves.circle(0.01), gs.curves.circle(0.02, clockwise=True),
                                support="free")
    with pytest.raises(InvalidSceneError, match="support='free'"):
        gs.scenes.paper2d(M=0.04)
    with pytest.raises(InvalidSceneError, match="support = 'loose'"):
        gs.scenes.paper2d(support="loose")
    with pytest.raises(InvalidSceneError, match="support='free' with one finger"):
        gs.scenes.with_modes(gs.scenes.pinch2d(extra_fingers=()))
    with pytest.raises(InvalidSceneError, match="nothing else holds the object"):
        gs.build(gs.scenes.pinch2d(extra_fingers=(), name="one_free"))




def test_grasp_quality_along_a_free_2d_pinch_has_its_closed_forms_and_newtons_law(pinch):
    mu, model = 0.5, pinch
    scene = model.scene
    res = model.simulate(1.0, t_eval=np.linspace(0.0, 1.0, 51))
    q = model.grasp_quality(res)
    # at the start two antipodal contacts at the ends of the ellipse's X axis, normals through
    # its centre (torque scale: their distance a): epsilon = mu / sqrt(2 + mu^2), exactly (2D)
    assert q["epsilon_lower"][0] == pytest.approx(mu / math.sqrt(2 + mu * mu), rel=1e-12)
    assert np.all(q["force_closure"] == 1.0)
    # the squeeze of two fingers pressing with f along the line between them: sqrt(2) f
    assert q["internal_force"][0] == pytest.approx(math.sqrt(2) * res["f1"][0], rel=1e-9)
    margin = np.minimum(mu * res["f1"] - np.abs(res["lam1"]), mu * res["f2"] - np.abs(res["lam2"]))
    np.testing.assert_allclose(q["cone_margin_min"], margin, rtol=1e-12, atol=1e-12)
    # Newton's law of the object from the contact forces: M Om'' = M g + sum of F_i
    forces = contact_forces(model, res)
    names = list(model.state_names)
    acc = np.array([model.rhs(x)[[names.index("dx"), names.index("dy")]] for x in res.x])
    mass = scene.params["M"]
    np.testing.assert_allclose(mass * acc, mass * np.array([0.0, -9.81]) + forces.sum(axis=1),
                               rtol=0, atol=1e-12)
    assert np.abs(acc).max() > 0.1                              # it moves


def test_a_sweep_measures_the_least_grasp_quality_of_a_free_2d_object(pinch, tmp_path):
    model = pinch
    ds = gs.sweep(model, {"mu": [0.3, 0.6]}, 0.2, store=tmp_path / "pinch.zarr",
                  measures=["min:epsilon"], samples=5, progress=False)
    values = np.asarray(ds["min_epsilon"]).ravel()
    res = model.simulate(0.2, t_eval=np.linspace(0.0, 0.2, 5))
    for mu, value in zip((0.3, 0.6), values):
        assert value == pytest.approx(float(np.min(model.grasp_quality(res, mu=mu)["epsilon_lower"])),
                                      rel=1e-6)
    assert 0 < values[0] < values[1]


def test_a_free_pinch_with_modes_slips_and_lets_go_as_the_3d_model_does():
    """With mu = 0.14 the asymmetric pinch (``_pinch``) holds at first, then each contact slides
    (rolling -> sliding where |lam| reaches mu f) and opens (f reaches 0): the object drops out of
    the grasp. The 2D model with modes (``derive.planar_modes`` of the free template) and the 3D
    one kept in its plane (``derive.grasp3d_modes``) locate the same four switches and follow
    the same motion through them."""
    # the outputs of the agreement test's scene: its model is this one's rolling model, built once
    scene = _pinch(gf=300.0, gl=300.0, wf=300.0**2, wl=300.0**2, outputs=("constraint_residual", "f1", "f2"))
    m2 = gs.build(gs.scenes.with_modes(scene))
    m3 = gs.build(gs.scenes.with_modes(_planar_3d(scene)))
    t = np.linspace(0.0, 0.06, 61)
    r2, r3 = (m.simulate(0.06, t_eval=t, mu=0.14, rtol=1e-11, atol=1e-12) for m in (m2, m3))
    switches = [[(e["contact"], e["from"], e["to"]) for e in r.events] for r in (r2, r3)]
    assert switches[0] == switches[1] == [(1, "rolling", "sliding"), (2, "rolling", "sliding"),
                                          (2, "sliding", "separated"), (1, "sliding", "separated")]
    np.testing.assert_allclose([e["t"] for e in r2.events], [e["t"] for e in r3.events], rtol=0, atol=1e-10)
    R = r3.object_rotations()
    worst = max(np.max(np.abs(r3["x"] + SHIFT - r2["x"])), np.max(np.abs(r3["y"] - r2["y"])),
                np.max(np.abs(-np.arctan2(R[:, 1, 0], R[:, 0, 0]) - r2["theta"])),
                *[np.max(np.abs(r3[k] - r2[k])) for k in ("q11", "q12", "q21", "q22")])
    assert worst <= 1e-10, worst           # measured 6e-13; the object falls 2 cm
    assert r2["y"][0] - r2["y"][-1] > 0.01
    # the rows where both contacts roll: from the 3D outputs with every mode rolling folded in
    # (the manifest's outputs_folded, 58 % of the general function's instructions), the
    # general function's numbers bit for bit
    rolling = (r3.modes == "rolling").all(axis=1)
    assert m3.manifest["outputs_folded"] and m3.manifest["folded_modes"] == [0, 0] and rolling.sum() >= 5
    p = modes._RUNS["grasp3d_modes"](m3, None, (0.14, 0.14), 0.0).params([modes.ROLLING] * 2)
    general = outputs_.by_name(m3, outputs_.along_rows(m3, r3.t[rolling], r3.x[rolling], p, None), shown=True)
    assert general and all(np.array_equal(general[k], r3[k][rolling]) for k in general)


def test_a_pinch_wedged_on_a_table_bounces_through_the_same_switches_in_2d_and_3d():
    """The asymmetric pinch (``_pinch``, mu = 0.14 at the fingers) over a table 3 cm below its
    centre (a line in 2D, a plane in 3D; mu = 0.5, e = 0.5): it slips, lands, and bounces
    wedged between finger 2 and the table, 32 switches in 0.06 s (slips, sticks, impacts that
    start, stop or turn other contacts' slips). The 2D and the 3D model kept in its plane
    locate the same switches (3e-14 s apart measured) and follow the same motion (7e-14). The
    3D model found Moreau's slip direction at an impact by a fixed-point iteration, which
    stopped this run by name at 0.0517 s (no consistent way for contact 2's slip); secant
    steps on the direction's angle find the direction 2D has."""
    scene = _pinch(gf=300.0, gl=300.0, wf=300.0**2, wl=300.0**2, outputs=("constraint_residual",))
    y_table = scene.initial_state()[scene.state_names.index("y")] - 0.03
    m2 = gs.build(gs.scenes.with_modes(scene, lines=[gs.scenes.world_line((0.0, y_table), (0.0, 1.0),
                                                                          support=math.pi / 2)]))
    m3 = gs.build(_planar_3d(scene, planes=[gs.scenes.world_plane((0.0, y_table, 0.0), (0.0, 1.0, 0.0),
                                                                  support=(-math.pi / 2, 0.0))]))
    law = gs.contact.coulomb((0.14, 0.14, 0.5), e=0.5)
    t = np.linspace(0.0, 0.06, 61)
    r2, r3 = (m.simulate(0.06, t_eval=t, mu=law, rtol=1e-11, atol=1e-12) for m in (m2, m3))
    switches = [[(e["contact"], e["from"], e["to"], e["witness"]) for e in r.events] for r in (r2, r3)]
    assert switches[0] == switches[1] and len(switches[0]) == 32
    assert switches[0][:3] == [(1, "rolling", "sliding", "cone"), (2, "rolling", "sliding", "cone"),
                               (3, "separated", "separated", "gap")]          # it bounces off the table
    assert sum(s[3] == "gap" for s in switches[0]) >= 6                       # 8 impacts measured
    np.testing.assert_allclose([e["t"] for e in r2.events], [e["t"] for e in r3.events], rtol=0, atol=1e-10)
    R = r3.object_rotations()
    worst = max(np.max(np.abs(r3["x"] + SHIFT - r2["x"])), np.max(np.abs(r3["y"] - r2["y"])),
                np.max(np.abs(-np.arctan2(R[:, 1, 0], R[:, 0, 0]) - r2["theta"])),
                *[np.max(np.abs(r3[k] - r2[k])) for k in ("q11", "q12", "q21", "q22")])
    assert worst <= 1e-10, worst


PRESS = {"R": 0.02, "r": 0.010, "m": 0.04, "g": 9.81, "link": 0.065, "fd": 0.5, "r_ctrl": 0.010}


def _pressed_disk(name: str, motion=None):
    """``(scene, 2D model, 3D model)``: a disk (radius 0.02 m, 0.04 kg, I = 0.4 m R^2: a
    ball's) hangs from the paper's finger, touching it 0.2 rad off its top, 0.5 mm above a
    table at y = 0 translated by ``motion`` (None: fixed); the law (32) presses the fingertip
    toward the disk's start centre. The 3D model with modes of the same ball, finger and
    table (a plane), kept in their plane, from the same start."""
    R, r, m, g, link = (PRESS[k] for k in ("R", "r", "m", "g", "link"))
    off = 0.2                                    # the contact, off the disk's top (rad)
    # the start: the fingertip centre above the disk, on the line through its contact
    centre = np.array([0.08, R + 0.0005])
    tip = centre + (R + r) * np.array([math.sin(off), math.cos(off)])
    q2 = math.acos((tip @ tip - 2 * link**2) / (2 * link**2))
    q1 = math.atan2(tip[0], tip[1]) - q2 / 2
    scene = gs.scenes.planar_finger(
        gs.curves.circle(r, span=3 * math.pi), gs.curves.circle(R, by="angle", span=3 * math.pi, clockwise=True),
        name=name, support="free", M=m, I=0.4 * m * R * R, gravity=(0.0, -g), q1_0=q1,
        u0_0=r * (q1 + q2 - math.pi - off), u1_0=-math.pi / 2 + off, outputs=())
    x2 = dict(zip(scene.state_names, scene.initial_state()))
    assert x2["q2"] == pytest.approx(q2, abs=1e-12)                  # the start as constructed
    line = gs.scenes.world_line((0.0, 0.0), (0.0, 1.0), support=math.pi / 2, motion=motion)
    model = gs.build(gs.scenes.with_modes(scene, lines=[line]))
    finger = Finger3D(chain=chains.finger1(), tip=surface_library.sphere(r), q0=(x2["q1"], x2["q2"]),
                      tip_contact=(x2["u0"] / r, 0.0), object_contact=(-x2["u1"], 0.0))
    ball = gs.scenes.paper3d(name=f"{name}_3d", fingers=(finger,), mass=m, rotation=np.eye(3),
                             inertia=np.eye(3) * 0.4 * m * R * R, k_center=0.0, dq0=None, outputs=(),
                             object_surface=surface_library.ellipsoid(R, R, R, lon=(-2.5, 4.0)),
                             position=(x2["x"] - SHIFT, x2["y"], 0.0))
    table = gs.scenes.world_plane((0.0, 0.0, 0.0), (0.0, 1.0, 0.0), support=(-math.pi / 2, 0.0),
                                  motion=None if motion is None else (*motion, "0"))
    return scene, model, gs.build(gs.scenes.with_modes(ball, planes=[table]))


def _same_motion(res, res3) -> float:
    """The largest difference of the disk's pose and the joint angles of a 2D run and its 3D
    counterpart."""
    R3 = res3.object_rotations()
    return max(np.max(np.abs(res3["x"] + SHIFT - res["x"])), np.max(np.abs(res3["y"] - res["y"])),
               np.max(np.abs(-np.arctan2(R3[:, 1, 0], R3[:, 0, 0]) - res["theta"])),
               np.max(np.abs(res3["q11"] - res["q1"])), np.max(np.abs(res3["q12"] - res["q2"])))


def test_one_finger_presses_a_free_disk_onto_a_line_as_the_3d_model_does():
    """One finger and a line of the world hold a free 2D object (``with_modes(scene, lines=...)``,
    ``_pressed_disk``). The disk falls, lands (an impact), rolls under the finger and comes to
    rest. Checked against the 3D model with modes kept in its plane (the landing to 1e-12 s,
    the motion to 1e-10), and the rest against its statics solved here from the joint angles
    and the disk's centre alone: the finger force F (on the finger, at the contact point p) and
    the table's friction T and normal force N meet the finger's joints,
    J^T F - (p - r_tip) x F (1, 1) = J^T (fd / r)(r_tip - a), and the disk's forces and moment:
    5 equations for 4 unknowns, consistent to round-off, and equal to the model's
    multipliers."""
    R, r, m, g, link, fd, r_ctrl = PRESS.values()
    scene, model, model3 = _pressed_disk("press2d")
    t = np.linspace(0.0, 1.0, 21)
    res = model.simulate(1.0, mu=0.8, t_eval=t, rtol=1e-11, atol=1e-12)
    res3 = model3.simulate(1.0, mu=0.8, t_eval=t, rtol=1e-11, atol=1e-12)
    assert [(e["contact"], e["from"], e["to"]) for e in res.events] == [(2, "separated", "rolling")]
    assert res.events[0]["t"] == pytest.approx(res3.events[0]["t"], abs=1e-12)
    worst = _same_motion(res, res3)
    assert worst <= 1e-10, worst
    assert np.ptp(res["x"]) > 1e-3                                   # it rolled under the finger
    # the statics at rest
    y = {k: v[-1] for k, v in res.outputs.items()}
    assert abs(res["dx"][-1]) < 1e-6 and abs(res["dtheta"][-1]) < 1e-4
    q1, q12 = res["q1"][-1], res["q1"][-1] + res["q2"][-1]
    tip = link * np.array([math.sin(q1) + math.sin(q12), math.cos(q1) + math.cos(q12)])
    J = link * np.array([[math.cos(q1) + math.cos(q12), math.cos(q12)],
                         [-math.sin(q1) - math.sin(q12), -math.sin(q12)]])
    c = np.array([res["x"][-1], res["y"][-1]])
    lever = r * (c - tip) / np.linalg.norm(c - tip)
    pull = fd / r_ctrl * (tip - np.array(scene.pivot))
    A = np.array([[J[0, 0] + lever[1], J[1, 0] - lever[0], 0, 0], [J[0, 1] + lever[1], J[1, 1] - lever[0], 0, 0],
                  [-1, 0, 1, 0], [0, -1, 0, 1], [(tip + lever - c)[1], -(tip + lever - c)[0], R, 0]])
    b = np.array([*(J.T @ pull), 0.0, m * g, 0.0])
    sol, *_ = np.linalg.lstsq(A, b, rcond=None)
    assert np.linalg.norm(A @ sol - b) < 1e-7 * np.linalg.norm(b)
    F, T, N = sol[:2], sol[2], sol[3]
    assert abs(T) > 0.03                                              # friction holds it
    assert y["normal_force2"] == pytest.approx(N, rel=1e-7)
    assert y["tangential_force2"] == pytest.approx(abs(T), rel=1e-6)
    assert math.hypot(y["normal_force1"], y["lam1"]) == pytest.approx(np.linalg.norm(F), rel=1e-7)
    assert res["y"][-1] == pytest.approx(R, abs=1e-10) and abs(y["gap2"]) < 1e-10


def test_a_driven_line_drags_the_pressed_disk_as_a_driven_plane_does():
    """The table of ``_pressed_disk`` is a conveyor moving at 0.05 m/s from the start
    (``world_line(motion=...)``): the disk lands on the moving belt (an impact that stops its
    slip or not), is carried off under the finger, and the 2D and 3D models agree on every
    switch (to 1e-12 s) and the motion (to 1e-10)."""
    _, model, model3 = _pressed_disk("press2d_belt", motion=("0.05 * t", "0"))
    t = np.linspace(0.0, 0.3, 16)
    res = model.simulate(0.3, mu=0.8, t_eval=t, rtol=1e-11, atol=1e-12)
    res3 = model3.simulate(0.3, mu=0.8, t_eval=t, rtol=1e-11, atol=1e-12)
    switches = [[(e["contact"], e["from"], e["to"]) for e in r.events] for r in (res, res3)]
    assert switches[0] == switches[1] and switches[0][0] == (2, "separated", "rolling")
    np.testing.assert_allclose([e["t"] for e in res.events], [e["t"] for e in res3.events], rtol=0, atol=1e-12)
    assert _same_motion(res, res3) <= 1e-10
    assert res["x"][-1] - res["x"][0] > 2e-3                          # the belt carried it


def test_a_strike_from_below_lifts_the_disk_off_the_table_through_the_impulse():
    """The fingertip of ``_pressed_disk`` strikes the disk resting on the table at 0.3 m/s from
    25 degrees below its equator. Held, the table would have to pull (its normal impulse < 0):
    the impact lets it go (``runtime.modes``, ``_GraspRun.impact``: the first consistent way
    of the other contacts), recorded as its own switch (witness ``impulse``). Exact checks:
    only the finger's impulse acts on the disk, so its angular momentum about the contact point,
    0 at rest before, is 0 after; the table contact separates; no energy is gained."""
    R, r, link = PRESS["R"], PRESS["r"], PRESS["link"]
    _, model, _ = _pressed_disk("press2d")
    alpha, v0 = math.radians(25), 0.3
    c = np.array([0.08, R])                                  # resting on the table
    n = np.array([math.cos(alpha), math.sin(alpha)])         # from the fingertip to the disk
    tip = c - (R + r + 0.0005) * n
    q2 = math.acos((tip @ tip - 2 * link**2) / (2 * link**2))
    q1 = math.atan2(tip[0], tip[1]) - q2 / 2
    J = link * np.array([[math.cos(q1) + math.cos(q1 + q2), math.cos(q1 + q2)],
                         [-math.sin(q1) - math.sin(q1 + q2), -math.sin(q1 + q2)]])
    names = list(model.state_names)
    x0 = np.zeros(len(names))
    dq = np.linalg.solve(J, v0 * n)
    for k, v in {"x": c[0], "y": c[1], "q1": q1, "q2": q2, "dq1": dq[0], "dq2": dq[1], "u_w1": math.pi / 2,
                 "u0": r * (alpha - (math.pi / 2 - q1 - q2)), "u1": math.pi - alpha}.items():
        x0[names.index(k)] = v
    res = model.simulate(0.01, x0=x0, mu=0.5, t_eval=np.linspace(0.0, 0.01, 11), rtol=1e-11, atol=1e-12)
    hit, let_go = res.events[:2]
    assert (hit["contact"], hit["from"], hit["witness"]) == (1, "separated", "gap")
    assert (let_go["contact"], let_go["from"], let_go["to"], let_go["witness"]) == \
        (2, "rolling", "separated", "impulse") and let_go["t"] == hit["t"]
    early = hit["t"] * (1 - 1e-9)
    before = model.simulate(early, x0=x0, mu=0.5, t_eval=[0.0, early], rtol=1e-11, atol=1e-12)
    # just after (1.4e-12 s: gravity's moment about p adds 1e-11 of the scale below)
    late = hit["t"] * (1 + 1e-9)
    after = model.simulate(late, x0=x0, mu=0.5, t_eval=[0.0, late], rtol=1e-11, atol=1e-12)
    s = dict(zip(names, after.x[-1]))
    # the contact point on the disk (the disk has not moved; the fingertip's path bent a little)
    point = model.scene.base.object.evaluate(s["u1"])
    th = s["theta"]
    p = c + np.array([math.cos(th) * point["x"] + math.sin(th) * point["y"],
                      -math.sin(th) * point["x"] + math.cos(th) * point["y"]])
    assert np.linalg.norm(p - (c - R * n)) < 1e-4
    v, arm = np.array([s["dx"], s["dy"]]), np.array([s["x"], s["y"]]) - p
    momentum = 0.4 * PRESS["m"] * R * R * -s["dtheta"] + PRESS["m"] * (arm[0] * v[1] - arm[1] * v[0])
    assert np.linalg.norm(v) > 0.05                          # struck
    assert abs(momentum) <= 1e-9 * PRESS["m"] * R * np.linalg.norm(v), momentum
    assert s["dy"] > 0.01                                     # lifted off: the support point rises
    assert after["kinetic_energy"][-1] <= before["kinetic_energy"][-1] * (1 + 1e-12)


def test_a_new_start_of_a_free_object_moves_the_point_the_law_pulls_toward(pinch, tmp_path):
    """``with_start(x=...)``: the paper's law pulls toward the object's start centre, which is
    then the new one (the manifest's ``start_implied``); a sweep measure that reads the scene
    is refused on a Dask client by name; a model with modes has no CasADi function."""
    moved = pinch.with_start(x=0.13)
    assert moved.start_params["xm"] == pytest.approx(0.13, abs=1e-15)
    assert moved.start_params["ym"] == pytest.approx(moved.initial_state()[1], abs=1e-15)
    res = moved.simulate(1.0)
    assert abs(res["x"][-1] - 0.13) < 1e-4           # held where it was put, not dragged back
    with pytest.raises(ValueError, match="'min:epsilon' reads the model's scene"):
        gs.sweep(pinch, {"mu": [0.3]}, 0.1, store=tmp_path / "s.zarr", client="processes",
                 measures=["min:epsilon"], progress=False)
    with pytest.raises(ValueError, match="a model with contact modes"):
        gs.build(gs.scenes.disk_on_incline()).casadi_function()


def test_the_pressed_disk_is_drawn_with_its_table_and_a_table_through_it_is_refused(tmp_path):
    """An animation of a 2D run with modes draws the lines of the world and the modes; a line
    that cuts the object at the start is refused by name; ``held`` reads every finger of a 2D
    model with modes (not only the first)."""
    _, model, _ = _pressed_disk("press2d")
    res = model.simulate(0.02, mu=0.8)
    assert gs.viz.animate(res, tmp_path / "press.gif", fps=5).stat().st_size > 1000
    scene = model.scene.base
    through = gs.scenes.with_modes(scene, lines=[gs.scenes.world_line((0.0, 0.03), (0.0, 1.0), support=math.pi / 2)])
    with pytest.raises(InvalidSceneError, match="line 1 cuts the object at the start"):
        gs.build(through)
    two = SimpleNamespace(manifest=gs.scenes.with_modes(gs.scenes.pinch2d()).manifest_extra())
    batch = SimpleNamespace(modes=[np.array([["rolling", "separated"]]), np.array([["rolling", "sliding"]])])
    assert list(sweeps._held_modes(two, batch)) == [0.0, 1.0]
