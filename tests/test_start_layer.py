"""The start as a layer of its own: solved numbers are run-time inputs, a new start reuses the
compiled code, starts are solved at run time, and a built model loads without SymPy."""
from __future__ import annotations

import json
import math
import os
import subprocess
import sys

import numpy as np
import pytest

import grasping_sym as gs
from grasping_sym.errors import InvalidSceneError, UnreachableStartError
from grasping_sym.geometry import surface_library
from grasping_sym.model import chains
from grasping_sym.model.grasp3d import Finger3D, GraspScene3D


def _tangency_defect(scene, x) -> float:
    """q1 + q2 - (pi/2 + theta + theta1(s) - psi0(s)), from the scene's contours (NumPy)."""
    f0, f1 = scene.fingertip.evaluate(x[6]), scene.object.evaluate(x[6])
    theta1 = math.atan2(float(f1["dx"]), float(f1["dy"]))
    psi0 = math.atan2(float(f0["dx"]), float(f0["dy"]))
    return x[1] + x[2] - (math.pi / 2 + x[0] + theta1 - psi0)


@pytest.mark.parametrize("given", [{"theta": 0.1}, {"theta": -0.5}, {"s": 0.002}, {"q1": 0.6}])
def test_run_time_start_is_the_scene_with_that_start(paper2d_model, given):
    """A start solved at run time (compiled conditions) is the start the scene itself solves
    (NumPy geometry: tangency fixes q2, contact fixes the pivot) for the same q1, theta, s:
    same q2, and the same pivot as the model's."""
    x = paper2d_model.initial_state(**given)
    for k, v in given.items():
        assert x[paper2d_model.state_names.index(k)] == v
    C = paper2d_model.library.constraints(x)[0]
    assert np.max(np.abs(C)) <= 1e-15
    assert np.all(x[3:6] == 0.0)  # at rest
    scene = gs.scenes.paper2d(q1_0=float(x[1]), theta_0=float(x[0]), u0_0=float(x[6]),
                              u1_0=float(x[6]))
    assert abs(_tangency_defect(scene, x)) <= 1e-14
    assert scene.q2_0 == pytest.approx(x[2], abs=1e-12)
    np.testing.assert_allclose(scene.pivot, list(paper2d_model.start_params.values()), rtol=0,
                               atol=1e-14)


def test_new_start_reuses_the_compiled_code(paper2d_model):
    """The start is not in the code's hash: a scene with another start compiles nothing and
    simulates as the run-time start does."""
    x = paper2d_model.initial_state(theta=0.1)
    scene = gs.scenes.paper2d(q1_0=float(x[1]), theta_0=0.1, u0_0=float(x[6]), u1_0=float(x[6]))
    moved = gs.build(scene)
    assert moved.build_info["source"] == "cache" and moved.build_info["start_source"] == "solved"
    assert moved.library_path == paper2d_model.library_path
    np.testing.assert_allclose(moved.initial_state(), x, rtol=0, atol=1e-13)
    kw = dict(method="radau", rtol=1e-6, atol=1e-9, t_eval=[0.0, 1.0])
    a = paper2d_model.simulate(1.0, x0=x, **kw).x[-1]
    b = moved.simulate(1.0, **kw).x[-1]
    np.testing.assert_allclose(a, b, rtol=0, atol=1e-9)
    again = gs.build(scene)
    assert again.build_info["start_source"] == "cache"
    started = paper2d_model.with_start(theta=0.1)  # the pivot stays with the scene
    assert started.start_params == paper2d_model.start_params
    assert started.initial_state().tolist() == x.tolist()


@pytest.mark.parametrize("given, match", [
    ({"q1": 0.5}, "no consistent pose with q1"),            # below the family's smallest q1
    ({"theta": 0.1, "q1": 0.5}, "give fewer coordinates"),  # over-determined
    ({"q1": 2.0}, r"outside its contour's domain"),
])
def test_unreachable_starts_are_refused_by_name(paper2d_model, given, match):
    with pytest.raises(UnreachableStartError, match=match):
        paper2d_model.initial_state(**given)


def test_bad_start_values_are_refused(paper2d_model):
    with pytest.raises(ValueError, match="'foo' is not a state"):
        paper2d_model.initial_state(foo=1.0)
    with pytest.raises(ValueError, match="q1 = nan must be a finite number"):
        paper2d_model.initial_state(q1=float("nan"))


