"""An atlas of two charts for a closed surface written over the unit sphere of directions.

The sphere, ellipsoid and superquadric of ``geometry.surface_library`` are each a function
``S = F(d)`` of a unit direction ``d`` (``F(d) = r d``, ``diag(a, b, c) d``, ``rho(d) d``).
One latitude-longitude chart ``d = e(u, v) = (cos v cos u, cos v sin u, sin v)`` leaves out
its poles ``d = (0, 0, +-1)``. The atlas adds a second chart, the same chart turned so that
its poles lie on the x axis:

- chart 0: ``d = e(u, v)`` (poles on z);
- chart 1: ``d = P e(u, v) = (sin v, cos v cos u, cos v sin u)`` (poles on x), with ``P``
  the cyclic permutation ``(e1, e2, e3) -> (e3, e1, e2)`` (a rotation: both charts' normals
  point outward).

Where one chart nears its pole the other is near its equator: a point at latitude ``|v| >=
1.3`` of one chart has ``|v'| <= pi/2 - 1.3 = 0.27`` in the other. A contact therefore
switches chart when it reaches ``|v| = 1.3`` (``runtime.atlas``) and never chatters.

The compiled model takes the chart as a run-time parameter ``c`` in ``{0, 1}`` and writes one
surface, exact at both values (a product with an exact 0 or 1), so one model serves both
charts and a switch costs no build: where ``F(P d) = P F(d)`` (equal semi-axes) chart 0's
values turned by ``c`` (:attr:`Atlas.turned`), else ``F(P_c e(u, v))`` with ``P_c = (1 - c) I
+ c P`` (:attr:`Atlas.blended`). ``docs/conventions.md`` section 15 has the state's map across
a switch.

A torus, or a surface of revolution whose contour stays off its axis, has no pole: its one
chart covers it whole where its angles repeat (``ParametricSurface.periods``). Its atlas is
that chart over three turns of each repeating angle (``LON``; a closed contour: two
traversals or more), and a contact that reaches the domain's edge is carried a whole
period back toward the domain's middle: the same point, the same frame (``runtime.atlas``). It
has no chart parameter and costs the compiled model nothing.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import sympy as sp

from grasping_sym.geometry.surfaces import CHART, ParametricSurface, U, V

#: The longitude and latitude of both charts: the latitude is where a contact switches chart;
#: the longitude reaches past +-pi so that a contact crossing the seam wraps (by 2 pi) rarely.
LON = (-3 * math.pi, 3 * math.pi)
LAT = (-1.3, 1.3)


def directions(chart) -> tuple[sp.Expr, sp.Expr, sp.Expr]:
    """``P_chart e(u, v)``: the unit direction of chart ``chart`` (0, 1, or the symbol
    ``CHART`` for the blend of both) at ``(U, V)``."""
    e = (sp.cos(V) * sp.cos(U), sp.cos(V) * sp.sin(U), sp.sin(V))
    if chart == 0:
        return e
    if chart == 1:
        return (e[2], e[0], e[1])
    return tuple((1 - chart) * e[i] + chart * e[i - 1] for i in range(3))


@dataclass(frozen=True, eq=False)
class Atlas:
    """Two charts of a surface ``S = F(d)`` (module docstring).

    ``second``: chart 1 alone (the first is the surface that holds this atlas); ``blended``:
    the surface in ``U, V`` and ``CHART`` that the compiled model evaluates, None where it
    turns chart 0 instead (``turned``); ``kind`` (``linear``: ``F(d) = diag(axes) d``;
    ``radial``: ``F(d) = rho(d) d``, ``rho = (sum (d_i / a_i)^n)^(-1/n)``), ``axes`` and ``n``:
    ``F`` as the run time maps a contact across charts (``manifest``)."""

    blended: ParametricSurface | None
    second: ParametricSurface
    kind: str
    axes: tuple[float, float, float]
    n: int = 2
    #: where all three semi-axes are equal (a sphere, a cube-like superquadric), ``F(P d) = P
    #: F(d)``: chart 1 is chart 0 turned by ``Q = R P R^T`` about the centre ``c`` (its
    #: placement ``S = c + R F(d)``), which the model computes from chart 0's values at the
    #: cost of a turn (``derive.bodies3d.surface_sx``); else None
    turned: tuple | None = None
    center: tuple[float, float, float] = (0.0, 0.0, 0.0)

    def manifest(self) -> dict:
        """What the run time reads to map a contact's state from one chart to the other."""
        return {"kind": self.kind, "axes": [float(a) for a in self.axes], "n": int(self.n)}

    def key(self) -> str:
        return f"atlas:{self.kind}:{self.axes!r}:{self.n}"


def surface_of(d, axes, kind: str, n: int) -> tuple[sp.Expr, sp.Expr, sp.Expr]:
    """``F(d)`` (shape frame, m) of the kind ``kind`` with semi-axes ``axes`` (SymPy Floats)."""
    if kind == "linear":
        return tuple(a * di for a, di in zip(axes, d))
    rho = sum(di**n / a**n for di, a in zip(d, axes)) ** sp.Rational(-1, n)
    return tuple(rho * di for di in d)


def make_atlas(name: str, axes, kind: str, n: int, place, center, rotation) -> Atlas:
    """The atlas of the surface ``F`` of kind ``kind`` (``Atlas``), ``place`` turning a shape
    frame's ``(x, y, z)`` expressions into the surface placed in the body at ``center`` turned
    by ``rotation`` (``surface_library._make``'s)."""
    second = place(surface_of(directions(1), axes, kind, n), f"{name} (chart 1)", chart=False)
    values = tuple(float(a) for a in axes)
    if values[0] == values[1] == values[2]:
        R = np.asarray(rotation, dtype=float)
        return Atlas(None, second, kind, values, n, tuple(map(tuple, (R @ P @ R.T).tolist())),
                     tuple(float(c) for c in center))
    blended = place(surface_of(directions(CHART), axes, kind, n), f"{name} (both charts)", chart=True)
    return Atlas(blended, second, kind, values, n, None, tuple(float(c) for c in center))


#: The cyclic permutation from chart 0's direction to chart 1's: ``d = P e``.
P = np.array([[0.0, 0.0, 1.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]])


def periodic_manifest(surface) -> dict | None:
    """What the run time reads to carry a contact across the seam of a surface whose chart
    repeats (``surface.periods``; None where none does): each coordinate's period (None: it
    does not repeat) and the middle of its domain, toward which a wrapped coordinate goes."""
    if surface.periods is None:
        return None
    return {"kind": "periodic", "periods": [None if p is None else float(p) for p in surface.periods],
            "centers": [0.5 * (float(a) + float(b)) for a, b in surface.domain]}


def manifest_entry(surface, param: str, u: str, v: str, psi: str | None) -> dict | None:
    """The run time's entry (``runtime.atlas``) for a contact's coordinates on ``surface``
    (``u``, ``v``: their state names; ``psi``: its frame angle's, or None): its atlas's, with
    the chart parameter ``param``; a repeating chart's, with no parameter; or None."""
    if surface.atlas is not None:
        return {"param": param, "u": u, "v": v, "psi": psi, **surface.atlas.manifest()}
    periodic = periodic_manifest(surface)
    return None if periodic is None else {"param": None, "u": u, "v": v, "psi": psi, **periodic}
