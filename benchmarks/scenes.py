"""Scenes used only by the benchmarks.

``ellipse2d`` is the "new 2D scene" of the cold-build test: the paper's catenary fingertip
against an elliptical object (semi-axes 20 mm x 30 mm), touching at the ellipse's leftmost
point, travelled so that its tangent there points along +Y like the paper's object contour.
The ellipse is not unit-speed, so the state has two contact parameters (8 states).
"""
from __future__ import annotations

import math

from grasping_sym import scenes
from grasping_sym.geometry import library
from grasping_sym.model.planar import PlanarFingerScene


def ellipse2d(**overrides) -> PlanarFingerScene:
    """Paper fingertip on an ellipse ``a = 0.02 m``, ``b = 0.03 m`` (eccentric angle ``t``)."""
    kwargs = dict(
        fingertip=library.paper_fingertip(),
        object=library.ellipse(0.02, 0.03, start=math.pi, span=1.0, clockwise=True,
                               name="benchmark ellipse"),
        name="ellipse2d",
        u1_0=math.pi,
    )
    kwargs.update(overrides)
    return scenes.planar_finger(**kwargs)
