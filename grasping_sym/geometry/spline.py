"""A contour through sampled points: a quintic (C^4) interpolating spline.

``spline(points)`` returns a :class:`SplineCurve`, a :class:`PlanarCurve` whose
coordinates are piecewise quintic polynomials in the parameter ``t`` that pass through
every given point.

Why quintic. The 2D dynamics use the contour's curvature ``kappa`` and its derivative along
the contour (``dkappa`` of ``derive.contour_functions``), i.e. third derivatives of the
coordinates. A cubic spline has a piecewise-constant third derivative (``dkappa`` jumps at
every point) and a curvature that is only C^0; a quintic spline is C^4, so ``kappa`` is C^2
and ``dkappa`` C^1: smooth enough for the integrators' error control.

Parameter and domain. ``parametrization='arclength'`` (default) fits first with the
chord-length parameter ``t_i = sum |P_k+1 - P_k|`` and then refits with ``t_i`` replaced by
the arclength of the fitted spline between the points (up to 4 times), so that ``t`` is the
arclength from the first point in metres to the fit's own accuracy (``| |c'(t)| - 1 |`` was
4e-6 with 12 points on a circle, 1e-11 with 96); ``'chord'`` keeps the chord-length
parameter. An open spline has the domain ``[0, L]`` (``L``: its parameter length) and
not-a-knot end conditions (``n - 5`` pieces for ``n`` points); a closed one (``closed=True``)
is periodic (C^4 across the first point too, ``n`` pieces), and its parameter wraps around:
the domain is ``[-L, 2L]``, so a contact starting anywhere on ``[0, L]`` may travel a full
turn either way.

Direction of travel: the points are traversed in their order, so an object contour
(clockwise about its body, see ``geometry.library``) lists its points clockwise.

How it becomes C. A piecewise polynomial with ``m`` pieces is written as the polynomial of
one piece in the local variable ``U = t - K(t)`` whose 13 coefficients (``K`` and the six
coefficients of each coordinate) are SymPy functions of ``t`` with zero derivative (they are
piecewise constant). ``codegen.translate`` turns them into outputs of ONE CasADi call node per
argument: a B-spline ``Function`` of the coefficient table over the breaks (a binary search
in the generated C, the table stored as data), called from the SX graph and never inlined;
the quintics stay inline SX. The cost is then independent of ``m`` (about 1400 rhs SX
instructions and 0.3-0.6 us per rhs call at 10 to 1000 points; a 1000-point scene compiles
in ~3 s instead of ~36 s with the former 0/1 sign() indicators over all pieces, see
``benchmarks/results/build_scaling.md``). The NumPy reference (lambdify) evaluates the same
functions by a table lookup (``_imp_``). A closed spline's wrap of ``t`` into ``[0, L]``
is two sign() steps, exact.

The SymPy side never differentiates the curve: the derivatives, speed, tangent and
curvature are written out from the polynomial pieces (SymPy would differentiate the
closed spline's sign() wrap into DiracDelta terms), and the two derivatives
``leaf_expressions`` asks SymPy for (of the speed and of the curvature) are returned by
nodes that know them (``_KnownDerivative``). Those nodes also answer SymPy's assumption
queries as "unknown" at once and walk their expression DAG instead of its tree (needed when
the coefficients were sums over all pieces; kept, as it costs nothing).
"""
from __future__ import annotations

import hashlib
import math
from collections.abc import Sequence
from dataclasses import dataclass
from functools import cached_property
from pathlib import Path

import casadi as ca
import numpy as np
import sympy as sp

from grasping_sym.errors import InvalidCurveError
from grasping_sym.geometry.curves import PlanarCurve, T, first_crossing

#: Fewest points a quintic spline needs (degree + 1).
MIN_POINTS = 6
#: A point closer than this fraction of the polyline's extent to the next one repeats it.
REPEAT_TOL = 1e-9
#: The polyline turning by more than this at a point (degrees) is a kink or reversal.
KINK_DEG = 120.0
#: Speed below this fraction of the median speed anywhere on the spline: not regular.
SPEED_TOL = 1e-3
#: Samples per interval between two points for the regularity and self-crossing checks.
SAMPLES_PER_INTERVAL = 8
#: Refits with the arclength of the previous fit as parameter (``parametrization='arclength'``).
ARCLENGTH_REFITS = 4

