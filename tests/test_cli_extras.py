"""The command line's smaller parts: --version, clean scene descriptions, bench's options, the
cache, and scene parameters for one run."""
from __future__ import annotations

import os

import pytest

from grasping_sym import __version__
from grasping_sym.cli import main


def test_version_and_clean_descriptions(capsys):
    with pytest.raises(SystemExit) as exc:
        main(["--version"])
    assert exc.value.code == 0 and capsys.readouterr().out.strip() == f"grasping-sym {__version__}"
    assert main(["list"]) == 0
    lines = capsys.readouterr().out.strip().splitlines()
    assert len(lines) >= 3
    for line in lines:
        assert "``" not in line and ":func:" not in line and line.rstrip().endswith((".", ")"))


def test_bench_help_shows_its_options(capsys):
    with pytest.raises(SystemExit):
        main(["bench", "--help"])
    out = capsys.readouterr().out
    assert "--quick" in out and "--only" in out and "--out" in out


def test_cache_list_and_clear(tmp_path, monkeypatch, capsys):
    root = tmp_path / "cache"
    monkeypatch.setenv("GRASPING_SYM_CACHE", str(root))
    assert main(["cache", "list"]) == 0 and "empty" in capsys.readouterr().out
    for name in ("paper2d-0123456789abcdef", "paper2d-fedcba9876543210", "ellipse-0000111122223333"):
        (root / name).mkdir(parents=True, mode=0o700)
        (root / name / "manifest.json").write_text("{}" * 1000)
    os.chmod(root, 0o700)
    assert main(["cache", "list"]) == 0
    out = capsys.readouterr().out
    assert "3 entries" in out and "paper2d-0123456789abcdef" in out
    assert main(["cache", "clear", "nosuch"]) == 2
    assert "no cache entries named ['nosuch']" in capsys.readouterr().err
    assert main(["cache", "clear", "paper2d"]) == 0
    assert sorted(p.name for p in root.iterdir()) == ["ellipse-0000111122223333"]
    os.chmod(root, 0o777)  # others may write here: refused, nothing removed
    assert main(["cache", "clear"]) == 2
    assert "others may write it" in capsys.readouterr().err
    assert (root / "ellipse-0000111122223333").exists()
    os.chmod(root, 0o700)


def test_simulate_takes_parameter_values(tmp_path, capsys):
    assert main(["simulate", "paper2d", "--param", "fd=0.8", "--t-final", "0.2", "--method", "radau",
                 "--rtol", "1e-6", "--atol", "1e-8", "--out", str(tmp_path)]) == 0
    assert "paper2d" in capsys.readouterr().out
    assert main(["simulate", "paper2d", "--param", "fd=abc", "--t-final", "0.2",
                 "--out", str(tmp_path)]) == 2
    assert "--param 'fd=abc'" in capsys.readouterr().err
