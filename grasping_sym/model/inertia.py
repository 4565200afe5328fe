"""Mass properties of rigid bodies of simple shape (SI units, body frame).

A scene takes an object's inertia as a 3x3 matrix about the object frame's origin in its axes
(``model.grasp3d``); these functions give it for solid bodies of uniform density whose centre
and axes are that frame's.
"""
from __future__ import annotations

import numpy as np


def solid_ellipsoid_inertia(mass: float, a: float, b: float, c: float) -> np.ndarray:
    """Inertia (kg m^2, 3x3) of a solid ellipsoid of uniform density about its centre, in its axes.

    Parameters
    ----------
    mass
        kg.
    a, b, c
        m, the semi-axes along x, y and z.

    Returns
    -------
    numpy.ndarray
        ``mass / 5 * diag(b^2 + c^2, a^2 + c^2, a^2 + b^2)``; a sphere of radius ``r`` gives
        ``2/5 mass r^2`` on the diagonal.
    """
    return mass / 5 * np.diag([b * b + c * c, a * a + c * c, a * a + b * b])
