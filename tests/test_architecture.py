"""The runtime floor loads what was built without the floors that build it: importing every
runtime module (what ``gs.load`` needs) imports no SymPy, no CasADi, and no module of the
model, derivation, emitter, toolchain, assembly or pipeline floors (the import contracts in
``pyproject.toml`` say so statically; this checks it in a fresh interpreter)."""
from __future__ import annotations

import json
import pkgutil
import subprocess
import sys

import grasping_sym.runtime


def test_the_runtime_imports_neither_sympy_casadi_nor_the_build():
    names = sorted(f"grasping_sym.runtime.{m.name}" for m in pkgutil.iter_modules(grasping_sym.runtime.__path__))
    assert len(names) > 10
    code = ("import importlib, json, sys\n"
            f"for n in {names!r}: importlib.import_module(n)\n"
            "print(json.dumps(sorted(sys.modules)))")
    loaded = set(json.loads(subprocess.run([sys.executable, "-c", code], check=True, capture_output=True,
                                           text=True).stdout))
    assert not {"sympy", "casadi"} & loaded
    above = ("model", "derive", "emit", "toolchain", "assemble", "pipeline", "symbolic", "geometry", "viz")
    assert not [m for m in loaded if m.split(".")[:2] in [["grasping_sym", a] for a in above]]


def test_a_loaded_model_names_what_casadi_function_needs(paper2d_model):
    """A model from ``gs.load`` runs without SymPy and has no scene: asking it for the CasADi
    functions names ``gs.build`` (a model from ``gs.build`` gives them)."""
    import pytest

    import grasping_sym as gs

    loaded = gs.load(paper2d_model.directory)
    with pytest.raises(ValueError, match=r"gs\.build\(scene\)"):
        loaded.casadi_function()
    assert paper2d_model.casadi_function().name() == "paper2d_ode"


def test_2d_and_3d_derivations_make_one_kind_of_system():
    """Both derivations return the canonical ``ConstrainedSystem``, with the constraint and
    its Jacobian of matching sizes: what the assembly reads never depends on the dimension."""
    import grasping_sym as gs
    from grasping_sym.derive.grasp3d import derive_grasp3d
    from grasping_sym.derive.planar import derive_template
    from grasping_sym.derive.system import ConstrainedSystem

    planar = derive_template(shared=True, gravity=False)
    spatial = derive_grasp3d(gs.scenes.pivot3d())
    for system in (planar, spatial):
        assert type(system) is ConstrainedSystem
        assert system.constraint.shape[0] == system.constraint_jac.shape[0]
        assert system.constraint_jac.shape[1] == system.n
