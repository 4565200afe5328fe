"""A library of contours: circle, ellipse, superellipse, polynomial graph, catenary, and a
quintic spline through sampled points (``spline``, in ``geometry.spline``).

All lengths are metres, in the body's local frame. The direction of travel matters in
the 2D scene (see ``grasping_sym.model.planar``): the fingertip contour runs
counterclockwise about its body (outward normal on the right of the tangent, signed
curvature > 0), the object contour clockwise (outward normal on the left, signed curvature
< 0), as the paper's contours do; then ``kappa0`` and ``kappa1`` are both positive for
convex shapes. Use ``clockwise=True`` for an object contour from this library.
"""
from __future__ import annotations

import math
import numbers
from collections.abc import Sequence

import numpy as np
import sympy as sp

from grasping_sym.errors import InvalidCurveError
from grasping_sym.geometry.curves import PlanarCurve, T
from grasping_sym.geometry.spline import SplineCurve, spline
from grasping_sym.geometry.values import as_real

__all__ = ["circle", "ellipse", "superellipse", "polynomial_graph", "catenary", "paper_fingertip",
           "paper_object", "spline", "SplineCurve"]


class _Numbers:
    """The numeric arguments of a library function, read and checked together.

    Any real number is accepted: ``int``, ``float``, NumPy's scalars (``np.float32``,
    ``np.int64``, ...) and 0-d arrays; booleans, complex numbers, strings, NaN and infinities
    are named. A Python ``int`` or ``float`` is kept as it is (the contour's expressions, and
    so its content hash, are those of earlier versions)."""

    def __init__(self, name: str):
        self.name = name
        self.problems: list[str] = []

    def real(self, label: str, value, *, positive: bool = False):
        number = as_real(value, keep_python=True)
        if number is None or not math.isfinite(number) or (positive and not number > 0):
            what = "a finite positive number" if positive else "a finite real number"
            self.problems.append(f"{label} = {value!r} must be {what}")
            return 1.0
        return number

    def positive(self, label: str, value):
        return self.real(label, value, positive=True)

    def point(self, label: str, value) -> tuple:
        try:
            pair = tuple(value) if not isinstance(value, str) else ()
        except TypeError:
            pair = ()
        numbers_ = [as_real(v, keep_python=True) for v in pair]
        if len(numbers_) != 2 or any(v is None or not math.isfinite(v) for v in numbers_):
            self.problems.append(f"{label} = {value!r} must be two finite real numbers (x, y) in metres")
            return (0.0, 0.0)
        return tuple(numbers_)

    def flag(self, label: str, value) -> bool:
        if isinstance(value, (bool, np.bool_)) or (isinstance(value, numbers.Integral) and value in (0, 1)):
            return bool(value)
        self.problems.append(f"{label} = {value!r} must be True or False")
        return False

    def done(self) -> None:
        if self.problems:
            raise InvalidCurveError(self.name, self.problems)


def _even_integer(check: _Numbers, n) -> int:
    if isinstance(n, numbers.Integral) and not isinstance(n, bool) and n >= 2 and n % 2 == 0:
        return int(n)
    check.problems.append(f"n = {n!r} must be an even integer >= 2 for a smooth curve")
    return 2


def circle(
    radius: float,
    center: tuple[float, float] = (0.0, 0.0),
    *,
    by: str = "arclength",
    start: float = 0.0,
    span: float = 1.0,
    clockwise: bool = False,
    name: str = "circle",
) -> PlanarCurve:
    """A circular arc of ``radius`` about ``center``.

    ``by='angle'`` uses the polar angle as parameter (speed = radius), ``by='arclength'``
    the arclength ``s = radius * angle``. ``start`` is the polar angle (rad) at parameter 0
    and ``span`` the half-width of the domain in radians of arc. ``clockwise`` reverses the
    direction of travel (curvature changes sign).
    """
    check = _Numbers(name)
    radius, span = check.positive("radius", radius), check.positive("span", span)
    start, center = check.real("start", start), check.point("center", center)
    clockwise = check.flag("clockwise", clockwise)
    if by not in ("angle", "arclength"):
        check.problems.append(f"by = {by!r}: use 'angle' or 'arclength'")
    check.done()
    sgn = -1 if clockwise else 1
    if by == "angle":
        phi, dom = start + sgn * T, (-span, span)
    else:
        phi, dom = start + sgn * T / radius, (-span * radius, span * radius)
    r = sp.Float(radius)
    return PlanarCurve(center[0] + r * sp.cos(phi), center[1] + r * sp.sin(phi), T, dom, name)


