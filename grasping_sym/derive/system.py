"""A constrained mechanical system as symbolic pieces, and its closed-loop assembly.

Every scene's derivation produces a ``ConstrainedSystem``: the Euler-Lagrange pieces
``M(q) a + h(q, v) + A(q, u)^T mu = tau(q, v)``, holonomic constraints ``C(q, u) = 0``
stabilised by Baumgarte (CSM) ``C'' + D C' + K C = 0``, and contact parameters ``u`` with
rates ``u' = sigma(q, v, u)``. ``C''`` is written ``Ahat a + bhat``: ``Ahat`` differs from
``A`` by the dependence of ``C`` on ``u`` (zero on the constraint manifold), so the
stabilisation acts on the true total derivatives of ``C``.

``assemble`` turns the pieces into ``xdot`` and ``mu`` with any array backend: CasADi SX for
code generation and NumPy for the independent reference evaluation used in tests.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import sympy as sp


@dataclass
class ConstrainedSystem:
    """Symbolic pieces of a closed-loop constrained system (all SymPy).

    Shapes: ``n`` coordinates, ``m`` constraints, ``k`` contact parameters.
    """

    state: list[sp.Symbol]            # [q (n), v (n), u (k)], the ODE state order
    n: int
    params: list[sp.Symbol]           # run-time parameters (inputs of the compiled code)
    mass_matrix: sp.Matrix            # (n, n)
    bias: sp.Matrix                   # (n, 1) Coriolis/centrifugal + gravity
    force: sp.Matrix                  # (n, 1) generalised control force tau
    constraint: sp.Matrix             # (m, 1) C
    constraint_jac: sp.Matrix         # (m, n) A = dC/dq with u fixed
    constraint_rate: sp.Matrix        # (m, 1) C' (total)
    # (m, n) Ahat = d C'' / d a, and (m, 1) bhat = C'' at a = 0; None: not derived in SymPy,
    # the translation to CasADi derives them from ``constraint_rate`` (``codegen.functions``)
    acc_jac: sp.Matrix | None
    acc_bias: sp.Matrix | None
    csm_damping: sp.Matrix            # (m, 1) D (diagonal)
    csm_stiffness: sp.Matrix          # (m, 1) K (diagonal)
    contact_rates: sp.Matrix          # (k, 1) sigma
    multipliers: list[sp.Symbol]      # mu symbols, used inside output expressions
    outputs: dict[str, sp.Expr] = field(default_factory=dict)
    constants: dict[sp.Symbol, float] = field(default_factory=dict)  # folded parameters
    op_counts: dict[str, int] = field(default_factory=dict)

    @property
    def m(self) -> int:
        return self.constraint.shape[0]

    def pieces(self) -> list[sp.Matrix]:
        """The matrices ``assemble`` needs, in its argument order."""
        return [self.mass_matrix, self.bias, self.force, self.constraint_jac, self.acc_jac,
                self.acc_bias, self.constraint_rate, self.constraint, self.csm_damping,
                self.csm_stiffness, self.contact_rates]


def assemble(n, v, pieces, solve, vcat, mul, transpose, qdot=None):
    """Closed-loop accelerations and multipliers from evaluated pieces.

    Parameters
    ----------
    n
        Number of coordinates.
    v
        Column of the ``n`` speeds.
    pieces
        Evaluated ``ConstrainedSystem.pieces()`` in the backend's matrix type.
    solve, vcat, mul, transpose
        Backend operations: ``solve(A, B)``, vertical concatenation of a list,
        elementwise product, transpose.
    qdot
        Rates of the position coordinates when they are not the speeds themselves (a
        quaternion with a body angular velocity: ``q' = N(q) v``); default ``v``.

    Returns
    -------
    xdot, mu
        ``[q'; a; sigma]`` and the constraint multipliers.
    """
    M, h, tau, A, Ahat, bhat, Cdot, C, D, K, sigma = pieces
    free = solve(M, tau - h)                 # M^-1 (tau - h)
    MinvAT = solve(M, transpose(A))          # M^-1 A^T
    S = Ahat @ MinvAT
    mu = solve(S, Ahat @ free + bhat + mul(D, Cdot) + mul(K, C))
    a = free - MinvAT @ mu
    return vcat([v if qdot is None else qdot, a, sigma]), mu
