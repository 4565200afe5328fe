"""The command line (`grasping-sym`) and the figures. Everything is written under tmp_path."""
from __future__ import annotations

import csv
import logging

import numpy as np
import pytest

from grasping_sym import cli
from grasping_sym.model.scenes import BUILTIN, paper2d
from grasping_sym.runtime.result import SimulationResult
from grasping_sym.viz import plots

PAPER2D_HEADER = [
    "t", "theta", "q1", "q2", "dtheta", "dq1", "dq2", "s",
    "Q", "R", "f", "lam", "delta_f", "delta_lam", "N1", "kappa_sum", "constraint_residual",
]
TIME_PNGS = [f"fig{p.paper_fig:02d}_{p.key}.png" for p in plots.TIME_PLOTS]


def _png_has_content(path) -> bool:
    import matplotlib.image as mpimg

    img = mpimg.imread(path)
    return img.ndim == 3 and img.shape[0] > 100 and img.shape[1] > 100 and float(img.std()) > 0.01


def test_list_names_every_builtin_scene(capsys):
    assert cli.main(["list"]) == 0
    out = capsys.readouterr().out
    for name in BUILTIN:
        assert name in out
    assert "Yoshida" in out  # the one-line description of paper2d


def test_simulate_paper2d_writes_csv_and_figures(tmp_path, capsys):
    out_dir = tmp_path / "run"
    code = cli.main(["simulate", "paper2d", "--t-final", "0.05", "--out", str(out_dir)])
    captured = capsys.readouterr()
    assert code == 0, captured.err
    with (out_dir / "trajectory.csv").open() as fh:
        rows = list(csv.reader(fh))
    assert rows[0] == PAPER2D_HEADER
    assert len(rows) == 1 + 51  # t_eval every ms from 0 to 0.05 s
    assert float(rows[-1][0]) == pytest.approx(0.05)
    for name in ["fig05_snapshots.png", *TIME_PNGS, "constraints_log.png", "overview.png"]:
        assert (out_dir / name).stat().st_size > 5000, name
    assert _png_has_content(out_dir / "fig05_snapshots.png")
    assert _png_has_content(out_dir / "fig06_delta_f.png")
    assert "max |Q|" in captured.out and "final s" in captured.out
    assert "[grasping-sym]" in captured.err  # progress on stderr


def test_unknown_scene_exits_2_and_names_known_scenes(tmp_path, capsys):
    code = cli.main(["simulate", "no_such_scene", "--out", str(tmp_path / "x")])
    err = capsys.readouterr().err
    assert code == 2
    assert "no_such_scene" in err and "paper2d" in err
    assert "Traceback" not in err
    assert not (tmp_path / "x").exists()


def test_draw_scene_contact_points_coincide():
    scene = paper2d()
    p = plots.pose(scene, scene.initial_state())
    np.testing.assert_allclose(p.contact_finger, p.contact_object, atol=1e-12)
    np.testing.assert_allclose(p.pivot, scene.pivot)
    # the drawn contours are tangent at the contact: their inertial tangents are parallel
    theta, q1, q2 = scene.initial_state()[:3]
    e0 = scene.fingertip.evaluate(np.array([scene.u0_0]))
    e1 = scene.object.evaluate(np.array([scene.u1_0]))
    t0 = plots._rot(np.pi / 2 - q1 - q2) @ np.array([e0["dx"][0], e0["dy"][0]])
    t1 = plots._rot(-theta) @ np.array([e1["dx"][0], e1["dy"][0]])
    assert abs(t0[0] * t1[1] - t0[1] * t1[0]) < 1e-12 * np.linalg.norm(t0) * np.linalg.norm(t1)


def test_missing_outputs_are_skipped_with_a_log_message(tmp_path, caplog):
    scene = paper2d()
    x0 = scene.initial_state()
    t = np.linspace(0.0, 0.01, 11)
    res = SimulationResult(t=t, x=np.tile(x0, (len(t), 1)), state_names=scene.state_names,
                           outputs={}, method="rk4")
    with caplog.at_level(logging.WARNING, logger="grasping_sym.viz.plots"):
        paths = plots.time_figures(scene, res, tmp_path)
    names = sorted(p.name for p in paths)
    assert names == sorted(["fig09_s.png", "fig10_dq1.png", "fig11_dq2.png",
                            "fig12_dtheta.png", "overview.png"])
    assert "delta_f" in caplog.text and "skipping" in caplog.text
