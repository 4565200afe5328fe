"""The documentation site builds with no warning, and the code of every tutorial and of the
README's quickstart runs as written."""
from __future__ import annotations

import os
import re
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent
TUTORIALS = sorted((ROOT / "docs" / "tutorials").glob("*.md"))


def test_the_site_builds_with_no_warning(tmp_path):
    env = {**os.environ, "NO_MKDOCS_2_WARNING": "1"}
    out = subprocess.run([sys.executable, "-m", "mkdocs", "build", "--strict", "-q", "-f",
                          str(ROOT / "mkdocs.yml"), "-d", str(tmp_path / "site")],
                         capture_output=True, text=True, env=env, cwd=ROOT)
    assert out.returncode == 0, out.stderr[-3000:]
    api = (tmp_path / "site" / "api" / "index.html").read_text()
    for name in ("simulate_many", "BatchResult", "animate", "casadi_function", "sweep"):
        assert name in api, name


@pytest.mark.parametrize("page", [*TUTORIALS, ROOT / "README.md"],
                         ids=[*(p.stem for p in TUTORIALS), "README"])
def test_every_tutorial_and_the_quickstart_run_as_written(page, tmp_path, monkeypatch):
    blocks = re.findall(r"```python\n(.*?)```", page.read_text(), flags=re.S)
    assert blocks, f"{page.name} has no code"
    monkeypatch.chdir(tmp_path)
    namespace: dict = {"__name__": "__tutorial__"}
    for k, code in enumerate(blocks):
        try:
            exec(compile(code, f"{page.name}[block {k}]", "exec"), namespace)  # noqa: S102 - our own docs
        except Exception as exc:  # noqa: BLE001
            pytest.fail(f"{page.name}, code block {k}: {type(exc).__name__}: {exc}")
