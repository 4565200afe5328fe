"""grasping_sym: rolling contact between arbitrary smooth shapes, as compiled equations of motion.

>>> import grasping_sym as gs
>>> model = gs.build(gs.scenes.paper2d())
>>> res = model.simulate(t_final=3.0)
"""
__version__ = "0.1.0"

from grasping_sym import scenes  # noqa: E402
from grasping_sym.geometry import library as curves  # noqa: E402
from grasping_sym.geometry.curves import PlanarCurve  # noqa: E402
from grasping_sym.pipeline import build  # noqa: E402
from grasping_sym.runtime.result import SimulationResult  # noqa: E402

__all__ = ["build", "scenes", "curves", "PlanarCurve", "SimulationResult", "__version__"]