_SOURCE_DIGEST = hashlib.sha256(Path(__file__).read_bytes()).hexdigest()[:16]
_GAUSS_X, _GAUSS_W = np.polynomial.legendre.leggauss(8)


@dataclass(frozen=True)
class SplineData:
    """The fitted spline: piece ``i`` is ``sum_j cx[j, i] (t - breaks[i])^j`` (and ``cy``)."""

    points: np.ndarray        # (n, 2) the points it interpolates (closed: without a repeat)
    params: np.ndarray        # parameter at each point, (n,); closed: (n + 1,), ending with L
    breaks: np.ndarray        # (m + 1,) piece boundaries, breaks[0] = 0, breaks[-1] = L
    cx: np.ndarray            # (6, m) power-basis coefficients, ascending degree
    cy: np.ndarray            # (6, m)
    closed: bool
    parametrization: str

    @property
    def length(self) -> float:
        """Parameter length ``L`` of one traversal (m for ``'arclength'``)."""
        return float(self.breaks[-1])

    def wrap(self, t: np.ndarray) -> np.ndarray:
        """Parameter reduced to ``[0, L]`` (closed splines), else unchanged."""
        if not self.closed:
            return t
        L = self.length
        return np.where(t <= 0, t + L, np.where(t > L, t - L, t))

    def piece(self, t: np.ndarray) -> np.ndarray:
        """Index of the piece used at ``t``: the one with ``breaks[i] <= t < breaks[i+1]``
        (the first and last pieces extend beyond the ends), as in the generated code."""
        return np.searchsorted(self.breaks[1:-1], t, side="right")

    def derivatives(self, t, order: int = 3) -> tuple[np.ndarray, np.ndarray]:
        """``(dx, dy)``, each of shape ``(order + 1,) + t.shape``: derivatives 0..order."""
        t = self.wrap(np.asarray(t, dtype=float))
        i = self.piece(t)
        u = t - self.breaks[i]
        out = []
        for c in (self.cx, self.cy):
            ds = []
            for k in range(order + 1):
                acc = np.zeros_like(u)
                for j in range(5, k - 1, -1):
                    acc = acc * u + c[j, i] * (math.factorial(j) / math.factorial(j - k))
                ds.append(acc)
            out.append(np.array(ds))
        return out[0], out[1]


def _fit(params: np.ndarray, pts: np.ndarray, closed: bool) -> SplineData:
    from scipy.interpolate import PPoly, make_interp_spline

    if closed:
        b = make_interp_spline(params, np.vstack([pts, pts[:1]]), k=5, bc_type="periodic")
    else:
        b = make_interp_spline(params, pts, k=5)
    L = float(params[-1])
    pps = [PPoly.from_spline((b.t, b.c[:, k], 5)) for k in range(2)]
    x = pps[0].x
    keep = (np.diff(x) > 0) & (x[:-1] >= -1e-12 * L) & (x[1:] <= L * (1 + 1e-12))
    idx = np.nonzero(keep)[0]
    breaks = np.append(x[idx], x[idx[-1] + 1])
    breaks[0], breaks[-1] = 0.0, L
    # PPoly stores the highest degree first
    cx, cy = (pp.c[::-1, idx].copy() for pp in pps)
    return SplineData(points=pts, params=params, breaks=breaks, cx=cx, cy=cy, closed=closed,
                      parametrization="")


def _interval_lengths(data: SplineData) -> np.ndarray:
    """Arclength of the spline between consecutive points (8-point Gauss per interval)."""
    a, b = data.params[:-1], data.params[1:]
    mid, half = (a + b) / 2, (b - a) / 2
    t = mid[:, None] + half[:, None] * _GAUSS_X[None, :]
    dx, dy = data.derivatives(t, order=1)
    return half * (np.hypot(dx[1], dy[1]) @ _GAUSS_W)


