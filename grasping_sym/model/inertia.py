"""Mass properties of rigid bodies of simple shape (SI units, body frame).

A scene takes an object's inertia as a 3x3 matrix about the object frame's origin in its axes
(``model.grasp3d``); these functions give it for solid bodies of uniform density whose centre
and axes are that frame's.
"""
from __future__ import annotations

import math

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


def solid_superquadric_inertia(mass: float, a: float, b: float, c: float, n: int) -> np.ndarray:
    """Inertia (kg m^2, 3x3) of the solid ``|x/a|^n + |y/b|^n + |z/c|^n <= 1`` of uniform
    density about its centre, in its axes (``surface_library.superquadric``'s body).

    Over the unit body ``|x|^n + |y|^n + |z|^n <= 1`` (Dirichlet's integral)

        int |x|^p |y|^q |z|^r dV = 8 G((p+1)/n) G((q+1)/n) G((r+1)/n) / (n^3 G((p+q+r+3)/n + 1))

    (``G`` the gamma function), so ``int x^2 dV / V = k = G(3/n) G(3/n + 1) / (G(1/n)
    G(5/n + 1))`` (times ``a^2`` for the scaled body) and the inertia is
    ``mass k diag(b^2 + c^2, a^2 + c^2, a^2 + b^2)``: ``k = 1/5`` for ``n = 2`` (the
    ellipsoid), and ``k -> 1/3`` as ``n`` grows (the box of half-sides ``a, b, c``).
    """
    k = math.gamma(3 / n) * math.gamma(3 / n + 1) / (math.gamma(1 / n) * math.gamma(5 / n + 1))
    return mass * k * np.diag([b * b + c * c, a * a + c * c, a * a + b * b])


def inertia_pattern(inertia) -> str:
    """``"diagonal"`` or ``"full"``: the structural pattern of a 3x3 inertia, which compiled
    code depends on (its values are inputs of a 3D structure, ``assemble.structure3d``)."""
    H = np.asarray(inertia, dtype=float)
    return "diagonal" if not np.any(H - np.diag(np.diag(H))) else "full"
