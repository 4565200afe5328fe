"""grasping_sym: rolling contact between arbitrary smooth shapes, as compiled equations of motion.

>>> import grasping_sym as gs
>>> model = gs.build(gs.scenes.paper2d())
>>> res = model.simulate(t_final=3.0)
>>> gs.viz.animate(res, "motion.gif")

The package's names are imported on first use (module ``__getattr__``): ``import
grasping_sym as gs; gs.load(path)`` runs a built model without importing SymPy.
"""
from __future__ import annotations

import importlib

__version__ = "0.1.0"

#: Public name -> (module, attribute or None for the module itself).
_LAZY = {
    "build": ("grasping_sym.pipeline", "build"),
    "load": ("grasping_sym.runtime.loader", "load"),
    "scenes": ("grasping_sym.model.scenes", None),
    "curves": ("grasping_sym.geometry.library", None),
    "surfaces": ("grasping_sym.geometry.surface_library", None),
    "PlanarCurve": ("grasping_sym.geometry.curves", "PlanarCurve"),
    "SimulationResult": ("grasping_sym.runtime.result", "SimulationResult"),
    "Model": ("grasping_sym.runtime.model", "Model"),
    "controllers": ("grasping_sym.model.controllers", None),
    "inputs": ("grasping_sym.runtime.inputs", None),
    "sweep": ("grasping_sym.sweeps", "sweep"),
    "viz": ("grasping_sym.viz", None),
    "contact": ("grasping_sym.contact", None),
    "quality": ("grasping_sym.quality", None),
    "hands": ("grasping_sym.model.hands", None),
    "export": ("grasping_sym.export", None),
}

__all__ = ["build", "load", "scenes", "curves", "surfaces", "PlanarCurve", "SimulationResult", "Model",
           "controllers", "inputs", "sweep", "viz", "contact", "quality", "hands", "export", "__version__"]


def __getattr__(name: str):
    if name not in _LAZY:
        raise AttributeError(f"module 'grasping_sym' has no attribute {name!r}")
    module, attr = _LAZY[name]
    value = importlib.import_module(module)
    if attr is not None:
        value = getattr(value, attr)
    globals()[name] = value  # later look-ups skip this function
    return value


def __dir__() -> list[str]:
    return sorted(set(globals()) | set(_LAZY))
