"""The 3D viewer: one self-contained HTML file, opened in headless Chromium (Debian's package),
whose screenshot shows the scene, and another one at another time; no text of a result (a
shared .npz, edited) runs as script in it; its options are bounded."""
from __future__ import annotations

import json
import re
import shutil
import subprocess

import numpy as np
import pytest
from PIL import Image

import grasping_sym as gs
from grasping_sym.errors import ViewOptionError
from grasping_sym.viz.viewer import _page


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


@pytest.fixture(scope="module")
def run3d(paper3d_model):
    return paper3d_model.simulate(0.5, t_eval=np.linspace(0, 0.5, 51))


def test_the_viewer_is_one_file_that_a_browser_draws(run3d, tmp_path):
    page = gs.viz.view(run3d, tmp_path / "grasp.html")
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
    with pytest.raises(ViewOptionError, match="animate"):
        gs.viz.view(res, tmp_path / "x.html")
    loaded = gs.SimulationResult.load(res.save(tmp_path / "r"))
    with pytest.raises(ViewOptionError, match="scene"):
        gs.viz.view(loaded, tmp_path / "x.html")
    # the options, bounded before any work (named with their bounds)
    for options, match in [({"frames": 0}, r"frames = 0: .* from 2 to 5000"),
                           ({"frames": 10**9}, "frames = 1000000000"),
                           ({"frames": 2.5}, "whole number"),
                           ({"fps": 0}, r"fps = 0: .*\(0, 240\]"),
                           ({"fps": float("nan")}, "fps = nan")]:
        with pytest.raises(ViewOptionError, match=match):
            gs.viz.view(res, tmp_path / "x.html", **options)
    assert not (tmp_path / "x.html").exists()


PAYLOAD = ('</script><script>document.title="PWNED";'
           'document.body.insertAdjacentHTML("beforeend","<p id=pwned></p>")</script><!--')


def test_no_text_of_a_result_runs_in_the_page(run3d, paper3d_model, tmp_path):
    """A shared .npz whose method, names and counters hold script: loaded and viewed, the page
    shows them as text, and no script of theirs runs (checked in the browser)."""
    saved = run3d.save(tmp_path / "shared.npz")
    with np.load(saved) as f:
        entries = {k: f[k] for k in f.files}
    meta = json.loads(str(entries["meta"]))
    meta["method"] = PAYLOAD
    meta["outputs"][0] = PAYLOAD + "\u2028"
    meta["stats"]["note"] = PAYLOAD
    entries["meta"] = np.array(json.dumps(meta))
    np.savez(saved, **entries)
    loaded = gs.SimulationResult.load(saved)
    assert loaded.method == PAYLOAD
    page = gs.viz.view(loaded, tmp_path / "shared.html", scene=paper3d_model.scene)
    text = page.read_text()
    assert text.count("<script") == 1 and text.count("</script>") == 1
    dom = subprocess.run([_chromium(), "--headless", "--disable-gpu", "--no-sandbox", "--dump-dom",
                          "--window-size=900,700", page.resolve().as_uri()],
                         capture_output=True, text=True, timeout=120).stdout
    assert "(drag to turn, scroll to zoom)" in dom        # the page's own script ran and drew
    assert 'paper3d: &lt;/script&gt;&lt;script&gt;document.title="PWNED"' in dom  # shown as text
    assert 'id="pwned"' not in dom and "<title>PWNED" not in dom   # the data's script never ran


def test_a_title_is_text_and_data_stays_in_its_script():
    title = "__DATA__</title><script>alert(1)</script>"
    page = _page(title, {"title": "a</script><!--<script>&\u2028\u2029", "n": [1.5]})
    assert page.count("<script") == 1 and page.count("</script>") == 1
    assert "<title>__DATA__&lt;/title&gt;&lt;script&gt;alert(1)&lt;/script&gt;</title>" in page
    data = re.search(r"const D = (.*);\n", page).group(1)
    assert "<" not in data and ">" not in data and "&" not in data and "\u2028" not in data
    assert json.loads(data) == {"title": "a</script><!--<script>&\u2028\u2029", "n": [1.5]}
