"""A library of surface patches: sphere, ellipsoid, superquadric, plane, torus, revolution.

All lengths are metres, in the body's local frame. Every constructor takes an optional
``center`` (3-vector, m) and ``rotation`` (3x3 proper rotation matrix, body-local from the
shape's own frame): ``S = center + rotation @ S_shape``. The unit normal ``S_u x S_v / |.|``
of the closed surfaces points outward.

The sphere, ellipsoid and superquadric share the latitude-longitude chart
``u = longitude`` (about the shape's z axis, default ``[-pi, pi]``), ``v = latitude``
(default ``[-1.3, 1.3]`` rad, i.e. 15 degrees short of each pole). The chart is singular at
the poles ``v = +-pi/2`` on the shape's z axis, so latitudes must stay inside
``(-pi/2, pi/2)``: rotate the shape so the region where contact happens lies near the
equator (e.g. for a fingertip pointing along local x, keep the shape's z axis sideways).
"""
from __future__ import annotations

import math
import numbers

import numpy as np
import sympy as sp

from grasping_sym.errors import InvalidSurfaceError
from grasping_sym.geometry.atlas import LAT as ATLAS_LAT
from grasping_sym.geometry.atlas import LON as ATLAS_LON
from grasping_sym.geometry.atlas import make_atlas
from grasping_sym.geometry.curves import PlanarCurve, T
from grasping_sym.geometry.surfaces import ParametricSurface, U, V
from grasping_sym.geometry.values import as_real

Vec3 = tuple[float, float, float]
_PI = math.pi


def _finite_positive(**values: float) -> list[str]:
    """Each value must be one finite positive real number (NumPy scalars and 0-d arrays too)."""
    return [f"{k} = {v!r} must be a finite positive number" for k, v in values.items()
            if not ((x := as_real(v)) is not None and 0 < x < math.inf)]


def _num(value):
    """A checked number as the library uses it: Python ``int``/``float`` unchanged (the same
    expressions and content hash as before), any other real number (``np.float32``, ...) as
    a ``float``."""
    return as_real(value, keep_python=True)


def _interval(label: str, span, lo: float = -math.inf, hi: float = math.inf) -> list[str]:
    try:
        pair = tuple(span) if not isinstance(span, str) else ()
    except TypeError:
        pair = ()
    values = [as_real(x) for x in pair]
    if len(values) != 2 or None in values:
        return [f"{label} = {span!r} must be a pair of numbers (min, max)"]
    a, b = values
    if not (math.isfinite(a) and math.isfinite(b) and lo < a < b < hi):
        return [f"{label} = ({a:.6g}, {b:.6g}) must satisfy {lo:.6g} < min < max < {hi:.6g}"]
    return []


def _real_array(value, shape: tuple[int, ...]) -> np.ndarray:
    """``value`` as a float array of ``shape``; ``ValueError`` unless it holds real numbers
    only (strings, booleans and complex numbers are refused, not converted)."""
    arr = np.asarray(value)
    if arr.dtype.kind not in "iuf":
        raise ValueError(f"dtype {arr.dtype}")
    return arr.astype(float).reshape(shape)


def _placement(center, rotation) -> tuple[list[str], np.ndarray, np.ndarray]:
    problems: list[str] = []
    c, R = np.zeros(3), np.eye(3)
    try:
        c = _real_array(center, (3,))
        if not np.isfinite(c).all():
            problems.append(f"center = {center!r} must be three finite numbers (m)")
    except (TypeError, ValueError):
        problems.append(f"center = {center!r} must be three finite numbers (m)")
    if rotation is not None:
        try:
            R = _real_array(rotation, (3, 3))
            if not (np.isfinite(R).all() and np.allclose(R.T @ R, np.eye(3), atol=1e-9)
                    and np.linalg.det(R) > 0):
                problems.append(f"rotation = {rotation!r} must be a proper rotation matrix "
                                "(orthonormal, det +1; a reflection would turn the normal inward)")
        except (TypeError, ValueError):
            problems.append(f"rotation = {rotation!r} must be a 3x3 rotation matrix")
    return problems, c, R


