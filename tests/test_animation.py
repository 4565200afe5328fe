"""res.animate: the motion written as a GIF, in 2D and 3D, frames evenly spaced in time."""
from __future__ import annotations

import numpy as np
import pytest
from PIL import Image

import grasping_sym as gs
from grasping_sym.errors import ViewOptionError
from grasping_sym.viz.animation import frame_rows


def _frames(path) -> list[np.ndarray]:
    im = Image.open(path)
    out = []
    for k in range(im.n_frames):
        im.seek(k)
        out.append(np.asarray(im.convert("RGB"), dtype=float))
    return out


def test_a_2d_run_animates_and_its_frames_move(paper2d_model, tmp_path):
    res = paper2d_model.simulate(1.0, method="radau", rtol=1e-6, atol=1e-8)
    path = gs.viz.animate(res, tmp_path / "motion.gif", fps=5, seconds=1.0)
    frames = _frames(path)
    assert len(frames) == len(frame_rows(res.t, 5, 1.0)) == 6
    assert np.abs(frames[0] - frames[-1]).mean() > 0.1  # the finger and the object moved
    with pytest.raises(ViewOptionError, match=r"\.gif"):
        gs.viz.animate(res, tmp_path / "motion.avi")
    loaded = gs.SimulationResult.load(res.save(tmp_path / "r"))
    with pytest.raises(ViewOptionError, match="scene"):
        gs.viz.animate(loaded, tmp_path / "x.gif")


@pytest.mark.parametrize("options, match", [
    ({"fps": 1e12}, r"fps = 1000000000000.0: give frames per second in \(0, 100\]"),
    ({"fps": -1}, r"fps = -1: .*\(0, 100\]"),
    ({"fps": "20"}, "fps = '20'"),
    ({"dpi": 1e5}, r"dpi = 100000.0: give dots per inch in \[10, 600\]"),
    ({"dpi": 0}, r"dpi = 0: .*\[10, 600\]"),
    ({"seconds": 1e9}, r"seconds = 1000000000.0: .*\(0, 600\] s"),
    ({"seconds": float("nan")}, "seconds = nan"),
    ({"fps": 100, "seconds": 600, "dpi": 600}, r"101 frames of 3840 x 3120 pixels .* lower fps, seconds or dpi"),
])
def test_options_are_bounded_before_anything_is_drawn(paper2d_model, tmp_path, options, match):
    res = paper2d_model.simulate(0.1)
    with pytest.raises(ViewOptionError, match=match):
        gs.viz.animate(res, tmp_path / "motion.gif", **options)
    assert not (tmp_path / "motion.gif").exists()


def test_a_3d_run_animates(paper3d_model, tmp_path):
    res = paper3d_model.simulate(0.5, method="radau", rtol=1e-6, atol=1e-9,
                                 t_eval=np.linspace(0, 0.5, 51))
    frames = _frames(gs.viz.animate(res, tmp_path / "grasp.gif", fps=4, seconds=0.5))
    assert len(frames) == 3 and frames[0].shape[2] == 3
    assert np.abs(frames[0] - frames[-1]).mean() > 0.01
