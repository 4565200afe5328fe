"""Translate SymPy expressions into CasADi SX, keeping shared subexpressions shared.

The walk is iterative (no recursion limit) and memoised on structurally equal SymPy
nodes, so a subexpression that occurs many times becomes one SX node: no exponential
re-expansion of the expression DAG. Applications of abstract contour functions (see
``grasping_sym.symbolic.contour_functions``) are replaced by the translation of their
concrete formulas, each translated once per argument. A SymPy function class with a
``_casadi_`` attribute is translated by calling it with the SX of its arguments.
"""
from __future__ import annotations

from collections.abc import Callable, Mapping

import casadi as ca
import sympy as sp

from grasping_sym.errors import GraspingSymError
from grasping_sym.geometry.curves import T

_UNARY: dict[type, Callable] = {
    sp.sin: ca.sin, sp.cos: ca.cos, sp.tan: ca.tan, sp.asin: ca.asin, sp.acos: ca.acos,
    sp.atan: ca.atan, sp.sinh: ca.sinh, sp.cosh: ca.cosh, sp.tanh: ca.tanh,
    sp.asinh: ca.asinh, sp.acosh: ca.acosh, sp.atanh: ca.atanh, sp.exp: ca.exp,
    sp.log: ca.log, sp.Abs: ca.fabs, sp.sign: ca.sign, sp.floor: ca.floor,
    sp.ceiling: ca.ceil,
}


class TranslationError(GraspingSymError):
    """A SymPy construct has no CasADi counterpart here."""


class SympyToCasadi:
    """Memoised SymPy -> CasADi SX translator.

    Parameters
    ----------
    symbols
        SX value of every free SymPy symbol.
    leaves
        For each abstract function class, its concrete SymPy expression in ``T``.
    """

    def __init__(self, symbols: Mapping[sp.Symbol, ca.SX],
                 leaves: Mapping[type, sp.Expr] | None = None):
        self.memo: dict[sp.Basic, ca.SX] = dict(symbols)
        self.leaves = dict(leaves or {})

    def __call__(self, expr) -> ca.SX:
        if isinstance(expr, sp.MatrixBase):
            rows = [[self(e) for e in expr.row(i)] for i in range(expr.rows)]
            return ca.vertcat(*[ca.horzcat(*r) for r in rows]) if rows else ca.SX(0, 1)
        return self._walk(sp.sympify(expr))

    def _walk(self, root: sp.Basic) -> ca.SX:
        memo = self.memo
        stack = [root]
        while stack:
            node = stack[-1]
            if node in memo:
                stack.pop()
                continue
            if type(node) in self.leaves:
                concrete = self.leaves[type(node)].subs(T, node.args[0])
                todo = [concrete] if concrete not in memo else []
            elif isinstance(node, sp.Piecewise):
                todo = [ec.expr for ec in node.args if ec.expr not in memo]
            else:
                todo = [a for a in node.args if a not in memo]
            if todo:
                stack.extend(todo)
                continue
            stack.pop()
            memo[node] = self._node(node)
        return memo[root]

    def _node(self, e: sp.Basic) -> ca.SX:
        m = self.memo
        if type(e) in self.leaves:
            return m[self.leaves[type(e)].subs(T, e.args[0])]
        if e.is_Number or e in (sp.pi, sp.E):
            if e.is_finite is False or e is sp.nan:
                raise TranslationError(f"non-finite constant {e} in an expression")
            return ca.SX(float(e))
        if e.is_Symbol:
            raise TranslationError(f"free symbol {e} has no value: declare it as a state or parameter")
        fn = type(e)
        if fn is sp.Piecewise:  # its arguments are (expr, cond) pairs: only the exprs are walked
            return self._piecewise(e)
        args = [m[a] for a in e.args]
        if e.is_Add:
            out = args[0]
            for a in args[1:]:
                out = out + a
            return out
        if e.is_Mul:
            out = args[0]
            for a in args[1:]:
                out = out * a
            return out
        if e.is_Pow:
            base, ex = args[0], e.args[1]
            if ex.is_Rational and ex.q in (1, 2) and abs(ex.p) // ex.q <= _MAX_MUL_POWER:
                # small integer and half-integer powers as products and one sqrt: several
                # times cheaper than pow() in C, and their derivatives stay pow-free
                return _small_power(base, int(ex.p), int(ex.q))
            if ex.is_Integer and ex < 0:
                return 1 / ca.constpow(base, float(-ex))
            return ca.constpow(base, args[1]) if ex.is_Number else ca.power(base, args[1])
        if fn in _UNARY:
            return _UNARY[fn](args[0])
        if fn is sp.atan2:
            return ca.atan2(args[0], args[1])
        if fn is sp.Max:
            return _fold(ca.fmax, args)
        if fn is sp.Min:
            return _fold(ca.fmin, args)
        impl = getattr(fn, "_casadi_", None)
        if impl is not None:
            # a SymPy function that knows its CasADi form (e.g. a spline's coefficient lookup,
            # a call node): called with the SX of its arguments
            return impl(*args)
        raise TranslationError(f"no CasADi translation for {fn.__name__} in {e}")

    def _piecewise(self, e: sp.Piecewise) -> ca.SX:
        out = None
        for expr, cond in reversed(e.args):
            val = self.memo[expr]
            if cond is sp.true:
                out = val
            else:
                if out is None:
                    raise TranslationError(f"Piecewise {e} has no default branch")
                out = ca.if_else(self._cond(cond), val, out)
        return out

    def _cond(self, c) -> ca.SX:
        ops = {sp.StrictLessThan: lambda a, b: a < b, sp.LessThan: lambda a, b: a <= b,
               sp.StrictGreaterThan: lambda a, b: a > b, sp.GreaterThan: lambda a, b: a >= b}
        if type(c) in ops:
            return ops[type(c)](self(c.args[0]), self(c.args[1]))
        if isinstance(c, sp.And):
            return _fold(ca.logic_and, [self._cond(a) for a in c.args])
        if isinstance(c, sp.Or):
            return _fold(ca.logic_or, [self._cond(a) for a in c.args])
        raise TranslationError(f"no CasADi translation for condition {c}")


#: Largest integer part of a power written out as products (``x**4``, ``x**(-9/2)``).
_MAX_MUL_POWER = 4


def _small_power(base: ca.SX, p: int, q: int) -> ca.SX:
    """``base ** (p / q)`` for ``q`` in (1, 2) and ``|p| / q <= _MAX_MUL_POWER``."""
    k = abs(p) // q  # integer part of the exponent
    out = ca.sqrt(base) if q == 2 else None
    for _ in range(k):
        out = base if out is None else out * base
    return 1 / out if p < 0 else out


def _fold(op, args):
    out = args[0]
    for a in args[1:]:
        out = op(out, a)
    return out
