"""`grasping-sym bench` passes its arguments to `python -m benchmarks.run` in the repository."""
from __future__ import annotations

import subprocess
import sys
from pathlib import Path

from grasping_sym import cli


def test_bench_passes_its_arguments_through(monkeypatch):
    calls = []
    monkeypatch.setattr(subprocess, "call", lambda cmd, cwd: calls.append((cmd, cwd)) or 0)
    assert cli.main(["bench", "--quick", "--only", "paper3d", "--out", "x"]) == 0
    (cmd, cwd), = calls
    assert cmd == [sys.executable, "-m", "benchmarks.run", "--quick", "--only", "paper3d", "--out", "x"]
    assert (Path(cwd) / "benchmarks" / "run.py").is_file()


def test_other_commands_still_refuse_unknown_arguments(capsys):
    try:
        cli.main(["list", "--quick"])
    except SystemExit as exc:
        assert exc.code == 2
    assert "unrecognized arguments: --quick" in capsys.readouterr().err


def test_benchmarks_run_accepts_the_documented_options():
    out = subprocess.run([sys.executable, "-m", "benchmarks.run", "--help"], capture_output=True, text=True,
                         cwd=Path(cli.__file__).resolve().parent.parent, check=True).stdout
    for option in ("--quick", "--only", "--out"):
        assert option in out
