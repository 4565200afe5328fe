"""Scenes from TOML files (grasping_sym.model.scene_files): the same scene as in Python, formulas
parsed and never run, every problem named."""
from __future__ import annotations

import math

import pytest

import grasping_sym as gs
from grasping_sym.cli import main
from grasping_sym.model.scene_files import SceneFileError, load_scene
from grasping_sym.pipeline import code_hash

ELLIPSE = """
[scene]
base = "planar_finger"
name = "toml_ellipse"
q1_0 = "pi / 6"
u1_0 = "pi + 0.3"
runtime = ["fd"]

[fingertip]
shape = "paper_fingertip"

[object]
shape = "ellipse"
a = 0.020
b = "0.03 / 2"
start = "pi"
span = "pi"
clockwise = true
name = "ellipse"
"""


def _file(tmp_path, text, name="scene.toml"):
    path = tmp_path / name
    path.write_text(text)
    return path


def test_a_file_makes_the_same_scene_as_python(tmp_path):
    from_file = load_scene(_file(tmp_path, ELLIPSE))
    ell = gs.curves.ellipse(0.020, 0.015, start=math.pi, span=math.pi, clockwise=True, name="ellipse")
    in_python = gs.scenes.planar_finger(gs.curves.paper_fingertip(), ell, name="toml_ellipse",
                                        q1_0=math.pi / 6, u1_0=math.pi + 0.3, runtime=("fd",))
    assert code_hash(from_file)["hash"] == code_hash(in_python)["hash"]
    assert from_file.pivot == pytest.approx(in_python.pivot, abs=1e-15)


def test_built_in_bases_take_their_keywords(tmp_path):
    s2 = load_scene(_file(tmp_path, '[scene]\nbase = "paper2d"\nname = "p2"\nfd = "0.5 + 0.1"\n'))
    assert s2.name == "p2" and s2.params["fd"] == pytest.approx(0.6)
    s3 = load_scene(_file(tmp_path, '[scene]\nbase = "pivot3d"\nname = "p3"\n'
                                    '[object_surface]\nshape = "superquadric"\na = 0.02\nb = 0.025\n'
                                    'c = 0.03\nn = 4\nname = "box"\n', "s3.toml"))
    assert s3.object_surface.name == "box"


@pytest.mark.parametrize("text, found", [
    ('[scene]\nbase = "nope"\n', "base = 'nope'"),
    ('[scene]\nbase = "planar_finger"\n[fingertip]\nshape = "blob"\n[object]\nshape = "circle"\n'
     'radius = 0.01\n', "shape = 'blob'"),
    ('[scene]\nbase = "paper2d"\nfd = "__import__(\'os\').system(\'echo hacked\')"\n', "fd"),
    ('[scene]\nbase = "paper2d"\n[extras]\nx = 1\n', "unknown tables ['extras']"),
    ('[scene\nbase = 1', "not valid TOML"),
    ('[object]\nshape = "circle"\n', "[scene] table is needed"),
    ('[scene]\nbase = "paper2d"\nfdd = 0.5\n', "unknown parameters ['fdd']"),
    ('[scene]\nbase = "pinch2d"\n[object]\nshape = "circle"\nradius = 0.02\n',
     '[object] is for base = "planar_finger"'),
    ('[scene]\nbase = "planar_finger"\nq1_0 = 0.5\nwhat = 1\n[fingertip]\nshape = "circle"\n'
     'radius = 0.01\n[object]\nshape = "circle"\nradius = 0.02\n', "unknown parameters ['what']"),
])
def test_bad_files_are_refused_by_name(tmp_path, text, found, capfd):
    with pytest.raises(SceneFileError) as exc:
        load_scene(_file(tmp_path, text))
    assert found in str(exc.value)
    assert "hacked" not in capfd.readouterr().out  # a formula is parsed, never run


def test_every_problem_is_named_at_once(tmp_path):
    text = ('[scene]\nbase = "planar_finger"\nq1_0 = "pi +"\n[fingertip]\nshape = "blob"\n'
            '[object]\nshape = "circle"\nradius = "sqrt("\n')
    with pytest.raises(SceneFileError) as exc:
        load_scene(_file(tmp_path, text))
    assert len(exc.value.problems) == 3


