"""The 3D viewer: one self-contained HTML file, opened in headless Chromium (Debian's package),
whose screenshot shows the scene, and another one at another time."""
from __future__ import annotations

import shutil
import subprocess

import numpy as np
import pytest
from PIL import Image

import grasping_sym as gs


def _chromium() -> str:
    for name in ("chromium", "chromium-browser", "google-chrome"):
        if path := shutil.which(name):
            return path
    pytest.fail("no headless browser: install Debian's chromium (apt install chromium); "
                ".ci/run does so")


def _shot(page, out, frame: int | None = None) -> np.ndarray:
    url = page.resolve().as_uri() + (f"#frame={frame}" if frame is not None else "")
    run = subprocess.run([_chromium(), "--headless", "--disable-gpu", "--no-sandbox",
                          "--hide-scrollbars", f"--screenshot={out}", "--window-size=900,700", url],
                         capture_output=True, text=True, timeout=120)
    assert out.exists(), run.stderr[-2000:]
    return np.asarray(Image.open(out).convert("RGB"), dtype=int)


def test_the_viewer_is_one_file_that_a_browser_draws(paper3d_model, tmp_path):
    res = paper3d_model.simulate(0.5, t_eval=np.linspace(0, 0.5, 51))
    page = res.view(tmp_path / "grasp.html")
    text = page.read_text()
    assert "http://" not in text and "https://" not in text and "<script src" not in text
    img = _shot(page, tmp_path / "first.png")
    r, g, b = img[..., 0], img[..., 1], img[..., 2]
    red = (r > 150) & (g < 130) & (b < 130)            # the object's mesh
    blue = (b > 130) & (r < 120)                        # fingertip 1
    green = (g > 120) & (r < 120) & (b < 120)           # fingertip 2
    grey = (abs(r - g) < 10) & (abs(g - b) < 10) & (r > 40) & (r < 110)   # the links
    assert red.sum() > 300 and blue.sum() > 50 and green.sum() > 50 and grey.sum() > 300
    last = _shot(page, tmp_path / "last.png", frame=-1)
    # another time, another picture: the scene itself moved (the rows between the title and
    # the time slider)
    assert np.abs(last[40:640] - img[40:640]).sum() > 1000


def test_the_viewer_refuses_what_it_cannot_draw(paper2d_model, tmp_path):
    res = paper2d_model.simulate(0.1)
    with pytest.raises(ValueError, match="animate"):
        res.view(tmp_path / "x.html")
    loaded = gs.SimulationResult.load(res.save(tmp_path / "r"))
    with pytest.raises(ValueError, match="scene"):
        loaded.view(tmp_path / "x.html")
