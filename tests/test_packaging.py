"""A plain (non-editable) install ships the committed generated code and uses it."""
from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent


def test_non_editable_install_uses_the_committed_code(tmp_path):
    # a copy of what a source distribution holds, so that the build leaves nothing in the clone
    src = tmp_path / "src"
    for name in ("grasping_sym", "generated"):
        shutil.copytree(ROOT / name, src / name, ignore=shutil.ignore_patterns("__pycache__"))
    for name in ("pyproject.toml", "README.md"):
        shutil.copy(ROOT / name, src / name)
    target = tmp_path / "site"
    subprocess.run([sys.executable, "-m", "pip", "install", "--quiet", "--no-deps",
                    "--no-build-isolation", "--target", str(target), str(src)],
                   check=True, capture_output=True, cwd=tmp_path)
    structure = json.loads((ROOT / "generated" / "paper2d" / "manifest.json").read_text())["structure"]
    for f in ("paper2d/paper2d_1.c", "paper2d/paper2d_1.h", "paper2d/manifest.json",
              "paper2d/start.json", "paper3d/paper3d_1.c", "templates/planar-s-horizontal.json",
              f"structures/{structure['name']}/structure.json",
              f"structures/{structure['name']}/{structure['name']}_1.c"):
        assert (target / "grasping_sym" / "generated" / f).is_file(), f
    code = (
        "import json, grasping_sym as gs; from grasping_sym.store import paths as cache; "
        "from grasping_sym.pipeline import generate_committed; "
        "m = gs.build(gs.scenes.paper2d()); err = ''\n"
        "try: generate_committed(['paper2d'])\n"
        "except RuntimeError as e: err = str(e)\n"
        "print(json.dumps({'file': gs.__file__, 'source': m.build_info['source'], "
        "'start': m.build_info['start_source'], 'generated': str(cache.generated_dir()), "
        "'refused': err}))"
    )
    env = {**os.environ, "PYTHONPATH": str(target), "GRASPING_SYM_CACHE": str(tmp_path / "cache")}
    out = json.loads(subprocess.run([sys.executable, "-c", code], check=True, capture_output=True,
                                    text=True, cwd=tmp_path, env=env).stdout)
    assert out["file"].startswith(str(target))
    assert out["generated"].startswith(str(target))
    assert out["source"] == "committed C" and out["start"] == "committed"
    assert "source checkout" in out["refused"]