def test_the_command_line_simulates_a_scene_file(tmp_path, capsys):
    path = _file(tmp_path, '[scene]\nbase = "paper2d"\nruntime = ["fd"]\n')
    assert main(["simulate", str(path), "--param", "fd=0.7", "--t-final", "0.05", "--out",
                 str(tmp_path / "out")]) == 0
    assert "scene            paper2d" in capsys.readouterr().out
    assert main(["simulate", str(path), "--param", "c=0.01", "--t-final", "0.05", "--out",
                 str(tmp_path / "out")]) == 2
    assert "runtime = [...]" in capsys.readouterr().err


def test_a_file_gives_the_scene_inputs_and_its_controller(tmp_path):
    """inputs = "torques" is a word, not a formula; controller = "none": the torques are the inputs."""
    scene = load_scene(_file(tmp_path, '[scene]\nbase = "paper2d"\ninputs = "torques"\n'
                                       'controller = "none"\nname = "pi"\n'))
    assert scene.inputs == "torques" and scene.input_names == ("u1", "u2")
    assert scene.controller is None and scene.name == "pi"
    assert load_scene(_file(tmp_path, '[scene]\nbase = "pivot3d"\ninputs = "torques"\n',
                            "s3.toml")).input_names == ("u1", "u2")


@pytest.mark.parametrize("text, found", [
    ('[scene]\nbase = "paper2d"\nq1_0 = "10**10**10"\n', "q1_0 = '10**10**10'"),
    ('[scene]\nbase = "paper2d"\nq1_0 = "' + "-" * 5000 + '1"\nfd = "' + "+".join(["0.1"] * 2000)
     + '"\nc = "' + "sin(" * 200 + "1" + ")" * 200 + '"\n', "nested more than 100 deep"),
    ('[scene]\nbase = "planar_finger"\n[fingertip]\nshape = ["ellipse"]\n[object]\nshape = "circle"\n'
     'radius = 0.02\n', "shape = ['ellipse']: choose one of"),
    ('[scene]\nbase = "paper2d"\ninputs = "forces"\n', "inputs = 'forces'"),
    ('[scene]\nbase = "paper2d"\ncontroller = "pid"\n', "controller = 'pid': choose one of"),
    ('[scene]\nbase = "paper2d"\nfd = nan\n', "fd = nan: give a finite number"),
    ('[scene]\nbase = "paper2d"\nfd = "sqrt(-1)"\n', "not a real number"),
    ('[scene]\nbase = "paper2d"\nfd = ' + "[" * 3000 + "]" * 3000 + "\n", "nested too deeply"),
])
def test_bad_values_are_refused_by_name_at_once(tmp_path, text, found):
    with pytest.raises(SceneFileError) as exc:
        load_scene(_file(tmp_path, text))
    assert found in str(exc.value)


def test_files_that_are_not_scene_files_are_refused_by_name(tmp_path):
    bad = tmp_path / "latin1.toml"
    bad.write_bytes(b'[scene]\nbase = "paper2d"\nname = "caf\xe9"\n')
    with pytest.raises(SceneFileError, match=r"not UTF-8 text: byte 36 \(0xe9\)"):
        load_scene(bad)
    big = tmp_path / "big.toml"
    big.write_bytes(b"# " + b"x" * (1 << 20) + b"\n")
    with pytest.raises(SceneFileError, match="a scene file has at most 1048576"):
        load_scene(big)
    for path in ("/dev/zero", tmp_path):
        with pytest.raises(SceneFileError, match="not a regular file"):
            load_scene(path)


def test_the_command_line_refuses_a_huge_formula_at_once(tmp_path, capsys):
    path = _file(tmp_path, '[scene]\nbase = "paper2d"\nq1_0 = "10**10**10"\n')
    assert main(["simulate", str(path), "--out", str(tmp_path / "out")]) == 2
    errors = [line for line in capsys.readouterr().err.splitlines() if "error" in line]
    assert len(errors) == 1 and "q1_0 = '10**10**10': the power" in errors[0]
    assert "beyond a double's range" in errors[0]
    assert not (tmp_path / "out").exists()