# ---------------------------------------------------------------------- input checks
def _input_problems(points, closed: bool) -> tuple[np.ndarray | None, list[str]]:
    """The points as an ``(n, 2)`` float array (closed: without a repeated first point) and
    every problem found in them; indices in the messages are those of the given points."""
    try:
        pts = np.array(points, dtype=float)
    except (TypeError, ValueError) as exc:
        return None, [f"points cannot be read as numbers ({exc}): give a sequence of (x, y) pairs"]
    if pts.ndim != 2 or pts.shape[1] != 2:
        return None, [f"points has shape {pts.shape}: give an (n, 2) array of (x, y) pairs (metres)"]
    problems: list[str] = []
    finite = np.isfinite(pts).all(axis=1)
    if not finite.all():
        bad = np.nonzero(~finite)[0]
        problems.append(f"{bad.size} point(s) have non-finite coordinates (indices {_indices(bad)}): "
                        "remove them or give finite values")
    index = np.nonzero(finite)[0]            # given index of each remaining point
    pts = pts[finite]
    if closed and len(pts) > 1 and np.array_equal(pts[0], pts[-1]):
        pts, index = pts[:-1], index[:-1]    # a closed polyline may repeat its first point
    n = len(pts)
    if n < MIN_POINTS:
        problems.append(f"{n} usable point(s){' (closed: without the repeated first point)' if closed else ''}; "
                        f"a quintic spline needs at least {MIN_POINTS}: sample the contour more densely")
    if n < 2:
        return None, problems
    extent = float(np.max(np.ptp(pts, axis=0)))
    if extent == 0:
        return None, problems + ["all points coincide: give points along the contour"]
    ring = np.vstack([pts, pts[:1]]) if closed else pts
    chord = np.hypot(*np.diff(ring, axis=0).T)
    rep = np.nonzero(chord <= REPEAT_TOL * extent)[0]
    if rep.size:
        pairs = ", ".join(f"{index[i]}-{index[(i + 1) % n]}" for i in rep[:8]) + (" ..." if rep.size > 8 else "")
        problems.append(f"{rep.size} repeated point(s): consecutive points {pairs} coincide (within "
                        f"{REPEAT_TOL:g} of the contour's size); remove the duplicates")
    if n >= 3:
        # turning of the polyline at each point: a kink or a reversal of direction
        d = np.diff(ring, axis=0)
        if closed:
            d_in, d_out, at = d, np.roll(d, -1, axis=0), (np.arange(n) + 1) % n
        else:
            d_in, d_out, at = d[:-1], d[1:], np.arange(1, n - 1)
        turn = np.degrees(np.abs(np.arctan2(d_in[:, 0] * d_out[:, 1] - d_in[:, 1] * d_out[:, 0],
                                            (d_in * d_out).sum(axis=1))))
        kinks = np.nonzero(turn > KINK_DEG)[0]
        if kinks.size:
            where = (", ".join(f"{index[at[i]]} ({turn[i]:.0f} deg)" for i in kinks[:8])
                     + (" ..." if kinks.size > 8 else ""))
            problems.append(f"the points turn back sharply (a kink or cusp, by more than {KINK_DEG:.0f} deg) at "
                            f"point(s) {where}: a spline through them is not a regular smooth contour; "
                            "remove the outlier, reorder the points or round the corner with more points")
    return pts, problems


def _indices(idx: np.ndarray) -> str:
    return ", ".join(str(int(i)) for i in idx[:8]) + (" ..." if idx.size > 8 else "")


