"""Process-wide state under threads: two threads building and running different models at once,
each in its own cache root (``store.paths.root_override``, a context variable), give the same
files and the same numbers as the same builds made in the session's cache (by one thread, with
no root override: whichever test built them first)."""
from __future__ import annotations

import threading
from pathlib import Path

import numpy as np

import grasping_sym as gs
from grasping_sym.store import paths

SCENES = ("paper2d", "pivot3d")


def _files_and_run(model) -> tuple[dict, np.ndarray]:
    """The model's C and manifest (bytes by file name) and a run's states."""
    files = {f: (model.directory / f).read_bytes() for f in (*model.manifest["files"], "manifest.json")}
    return files, model.simulate(0.2, t_eval=np.linspace(0, 0.2, 5)).x


def _build_and_run(name: str, root: Path) -> tuple[dict, np.ndarray, set]:
    """``_files_and_run`` of the scene built in ``root``, and what its root holds."""
    with paths.root_override(root):
        assert paths.cache_root() == root
        model = gs.build(gs.scenes.BUILTIN[name]())
        assert model.directory.parent == root
        files, x = _files_and_run(model)
        made = {p.name for p in root.iterdir() if p.name.startswith(name)}
    return files, x, made


def test_two_threads_build_and_run_as_one_thread_does(tmp_path):
    serial = {name: _files_and_run(gs.build(gs.scenes.BUILTIN[name]())) for name in SCENES}
    results: dict = {}
    failures: list = []
    barrier = threading.Barrier(len(SCENES))

    def work(name: str) -> None:
        try:
            barrier.wait()
            results[name] = _build_and_run(name, tmp_path / "threads" / name)
        except BaseException as exc:  # reported below, by scene
            failures.append((name, exc))

    threads = [threading.Thread(target=work, args=(name,)) for name in SCENES]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    assert not failures, failures
    assert paths._ROOT_OVERRIDE.get() is None  # no thread's root leaked into this one
    for name in SCENES:
        files, x, made = results[name]
        assert files == serial[name][0], f"{name}: other C or manifest than a serial build"
        assert np.array_equal(x, serial[name][1]), f"{name}: other numbers than a serial run"
        assert len(made) == 1, f"{name}: its root holds {made}"
        other = (tmp_path / "threads" / name)
        assert not any(p.name.startswith(tuple(s for s in SCENES if s != name)) for p in other.iterdir())