@pytest.mark.parametrize("given", [{"q11": 0.6}, {"q12": 1.1, "dq11": 0.5}])
def test_3d_run_time_start_is_on_the_contact_manifold(given):
    """pivot3d started elsewhere at run time: the NumPy oracle (tests/oracles) finds the
    bodies touching, normals opposed and the frame angle psi right; the admissible speeds
    keep the contact; the run stays on the constraints."""
    from tests.oracles.contact3d_numeric import contact_residuals
    from tests.oracles.reference3d import Reference3D

    ref = Reference3D()
    model = gs.build(gs.scenes.pivot3d(position=tuple(ref.pivot), name="pivot3d_ref"))
    moved = model.with_start(**given)
    assert moved.library_path == model.library_path and moved.build_info["source"] == "run-time start"
    x = moved.initial_state()
    for k, v in given.items():
        assert x[model.state_names.index(k)] == v
    assert np.linalg.norm(x[2:6]) == pytest.approx(1.0, abs=1e-15)
    pose_f, pose_o = ref.poses(x)
    res = contact_residuals(ref.fingertip, pose_f, ref.object_surface, pose_o, x[11:16])
    assert res["max"] <= 1e-12, res
    assert np.max(np.abs(model.library.constraints(x)[2])) <= 1e-13   # Cdot: speeds admissible
    run = moved.simulate(0.2, method="radau", rtol=1e-8, atol=1e-11)
    assert run.outputs["constraint_residual"].max() <= 1e-9
    assert gs.load(moved.path).initial_state().tolist() == x.tolist()


def test_3d_new_start_moves_the_spring_rest_point(paper3d_model):
    """paper3d's centre spring rests where the fingertip centres were at the start: the
    compiled start function gives the stored rest point at the stored start, and a new one
    at a new start."""
    from grasping_sym.runtime.start import _conditions_function

    x0 = paper3d_model.initial_state()
    G, _, implied = _conditions_function(paper3d_model)(x0)
    assert np.max(np.abs(G)) <= 1e-14
    np.testing.assert_allclose(implied, list(paper3d_model.start_params.values()), rtol=0, atol=1e-15)
    moved = paper3d_model.with_start(q11=float(x0[0]) + 0.05)
    shift = np.subtract(list(moved.start_params.values()), list(paper3d_model.start_params.values()))
    assert 1e-4 < np.linalg.norm(shift) < 1e-2
    assert np.max(np.abs(paper3d_model.library.constraints(moved.initial_state())[0])) <= 1e-15


def test_paper_formulation_run_time_start_is_refused_by_name():
    model = gs.build(gs.scenes.pivot3d(formulation="paper", dq0=(1.0, -0.5), name="pivot3d_paper",
                                       outputs=("constraint_residual",)))
    with pytest.raises(NotImplementedError, match="formulation='regular'"):
        model.initial_state(q11=0.5)


def test_solved_numbers_are_inputs_not_constants(paper2d_model):
    """The pivot is a run-time input after the user's parameters; its digits are not in the C."""
    assert paper2d_model.p_names[-2:] == ("xm", "ym")
    c = "".join((paper2d_model.directory / f).read_text() for f in paper2d_model.manifest["files"])
    for v in paper2d_model.start_params.values():
        assert repr(v)[:10] not in c
    p = paper2d_model.default_params.copy()
    x = paper2d_model.initial_state()
    moved = paper2d_model.rhs(x, p + np.array([0.0, 1e-3]))  # the pivot moved by 1 mm
    assert np.max(np.abs(moved - paper2d_model.rhs(x))) > 1.0


def test_load_in_a_fresh_process_without_sympy(paper2d_model):
    code = (
        "import sys, json; import grasping_sym as gs; m = gs.load(sys.argv[1]); "
        "r = m.simulate(0.5, method='radau', rtol=1e-6, atol=1e-9, t_eval=[0.0, 0.5]); "
        "print(json.dumps({'sympy': 'sympy' in sys.modules, 'casadi': 'casadi' in sys.modules, "
        "'x': r.x[-1].tolist()}))"
    )
    out = subprocess.run([sys.executable, "-c", code, str(paper2d_model.path)], check=True,
                         capture_output=True, text=True, env={**os.environ}).stdout
    got = json.loads(out)
    assert got["sympy"] is False and got["casadi"] is False  # the C integrators need neither
    ref = paper2d_model.simulate(0.5, method="radau", rtol=1e-6, atol=1e-9, t_eval=[0.0, 0.5]).x[-1]
    assert got["x"] == ref.tolist()


def test_load_refuses_a_directory_without_a_model(tmp_path):
    with pytest.raises(FileNotFoundError, match="holds no built model"):
        gs.load(tmp_path)


BAD_NAMES = ["../../x", "a__b", "_x", "x_", "café", "gs", "gs_model", "int", "a-b", "", "9lives",
             "x" * 65]


@pytest.mark.parametrize("name", BAD_NAMES)
def test_scene_names_follow_one_rule_in_2d_and_3d(name):
    with pytest.raises(InvalidSceneError, match="name"):
        gs.scenes.paper2d(name=name)
    finger = Finger3D(chain=chains.finger1(), tip=surface_library.sphere(0.01),
                      q0=chains.FINGER1_Q_OPPOSED, tip_contact=(0.0, 0.1), object_contact=(2.7, 0.25))
    with pytest.raises(InvalidSceneError, match="name"):
        GraspScene3D(name=name, fingers=(finger,), object_surface=surface_library.ellipsoid(0.02, 0.025, 0.03),
                     mass=0.04, inertia=(1e-5, 1e-5, 1e-5), support="pivot")


@pytest.mark.parametrize("name", ["paper2d", "ellipse_v2", "A1", "my_scene_2"])
def test_good_scene_names_pass(name):
    assert gs.scenes.paper2d(name=name).name == name
