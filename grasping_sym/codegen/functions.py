"""CasADi functions of a derived system: closed-loop right-hand side, Jacobian, outputs.

Names (also the C symbols): ``{name}_rhs`` with CasADi's DAE signature
``(t, x, z, p, u) -> (ode, alg, quad, zero)`` so that CVODES/IDAS can use the compiled code
directly; ``jac_{name}_rhs`` (CasADi's naming rule for a compiled function's Jacobian);
``{name}_outputs`` ``(x, p) -> y``, only when outputs were requested.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import casadi as ca
import sympy as sp

from grasping_sym.codegen.translate import SympyToCasadi
from grasping_sym.derive.system import ConstrainedSystem, assemble

#: CasADi Function options: eliminate common subexpressions in the SX graph.
FUNCTION_OPTIONS = {"cse": True}


@dataclass
class CasadiModel:
    """The CasADi functions of one scene and the figures of merit of their graphs."""

    rhs: ca.Function
    jac: ca.Function
    outputs: ca.Function | None
    output_names: tuple[str, ...]
    op_counts: dict[str, int] = field(default_factory=dict)

    def functions(self) -> list[ca.Function]:
        return [f for f in (self.rhs, self.jac, self.outputs) if f is not None]


def _casadi_backend():
    return dict(
        solve=ca.solve,
        vcat=lambda parts: ca.vertcat(*parts),
        mul=lambda a, b: a * b,
        transpose=lambda a: a.T,
    )


def build_casadi(system: ConstrainedSystem, leaves: dict, name: str) -> CasadiModel:
    """Translate ``system`` (with concrete contour ``leaves``) into CasADi functions."""
    nx, npar = len(system.state), len(system.params)
    x = ca.SX.sym("x", nx)
    p = ca.SX.sym("p", npar)
    symbols = {s: x[i] for i, s in enumerate(system.state)}
    symbols.update({s: p[i] for i, s in enumerate(system.params)})
    symbols.update({s: ca.SX(v) for s, v in system.constants.items()})  # folded
    tr = SympyToCasadi(symbols, leaves)
    pieces = [tr(mat) for mat in system.pieces()]
    v = x[system.n:2 * system.n]
    xdot, mu = assemble(system.n, v, pieces, **_casadi_backend())

    t = ca.SX.sym("t")
    empty = ca.SX(0, 1)
    dyn_in = [t, x, empty, p, empty]
    raw = ca.Function(f"{name}_rhs", dyn_in, [xdot, empty, empty, empty],
                      ca.dyn_in(), ca.dyn_out())
    rhs = ca.Function(f"{name}_rhs", dyn_in, [xdot, empty, empty, empty],
                      ca.dyn_in(), ca.dyn_out(), FUNCTION_OPTIONS)
    jac = rhs.jacobian()
    op_counts = {
        "rhs_sx_instructions_before_cse": raw.n_instructions(),
        "rhs_sx_instructions": rhs.n_instructions(),
        "jac_sx_instructions": jac.n_instructions(),
    }
    outputs = None
    names = tuple(system.outputs)
    if names:
        for i, m in enumerate(system.multipliers):
            tr.memo[m] = mu[i]
        y = ca.vertcat(*[tr(system.outputs[k]) for k in names])
        outputs = ca.Function(f"{name}_outputs", [x, p], [y], ["x", "p"], ["y"],
                              FUNCTION_OPTIONS)
        op_counts["outputs_sx_instructions"] = outputs.n_instructions()
    return CasadiModel(rhs=rhs, jac=jac, outputs=outputs, output_names=names,
                       op_counts=op_counts)


def sympy_op_counts(system: ConstrainedSystem) -> dict[str, int]:
    """Operation counts of the SymPy pieces before and after SymPy's CSE."""
    exprs = [e for mat in system.pieces() for e in mat]
    before = sum(sp.count_ops(e) for e in exprs)
    repl, reduced = sp.cse(exprs, optimizations=None)
    after = sum(sp.count_ops(r) for _, r in repl) + sum(sp.count_ops(e) for e in reduced)
    return {"sympy_ops_before_cse": int(before), "sympy_ops_after_cse": int(after)}
