"""The command line on 3D scenes and the 3D figures (``grasping_sym.viz.plots3d``).

Everything is written under tmp_path (builds go to the session's private cache, conftest).
"""
from __future__ import annotations

import csv
import logging
import math

import numpy as np
import pytest

from grasping_sym import cli
from grasping_sym.geometry import surface_library
from grasping_sym.model.scenes import paper2d, paper3d, pivot3d
from grasping_sym.runtime.result import SimulationResult
from grasping_sym.viz import plots3d

FIGURES_3D = ["snapshots.png", "contact_traces.png", "multipliers.png", "arclengths_residuals.png",
              "pose_joints.png"]


def _png_has_content(path) -> bool:
    import matplotlib.image as mpimg

    img = mpimg.imread(path)
    return img.ndim == 3 and img.shape[0] > 300 and img.shape[1] > 300 and float(img.std()) > 0.01


@pytest.mark.parametrize("factory", [paper3d, pivot3d], ids=["paper3d", "pivot3d"])
def test_simulate_3d_writes_csv_and_figures(factory, tmp_path, capsys):
    scene = factory()
    out_dir = tmp_path / "run"
    code = cli.main(["simulate", scene.name, "--t-final", "0.3", "--out", str(out_dir)])
    captured = capsys.readouterr()
    assert code == 0, captured.err
    with (out_dir / "trajectory.csv").open() as fh:
        rows = list(csv.reader(fh))
    assert rows[0] == ["t", *scene.state_names, *scene.outputs]
    assert len(rows) == 1 + 301  # every ms from 0 to 0.3 s
    assert float(rows[-1][0]) == pytest.approx(0.3)
    assert np.all(np.isfinite(np.array(rows[1:], dtype=float)))
    for name in FIGURES_3D:
        path = out_dir / name
        assert path.stat().st_size > 5000, name
        assert _png_has_content(path), name
        assert f"figure           {path}" in captured.out  # the list of written files
    assert f"figures          {len(FIGURES_3D)} PNG files" in captured.out
    assert "dop853, t_final 0.3 s" in captured.out  # the 3D default integrator
    assert "max residual" in captured.out and "trace 1" in captured.out and "min f1" in captured.out
    assert "[grasping-sym]" in captured.err
    assert sorted(p.name for p in out_dir.iterdir()) == sorted(["trajectory.csv", *FIGURES_3D])


def test_simulate_defaults_depend_on_the_scene_kind():
    parse = cli.make_parser().parse_args

    def settings(scene, *extra):
        return cli.simulate_settings(parse(["simulate", scene.name, "--out", "x", *extra]), scene)

    # simulate's own defaults (the manifest's "defaults"): radau in 2D, dop853 in 3D
    assert settings(paper2d()) == (3.0, "radau", 1e-6, 1e-9)
    assert settings(paper2d(), "--method", "cvodes") == (3.0, "cvodes", 1e-10, 1e-12)
    assert settings(paper3d()) == (5.0, "dop853", 1e-7, 1e-9)
    assert settings(paper3d(), "--method", "radau") == (5.0, "radau", 1e-6, 1e-9)
    assert settings(paper3d(), "--method", "cvodes") == (5.0, "cvodes", 1e-10, 1e-12)
    assert settings(pivot3d(), "--t-final", "2", "--rtol", "1e-5", "--atol", "1e-7") == \
        (2.0, "dop853", 1e-5, 1e-7)


@pytest.mark.parametrize("n", [3, 7, 64, 5000])
def test_trace_arclength_of_a_circle_on_a_sphere(n):
    """A latitude circle sampled at n + 1 points (closed): the polyline is the inscribed
    regular n-gon, of perimeter exactly 2 n rho sin(pi / n) (rho = r cos v0), which tends to
    the circumference 2 pi rho."""
    r, v0 = 0.01, 0.4
    sphere = surface_library.sphere(r)
    u = np.linspace(-math.pi, math.pi, n + 1)
    points = sphere.evaluate(u, np.full_like(u, v0))["point"]
    s = plots3d.trace_arclength(points)
    rho = r * math.cos(v0)
    assert s[0] == 0.0 and np.all(np.diff(s) > 0)
    assert s[-1] == pytest.approx(2 * n * rho * math.sin(math.pi / n), rel=1e-13)
    if n >= 5000:
        assert s[-1] == pytest.approx(2 * math.pi * rho, rel=1e-6)
    # invariant under a rigid motion (the object frame vs the world)
    rot = np.linalg.qr(np.random.default_rng(n).normal(size=(3, 3)))[0]
    moved = plots3d.trace_arclength(points @ rot.T + np.array([1.0, -2.0, 3.0]))
    np.testing.assert_allclose(moved, s, rtol=1e-12, atol=1e-15)


def test_contact_traces_roll_without_slip(tmp_path):
    """Rolling: the contact point travels as far on the object as on the fingertip."""
    import grasping_sym as gs

    scene = paper3d()
    result = gs.build(scene).simulate(1.0, method="radau", rtol=1e-6, atol=1e-9)
    for tr in plots3d.contact_traces(scene, result):
        assert tr.s_object[-1] > 1e-4  # m: the contact does move
        np.testing.assert_allclose(tr.s_tip, tr.s_object, rtol=1e-5, atol=1e-9)
        assert tr.object_points.shape == (len(result.t), 3)


def test_figures_without_outputs_skip_the_multipliers(caplog):
    scene = pivot3d()
    t = np.linspace(0.0, 0.01, 11)
    x = np.zeros((len(t), len(scene.state_names)))
    res = SimulationResult(t=t, x=x, state_names=scene.state_names, outputs={}, method="rk4")
    with caplog.at_level(logging.WARNING, logger="grasping_sym.viz.plots3d"):
        assert plots3d.multipliers_figure(scene, res) is None
    assert "skipping" in caplog.text
    fig = plots3d.arclength_figure(scene, res, plots3d.contact_traces(scene, res))
    assert len(fig.axes) == 2  # arclengths and residuals; no orthonormality panel


def test_sundials_on_a_grasp_that_projects_is_refused_before_the_build(tmp_path, capsys):
    """paper3d projects its steps (no stabilisation gain), which cvodes cannot: the command
    says so, and how to run it, before it builds or writes anything; ``--project`` takes
    simulate's settings by name."""
    code = cli.main(["simulate", "paper3d", "--method", "cvodes", "--out", str(tmp_path / "x")])
    err = capsys.readouterr().err
    assert code == 2 and "cannot do" in err and "--project off" in err and "Traceback" not in err
    assert not (tmp_path / "x").exists()
    parse = cli.make_parser().parse_args
    assert [cli.PROJECT[parse(["simulate", "paper3d", "--out", "x", *extra]).project]
            for extra in ([], ["--project", "steps"], ["--project", "rows"], ["--project", "off"])] == \
        [None, "steps", True, False]
