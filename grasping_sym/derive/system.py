"""A constrained mechanical system as symbolic pieces, and its closed-loop assembly.

Every scene's derivation, 2D or 3D, produces a ``ConstrainedSystem``: the Euler-Lagrange
pieces ``M(q) a + h(q, v) + A(q, u)^T mu = tau(q, v)``, holonomic constraints ``C(q, u) = 0``
stabilised by Baumgarte (CSM) ``C'' + D C' + K C = 0``, and contact parameters ``u`` with
rates ``u' = sigma(q, v, u)``. ``C''`` is written ``Ahat a + bhat``: ``Ahat`` differs from
``A`` by the dependence of ``C`` on ``u`` (zero on the constraint manifold), so the
stabilisation acts on the true total derivatives of ``C``.

The pieces are in one backend: SymPy for a planar template (``derive.planar``; contours as
abstract functions, closed by ``assemble.functions.build_template``), CasADi SX for a 3D scene
(``derive.grasp3d``, which closes the loop itself and fills ``xdot``, the start conditions and
the drawing geometry). Code above asks the record, never which derivation made it.

``assemble`` turns the pieces into ``xdot`` and ``mu`` with any array backend: CasADi SX for
code generation and NumPy for the independent reference evaluation used in tests.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    import casadi as ca
    import sympy as sp

#: The names of the canonical pieces in :meth:`ConstrainedSystem.named` (``"pieces"``).
PIECE_NAMES = {"M": "mass_matrix", "h": "bias", "tau": "force", "A": "constraint_jac",
               "Ahat": "acc_jac", "bhat": "acc_bias", "Cdot": "constraint_rate", "C": "constraint",
               "sigma": "contact_rates", "mu": "multipliers"}


@dataclass
class ConstrainedSystem:
    """Symbolic pieces of a closed-loop constrained system (all SymPy, or all CasADi SX).

    Shapes: ``n`` speeds, ``m`` constraints, ``k`` contact parameters.
    """

    state: Any                        # [q, v (n), u (k)], the ODE state order: SymPy
                                      # symbols, or the SX column ``x``
    n: int
    params: Any                       # run-time parameters (inputs of the compiled code):
                                      # SymPy symbols, or the SX column ``p``
    mass_matrix: Any                  # (n, n) M
    bias: Any                         # (n, 1) h: Coriolis/centrifugal + gravity
    force: Any                        # (n, 1) generalised applied force tau
    constraint: Any                   # (m, 1) C
    constraint_jac: Any               # (m, n) A = dC/dq with u fixed
    constraint_rate: Any              # (m, 1) C' (total)
    # (m, n) Ahat = d C'' / d a, and (m, 1) bhat = C'' at a = 0; None: not derived in SymPy,
    # the translation to CasADi derives them from ``constraint_rate`` (``assemble.functions``)
    acc_jac: Any
    acc_bias: Any
    csm_damping: Any                  # (m, 1) D (diagonal)
    csm_stiffness: Any                # (m, 1) K (diagonal)
    contact_rates: Any                # (k, 1) sigma
    # mu: SymPy symbols the outputs use for them (their values come from the closed loop),
    # or, closed in CasADi, the (m, 1) SX of their values
    multipliers: Any
    outputs: dict[str, Any] = field(default_factory=dict)
    constants: dict[sp.Symbol, float] = field(default_factory=dict)  # folded parameters
    op_counts: dict[str, int] = field(default_factory=dict)
    #: q' where the positions' rates are not the speeds (a quaternion with a body angular
    #: velocity: ``q' = N(q) v``); None: ``q' = v``
    position_rates: Any = None
    # ---- the closed loop, when the derivation closes it itself (CasADi SX, 3D)
    #: ``x'(x, p)``
    xdot: ca.SX | None = None
    #: the names of ``params``' entries
    param_names: tuple[str, ...] = ()
    #: every condition of a consistent start, by name (zero there, ``runtime.start``)
    start_conditions: dict[str, Any] = field(default_factory=dict)
    #: the values the start parameters (``scene.start_param_names``) take at the state: 3D,
    #: the mean of the fingertip centres ``r_bar`` (m, world frame)
    start_values: ca.SX | None = None
    #: the controller's time, and whether the law reads it itself
    t: ca.SX | None = None
    reads_time: bool = False
    #: what drawings read, by name (3D: ``R``, ``pos``, ``joints{i}``, ``Pi{i}``, ``p_f{i}``,
    #: ``p_o{i}``, ``psi{i}``; world frame, m)
    geometry: dict[str, Any] = field(default_factory=dict)

    @property
    def m(self) -> int:
        return self.constraint.shape[0]

    @property
    def x(self) -> ca.SX:
        """The state (the closed loop's CasADi name of ``state``)."""
        return self.state

    @property
    def p(self) -> ca.SX:
        """The run-time parameters (the closed loop's CasADi name of ``params``)."""
        return self.params

    def pieces(self) -> list:
        """The matrices ``assemble`` needs, in its argument order."""
        return [self.mass_matrix, self.bias, self.force, self.constraint_jac, self.acc_jac,
                self.acc_bias, self.constraint_rate, self.constraint, self.csm_damping,
                self.csm_stiffness, self.contact_rates]

    def named(self, which: str) -> dict[str, Any]:
        """``"pieces"`` (by the names of :data:`PIECE_NAMES`), ``"geometry"`` or ``"outputs"``."""
        if which == "pieces":
            return {k: getattr(self, attr) for k, attr in PIECE_NAMES.items()}
        if which in ("geometry", "outputs"):
            return getattr(self, which)
        raise ValueError(f"no {which!r} in a system: 'pieces', 'geometry' or 'outputs'")

    def function(self, name: str, which: str) -> ca.Function:
        """An (uncompiled) CasADi ``Function(x, p) -> dict`` of :meth:`named` ``(which)``, the
        law's time at 0 (a law that reads it: at the start). CasADi systems only."""
        import casadi as ca  # noqa: PLC0415 - a SymPy system needs no CasADi

        if self.xdot is None:
            raise ValueError("a SymPy system has no CasADi function: translate it first "
                             "(assemble.functions.build_template)")
        d = self.named(which)
        values = list(d.values())
        if self.t is not None:
            values = ca.substitute(values, [self.t], [ca.SX(0)])
        return ca.Function(name, [self.x, self.p], values, ["x", "p"], list(d))


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
