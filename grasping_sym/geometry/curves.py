"""Planar parametric curves: the contours of fingertips and objects.

A contour is a pair of SymPy expressions ``(x(t), y(t))`` in one parameter ``t`` with a
closed domain ``[t_min, t_max]``, given in the body's local frame (metres). Any regular
parameterisation works; arclength is not required. Everything the dynamics needs (unit
tangent, speed, signed curvature and its derivative) is derived symbolically here.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from functools import cached_property

import numpy as np
import sympy as sp

from grasping_sym.errors import ExpressionError, InvalidCurveError
from grasping_sym.geometry.expressions import to_expression

#: The parameter symbol every curve is written in (curves are re-expressed in it).
T = sp.Symbol("t", real=True)


@dataclass(frozen=True, eq=False)
class PlanarCurve:
    """A regular planar curve ``c(t) = (x(t), y(t))`` for ``t`` in ``domain``.

    Parameters
    ----------
    x, y
        SymPy expressions in ``param`` (metres, local body frame).
    param
        The curve parameter symbol; it is replaced by the module symbol ``T``.
    domain
        ``(t_min, t_max)``, finite, ``t_min < t_max``.
    name
        A short label used in messages and plots.
    """

    x: sp.Expr
    y: sp.Expr
    param: sp.Symbol = T
    domain: tuple[float, float] = (-1.0, 1.0)
    name: str = "curve"
    _checked: bool = field(default=False, repr=False)

    def __post_init__(self) -> None:
        names = {str(self.param): self.param, "t": T}
        try:
            x = to_expression(self.x, names, f"contour '{self.name}': x")
            y = to_expression(self.y, names, f"contour '{self.name}': y")
        except ExpressionError as exc:
            raise InvalidCurveError(self.name, [str(exc)]) from None
        if self.param != T:
            x, y = x.subs(self.param, T), y.subs(self.param, T)
        object.__setattr__(self, "x", x)
        object.__setattr__(self, "y", y)
        object.__setattr__(self, "param", T)
        object.__setattr__(self, "domain", (float(self.domain[0]), float(self.domain[1])))
        problems = self._static_problems()
        if problems:
            raise InvalidCurveError(self.name, problems)

    # ----------------------------------------------------------------- symbolic
    @cached_property
    def d1(self) -> tuple[sp.Expr, sp.Expr]:
        """First derivative ``c'(t)``."""
        return sp.diff(self.x, T), sp.diff(self.y, T)

    @cached_property
    def d2(self) -> tuple[sp.Expr, sp.Expr]:
        """Second derivative ``c''(t)``."""
        return sp.diff(self.d1[0], T), sp.diff(self.d1[1], T)

    @cached_property
    def unit_speed(self) -> bool:
        """True when ``|c'(t)| == 1`` on the domain (an arclength parameterisation).

        Decided numerically at 201 points to 1e-12, which is far below any tolerance the
        dynamics uses; symbolic simplification misses such identities too often to rely on.
        """
        f = sp.lambdify(T, self.d1[0] ** 2 + self.d1[1] ** 2 - 1, "numpy")
        with np.errstate(all="ignore"):
            r = np.asarray(f(np.linspace(*self.domain, 201)), dtype=float)
        return bool(np.all(np.abs(r) < 1e-12))

    @cached_property
    def speed(self) -> sp.Expr:
        """``|c'(t)|`` (m per unit parameter); the symbol 1 for unit-speed curves."""
        if self.unit_speed:
            return sp.Integer(1)
        return sp.sqrt(self.d1[0] ** 2 + self.d1[1] ** 2)

    @cached_property
    def tangent(self) -> tuple[sp.Expr, sp.Expr]:
        """Unit tangent ``c'/|c'|`` in the local frame."""
        return self.d1[0] / self.speed, self.d1[1] / self.speed

    @cached_property
    def curvature(self) -> sp.Expr:
        """Signed curvature ``(x'y'' - x''y')/|c'|^3`` (1/m), positive when turning left."""
        (x1, y1), (x2, y2) = self.d1, self.d2
        return (x1 * y2 - x2 * y1) / self.speed**3

    def key(self) -> str:
        """A canonical text of the definition, for content hashing."""
        return f"{sp.srepr(self.x)}|{sp.srepr(self.y)}|{self.domain[0]!r}|{self.domain[1]!r}"

    # ----------------------------------------------------------------- numeric
    @cached_property
    def _numeric(self):
        exprs = [self.x, self.y, *self.d1, self.speed, self.curvature]
        return sp.lambdify(T, exprs, "numpy")

    def evaluate(self, t) -> dict[str, np.ndarray]:
        """Numeric point, derivative, speed and curvature at parameter values ``t``."""
        t = np.asarray(t, dtype=float)
        vals = self._numeric(t)
        vals = [np.broadcast_to(np.asarray(v, dtype=float), t.shape) for v in vals]
        x, y, dx, dy, speed, kappa = vals
        return {"x": x, "y": y, "dx": dx, "dy": dy, "speed": speed, "curvature": kappa}

    def in_domain(self, t: float) -> bool:
        """Whether ``t`` lies in the declared domain."""
        return self.domain[0] <= t <= self.domain[1]

    # ----------------------------------------------------------------- checks
    def _static_problems(self) -> list[str]:
        problems: list[str] = []
        t0, t1 = self.domain
        if not (math.isfinite(t0) and math.isfinite(t1)):
            problems.append(f"domain ({t0}, {t1}) is not finite: give finite bounds")
        elif not t0 < t1:
            problems.append(f"domain ({t0}, {t1}) is empty: give t_min < t_max")
        for label, e in (("x", self.x), ("y", self.y)):
            extra = e.free_symbols - {T}
            if extra:
                names = ", ".join(sorted(map(str, extra)))
                problems.append(
                    f"{label}(t) has free symbols {names} besides the parameter t: "
                    "substitute numbers for them"
                )
            if e.has(sp.Abs, sp.sign, sp.Heaviside, sp.Min, sp.Max, sp.floor, sp.ceiling):
                problems.append(
                    f"{label}(t) = {e} uses a non-smooth function; contours must be smooth "
                    "(C^3): rewrite it with smooth functions or split the contour"
                )
            if e.has(sp.Piecewise):
                problems.append(
                    f"{label}(t) is piecewise: a contour must be one smooth expression"
                )
        return problems

    def check(self, n_samples: int = 401) -> None:
        """Check regularity and finiteness on the domain; raise listing every problem.

        Samples ``n_samples`` parameter values evenly over the domain (ends included), then
        refines every sampled local minimum and maximum of the speed with a bounded Brent
        search, so that a cusp (speed 0) or a pole (speed unbounded) between two samples
        is found too.
        """
        if self._checked:
            return
        ts = np.linspace(*self.domain, n_samples)
        with np.errstate(all="ignore"):
            v = self.evaluate(ts)
        problems: list[str] = []
        for key in ("x", "y", "dx", "dy", "curvature"):
            bad = ~np.isfinite(v[key])
            if bad.any():
                problems.append(
                    f"{key} is not finite at t = {ts[bad][0]:.6g} (and {bad.sum() - 1} more "
                    "samples): shrink the domain or fix the formula"
                )
        problems += self._speed_problems(ts, v["speed"])
        if problems:
            raise InvalidCurveError(self.name, problems)
        object.__setattr__(self, "_checked", True)

    def _speed_problems(self, ts: np.ndarray, speed: np.ndarray) -> list[str]:
        """Zero or unbounded speed, looked for around each sampled local extremum."""
        def speed_at(t: np.ndarray) -> np.ndarray:
            with np.errstate(all="ignore"):
                val = np.broadcast_to(np.asarray(self.evaluate(t)["speed"], dtype=float), t.shape)
            return np.where(np.isfinite(val), val, np.inf)

        speed = np.where(np.isfinite(speed), speed, np.nan)
        if np.all(np.isnan(speed)):
            return []  # reported as not finite already
        typical = float(np.nanmedian(speed))
        if np.nanmax(speed) - np.nanmin(speed) <= 1e-9 * typical:
            return []  # constant speed (e.g. an arclength parameterisation): nothing to refine
        i_min, i_max = int(np.nanargmin(speed)), int(np.nanargmax(speed))
        lo_pts, hi_pts = [(float(speed[i_min]), float(ts[i_min]))], []
        for i in range(len(ts)):
            left = speed[i - 1] if i > 0 else math.inf
            right = speed[i + 1] if i < len(ts) - 1 else math.inf
            window = (ts[max(i - 1, 0)], ts[min(i + 1, len(ts) - 1)])
            if speed[i] < left and speed[i] <= right:
                lo_pts.append(_refine(speed_at, window))
            left = speed[i - 1] if i > 0 else -math.inf
            right = speed[i + 1] if i < len(ts) - 1 else -math.inf
            if speed[i] > left and speed[i] >= right:
                value, t = _refine(lambda t: -speed_at(t), window)
                hi_pts.append((-value, t))
        problems = []
        low, t_low = min(lo_pts)
        if low <= 1e-9 * typical:
            problems.append(
                f"not regular: speed |c'(t)| = {low:.3g} at t = {t_low:.6g} (typical speed "
                f"{typical:.3g}); the tangent and curvature are undefined there: "
                "reparameterise or exclude that point from the domain"
            )
        high, t_high = max(hi_pts) if hi_pts else (float(speed[i_max]), float(ts[i_max]))
        if high >= 1e8 * typical:
            problems.append(
                f"speed |c'(t)| is not finite (unbounded) near t = {t_high:.6g} (reaches "
                f"{high:.3g}, typical {typical:.3g}): a pole of the parameterisation; exclude it "
                "from the domain"
            )
        return problems


def _refine(f, window: tuple[float, float], points: int = 33, rounds: int = 12) -> tuple[float, float]:
    """``(min f, argmin)`` of a vectorised ``f`` on ``window``, by zooming: sample ``points``
    values, keep the two intervals around the least, repeat (each round narrows the window
    16-fold: 12 rounds reach 1e-14 of it). Finds the minimum of a smooth function near a
    sampled local minimum as a bounded Brent search does, with no SciPy import (0.25 s)."""
    lo, hi = float(window[0]), float(window[1])
    best = (math.inf, lo)
    for _ in range(rounds):
        ts = np.linspace(lo, hi, points)
        vals = f(ts)
        k = int(np.argmin(vals))
        if vals[k] <= best[0]:
            best = (float(vals[k]), float(ts[k]))
        lo, hi = ts[max(k - 1, 0)], ts[min(k + 1, points - 1)]
        if hi - lo <= 1e-15 * (1 + abs(lo)):
            break
    return best
