"""A cached scene is found by its definition (``pipeline.stages.definition_key``): the law's
definition read from its code (``model.law_keys``), never by running it. What is read must
tell apart every two laws that differ, and the model found must be the one the law's
expressions key."""
from __future__ import annotations

import numpy as np
import pytest

import grasping_sym as gs
from grasping_sym.model import controllers
from grasping_sym.model.law_keys import function_definition, value_definition
from grasping_sym.pipeline import making

GAIN = 0.5


def _law_of(c):
    return gs.controllers.law(lambda m: [-c * dq for dq in m.dq], name="extra")


def _reads_global(m):
    return [-GAIN * dq for dq in m.dq]


def _with_default(m, k=0.1):
    return [-k * dq for dq in m.dq]


class _Gains:
    k = 0.1


def test_a_laws_definition_changes_with_everything_it_reads(monkeypatch):
    assert _law_of(0.1).definition == _law_of(0.1).definition
    assert _law_of(0.1).definition != _law_of(0.2).definition  # a closure's value
    assert _law_of(0.1).definition != _law_of(np.float64(0.1)).definition  # and its type
    before = gs.controllers.law(_reads_global).definition
    monkeypatch.setitem(globals(), "GAIN", 0.25)
    assert gs.controllers.law(_reads_global).definition != before  # a global's value
    a = function_definition(_with_default)
    _with_default.__defaults__ = (0.2,)
    try:
        assert function_definition(_with_default) != a  # a default
    finally:
        _with_default.__defaults__ = (0.1,)
    # bytecode: the same names, another operation
    assert function_definition(lambda m: m.q + 1) != function_definition(lambda m: m.q - 1)
    # arrays by content; a helper function by its own definition
    w = np.array([1.0, 2.0])
    assert value_definition(w) != value_definition(w * 2)

    def helper(x):
        return 2 * x

    def helper2(x):
        return 3 * x

    def calls(h):
        return lambda m: h(m.q)

    assert function_definition(calls(helper)) != function_definition(calls(helper2))
    # presets by name and parameters, sums by their terms
    assert controllers.damping(0.1).definition != controllers.damping(0.2).definition
    assert (controllers.paper2d() + controllers.damping(0.1)).definition \
        != (controllers.damping(0.1) + controllers.paper2d()).definition
    assert controllers.turn3d(0.3, 1e-2).definition != controllers.turn3d(0.3, 1e-2, axis=(0, 1, 0)).definition


class _Law:
    def __init__(self, k):
        self.k = k

    def torques(self, m):
        return [-self.k * dq for dq in m.dq]


def _imports(m):
    from json import loads  # a module the user may edit: not read
    return [loads("0.1") * dq for dq in m.dq]


def _reads_globals(m):
    return [globals()["GAIN"] * dq for dq in m.dq]


def _reads_a_missing_name(m):
    return [MISSING * dq for dq in m.dq]  # noqa: F821 - the point: a name read at run time


def test_what_cannot_be_read_whole_gives_no_definition():
    g = _Gains()
    assert gs.controllers.law(lambda m: [-g.k * dq for dq in m.dq]).definition is None
    assert value_definition(pytest) is None  # a module that is not a fixed library's
    assert value_definition({"k": g}) is None
    assert (controllers.paper2d() + gs.controllers.law(lambda m: [g.k * m.dq[0]])).definition is None
    # a bound method: its instance is not read (two gains, one text, were they read as code)
    assert gs.controllers.law(_Law(1.0).torques).definition is None
    for fn in (_imports, _reads_globals, _reads_a_missing_name):
        assert gs.controllers.law(fn).definition is None, fn.__name__


def test_a_law_that_names_itself_is_read_once_and_the_text_is_the_same_in_every_process():
    """A law whose function reads the law itself (through a global) has a definition; a set
    among its constants is written sorted, so the text does not change with the string hash's
    seed from one process to the next."""
    import subprocess
    import sys

    script = ("import hashlib, grasping_sym as gs\n"
              "def f(m):\n"
              "    return [m.dq[0] if 'a' in {'a', 'b', 'c', 'd'} else 0 * LAW.name]\n"
              "LAW = gs.controllers.law(f)\n"
              "print(hashlib.sha256(LAW.definition.encode()).hexdigest())\n")
    seen = {subprocess.run([sys.executable, "-c", script], capture_output=True, text=True, check=True,
                           env={**__import__("os").environ, "PYTHONHASHSEED": str(seed)}).stdout
            for seed in (1, 2, 3)}
    assert len(seen) == 1 and len(next(iter(seen)).strip()) == 64


