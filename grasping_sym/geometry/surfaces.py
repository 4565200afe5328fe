"""Parametric surfaces: the fingertip and object shapes of the 3D model.

A surface patch is a 3-vector of SymPy expressions ``S(u, v)`` in two parameters with a
closed rectangular domain ``[u_min, u_max] x [v_min, v_max]``, given in the body's local
frame (metres). Any regular chart works; it need not be orthogonal. Everything the contact
kinematics needs is derived symbolically here, by exact construction (no ``simplify``).

Conventions
-----------
* Unit normal ``n = S_u x S_v / |S_u x S_v|``. The library's closed surfaces are written so
  that ``n`` points outward (away from the body's material).
* Second fundamental form ``II = [[L, M], [M, N]]`` with ``L = S_uu . n`` etc., shape operator
  ``W = I^-1 II`` (so ``[n_u, n_v] = -[S_u, S_v] W``), principal curvatures = eigenvalues of
  ``W``, mean curvature ``H = tr(W)/2``. With an outward normal a convex surface has
  *negative* ``L, N, H`` and principal curvatures: a sphere of radius ``r`` has
  ``H = -1/r``, ``K = 1/r^2``.
* Montana's contact quantities (D. J. Montana, "The kinematics of contact and grasp",
  Int. J. Robotics Research 7(3), 1988) are positive on convex surfaces with the outward
  normal: a sphere has ``K_p = I/r``. See :meth:`ParametricSurface.curvature_form`.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from functools import cached_property

import numpy as np
import sympy as sp

from grasping_sym.errors import ExpressionError, InvalidSurfaceError
from grasping_sym.geometry.expressions import to_expression
from grasping_sym.geometry.values import as_component, as_real

#: The parameter symbols every surface is written in (surfaces are re-expressed in them).
U = sp.Symbol("u", real=True)
V = sp.Symbol("v", real=True)
#: The chart of an atlas's blended surface (``geometry.atlas``): 0 or 1, a run-time parameter.
CHART = sp.Symbol("chart", real=True)

def _read_domain(domain) -> tuple[tuple[float, float], tuple[float, float]] | None:
    """``((u_min, u_max), (v_min, v_max))`` as floats, or None if it is not two pairs of real
    numbers (any real type: NumPy scalars and 0-d arrays too; not strings or booleans)."""
    try:
        pairs = [tuple(p) for p in domain] if not isinstance(domain, str) else []
    except TypeError:
        return None
    if len(pairs) != 2 or any(len(p) != 2 or isinstance(p, str) for p in pairs):
        return None
    values = [as_real(x) for p in pairs for x in p]
    if None in values:
        return None
    return (values[0], values[1]), (values[2], values[3])


_NON_SMOOTH = (sp.Abs, sp.sign, sp.Heaviside, sp.Min, sp.Max, sp.floor, sp.ceiling, sp.frac)
Matrix = sp.ImmutableMatrix


@dataclass(frozen=True, eq=False)
class ParametricSurface:
    """A regular surface patch ``S(u, v)`` for ``(u, v)`` in ``domain``.

    Parameters
    ----------
    S
        Three SymPy expressions (any sequence or 3x1 matrix) in ``params``: the point in the
        body's local frame, metres. Stored as a 3x1 ``ImmutableMatrix`` in ``U, V``.
    params
        The two parameter symbols ``(u, v)``; replaced by the module symbols ``(U, V)``.
    domain
        ``((u_min, u_max), (v_min, v_max))``, finite, each ``min < max``.
    name
        A short label used in messages and plots.
    """

    S: sp.ImmutableMatrix
    params: tuple[sp.Symbol, sp.Symbol] = (U, V)
    domain: tuple[tuple[float, float], tuple[float, float]] = ((-1.0, 1.0), (-1.0, 1.0))
    name: str = "surface"
    _checked: bool = field(default=False, repr=False)
    #: an atlas of two charts of which this surface is the first (``geometry.atlas.Atlas``;
    #: the library's closed surfaces with ``atlas=True``), else None
    atlas: object = field(default=None, repr=False)
    #: True for an atlas's blended surface, whose expressions hold ``CHART`` too
    charted: bool = field(default=False, repr=False)
    #: ``(P_u, P_v)``: the periods of the coordinates that repeat (None for one that does
    #: not) on a surface that one chart covers by repeating (``geometry.atlas``: the torus
    #: and the surfaces of revolution with ``atlas=True``); None where none repeats
    periods: tuple | None = field(default=None, repr=False)

    def __post_init__(self) -> None:
        names = {str(self.params[0]): self.params[0], str(self.params[1]): self.params[1],
                 "u": U, "v": V}
        if isinstance(self.S, str):
            raise InvalidSurfaceError(self.name, ["S is one string: give three expressions (or "
                                                  "formulas as text), one per component"])
        dom, bad_domain = _read_domain(self.domain), []
        if dom is None:  # named with the other problems; a placeholder lets those checks run
            dom = ((-1.0, 1.0), (-1.0, 1.0))
            bad_domain = [f"domain = {self.domain!r} is not two pairs of real numbers: give "
                          "((u_min, u_max), (v_min, v_max)), finite numbers with min < max (e.g. "
                          "((-3.1416, 3.1416), (-1.3, 1.3))); a formula such as pi must be "
                          "evaluated first"]
        try:
            comps = [to_expression(as_component(c), names, f"surface '{self.name}': S[{i}]")
                     for i, c in enumerate(self.S)]
        except ExpressionError as exc:
            raise InvalidSurfaceError(self.name, [*bad_domain, str(exc)]) from None
        except (TypeError, ValueError, sp.SympifyError) as exc:
            raise InvalidSurfaceError(self.name, [*bad_domain, f"cannot read S ({exc}): give three "
                                                  "expressions, one per component"]) from exc
        if len(comps) != 3:
            raise InvalidSurfaceError(self.name, [*bad_domain, f"S has {len(comps)} components: "
                                                  "give exactly three"])
        p_u, p_v = self.params
        comps = [c.xreplace({p_u: U, p_v: V}) for c in comps]  # simultaneous: (v, u) works too
        object.__setattr__(self, "S", Matrix(comps))
        object.__setattr__(self, "params", (U, V))
        object.__setattr__(self, "domain", dom)
        problems = bad_domain + self._static_problems()
        if problems:
            raise InvalidSurfaceError(self.name, problems)

    # ----------------------------------------------------------------- derivatives
    @cached_property
    def S_u(self) -> sp.ImmutableMatrix:
        """``dS/du`` (m per unit u), local frame."""
        return self.S.diff(U)

    @cached_property
    def S_v(self) -> sp.ImmutableMatrix:
        """``dS/dv`` (m per unit v), local frame."""
        return self.S.diff(V)

    @cached_property
    def S_uu(self) -> sp.ImmutableMatrix:
        return self.S_u.diff(U)

    @cached_property
    def S_uv(self) -> sp.ImmutableMatrix:
        return self.S_u.diff(V)

    @cached_property
    def S_vv(self) -> sp.ImmutableMatrix:
        return self.S_v.diff(V)

    # ----------------------------------------------------------------- fundamental forms
    @cached_property
    def first_fundamental_form(self) -> sp.ImmutableMatrix:
        """``I = [[E, F], [F, G]]`` with ``E = S_u.S_u, F = S_u.S_v, G = S_v.S_v`` (m^2)."""
        E, F, G = self.S_u.dot(self.S_u), self.S_u.dot(self.S_v), self.S_v.dot(self.S_v)
        return Matrix([[E, F], [F, G]])

    @cached_property
    def area_element(self) -> sp.Expr:
        """``sqrt(EG - F^2) = |S_u x S_v|`` (m^2 per unit u v); zero where the chart is singular."""
        (E, F), (_, G) = self.first_fundamental_form.tolist()
        return sp.sqrt(E * G - F**2)

    @cached_property
    def normal(self) -> sp.ImmutableMatrix:
        """Unit normal ``S_u x S_v / |S_u x S_v|`` (outward for the library's closed surfaces)."""
        return self.S_u.cross(self.S_v) / self.area_element

    @cached_property
    def second_fundamental_form(self) -> sp.ImmutableMatrix:
        """``II = [[L, M], [M, N]]``, ``L = S_uu . n``, ``M = S_uv . n``, ``N = S_vv . n`` (m)."""
        c, a = self.S_u.cross(self.S_v), self.area_element
        L, M, N = (self.S_uu.dot(c) / a, self.S_uv.dot(c) / a, self.S_vv.dot(c) / a)
        return Matrix([[L, M], [M, N]])

    @cached_property
    def _I_inv(self) -> sp.ImmutableMatrix:
        (E, F), (_, G) = self.first_fundamental_form.tolist()
        det = E * G - F**2
        return Matrix([[G / det, -F / det], [-F / det, E / det]])

    @cached_property
    def shape_operator(self) -> sp.ImmutableMatrix:
        """Weingarten map in chart coordinates, ``W = I^-1 II`` (1/m); ``dn = -dS W``."""
        return self._I_inv * self.second_fundamental_form

    @cached_property
    def gaussian_curvature(self) -> sp.Expr:
        """``K = (LN - M^2) / (EG - F^2)`` (1/m^2); independent of the normal's orientation."""
        (E, F), (_, G) = self.first_fundamental_form.tolist()
        (L, M), (_, N) = self.second_fundamental_form.tolist()
        return (L * N - M**2) / (E * G - F**2)

    @cached_property
    def mean_curvature(self) -> sp.Expr:
        """``H = (EN - 2FM + GL) / (2(EG - F^2))`` (1/m); ``-1/r`` on a sphere with outward n."""
        (E, F), (_, G) = self.first_fundamental_form.tolist()
        (L, M), (_, N) = self.second_fundamental_form.tolist()
        return (E * N - 2 * F * M + G * L) / (2 * (E * G - F**2))

    def normal_curvature(self, du: sp.Expr, dv: sp.Expr) -> sp.Expr:
        """Normal curvature ``II(d, d) / I(d, d)`` (1/m) in the tangent direction ``d = S_u du + S_v dv``."""
        d = Matrix([du, dv])
        return (d.T * self.second_fundamental_form * d)[0] / (d.T * self.first_fundamental_form * d)[0]

    @cached_property
    def christoffel(self) -> tuple[tuple[tuple[sp.Expr, ...], ...], ...]:
        """Christoffel symbols of the second kind, ``Gamma[k][i][j]`` (index 0 = u, 1 = v).

        ``S_ij = Gamma[0][i][j] S_u + Gamma[1][i][j] S_v + II_ij n``, computed as
        ``Gamma^k_ij = g^kl (S_ij . S_l)``.
        """
        second = ((self.S_uu, self.S_uv), (self.S_uv, self.S_vv))
        firsts = (self.S_u, self.S_v)
        dots = [[[second[i][j].dot(firsts[m]) for m in range(2)] for j in range(2)] for i in range(2)]
        g = self._I_inv
        return tuple(
            tuple(tuple(g[k, 0] * dots[i][j][0] + g[k, 1] * dots[i][j][1] for j in range(2)) for i in range(2))
            for k in range(2)
        )

    # ----------------------------------------------------------------- Montana 1988
    @cached_property
    def frame(self) -> tuple[sp.ImmutableMatrix, sp.ImmutableMatrix, sp.ImmutableMatrix]:
        """Montana's chart-aligned orthonormal frame ``(x, y, n)`` at ``S(u, v)``, local frame.

        ``x = S_u / |S_u|``, ``y = n x x = (E S_v - F S_u) / sqrt(E (EG - F^2))``, ``n`` the
        unit normal; right-handed. For an orthogonal chart ``y = S_v / |S_v|`` (Montana's
        normalized Gauss frame).
        """
        (E, F), (_, G) = self.first_fundamental_form.tolist()
        sE, a = sp.sqrt(E), self.area_element
        return self.S_u / sE, (E * self.S_v - F * self.S_u) / (sE * a), self.normal

    @cached_property
    def montana_metric(self) -> sp.ImmutableMatrix:
        """Montana's metric ``M_p`` (m per unit parameter): ``[x.dS, y.dS]^T = M_p [du, dv]^T``.

        ``M_p = [[sqrt(E), F/sqrt(E)], [0, sqrt(EG - F^2)/sqrt(E)]]`` = ``[x y]^T [S_u S_v]``,
        i.e. ``[[|S_u|, |S_v| cos(a)], [0, |S_v| sin(a)]]`` with ``a`` the angle between ``S_u``
        and ``S_v``; ``I = M_p^T M_p``. For an orthogonal chart it is Montana's
        ``diag(|S_u|, |S_v|)``.
        """
        (E, F), (_, G) = self.first_fundamental_form.tolist()
        sE = sp.sqrt(E)
        return Matrix([[sE, F / sE], [0, self.area_element / sE]])

    @cached_property
    def _M_inv(self) -> sp.ImmutableMatrix:
        (E, F), (_, G) = self.first_fundamental_form.tolist()
        sE, a = sp.sqrt(E), self.area_element
        return Matrix([[1 / sE, -F / (sE * a)], [0, sE / a]])

    @cached_property
    def curvature_form(self) -> sp.ImmutableMatrix:
        """Montana's curvature form ``K_p = [x y]^T [n_u n_v] M_p^-1`` (1/m), symmetric 2x2.

        The derivative of the normal in the frame ``(x, y)``: moving the point by ``w``
        (frame components, m) turns ``n`` by ``K_p w``. Computed exactly as
        ``K_p = -M_p^-T II M_p^-1 = -M_p W M_p^-1``: its eigenvalues are minus the principal
        curvatures, ``+1/r`` on a sphere with the outward normal.
        """
        Mi = self._M_inv
        return -Mi.T * self.second_fundamental_form * Mi

    @cached_property
    def torsion_form(self) -> sp.ImmutableMatrix:
        """Montana's torsion form ``T_p = y^T [x_u x_v] M_p^-1`` (1/m), a 1x2 row.

        The rate at which the frame turns about ``n`` as the point moves by ``w`` (frame
        components): ``y . dx = T_p w``. Computed exactly from ``y . x_i = y . S_ui / |S_u|``.
        For the sphere chart of the library (u = longitude, v = latitude) ``T_p = [tan(v)/r, 0]``.
        """
        (E, F), (_, G) = self.first_fundamental_form.tolist()
        y = self.frame[1]
        sE = sp.sqrt(E)
        return Matrix([[y.dot(self.S_uu) / sE, y.dot(self.S_uv) / sE]]) * self._M_inv

    def key(self) -> str:
        """A canonical text of the definition, for content hashing."""
        (u0, u1), (v0, v1) = self.domain
        return "|".join([*(sp.srepr(c) for c in self.S), repr(u0), repr(u1), repr(v0), repr(v1),
                         *([] if self.atlas is None else [self.atlas.key()]),
                         *([] if self.periods is None else [f"periods:{self.periods!r}"])])

    # ----------------------------------------------------------------- numeric
    @cached_property
    def _numeric(self):
        # cse=True: the curvature forms share most subexpressions; for a superquadric it cuts
        # lambdify from 2.5 s to 0.3 s and an evaluation on a 41x41 grid from 0.5 s to 1.5 ms.
        x, y, n = self.frame
        exprs = [*self.S, *n, *self.first_fundamental_form, *self.second_fundamental_form,
                 self.gaussian_curvature, self.mean_curvature, *self.shape_operator, *x, *y,
                 *self.montana_metric, *self.curvature_form, *self.torsion_form]
        return sp.lambdify((U, V), exprs, "numpy", cse=True)

    def _by_chart(self, method: str, u, v, chart) -> dict[str, np.ndarray]:
        """``method`` at ``(u, v)`` each in its chart (``chart``: 0 or 1 per point; chart 1 is
        the atlas's ``second``): the rows of a run whose contact switched chart."""
        u, v, c = np.broadcast_arrays(np.asarray(u, dtype=float), np.asarray(v, dtype=float),
                                      np.asarray(chart))
        one = c == 1
        if self.atlas is None or not one.any():
            return getattr(self, method)(u, v)
        out = getattr(self, method)(u, v)
        other = getattr(self.atlas.second, method)(u[one], v[one])
        for k in out:
            out[k] = np.array(out[k], copy=True)
            out[k][one] = other[k]
        return out

    def evaluate(self, u, v, chart=None) -> dict[str, np.ndarray]:
        """Numeric geometry at parameter values ``u, v`` (broadcast together, shape ``sh``);
        ``chart`` (a surface with an atlas): each point's chart (0 or 1), as a run's
        ``SimulationResult.charts`` gives them.

        Returns ``point``, ``normal``, ``x``, ``y`` (``sh + (3,)``, local frame, m / unit);
        ``E F G L M N`` (``sh``); ``K`` Gaussian (1/m^2), ``H`` mean (1/m), ``k1 <= k2``
        principal curvatures (1/m, sign of ``H``, from ``H -+ sqrt(H^2 - K)``); ``shape_operator``, ``M_p``, ``K_p``
        (``sh + (2, 2)``) and ``T_p`` (``sh + (2,)``) as defined on the properties.
        """
        if chart is not None:
            return self._by_chart("evaluate", u, v, chart)
        u, v = np.broadcast_arrays(np.asarray(u, dtype=float), np.asarray(v, dtype=float))
        vals = [np.broadcast_to(np.asarray(a, dtype=float), u.shape) for a in self._numeric(u, v)]

        def stack(i: int, k: int) -> np.ndarray:
            return np.stack(vals[i:i + k], axis=-1)

        ff1, ff2 = stack(6, 4), stack(10, 4)
        K, H = vals[14], vals[15]
        root = np.sqrt(np.maximum(H * H - K, 0.0))
        sh2 = u.shape + (2, 2)
        return {
            "point": stack(0, 3), "normal": stack(3, 3), "x": stack(20, 3), "y": stack(23, 3),
            "E": ff1[..., 0], "F": ff1[..., 1], "G": ff1[..., 3], "L": ff2[..., 0], "M": ff2[..., 1], "N": ff2[..., 3],
            "K": K, "H": H, "k1": H - root, "k2": H + root,
            "shape_operator": stack(16, 4).reshape(sh2), "M_p": stack(26, 4).reshape(sh2),
            "K_p": stack(30, 4).reshape(sh2), "T_p": stack(34, 2),
        }

    @cached_property
    def _numeric_frame(self):
        x, y, n = self.frame
        return sp.lambdify((U, V), [*self.S, *n, *x, *y], "numpy", cse=True)

    def evaluate_frame(self, u, v, chart=None) -> dict[str, np.ndarray]:
        """``evaluate``'s ``point``, ``normal``, ``x``, ``y`` alone (``sh + (3,)`` each), without
        the curvatures: what a contact's place and frame need (grasp quality along a run);
        ``chart`` as for ``evaluate``."""
        if chart is not None:
            return self._by_chart("evaluate_frame", u, v, chart)
        u, v = np.broadcast_arrays(np.asarray(u, dtype=float), np.asarray(v, dtype=float))
        vals = np.empty(u.shape + (12,))
        for k, a in enumerate(self._numeric_frame(u, v)):
            vals[..., k] = a  # an entry that does not depend on u, v is a number: broadcast
        return {"point": vals[..., 0:3], "normal": vals[..., 3:6], "x": vals[..., 6:9], "y": vals[..., 9:12]}

    def in_domain(self, u: float, v: float) -> bool:
        """Whether ``(u, v)`` lies in the declared domain."""
        (u0, u1), (v0, v1) = self.domain
        return u0 <= u <= u1 and v0 <= v <= v1

    # ----------------------------------------------------------------- checks
    def _static_problems(self) -> list[str]:
        problems: list[str] = []
        for label, (a, b) in zip("uv", self.domain):
            if not (math.isfinite(a) and math.isfinite(b)):
                problems.append(f"{label}-domain ({a}, {b}) is not finite: give finite bounds")
            elif not a < b:
                problems.append(f"{label}-domain ({a}, {b}) is empty: give {label}_min < {label}_max")
        for label, e in zip(("S_x", "S_y", "S_z"), self.S):
            extra = e.free_symbols - ({U, V, CHART} if self.charted else {U, V})
            if extra:
                names = ", ".join(sorted(map(str, extra)))
                problems.append(f"{label}(u, v) has free symbols {names} besides the parameters u, v: "
                                "substitute numbers for them")
            if e.has(*_NON_SMOOTH):
                problems.append(f"{label}(u, v) = {e} uses a non-smooth function; surfaces must be smooth "
                                "(C^3): rewrite it with smooth functions (e.g. even powers) or split the patch")
            if e.has(sp.Piecewise):
                problems.append(f"{label}(u, v) is piecewise: a surface patch must be one smooth expression")
        return problems

    def check(self, n: int = 41) -> None:
        """Check regularity and finiteness on an ``n x n`` grid over the domain (edges included).

        Raises :class:`InvalidSurfaceError` listing every problem, each with the first
        offending ``(u, v)`` and a fix.
        """
        if self._checked:
            return
        (u0, u1), (v0, v1) = self.domain
        uu, vv = np.meshgrid(np.linspace(u0, u1, n), np.linspace(v0, v1, n), indexing="ij")
        with np.errstate(all="ignore"):
            val = self.evaluate(uu, vv)
        problems: list[str] = []
        for key in ("point", "normal", "E", "F", "G", "L", "M", "N", "K", "H", "K_p", "T_p"):
            a = val[key]
            bad = ~np.isfinite(a.reshape(uu.shape + (-1,))).all(axis=-1)
            if bad.any():
                i = np.unravel_index(np.argmax(bad), bad.shape)
                problems.append(f"{key} is not finite at (u, v) = ({uu[i]:.6g}, {vv[i]:.6g}) (and "
                                f"{bad.sum() - 1} more samples): shrink the domain or fix the formula")
        with np.errstate(all="ignore"):
            area = np.sqrt(np.maximum(val["E"] * val["G"] - val["F"] ** 2, 0.0))
        ok = np.isfinite(area)
        scale = max(float(np.max(area[ok], initial=0.0)), 1e-300)
        tiny = ok & (area <= 1e-9 * scale)
        if tiny.any():
            i = np.unravel_index(np.argmax(tiny), tiny.shape)
            problems.append(
                f"not regular: |S_u x S_v| = {area[i]:.3g} at (u, v) = ({uu[i]:.6g}, {vv[i]:.6g}) "
                f"(and {tiny.sum() - 1} more samples; largest {scale:.3g}): the normal and curvatures "
                "are undefined there (e.g. a pole of a latitude-longitude chart): shrink the domain to "
                "exclude it or use a chart whose singular points lie outside the patch (rotate it)"
            )
        if problems:
            raise InvalidSurfaceError(self.name, problems)
        object.__setattr__(self, "_checked", True)
