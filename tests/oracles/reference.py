"""Evaluate a derived system without CasADi: SymPy ``lambdify`` to NumPy.

This is the independent path the compiled code is tested against, and the "as a user
would write it by hand" baseline of the benchmarks. The contour functions are replaced by
their concrete formulas and every piece is lambdified; the closed loop is assembled by the
same ``assemble`` as the generated code, with NumPy's linear solver.
"""
from __future__ import annotations

from collections.abc import Callable
from dataclasses import replace

import mpmath
import numpy as np
import sympy as sp
from sympy.printing.numpy import NumPyPrinter

from grasping_sym.derive.planar import derive_planar
from grasping_sym.derive.system import ConstrainedSystem, assemble
from grasping_sym.geometry.curves import T
from grasping_sym.model.planar import PlanarFingerScene
from grasping_sym.symbolic.contour_functions import OBJECT, fingertip_functions, leaf_expressions

_NUMPY = dict(
    solve=np.linalg.solve,
    vcat=lambda parts: np.concatenate([np.ravel(p) for p in parts]),
    mul=lambda a, b: a * b,
    transpose=lambda a: a.T,
)



def _mp_solve(A, B):
    """``A^-1 B`` for object arrays of mpf (mpmath's LU, at the working precision)."""
    A_mp = mpmath.matrix(A.tolist())
    cols = B.reshape(B.shape[0], -1)
    out = [mpmath.lu_solve(A_mp, mpmath.matrix(cols[:, j].tolist())) for j in range(cols.shape[1])]
    return np.array([[out[j][i] for j in range(len(out))] for i in range(cols.shape[0])],
                    dtype=object).reshape(B.shape)


#: ``assemble``'s backend in mpmath (``ReferenceModel.evaluate(exact=True)``).
_MPMATH = dict(_NUMPY, solve=_mp_solve)


def substitute_leaves(expr, leaves: dict[type, sp.Expr]):
    """Replace every abstract contour function application in ``expr`` by its concrete
    expression (``contour_functions.leaf_expressions``) at that application's argument."""
    if not leaves:
        return expr
    # one walk of the expression for every class at once (a walk per class took most of a
    # two-finger reference's construction: 14 classes over 1703 expressions)
    repl = {}
    for app in expr.atoms(*leaves):
        cls = type(app) if type(app) in leaves else next(c for c in leaves if isinstance(app, c))
        repl[app] = leaves[cls].subs(T, app.args[0])
    return expr.xreplace(repl)


class _ExactFloatPrinter(NumPyPrinter):
    """Print every Float as the exact double it holds (SymPy's default keeps 15 digits,
    an error of ~1e-16 that the stiff stabilisation gains amplify to ~1e-8)."""

    def _print_Float(self, expr):
        return repr(float(expr))


def _lambdify(args, expr):
    printer = _ExactFloatPrinter({"fully_qualified_modules": False, "inline": True,
                                  "allow_unknown_functions": True, "user_functions": {}})
    return sp.lambdify(args, expr, "numpy", printer=printer, cse=True)


def with_acceleration_terms(system: ConstrainedSystem) -> ConstrainedSystem:
    """``system`` with ``Ahat = dC'/dv`` and ``bhat = dC'/dz z'`` derived in SymPy when the
    derivation left them to the translation to CasADi (which derives them by AD): SymPy's
    own second derivatives, an independent path to the same terms."""
    if system.acc_jac is not None:
        return system
    n = system.n
    v = sp.Matrix(system.state[n:2 * n])
    z = sp.Matrix([*system.state[:n], *system.state[2 * n:]])
    zdot = sp.Matrix([*v, *system.contact_rates])
    Cdot = system.constraint_rate
    return replace(system, acc_jac=Cdot.jacobian(v), acc_bias=Cdot.jacobian(z) * zdot)


class ReferenceModel:
    """NumPy evaluation of a scene's closed loop, straight from the SymPy derivation."""

    def __init__(self, scene: PlanarFingerScene, system: ConstrainedSystem | None = None):
        self.scene = scene
        self.system = with_acceleration_terms(system or derive_planar(scene))
        leaves = leaf_expressions(OBJECT, scene.object)
        tips = [scene.fingertip, *(f.fingertip for f in scene.extra_fingers)]
        for i, tip in enumerate(tips, start=1):
            leaves.update(leaf_expressions(fingertip_functions(i), tip))
        self._constants = list(self.system.constants.values())
        args = [*self.system.state, *self.system.params, *self.system.constants]
        self._args = args
        self._concrete = [substitute_leaves(m, leaves) for m in self.system.pieces()]
        self._pieces = [_lambdify(args, m) for m in self._concrete]
        self._exact_pieces: list[Callable] | None = None
        names = tuple(self.system.outputs)
        self.output_names = names
        outs = sp.Matrix([substitute_leaves(sp.sympify(self.system.outputs[k]), leaves)
                          for k in names]) if names else None
        self._outputs: Callable | None = (
            _lambdify([*args, *self.system.multipliers], outs)
            if names else None
        )

    def _p(self, p):
        if p is None:
            return [float(self.scene.params[k]) for k in self.scene.runtime]
        return list(np.ravel(p))

    def evaluate(self, x, p=None) -> tuple[np.ndarray, np.ndarray]:
        """``(xdot, mu)`` at state ``x``."""
        args = [*np.ravel(x), *self._p(p), *self._constants]
        pieces = [np.asarray(f(*args), dtype=float) for f in self._pieces]
        n = self.system.n
        v = np.asarray(x, dtype=float)[n:2 * n, None]
        xdot, mu = assemble(n, v, pieces, **_NUMPY)
        return xdot, np.ravel(mu)

    def rhs_exact(self, x, p=None, digits: int = 40) -> np.ndarray:
        """The closed-loop right-hand side at the doubles ``x``, ``p`` evaluated in
        ``digits``-digit arithmetic (mpmath), rounded to doubles at the end: the exact value
        that double-precision evaluations are judged against."""
        if self._exact_pieces is None:
            self._exact_pieces = [sp.lambdify(self._args, m, "mpmath", cse=True)
                                  for m in self._concrete]
        with mpmath.workdps(digits):
            args = [mpmath.mpf(float(a)) for a in (*np.ravel(x), *self._p(p), *self._constants)]
            pieces = [np.array(mpmath.matrix(f(*args)).tolist(), dtype=object)
                      for f in self._exact_pieces]
            n = self.system.n
            v = np.array([[mpmath.mpf(float(a))] for a in np.ravel(x)[n:2 * n]], dtype=object)
            xdot, _ = assemble(n, v, pieces, **_MPMATH)
            return np.array([float(a) for a in np.ravel(xdot)])

    def rhs(self, x, p=None) -> np.ndarray:
        """The closed-loop right-hand side."""
        return self.evaluate(x, p)[0]

    def outputs(self, x, p=None) -> dict[str, float]:
        """The scene's requested outputs at ``x``."""
        _, mu = self.evaluate(x, p)
        vals = np.ravel(self._outputs(*np.ravel(x), *self._p(p), *self._constants, *mu))
        return dict(zip(self.output_names, map(float, vals)))