def _make(name: str, xyz, center, rotation, domain, problems: list[str], atlas=None,
          periods=None) -> ParametricSurface:
    """The surface ``center + rotation @ xyz``; with ``atlas = (axes, kind, n)`` the first
    chart of an atlas of two (``geometry.atlas``), placed alike; ``periods``: its coordinates'
    periods where one chart covers it by repeating (``ParametricSurface.periods``)."""
    more, c, R = _placement(center, rotation)
    problems = problems + more
    if problems:
        raise InvalidSurfaceError(name, problems)
    dom = tuple(tuple(_num(x) for x in pair) for pair in domain)

    def place(shape_xyz, label: str, chart: bool = False) -> ParametricSurface:
        out = []
        for i in range(3):  # skip zero entries so the identity placement leaves S unchanged
            e = sum((shape_xyz[j] if R[i, j] == 1.0 else sp.Float(R[i, j]) * shape_xyz[j])
                    for j in range(3) if R[i, j] != 0.0)
            out.append(e + sp.Float(c[i]) if c[i] != 0.0 else e)
        return ParametricSurface(out, (U, V), dom, label, charted=chart)

    if atlas is None:
        out = place(xyz, name)
        if periods is not None:
            object.__setattr__(out, "periods", tuple(None if q is None else float(q) for q in periods))
        return out
    axes, kind, n = atlas  # ``xyz`` is chart 0's F(e(u, v))
    first = place(xyz, name)
    object.__setattr__(first, "atlas", make_atlas(name, axes, kind, n, place, c, R))
    return first


def _charts(atlas, lon, lat, defaults) -> tuple[list[str], tuple, tuple]:
    """``(problems, lon, lat)``: an atlas's own domain (``geometry.atlas``) when ``atlas``;
    a ``lon`` or ``lat`` given with it is refused by name."""
    if atlas is not True:
        return ([] if atlas is False else [f"atlas = {atlas!r} must be True or False"]), lon, lat
    if (lon, lat) != defaults:
        return (["lon and lat are the atlas's own with atlas=True (longitude (-3 pi, 3 pi), both "
                 "charts' latitude (-1.3, 1.3), where a contact switches chart): leave them out"],
                ATLAS_LON, ATLAS_LAT)
    return [], ATLAS_LON, ATLAS_LAT


def _latlon_problems(lon, lat) -> list[str]:
    return _interval("lon", lon) + _interval("lat", lat, -_PI / 2, _PI / 2)


def sphere(radius: float, center: Vec3 = (0.0, 0.0, 0.0), rotation=None, *,
           lon: tuple[float, float] = (-_PI, _PI), lat: tuple[float, float] = (-1.3, 1.3),
           name: str = "sphere", atlas: bool = False) -> ParametricSurface:
    """Sphere ``r (cos v cos u, cos v sin u, sin v)``: ``u`` longitude, ``v`` latitude (rad).

    ``lat`` must lie strictly inside ``(-pi/2, pi/2)`` (the poles are singular points of the
    chart). Orthogonal chart: ``E = r^2 cos^2 v``, ``F = 0``, ``G = r^2``.

    ``atlas=True``: the whole sphere, in two charts (``geometry.atlas``): a contact that
    reaches latitude +-1.3 of one continues in the other, poles and seam included.
    """
    atlas_problems, lon, lat = _charts(atlas, lon, lat, ((-_PI, _PI), (-1.3, 1.3)))
    problems = _finite_positive(radius=radius) + _latlon_problems(lon, lat) + atlas_problems
    r = sp.Float(as_real(radius)) if not problems else sp.Integer(1)
    xyz = (r * sp.cos(V) * sp.cos(U), r * sp.cos(V) * sp.sin(U), r * sp.sin(V))
    return _make(name, xyz, center, rotation, (lon, lat), problems,
                 atlas=((r, r, r), "linear", 2) if atlas is True else None)


def ellipsoid(a: float, b: float, c: float, center: Vec3 = (0.0, 0.0, 0.0), rotation=None, *,
              lon: tuple[float, float] = (-_PI, _PI), lat: tuple[float, float] = (-1.3, 1.3),
              name: str = "ellipsoid", atlas: bool = False) -> ParametricSurface:
    """Ellipsoid ``(a cos v cos u, b cos v sin u, c sin v)`` with semi-axes ``a, b, c`` (m).

    Same latitude-longitude chart as :func:`sphere` (parametric, not geodetic, latitude);
    not orthogonal unless ``a == b``. ``atlas=True``: the whole ellipsoid in two charts, as
    :func:`sphere`'s.
    """
    atlas_problems, lon, lat = _charts(atlas, lon, lat, ((-_PI, _PI), (-1.3, 1.3)))
    problems = _finite_positive(a=a, b=b, c=c) + _latlon_problems(lon, lat) + atlas_problems
    ka, kb, kc = (sp.Float(as_real(s)) for s in (a, b, c)) if not problems else (1, 1, 1)
    xyz = (ka * sp.cos(V) * sp.cos(U), kb * sp.cos(V) * sp.sin(U), kc * sp.sin(V))
    return _make(name, xyz, center, rotation, (lon, lat), problems,
                 atlas=((ka, kb, kc), "linear", 2) if atlas is True else None)


