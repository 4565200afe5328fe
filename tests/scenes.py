"""Scenes that several test files build: one build serves them all through the session's
cache (``tests/conftest.py``), whichever file builds it first."""
from __future__ import annotations

import numpy as np

import grasping_sym as gs
from grasping_sym.geometry import surface_library
from grasping_sym.model import chains
from grasping_sym.model.grasp3d import Finger3D

BALL_R, BALL_M = 0.02, 0.04


def pressed_ball(name: str, offset: float, axes=None, surface=None, object_contact=(np.pi / 2, 0.0),
                 rotation=None):
    """``(a, scene)``: a free ball (radius 0.02 m, 0.04 kg, given centre ``a`` 0.5 mm above a
    table at y = 0) pressed from above by ``chains.finger1`` (fingertip sphere 0.010 m), its
    fingertip centre ``offset`` m beside the ball's top; ``axes``: an ellipsoid's semi-axes
    instead (its centre as high, its inertia a solid ellipsoid's). ``surface``: the ball's
    surface written otherwise (radius 0.02 m), ``object_contact`` the guess of the finger's
    contact on it (the top, ``(pi/2, 0)`` on the default chart); ``rotation``: the ball's at
    the start (a start value: the same compiled model)."""
    R, r, link = BALL_R, 0.010, 0.065
    centre = np.array([-0.05, R + 0.0005, 0.0])
    d = centre + (offset, R + r, 0.0) - np.array([-0.1275, 0.0, 0.0])
    q2 = np.arccos((d @ d - 2 * link**2) / (2 * link**2))
    q1 = np.arctan2(d[0], d[1]) - q2 / 2
    finger = Finger3D(chain=chains.finger1(), tip=surface_library.sphere(r, name="fingertip"),
                      q0=(q1, q2), tip_contact=(q1 + q2 - np.pi, 0.0), object_contact=tuple(object_contact))
    semi = (R, R, R) if axes is None else tuple(axes)
    inertia = np.eye(3) * 0.4 * BALL_M * R * R if axes is None else \
        np.array(gs.scenes.solid_ellipsoid_inertia(BALL_M, *semi))
    if surface is None:
        surface = surface_library.ellipsoid(*semi, lon=(-2.5, 4.0), name="ball")
    return centre, gs.scenes.paper3d(name=name, fingers=(finger,), mass=BALL_M,
                                     inertia=inertia, rotation=np.eye(3) if rotation is None else rotation,
                                     object_surface=surface,
                                     position=tuple(centre), k_center=0.0, dq0=None, outputs=())
