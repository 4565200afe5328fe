"""Scenes used only by the benchmarks.

``ellipse2d`` is the "new 2D scene" of the cold-build test: the paper's catenary fingertip
against an elliptical object (semi-axes 20 mm x 30 mm), touching at the ellipse's leftmost
point, travelled so that its tangent there points along +Y like the paper's object contour.
The ellipse is not unit-speed, so the state has two contact parameters (8 states).
"""
from __future__ import annotations

import math

from grasping_sym.geometry import library
from grasping_sym.model import scenes
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


def fingers2d(n: int, **overrides) -> PlanarFingerScene:
    """``n`` = 1, 2 or 3 fingers with circular tips (r = 10 mm) on a pivoted ellipse
    (25 x 18 mm), as in ``tests/test_planar_multifinger.py``: finger 1 is the paper's, finger 2
    opposite it (base mirrored about the pivot), finger 3 from above."""
    from grasping_sym.model.planar import ExtraFinger

    tip = library.circle(0.01, name="tip")
    obj = library.ellipse(0.025, 0.018, span=6.2, clockwise=True, name="ellipse")
    u1 = -(math.pi + 0.3)
    xm, ym = scenes.planar_finger(tip, obj, name="one", u1_0=u1).pivot
    extra = [ExtraFinger(library.circle(0.01, name="tip2"), base=(2 * xm, 0.0), u1_0=0.35),
             ExtraFinger(library.circle(0.01, name="tip3"), base=(xm - 0.0325, ym + 0.149),
                         u1_0=-math.pi / 2 + 0.1)][:n - 1]
    outputs = ("constraint_residual", *(("f",) if n == 1 else (f"f{i}" for i in range(1, n + 1))))
    kwargs = dict(fingertip=tip, object=obj, name=f"fingers{n}", u1_0=u1, extra_fingers=tuple(extra),
                  outputs=outputs)
    kwargs.update(overrides)
    return scenes.planar_finger(**kwargs)