def superquadric(a: float, b: float, c: float, n: int = 4, center: Vec3 = (0.0, 0.0, 0.0), rotation=None, *,
                 lon: tuple[float, float] = (-_PI, _PI), lat: tuple[float, float] = (-1.3, 1.3),
                 name: str = "superquadric", atlas: bool = False) -> ParametricSurface:
    """Superquadric ``|x/a|^n + |y/b|^n + |z/c|^n = 1`` with an even integer ``n >= 2`` (m).

    Written in radial form over the sphere's latitude-longitude chart:
    ``S = rho(u, v) d(u, v)`` with the unit direction ``d = (cos v cos u, cos v sin u, sin v)``
    and ``rho = ((d_x/a)^n + (d_y/b)^n + (d_z/c)^n)^(-1/n)``. For even ``n`` the bracket is a
    sum of even powers of a unit vector's components, never zero, so ``rho`` is smooth
    (analytic) and positive; the chart is regular wherever the sphere's is
    (``(S_u x S_v) . d = rho^2 cos v > 0``), i.e. away from the poles. Barr's usual
    ``sign(cos)|cos|^(2/n)`` form is neither smooth nor regular at the flat faces' centres.
    ``atlas=True``: the whole surface in two charts, as :func:`sphere`'s.
    """
    atlas_problems, lon, lat = _charts(atlas, lon, lat, ((-_PI, _PI), (-1.3, 1.3)))
    problems = _finite_positive(a=a, b=b, c=c) + _latlon_problems(lon, lat) + atlas_problems
    if not (isinstance(n, numbers.Integral) and not isinstance(n, bool) and n >= 2 and n % 2 == 0):
        problems.append(f"n = {n!r} must be an even integer >= 2 for a smooth surface")
    if problems:
        raise InvalidSurfaceError(name, problems)
    n = int(n)
    d = (sp.cos(V) * sp.cos(U), sp.cos(V) * sp.sin(U), sp.sin(V))
    axes = tuple(sp.Float(as_real(s)) for s in (a, b, c))
    rho = sum(di**n / s**n for di, s in zip(d, axes)) ** sp.Rational(-1, n)
    return _make(name, tuple(rho * di for di in d), center, rotation, (lon, lat), [],
                 atlas=(axes, "radial", n) if atlas is True else None)


def plane(size_x: float, size_y: float, center: Vec3 = (0.0, 0.0, 0.0), rotation=None, *,
          name: str = "plane") -> ParametricSurface:
    """Rectangle ``(u, v, 0)``, ``|u| <= size_x/2``, ``|v| <= size_y/2`` (m); normal ``+z``."""
    problems = _finite_positive(size_x=size_x, size_y=size_y)
    if not problems:
        size_x, size_y = _num(size_x), _num(size_y)
    dom = ((-size_x / 2, size_x / 2), (-size_y / 2, size_y / 2)) if not problems else ((-1, 1), (-1, 1))
    return _make(name, (U, V, sp.Integer(0)), center, rotation, dom, problems)


def torus(R: float, r: float, center: Vec3 = (0.0, 0.0, 0.0), rotation=None, *,
          u: tuple[float, float] = (-_PI, _PI), v: tuple[float, float] = (-_PI, _PI),
          name: str = "torus", atlas: bool = False) -> ParametricSurface:
    """Torus patch ``((R + r cos v) cos u, (R + r cos v) sin u, r sin v)``, ``R > r > 0`` (m).

    ``u`` turns about the shape's z axis, ``v`` around the tube; outward normal
    ``(cos v cos u, cos v sin u, sin v)``; Gaussian curvature ``cos v / (r (R + r cos v))``.
    ``atlas=True``: the whole torus, its one chart over three turns of each angle (``u`` and
    ``v`` in ``(-3 pi, 3 pi)``), both repeating (``geometry.atlas``): a contact that reaches
    the edge goes on a turn back, the same point, at the step where it happens.
    """
    problems = _finite_positive(R=R, r=r) + _interval("u", u) + _interval("v", v)
    periods = None
    if atlas is True:
        if (u, v) != ((-_PI, _PI), (-_PI, _PI)) and not problems:
            problems.append("u and v are the atlas's own with atlas=True (three turns each, (-3 pi, 3 pi), "
                            "both repeating): leave them out")
        u, v, periods = ATLAS_LON, ATLAS_LON, (2 * _PI, 2 * _PI)
    elif atlas is not False:
        problems.append(f"atlas = {atlas!r} must be True or False")
    if not problems and not as_real(R) > as_real(r):
        problems.append(f"R = {R!r} must exceed r = {r!r}: a spindle torus is not regular")
    kR, kr = (sp.Float(as_real(R)), sp.Float(as_real(r))) if not problems else (2, 1)
    w = kR + kr * sp.cos(V)
    return _make(name, (w * sp.cos(U), w * sp.sin(U), kr * sp.sin(V)), center, rotation, (u, v), problems,
                 periods=periods)


