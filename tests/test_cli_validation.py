"""Bad command-line input: one line on stderr and exit code 2, found before any work (nothing
is built, simulated, swept or written)."""
from __future__ import annotations

import os

import pytest

import grasping_sym.pipeline
from grasping_sym.cli import MAX_T_FINAL, main


@pytest.fixture
def no_work(monkeypatch):
    """Any build fails the test: a bad argument must be refused before the work starts."""

    def build(*args, **kwargs):
        raise AssertionError("the command built a model before refusing its arguments")

    monkeypatch.setattr(grasping_sym.pipeline, "build", build)


def _refused(capsys, argv: list[str], *needles: str) -> str:
    """Exit code 2 and one line of error on stderr (besides progress lines), no traceback."""
    assert main(argv) == 2
    lines = [line for line in capsys.readouterr().err.splitlines() if not line.startswith("[grasping-sym] ")]
    assert len(lines) == 1 and lines[0].startswith("grasping-sym: error: "), lines
    for needle in needles:
        assert needle in lines[0], lines[0]
    return lines[0]


def test_simulate_refuses_an_out_that_is_a_file_before_running(tmp_path, capsys, no_work):
    path = tmp_path / "notes.txt"
    path.write_text("mine")
    _refused(capsys, ["simulate", "paper2d", "--t-final", "0.1", "--out", str(path)],
             "--out", "it is a file")
    _refused(capsys, ["simulate", "paper2d", "--t-final", "0.1", "--out", str(path / "inner")],
             "notes.txt is a file, not a directory")
    assert path.read_text() == "mine" and os.listdir(tmp_path) == ["notes.txt"]


@pytest.mark.skipif(not hasattr(os, "geteuid") or os.geteuid() == 0,
                    reason="root writes into a read-only directory")
def test_simulate_refuses_an_unwritable_out_before_running(tmp_path, capsys, no_work):
    locked = tmp_path / "locked"
    locked.mkdir(mode=0o500)
    try:
        _refused(capsys, ["simulate", "paper2d", "--out", str(locked)], "cannot write there")
    finally:
        locked.chmod(0o700)


@pytest.mark.parametrize("argv, needles", [
    (["--param", "fd=-3"], ["--param fd", "-3", "must be > 0", "paper2d"]),
    (["--param", "gf=-1"], ["--param gf", "must be >= 0"]),
    (["--param", "fd=nan"], ["--param 'fd=nan'", "finite number"]),
    (["--t-final", "1e9"], ["--t-final 1e+09", f"at most {MAX_T_FINAL:g} s"]),
    (["--t-final", "inf"], ["--t-final", "finite number > 0"]),
    (["--t-final", "1e-13", "--method", "cvodes"], ["cvodes", "shorter than"]),
    (["--method", "bogus"], ["--method", "invalid choice"]),
    (["--rtol", "5"], ["rtol = 5.0 must be below 1"]),
    (["--param", "fd=1", "--param", "fd=2"], ["--param fd: given twice (1 and 2)"]),
])
def test_simulate_refuses_bad_values_before_running(tmp_path, capsys, no_work, argv, needles):
    out = tmp_path / "out"
    _refused(capsys, ["simulate", "paper2d", "--out", str(out), *argv], *needles)
    assert not out.exists()


def test_simulate_refuses_an_empty_out(tmp_path, capsys, no_work, monkeypatch):
    monkeypatch.chdir(tmp_path)
    _refused(capsys, ["simulate", "paper2d", "--out", ""], "--out is empty")
    assert list(tmp_path.iterdir()) == []


def test_a_missing_argument_is_one_line_too(capsys):
    _refused(capsys, ["simulate", "paper2d"], "--out", "required")
    _refused(capsys, [], "required")


@pytest.mark.parametrize("argv, needles", [
    (["--param", "fd=0.3:1:3", "--chunk", "0"], ["--chunk", "'0' must be an integer >= 1"]),
    (["--param", "fd=0.3:1:3", "--chunk", "x"], ["--chunk", "not an integer"]),
    (["--param", "fd=nan:1:3"], ["--param 'fd=nan:1:3'", "finite numbers"]),
    (["--param", "fd=0.5,nan"], ["finite numbers"]),
    (["--param", "fd=0.5:1:10000000000"], ["NUM an integer from 1 to 1,000,000"]),
    (["--param", "fd=-3:1:3"], ["--param fd", "-3", "must be > 0"]),
    (["--param", "fd=0.3:1:3", "--show", "bogus"], ["--show 'bogus'", "settle_<state>", "min_f"]),
    (["--param", "fd=0.3:1:3", "--show", "f"], ["--show 'f'"]),
    (["--param", "fd=0.3:1:3", "--t-final", "1e9"], [f"at most {MAX_T_FINAL:g} s"]),
    (["--param", "fd=0.3:1:3", "--param", "fd=0.5,0.6"], ["each name once"]),
    (["--param", "fd=0.3:1:3", "--param", "gf=0:1:2", "--param", "q1_0=0.5,0.6"], ["3 axes"]),
    (["--param", "mass=1,2"], ["scene is invalid (1 problem(s)): - runtime parameter 'mass'"]),
    ([], ["at least one --param"]),
])
def test_sweep_refuses_bad_values_before_sweeping(tmp_path, capsys, no_work, argv, needles):
    out = tmp_path / "out"
    _refused(capsys, ["sweep", "paper2d", "--out", str(out), "--quiet", *argv], *needles)
    assert not out.exists()


def test_sweep_refuses_a_store_that_is_a_file_before_sweeping(tmp_path, capsys, no_work):
    (tmp_path / "sweep.zarr").write_text("mine")
    _refused(capsys, ["sweep", "paper2d", "--param", "fd=0.3:1:3", "--out", str(tmp_path)],
             "sweep.zarr is a file, not a Zarr store")
    assert (tmp_path / "sweep.zarr").read_text() == "mine"
