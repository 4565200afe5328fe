"""gs.load of a model whose files were edited: manifest.json's domain bounds and start.json's
numbers are checked before anything is used, and each problem is named with its file and
field (a copy of the session's paper2d under tmp_path, edited)."""
from __future__ import annotations

import json
import math
import shutil

import pytest

import grasping_sym as gs
from grasping_sym.errors import CorruptCacheError


@pytest.fixture
def copy(paper2d_model, tmp_path):
    directory = tmp_path / "paper2d"
    shutil.copytree(paper2d_model.directory, directory, symlinks=True)
    return directory


def _edit(path, change):
    data = json.loads(path.read_text())
    change(data)
    path.write_text(json.dumps(data))


@pytest.mark.parametrize("change, match", [
    (lambda m: m["lower"].__setitem__(6, math.nan), r"lower\[6\] = nan \(state 's'\): each bound must "
                                                    "be a finite number or null"),
    (lambda m: m["upper"].__setitem__(6, math.inf), r"upper\[6\] = inf \(state 's'\)"),
    (lambda m: m.update(lower=m["upper"], upper=m["lower"]), r"the bounds of state 's' are inverted "
                                                             "or empty: lower = 0.03, upper = -0.03"),
])
def test_nan_or_inverted_domain_bounds_are_refused(copy, change, match):
    """A NaN bound compares false both ways and would turn the domain check off."""
    _edit(copy / "manifest.json", change)
    with pytest.raises(CorruptCacheError, match=match) as err:
        gs.load(copy)
    assert "manifest.json is not a valid manifest" in str(err.value)


@pytest.mark.parametrize("change, match", [
    (lambda s: s.update(initial_state="abc"), "initial_state is a str: expected a list of 7 numbers"),
    (lambda s: s["initial_state"].pop(), "initial_state is 6 entries: expected a list of 7 numbers"),
    (lambda s: s["initial_state"].__setitem__(2, math.nan), r"initial_state\[2\] = nan \(state 'q2'\): "
                                                            "each entry must be a finite number"),
    (lambda s: s["initial_state"].__setitem__(0, "1.0"), r"initial_state\[0\] = '1.0' \(state"),
    (lambda s: s.update(start_params={}), r"start_params lacks \['"),
    (lambda s: s.update(start_params=[1.0]), "start_params is a list"),
    (lambda s: s.pop("key"), "key = None is not the scene definition's hash"),
])
def test_a_bad_start_file_is_named_with_its_field(copy, change, match):
    """Before: numpy's conversion error, or a NaN start blamed on an x0 never passed."""
    _edit(copy / "start.json", change)
    with pytest.raises(CorruptCacheError, match=match) as err:
        gs.load(copy)
    assert f"{copy / 'start.json'} is not a valid start of paper2d" in str(err.value)


def test_a_start_file_that_is_not_json_is_named(copy):
    (copy / "start.json").write_text('{"initial_state": [0.1,')
    with pytest.raises(CorruptCacheError, match=r"start\.json is not a JSON object \(damaged or edited\)"):
        gs.load(copy)
    assert gs.load(copy / "starts" / next((copy / "starts").iterdir()).name).name == "paper2d"


def test_a_build_never_uses_a_damaged_cached_start(paper2d_model, tmp_path, monkeypatch):
    """gs.build finds the start of its scene definition in the cache, edited: it is not used
    (a NaN start would be blamed on an x0 never passed); the start is taken afresh."""
    root = tmp_path / "cache"
    entry = root / paper2d_model.directory.name
    shutil.copytree(paper2d_model.directory, entry, symlinks=True)
    monkeypatch.setenv("GRASPING_SYM_CACHE", str(root))
    for start in (entry / "starts").iterdir():
        _edit(start, lambda s: s["initial_state"].__setitem__(2, math.nan))
    model = gs.build(gs.scenes.paper2d())
    assert model.build_info["start_source"] != "cache"
    assert model.initial_state()[2] == paper2d_model.initial_state()[2]