_AXES = {"x": (1, 2, 0), "y": (2, 0, 1), "z": (0, 1, 2)}  # (e1, e2, axis), right-handed


def surface_of_revolution(curve: PlanarCurve, axis: str = "z", center: Vec3 = (0.0, 0.0, 0.0), rotation=None,
                          *, angle: tuple[float, float] = (-_PI, _PI), name: str | None = None,
                          atlas: bool = False) -> ParametricSurface:
    """Revolve a contour ``(x(t), y(t))`` about ``axis``: ``x`` is the radius, ``y`` the height.

    ``S(u, v) = x(v) (cos u e1 + sin u e2) + y(v) e_axis`` with ``(e1, e2, e_axis)`` right-handed
    (axis 'z': ``(e_x, e_y, e_z)``; 'y': ``(e_z, e_x, e_y)``; 'x': ``(e_y, e_z, e_x)``):
    ``u`` is the angle of revolution (rad, domain ``angle``), ``v`` the contour's parameter
    (its domain). The normal points to the right of the contour's direction of travel, i.e.
    outward for a counterclockwise contour (the curve library's default, ``clockwise=False``).
    ``library.circle(r, by='angle')`` about 'z' gives exactly :func:`sphere`'s chart, and
    ``library.circle(r, (R, 0), by='angle', span=pi)`` :func:`torus`'s.
    The radius ``x(t)`` must stay positive: where the contour meets the axis the chart has a pole.

    ``atlas=True``: the whole surface (``geometry.atlas``), the angle over three turns
    (``(-3 pi, 3 pi)``) and repeating, and a closed contour's parameter repeating too (its
    period, ``curve.period``; its domain must then hold two traversals or more, e.g.
    ``library.circle(r, (R, 0), by='angle', span=2 * pi)``): a contact that reaches the edge
    goes on a turn (or a traversal) back, the same point, at the step where it happens.
    """
    name = name or f"revolved {getattr(curve, 'name', 'curve')}"
    if not isinstance(curve, PlanarCurve):
        raise InvalidSurfaceError(name, [f"curve = {curve!r} must be a PlanarCurve"])
    problems = _interval("angle", angle)
    periods = None
    if atlas is True:
        if angle != (-_PI, _PI) and not problems:
            problems.append("angle is the atlas's own with atlas=True (three turns, (-3 pi, 3 pi), "
                            "repeating): leave it out")
        angle, period = ATLAS_LON, curve.period
        t0, t1 = curve.domain
        if period is not None and not (t1 - t0) >= 2 * period * (1 - 1e-12):
            problems.append(f"the closed contour's domain {tuple(curve.domain)} holds less than two traversals "
                            f"(period {period:.6g}): with atlas=True give it two or more (e.g. "
                            "library.circle(..., span=2 * pi) for a circle by angle), so that a contact "
                            "carried a traversal back lands inside it")
        periods = (2 * _PI, period)
    elif atlas is not False:
        problems.append(f"atlas = {atlas!r} must be True or False")
    if axis not in _AXES:
        problems.append(f"axis = {axis!r}: use 'x', 'y' or 'z'")
        axis = "z"
    ts = np.linspace(*curve.domain, 401)
    with np.errstate(all="ignore"):
        radius = curve.evaluate(ts)["x"]
    if not (radius > 0).all():
        i = int(np.argmax(~(radius > 0)))
        problems.append(f"the contour's radius x(t) = {radius[i]:.3g} at t = {ts[i]:.6g} is not positive: "
                        "keep the contour on the x > 0 side of the axis (shift it or shrink its domain)")
    x, y = curve.x.xreplace({T: V}), curve.y.xreplace({T: V})
    i1, i2, ia = _AXES[axis]
    xyz = [sp.Integer(0)] * 3
    xyz[i1], xyz[i2], xyz[ia] = x * sp.cos(U), x * sp.sin(U), y
    return _make(name, tuple(xyz), center, rotation, (angle, curve.domain), problems, periods=periods)
