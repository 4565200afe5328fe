"""How the runs of each kind of scene (``model.kinds``) are drawn and summed up by the
command line: ``write_figures(scene, result, out_dir)`` and ``summary_lines(scene, result)``."""
from __future__ import annotations

from pathlib import Path

from grasping_sym.model import kinds
from grasping_sym.viz.body import summary_lines as body_summary
from grasping_sym.viz.body import write_figures as body_figures
from grasping_sym.viz.plots import write_figures as planar_figures
from grasping_sym.viz.plots3d import summary_lines as summary_lines3d
from grasping_sym.viz.plots3d import write_figures3d

#: kind name -> (write_figures, summary_lines)
KINDS = {
    "planar": (planar_figures, lambda scene, result: []),
    "grasp3d": (write_figures3d, summary_lines3d),
    "body": (body_figures, body_summary),
    "body2d": (body_figures, body_summary),
    "planar_modes": (body_figures, body_summary),
    "grasp3d_modes": (body_figures, body_summary),
}


def write_figures(scene, result, out_dir: Path | str) -> list:
    """The figures of a run of ``scene`` written into ``out_dir`` (2D: the paper's time plots
    and the scene; 3D: snapshots and contact traces, the geometry derived once, 1-3 s)."""
    return kinds.of(scene, KINDS, "figures")[0](scene, result, out_dir)


def summary_lines(scene, result) -> list[str]:
    """Lines ``grasping-sym simulate`` prints of a run beyond the common ones."""
    return kinds.of(scene, KINDS, "a summary")[1](scene, result)