def test_a_cached_scene_is_found_without_running_its_law(monkeypatch):
    scene = gs.scenes.paper2d(controller=controllers.paper2d() + _law_of(0.004))
    first = gs.build(scene)
    # the definition found the model the law's expressions key
    assert making.code_hash(scene)["hash"] == first.manifest["hash"]

    def never(*a, **k):
        raise AssertionError("the law was run or its expressions hashed")

    monkeypatch.setattr(controllers.Controller, "torques", never)
    monkeypatch.setattr(making, "controller_key", never)
    again = gs.build(gs.scenes.paper2d(controller=controllers.paper2d() + _law_of(0.004)))
    assert again.build_info["key"] == "definition" and again.build_info["source"] == "cache"
    assert again.directory == first.directory
    np.testing.assert_array_equal(again.initial_state(), first.initial_state())
    # another gain is another definition: it is not found, and needs the law
    with pytest.raises(AssertionError, match="the law was run"):
        gs.build(gs.scenes.paper2d(controller=controllers.paper2d() + _law_of(0.008)))


def test_another_gain_builds_another_model_and_an_unreadable_law_still_builds():
    a = gs.build(gs.scenes.paper2d(controller=controllers.paper2d() + _law_of(0.004)))
    b = gs.build(gs.scenes.paper2d(controller=controllers.paper2d() + _law_of(0.008)))
    assert a.directory != b.directory
    x = a.initial_state().copy()
    x[3:6] = [0.1, -0.2, 0.3]  # moving: the extra damping shows
    assert not np.allclose(a.rhs(x)[3:6], b.rhs(x)[3:6], rtol=1e-6)
    g = _Gains()
    g.k = 0.004
    scene = gs.scenes.paper2d(controller=controllers.paper2d()
                              + gs.controllers.law(lambda m: [-g.k * dq for dq in m.dq]))
    c = gs.build(scene)
    assert c.build_info["key"] == "expressions" and c.directory == a.directory


@pytest.mark.parametrize("scene", ["paper2d", "paper3d"])
def test_a_cached_build_in_a_new_process_imports_nothing_that_builds(scene):
    """A build that finds its model by its definition, and the run after it, import none of
    the floors that derive, write or compile (``pipeline.making``): not the assembly, the
    emitter, the derivation or the compiler's library."""
    import json
    import os
    import subprocess
    import sys

    code = ("import json, sys\n"
            "import grasping_sym as gs\n"
            f"scene = gs.scenes.{scene}()\n"
            "before = set(sys.modules)\n"
            "model = gs.build(scene)\n"
            "res = model.simulate(0.05)\n"
            "print(json.dumps({'new': sorted(set(sys.modules) - before),\n"
            "                  'key': model.build_info['key'], 'source': model.build_info['source'],\n"
            "                  'ok': bool(abs(res.t[-1] - 0.05) < 1e-12)}))\n")
    run = [sys.executable, "-c", code]
    subprocess.run(run, check=True, capture_output=True, env={**os.environ})  # fills the cache
    got = json.loads(subprocess.run(run, check=True, capture_output=True, text=True,
                                    env={**os.environ}).stdout)
    assert (got["key"], got["source"], got["ok"]) == ("definition", "cache", True)
    building = ("grasping_sym.assemble", "grasping_sym.emit", "grasping_sym.derive",
                "grasping_sym.pipeline.making", "grasping_sym.pipeline.committed",
                "grasping_sym.toolchain.library", "grasping_sym.toolchain.objects")
    assert not [m for m in got["new"] if m.startswith(building)], got["new"]
    assert "grasping_sym.runtime.model" in got["new"]  # the check sees what the build imported


def test_a_cached_scene_is_found_without_reading_the_sources(monkeypatch):
    """The definition key takes the package's sources by their files' stat
    (``store.paths.sources_stamp``): a cached scene is found without reading the source tree
    (``tree_digest``). Another stamp (a source edited) misses the lookup: the build keys the
    code by the sources read whole, finds the same model, and records the new definition."""
    from grasping_sym.store import paths

    first = gs.build(gs.scenes.paper2d())
    real = paths.tree_digest

    def never():
        raise AssertionError("the source tree was read")

    monkeypatch.setattr(paths, "tree_digest", never)
    again = gs.build(gs.scenes.paper2d())
    assert (again.build_info["key"], again.build_info["source"]) == ("definition", "cache")
    assert again.directory == first.directory
    monkeypatch.setattr(paths, "tree_digest", real)
    monkeypatch.setattr(paths, "sources_stamp", lambda: "0" * 64)  # as after an edit
    moved = gs.build(gs.scenes.paper2d())
    assert (moved.build_info["key"], moved.build_info["source"]) == ("expressions", "cache")
    assert moved.directory == first.directory
    assert gs.build(gs.scenes.paper2d()).build_info["key"] == "definition"
