"""Golden test: the committed generated C equals a fresh generation, byte for byte, and the
committed start (solved numbers) equals a fresh solve to a tolerance.

To accept a deliberate change, run ``make generate`` (or set GRASPING_SYM_UPDATE_GOLDEN=1
for this test), then commit ``generated/``.
"""
from __future__ import annotations

import json
import os
import subprocess
import sys

import pytest

from grasping_sym.model.scenes import BUILTIN
from grasping_sym.pipeline import generate_committed
from grasping_sym.store.paths import generated_dir


def test_committed_generated_code_is_current():
    if os.environ.get("GRASPING_SYM_UPDATE_GOLDEN") == "1":
        generate_committed()
    differ = generate_committed(check=True)
    stale = {k: v for k, v in differ.items() if v}
    report = "\n".join(d for files in stale.values() for d in files.values())
    assert not stale, (
        f"generated/ is stale for {({k: sorted(v) for k, v in stale.items()})}: run `make generate` "
        f"and commit generated/\n{report}"
    )


def test_every_builtin_scene_has_committed_code():
    for name in BUILTIN:
        manifest = json.loads((generated_dir() / name / "manifest.json").read_text())
        for f in (*manifest["files"], "start.json"):
            assert (generated_dir() / name / f).is_file(), f"generated/{name}/{f} missing"
        assert f"{name}_1.c" in manifest["files"]


def test_generation_does_not_depend_on_hash_seed(tmp_path):
    """Two processes with different hash seeds write identical C."""
    outs = []
    for seed in ("1", "2"):
        d = tmp_path / seed
        code = (
            "import sys; from pathlib import Path; import grasping_sym as gs; "
            "from grasping_sym.pipeline import generate; "
            f"generate(gs.scenes.paper2d(), Path({str(d)!r}), count_ops=False)"
        )
        env = {**os.environ, "PYTHONHASHSEED": seed}
        subprocess.run([sys.executable, "-c", code], check=True, env=env)
        outs.append([(d / f).read_bytes() for f in sorted(os.listdir(d)) if f.endswith((".c", ".h"))])
    assert outs[0] == outs[1] and len(outs[0]) == 4  # a model in layers: two C files, their headers


def test_the_code_hash_reads_every_module_the_build_imports():
    """The tree the code's hash reads (``store.paths.tree_digest``) holds every package file
    a build of a 2D and a 3D scene imports: none can shape code unseen."""
    code = (
        "import sys, json; import grasping_sym as gs; from grasping_sym import pipeline; "
        "from grasping_sym.pipeline import making, committed; "
        "from grasping_sym.assemble import scene_functions; from grasping_sym.derive import start3d; "
        "gs.scenes.paper2d(); gs.scenes.paper3d(); "
        "print(json.dumps(sorted(m.__file__ for n, m in sys.modules.items() "
        "if n.startswith('grasping_sym') and getattr(m, '__file__', None))))"
    )
    import json

    from grasping_sym.store import paths

    out = subprocess.run([sys.executable, "-c", code], check=True, capture_output=True,
                         text=True).stdout
    imported = {os.path.realpath(f) for f in json.loads(out)}
    hashed = {os.path.realpath(f) for _, f in paths._tree_files()}
    assert len(imported) > 40
    missing = imported - hashed
    assert not missing, f"imported by the build, not in the code's hash: {sorted(missing)}"
    assert {os.path.realpath(paths.PACKAGE_DIR / "c" / "radau5.c")} <= hashed


def test_the_sources_stamp_follows_the_files_and_a_tree_changed_since_is_refused(tmp_path, monkeypatch):
    """The stamp a definition key takes (``store.paths.sources_stamp``: the files' stat, not
    their content) changes with a byte appended to a module; the tree read whole after a file
    changed under the process's stamp raises ``SourcesChangedError`` (the code in memory is
    not the code on disk), and a process that goes on reads the new stamp."""
    import shutil

    from grasping_sym.errors import SourcesChangedError
    from grasping_sym.store import paths

    copy = tmp_path / "grasping_sym"
    shutil.copytree(paths.PACKAGE_DIR, copy, ignore=shutil.ignore_patterns("__pycache__"))
    monkeypatch.setattr(paths, "PACKAGE_DIR", copy)
    try:
        paths.tree_digest.cache_clear()
        paths.sources_stamp.cache_clear()
        first = paths.sources_stamp()
        assert paths.sources_stamp.__wrapped__() == first
        digest = paths.tree_digest()  # the same stamp: read
        with open(copy / "derive" / "spatial.py", "a") as fh:
            fh.write("\n")
        assert paths.sources_stamp.__wrapped__() != first
        paths.tree_digest.cache_clear()
        with pytest.raises(SourcesChangedError, match="Restart Python"):
            paths.tree_digest()
        assert paths.sources_stamp() != first and paths.tree_digest() != digest
    finally:
        paths.tree_digest.cache_clear()
        paths.sources_stamp.cache_clear()


def test_the_code_hash_changes_with_any_file_below_the_top_floors(tmp_path, monkeypatch):
    """A byte changed in any module or C file of the build's floors changes the hash; one in
    a top floor (``ABOVE_THE_BUILD``: figures, sweeps, the command line) does not."""
    import shutil

    from grasping_sym.store import paths

    copy = tmp_path / "grasping_sym"
    shutil.copytree(paths.PACKAGE_DIR, copy, ignore=shutil.ignore_patterns("__pycache__"))
    monkeypatch.setattr(paths, "PACKAGE_DIR", copy)

    def digest() -> str:  # (the stamp too: the tree read whole must have the process's stamp)
        paths.tree_digest.cache_clear()
        paths.sources_stamp.cache_clear()
        return paths.tree_digest()

    try:
        before = digest()
        for rel, changes in (("derive/spatial.py", True), ("c/lu.c", True), ("errors.py", True),
                             ("viz/plots.py", False), ("cli.py", False)):
            with open(copy / rel, "a") as fh:
                fh.write("\n")
            after = digest()
            assert (after != before) == changes, rel
            before = after
    finally:
        paths.tree_digest.cache_clear()
        paths.sources_stamp.cache_clear()