def ellipse(
    a: float,
    b: float,
    center: tuple[float, float] = (0.0, 0.0),
    *,
    start: float = 0.0,
    span: float = 1.0,
    clockwise: bool = False,
    name: str = "ellipse",
) -> PlanarCurve:
    """Ellipse ``(a cos t, b sin t)`` (semi-axes in metres); no closed-form arclength.

    The parameter is the eccentric angle ``t``, domain ``start +- span``.
    """
    check = _Numbers(name)
    a, b, span = check.positive("a", a), check.positive("b", b), check.positive("span", span)
    start, center = check.real("start", start), check.point("center", center)
    clockwise = check.flag("clockwise", clockwise)
    check.done()
    phi = -T if clockwise else T
    return PlanarCurve(
        center[0] + sp.Float(a) * sp.cos(phi),
        center[1] + sp.Float(b) * sp.sin(phi),
        T,
        (start - span, start + span),
        name,
    )


def superellipse(
    a: float,
    b: float,
    n: int = 4,
    *,
    start: float = 0.0,
    span: float = 1.0,
    clockwise: bool = False,
    name: str = "superellipse",
) -> PlanarCurve:
    """Superellipse ``|x/a|^n + |y/b|^n = 1`` with an even integer ``n >= 2``.

    Written in polar form ``r(t) = (cos^n t / a^n + sin^n t / b^n)^(-1/n)``, which is smooth
    and regular everywhere for even ``n`` (the usual ``sign(cos t)|cos t|^(2/n)`` form is not).
    """
    check = _Numbers(name)
    a, b, span = check.positive("a", a), check.positive("b", b), check.positive("span", span)
    start, n = check.real("start", start), _even_integer(check, n)
    clockwise = check.flag("clockwise", clockwise)
    check.done()
    phi = -T if clockwise else T
    r = (sp.cos(phi) ** n / sp.Float(a) ** n + sp.sin(phi) ** n / sp.Float(b) ** n) ** sp.Rational(-1, n)
    return PlanarCurve(r * sp.cos(phi), r * sp.sin(phi), T, (start - span, start + span), name)


def polynomial_graph(
    coefficients: Sequence[float],
    domain: tuple[float, float],
    *,
    offset: float = 0.0,
    name: str = "polynomial",
) -> PlanarCurve:
    """The graph ``X = offset + sum_k c_k t^k``, ``Y = t`` (a contour bulging along X).

    ``coefficients`` are ``c_0, c_1, ...`` (SI units); ``t`` is the local Y coordinate.
    """
    check = _Numbers(name)
    try:
        coefficients = list(coefficients) if not isinstance(coefficients, str) else None
    except TypeError:
        coefficients = None
    if coefficients is None:
        check.problems.append("coefficients must be a sequence of numbers c_0, c_1, ...")
        coefficients = [0.0]
    elif not coefficients:
        check.problems.append("coefficients is empty: give at least one")
    coefficients = [check.real(f"coefficients[{k}]", c) for k, c in enumerate(coefficients)]
    offset = check.real("offset", offset)
    check.done()
    poly = sum(sp.Float(c) * T**k for k, c in enumerate(coefficients))
    return PlanarCurve(offset + poly, T, T, domain, name)


def catenary(
    k: float,
    x0: float,
    *,
    s0: float = 0.0,
    sign: int = 1,
    domain: tuple[float, float] = (-0.03, 0.03),
    name: str = "catenary",
) -> PlanarCurve:
    """The paper's unit-speed catenary contour (eqs 37-40).

    ``X(s) = x0 + sign * sqrt(1 + 4 k^2 (s - s0)^2) / (2k)``,
    ``Y(s) = asinh(2 k (s - s0)) / (2k)``: curvature ``2k`` at its vertex ``s = s0``.
    """
    check = _Numbers(name)
    k, x0, s0 = check.positive("k", k), check.real("x0", x0), check.real("s0", s0)
    if isinstance(sign, bool) or as_real(sign) not in (1.0, -1.0):
        check.problems.append(f"sign = {sign!r} must be +1 or -1")
    check.done()
    sign = sign if type(sign) in (int, float) else int(as_real(sign))
    kk = sp.Float(k)
    u = T - sp.Float(s0)
    x = sp.Float(x0) + sign * sp.sqrt(1 + 4 * kk**2 * u**2) / (2 * kk)
    y = sp.asinh(2 * kk * u) / (2 * kk)
    return PlanarCurve(x, y, T, domain, name)


def paper_fingertip() -> PlanarCurve:
    """Fingertip contour of Yoshida-Arimoto-Tahara 2009, eqs (37)-(38)."""
    return catenary(20.0, 0.035, sign=-1, domain=(-0.03, 0.03), name="paper fingertip")


def paper_object() -> PlanarCurve:
    """Object contour of Yoshida-Arimoto-Tahara 2009, eqs (39)-(40)."""
    return catenary(50.0, -0.03, s0=3.363e-3, sign=1, domain=(-0.03, 0.03), name="paper object")