def _fitted_problems(data: SplineData) -> list[str]:
    """Regularity (speed) and self-crossing of the fitted spline, sampled densely."""
    q = SAMPLES_PER_INTERVAL
    a, b = data.params[:-1], data.params[1:]
    s = np.linspace(0.0, 1.0, q + 1)[:-1]
    t = (a[:, None] + (b - a)[:, None] * s[None, :]).ravel()
    t = np.append(t, data.params[-1])
    dx, dy = data.derivatives(t, order=1)
    speed = np.hypot(dx[1], dy[1])
    problems = []
    med = float(np.median(speed))
    low = np.nonzero(speed < SPEED_TOL * med)[0]
    if low.size:
        k = int(low[np.argmin(speed[low])])
        i = min(k // q, len(a) - 1)
        problems.append(f"the spline is not regular: its speed |c'(t)| falls to {speed[k]:.3g} (median "
                        f"{med:.3g}) at t = {t[k]:.6g}, between points {i} and {i + 1}: a cusp; remove or "
                        "move the points there")
    xy = np.column_stack([dx[0], dy[0]])
    crossing = first_crossing(xy, closed=data.closed)
    if crossing is not None:
        ta, tb = (t[k] if f == 0 else t[k + 1] if f == 1 else t[k] + f * (t[k + 1] - t[k])
                  for k, f in crossing)
        i, j = (min(max(int(np.searchsorted(data.params, tc, side="right")) - 1, 0), len(a) - 1)
                for tc in (ta, tb))
        problems.append(f"the spline crosses itself: near t = {ta:.6g} (between points {i} and "
                        f"{i + 1}) and t = {tb:.6g} (between points {j} and {j + 1}); reorder "
                        "the points along the contour or remove the loop")
    return problems


# ---------------------------------------------------------------------- SymPy form
try:  # every assumption SymPy defines (a private name; the fallback is its 1.14 list)
    from sympy.core.assumptions import _assume_defined as _FACTS
except ImportError:  # pragma: no cover
    _FACTS = frozenset(
        "algebraic antihermitian commutative complex composite even extended_negative "
        "extended_nonnegative extended_nonpositive extended_nonzero extended_positive "
        "extended_real finite hermitian imaginary infinite integer irrational negative "
        "noninteger nonnegative nonpositive nonzero odd polar positive prime rational real "
        "transcendental zero".split())


class _KnownDerivative:
    """A SymPy node whose derivative in ``T`` is given (``_gs_derivative``), not computed.

    SymPy's own differentiation of a spline's expressions (sums over all pieces) costs
    minutes for a few hundred pieces; the spline knows its derivatives in closed form. A node
    rebuilt by SymPy (e.g. by ``subs``) loses the attribute and is differentiated normally.
    """

    def _known(self, s, n=1):
        d = self.__dict__.get("_gs_derivative")
        return d if (d is not None and n == 1 and s == T) else None

    def _eval_derivative(self, s):
        d = self._known(s)
        return d if d is not None else super()._eval_derivative(s)

    def _eval_derivative_n_times(self, s, n):
        d = self._known(s, n)
        return d if d is not None else super()._eval_derivative_n_times(s, n)


def _unique_nodes(root: sp.Basic, descend=lambda node: True):
    """Every distinct node of ``root`` once (its expression DAG, not its tree); the arguments
    of a node are visited when ``descend(node)``."""
    seen, stack = {id(root)}, [root]
    while stack:
        node = stack.pop()
        yield node
        if node is root or descend(node):
            for a in node.args:
                if id(a) not in seen:
                    seen.add(id(a))
                    stack.append(a)


def _own_free_symbols(node) -> bool:
    """Whether ``node`` defines its free symbols itself (atoms, bound variables, ours)."""
    return node.is_Atom or type(node).free_symbols is not sp.Basic.free_symbols


class _DagWalks:
    """``free_symbols`` and ``replace`` computed over the expression DAG.

    A spline's expressions repeat subexpressions (the coefficients and ``U`` occur in every
    derivative); SymPy walks them as trees, once per occurrence, in every
    ``Derivative`` it builds. These two give SymPy's results, visiting each node once.
    """

    @property
    def free_symbols(self):
        fs = self.__dict__.get("_gs_free_symbols")
        if fs is None:
            fs = set()
            for node in _unique_nodes(self, descend=lambda n: not _own_free_symbols(n)):
                if node is not self and _own_free_symbols(node):
                    fs |= node.free_symbols
            self.__dict__["_gs_free_symbols"] = fs = frozenset(fs)
        return set(fs)

    def replace(self, query, value, map=False, simultaneous=True, exact=None):
        if not map and callable(query) and not isinstance(query, type):
            if not any(query(node) for node in _unique_nodes(self)):
                return self
        return super().replace(query, value, map=map, simultaneous=simultaneous, exact=exact)


def _opaque(name: str, base: type, *mixins: type) -> type:
    """``base`` whose assumption queries (``is_zero``, ``is_positive``, ...) answer "unknown"
    at once instead of analysing every term (SymPy asks ``is_zero`` of each derivative it
    returns; on a sum over all pieces that analysis takes minutes). Commutative, as always."""
    ns = {f"_eval_is_{f}": (lambda self: None) for f in _FACTS}
    ns["_eval_is_commutative"] = lambda self: True
    ns["__module__"] = __name__
    return type(name, (*mixins, _DagWalks, base), ns)


_SplinePow = _opaque("_SplinePow", sp.Pow, _KnownDerivative)
_SplineMul = _opaque("_SplineMul", sp.Mul, _KnownDerivative)
_SplineAdd = _opaque("_SplineAdd", sp.Add)


def _known(cls, args, derivative):
    node = cls(*args, evaluate=False)
    node.__dict__["_gs_derivative"] = derivative
    return node


def _add(*args):
    return sp.Add(*args, evaluate=False)


def _mul(*args):
    return sp.Mul(*args, evaluate=False)


def _pow(b, e):
    return sp.Pow(b, e, evaluate=False)


#: Outer knots of the lookup: the first and last pieces extend beyond the ends.
_FAR = 1e300


class _Lookup:
    """The piece's 13 coefficients at ``t`` (its knot ``K`` and the six coefficients of each
    coordinate) as ONE CasADi call: a ``Function.bspline`` over the breaks, called from SX as
    a call node (never inlined; binary search in the generated C). The call is made once per
    SX argument, so the 13 :class:`_Coefficient` functions share it.

    Piecewise constant as a degree-1 B-spline with every inner break doubled and each row
    repeated (``c (1 - s) + c s``: within 1 ulp of ``c``): CasADi 3.8.2's degree-0 B-spline
    corrupts memory when evaluated at or next to a knot.
    """

    def __init__(self, data: SplineData, tag: str):
        br = data.breaks
        m = len(br) - 1
        self.table = np.column_stack([br[:-1], data.cx.T, data.cy.T])          # (m, 13)
        self.inner = np.asarray(br[1:-1], dtype=float)
        knots = [-_FAR, -_FAR, *np.repeat(self.inner, 2).tolist(), _FAR, _FAR]
        coefs = np.repeat(self.table, 2, axis=0).ravel().tolist()
        self.function = ca.Function.bspline(f"spline_{tag}", [knots], coefs, [1],
                                            self.table.shape[1], {})
        self._calls: list[tuple[ca.SX, ca.SX]] = []
        assert self.table.shape == (m, 13)

    def call(self, t: ca.SX) -> ca.SX:
        for arg, out in self._calls:
            if ca.is_equal(arg, t, 0):
                return out
        out = self.function.call([t], False, True)[0]
        self._calls = [*self._calls[-15:], (t, out)]
        return out

    def numeric(self, t, j: int):
        """Coefficient ``j`` at ``t`` (NumPy), the piece chosen as the generated code does."""
        i = np.searchsorted(self.inner, np.asarray(t, dtype=float), side="right")
        return self.table[i, j]


class _Coefficient(sp.Function):
    """Coefficient ``j`` of the piece at ``t``: piecewise constant, so its derivative is 0
    (the derivatives of the curve come from the polynomial in ``t - K(t)``)."""

    nargs = 1
    _lookup: _Lookup
    _j: int

    def fdiff(self, argindex=1):
        return sp.S.Zero

    def _eval_is_real(self):
        return True


def _coefficients(data: SplineData) -> list[type]:
    """The 13 SymPy functions ``K, cx0..cx5, cy0..cy5`` of ``t`` sharing one lookup; each
    translates to its output of the lookup call (``_casadi_``) and lambdifies to a NumPy
    table lookup (``_imp_``)."""
    h = hashlib.sha256()
    for arr in (data.breaks, data.cx, data.cy):
        h.update(np.ascontiguousarray(arr, dtype="<f8").tobytes())
    tag = h.hexdigest()[:12]
    lookup = _Lookup(data, tag)
    names = ["K", *(f"cx{j}" for j in range(6)), *(f"cy{j}" for j in range(6))]
    out = []
    for j, nm in enumerate(names):
        out.append(type(f"spline_{tag}_{nm}", (_Coefficient,), {
            "_lookup": lookup, "_j": j, "__module__": __name__,
            "_casadi_": staticmethod(lambda t, j=j: lookup.call(t)[j]),
            "_imp_": staticmethod(lambda t, j=j: lookup.numeric(t, j)),
        }))
    return out


def _expressions(data: SplineData) -> dict[str, sp.Expr]:
    """SymPy expressions of the point, derivatives, speed and curvature (see module doc)."""
    L = data.length
    tw: sp.Expr = T
    if data.closed:
        # t + L for t < 0, t - L for t > L: steps G = sign(d)(sign(d) + 1) in {0, 2}
        def g(d):
            s = sp.sign(_add(T, sp.Float(-d)))
            return _mul(s, _add(s, sp.Integer(1)))
        tw = _add(T, _mul(sp.Float(L / 2), _add(sp.Integer(2), _mul(sp.Integer(-1), g(0.0)))),
                  _mul(sp.Float(-L / 2), g(L)))
    fns = _coefficients(data)
    K = fns[0](tw)
    U = _add(tw, _mul(sp.Integer(-1), K))

    def horner(cs):
        out = cs[-1]
        for c in reversed(cs[:-1]):
            out = _add(c, _mul(U, out))
        return out

    def scaled(c, f):
        return c if f == 1 else _mul(sp.Integer(f), c)

    res = {}
    for name, off in (("x", 1), ("y", 7)):
        C = [fns[off + j](tw) for j in range(6)]
        res[name] = horner(C)
        res[f"d1{name}"] = horner([scaled(C[j], j) for j in range(1, 6)])
        res[f"d2{name}"] = horner([scaled(C[j], j * (j - 1)) for j in range(2, 6)])
        res[f"d3{name}"] = horner([scaled(C[j], j * (j - 1) * (j - 2)) for j in range(3, 6)])
    x1, y1, x2, y2 = res["d1x"], res["d1y"], res["d2x"], res["d2y"]
    x3, y3 = res["d3x"], res["d3y"]
    minus = sp.Integer(-1)
    D = _add(_mul(x1, x2), _mul(y1, y2))                       # (|c'|^2)' / 2
    N = _add(_mul(x1, y2), _mul(minus, x2, y1))                # x'y'' - x''y'
    dN = _add(_mul(x1, y3), _mul(minus, x3, y1))               # x'y''' - x'''y'
    Q = _add(_pow(x1, 2), _pow(y1, 2))
    speed = _SplinePow(Q, sp.S.Half, evaluate=False)
    inv = _pow(speed, -1)
    # the derivatives SymPy is asked for (leaf_expressions: d|c'|/dt, dkappa/dt), returned as
    # opaque nodes: SymPy checks is_zero on every derivative it computes
    speed.__dict__["_gs_derivative"] = _SplineMul(D, inv, evaluate=False)
    dkappa = _SplineAdd(_mul(dN, _pow(speed, -3)), _mul(sp.Integer(-3), N, D, _pow(speed, -5)),
                        evaluate=False)
    kappa = _known(_SplineMul, (N, _pow(speed, -3)), dkappa)
    res.update(speed=speed, tangent=(_mul(x1, inv), _mul(y1, inv)), curvature=kappa)
    return res


# ---------------------------------------------------------------------- the curve
@dataclass(frozen=True, eq=False)
class SplineCurve(PlanarCurve):
    """A :class:`PlanarCurve` made by :func:`spline`; ``spline_data`` holds the fit.

    Its derivatives, speed and curvature are written out in closed form (not derived by
    SymPy), and it evaluates numerically from the coefficient arrays.
    """

    spline_data: SplineData | None = None

    def _static_problems(self) -> list[str]:
        # The expressions contain sign() only in the exact wrap of a closed spline's
        # parameter; the pieces agree to the 4th derivative at the breaks (a C^4 curve), which
        # is what the base class's "non-smooth function" check guards. The domain and the
        # pieces are checked when the spline is fitted.
        t0, t1 = self.domain
        if not (math.isfinite(t0) and math.isfinite(t1) and t0 < t1):
            return [f"domain ({t0}, {t1}) must be finite with t_min < t_max"]
        return []

    @cached_property
    def _parts(self) -> dict:
        return _expressions(self.spline_data)

    @cached_property
    def d1(self):
        return self._parts["d1x"], self._parts["d1y"]

    @cached_property
    def d2(self):
        return self._parts["d2x"], self._parts["d2y"]

    @cached_property
    def d3(self):
        """Third derivative ``c'''(t)`` (the spline's own closed form)."""
        return self._parts["d3x"], self._parts["d3y"]

    @cached_property
    def speed(self):
        return self._parts["speed"]

    @cached_property
    def tangent(self):
        return self._parts["tangent"]

    @cached_property
    def curvature(self):
        return self._parts["curvature"]

    @cached_property
    def unit_speed(self) -> bool:
        ts = np.linspace(*self.domain, 201)
        return bool(np.all(np.abs(self.evaluate(ts)["speed"] - 1) < 1e-12))

    @cached_property
    def period(self) -> float | None:
        """``L`` for a closed spline (its domain ``[-L, 2L]`` runs round three times), else None."""
        return self.spline_data.length if self.spline_data.closed else None

    def _crossing_problems(self) -> list[str]:
        return []  # checked on the fit's own samples when it was made (``_fitted_problems``)

    @cached_property
    def _numeric(self):
        data = self.spline_data

        def f(t):
            dx, dy = data.derivatives(t, order=2)
            speed = np.hypot(dx[1], dy[1])
            kappa = (dx[1] * dy[2] - dx[2] * dy[1]) / speed**3
            return [dx[0], dy[0], dx[1], dy[1], speed, kappa]
        return f

    def key(self) -> str:
        """Hash of the fitted coefficients, the domain and this module's source text."""
        d = self.spline_data
        h = hashlib.sha256()
        for arr in (d.breaks, d.cx, d.cy):
            h.update(np.ascontiguousarray(arr, dtype="<f8").tobytes())
        h.update(repr((d.closed, self.domain)).encode())
        return f"spline|{_SOURCE_DIGEST}|{h.hexdigest()}|{self.domain[0]!r}|{self.domain[1]!r}"


def spline(
    points: Sequence[Sequence[float]] | np.ndarray,
    *,
    closed: bool = False,
    parametrization: str = "arclength",
    name: str = "spline",
) -> SplineCurve:
    """A C^4 contour through ``points``: the quintic interpolating spline.

    Parameters
    ----------
    points
        ``(n, 2)`` points (metres, local body frame) in the order of travel, ``n >= 6``. A
        closed contour may repeat its first point at the end.
    closed
        Periodic spline (C^4 across the first point too); domain ``[-L, 2L]``, the
        parameter wrapping around every ``L``. Open: domain ``[0, L]``, not-a-knot ends.
    parametrization
        ``'arclength'`` (default): ``t`` is the arclength from the first point (m), to the
        spline's own accuracy; ``'chord'``: the cumulative chord length through the points.
    name
        Label used in messages and plots.

    Raises
    ------
    InvalidCurveError
        Listing every problem: too few points, non-finite values, repeated points, a sharp
        kink or reversal, a fitted spline that is not regular or crosses itself.
    """
    pts, problems = _input_problems(points, bool(closed))
    if parametrization not in ("arclength", "chord"):
        problems.append(f"parametrization = {parametrization!r}: use 'arclength' or 'chord'")
    if pts is None or problems:
        raise InvalidCurveError(name, problems)
    ring = np.vstack([pts, pts[:1]]) if closed else pts
    params = np.concatenate([[0.0], np.cumsum(np.hypot(*np.diff(ring, axis=0).T))])
    data = _fit(params, pts, bool(closed))
    if parametrization == "arclength":
        for _ in range(ARCLENGTH_REFITS):
            new = np.concatenate([[0.0], np.cumsum(_interval_lengths(data))])
            converged = np.max(np.abs(new - params)) <= 1e-14 * new[-1]
            params = new
            data = _fit(params, pts, bool(closed))
            if converged:
                break
    data = SplineData(points=pts, params=params, breaks=data.breaks, cx=data.cx, cy=data.cy,
                      closed=bool(closed), parametrization=parametrization)
    problems += _fitted_problems(data)
    if problems:
        raise InvalidCurveError(name, problems)
    L = data.length
    domain = (-L, 2 * L) if closed else (0.0, L)
    parts = _expressions(data)
    curve = SplineCurve(parts["x"], parts["y"], T, domain, name, spline_data=data)
    curve.__dict__["_parts"] = parts
    return curve
