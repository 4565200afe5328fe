"""Figures, animations and the HTML viewer: functions of (scene, result), never methods of
either. A run from ``gs.build`` carries its scene (``result.scene``); pass ``scene=`` for a
loaded one.

>>> gs.viz.animate(res, "motion.gif", fps=10)     # 2D and 3D
>>> gs.viz.view(res, "grasp.html")                # 3D: one self-contained page
>>> gs.viz.cone(res, "cone.png")                  # a run with mu: |F_t|/f against mu
>>> gs.viz.modes(res, "modes.png")                # a run with contact modes: bands, switches
"""
from __future__ import annotations

from pathlib import Path

from grasping_sym.viz.animation import animate as _animate
from grasping_sym.viz.cone import cone_figure as cone
from grasping_sym.viz.kinds import summary_lines, write_figures
from grasping_sym.viz.modes import modes_figure as modes
from grasping_sym.viz.options import known_options
from grasping_sym.viz.viewer import write_viewer

__all__ = ["animate", "cone", "modes", "summary_lines", "view", "write_figures"]


def animate(result, path: Path | str, scene=None, **options) -> Path:
    """Write the motion of ``result`` to ``path`` (``.gif``, or ``.mp4`` with ffmpeg): the
    scene drawn at evenly spaced times (``viz.animation.animate``: ``fps``, ``seconds``,
    ``dpi``). ``scene`` defaults to the run's (a model made by ``gs.build`` sets it)."""
    known_options(_animate, "animate", options)
    return _animate(result, path, scene, **options)


def view(result, path: Path | str, scene=None, **options) -> Path:
    """Write an interactive 3D viewer of ``result`` to ``path`` (one self-contained ``.html``:
    no network, nothing to install; ``viz.viewer.write_viewer``)."""
    known_options(write_viewer, "view", options)
    return write_viewer(result, path, scene, **options)
