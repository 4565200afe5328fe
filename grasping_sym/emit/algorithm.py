"""A CasADi SX Function's algorithm, read through CasADi's documented instruction API.

``Function.instruction_id(k)``, ``instruction_input(k)``, ``instruction_output(k)`` and
``instruction_constant(k)`` (CasADi's example ``accessing_sx_algorithm.py``) give the
straight-line program that CasADi's code generator prints, one statement per instruction, on
a work vector ``w``:

- ``INPUT``: ``w[out] = arg[i][nz]`` (``ins = (i, nz)``);
- ``OUTPUT``: ``res[i][nz] = w[in]`` (``out = (i, nz)``);
- ``CONST``: ``w[out] = value``;
- every other operation: ``w[out] = op(w[in0], w[in1])``.

The rewrites of the generated C (``codegen.lanes``, ``codegen.vecmath``) are built from this
list, not from the C that CasADi prints. ``C_SCALAR`` spells each operation as CasADi's code
generator does, so scalar code emitted from it computes what CasADi's does, bit for bit.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import casadi as ca

#: CasADi's operation codes by name (``OP_ADD`` -> ``"ADD"``).
OP_NAMES: dict[int, str] = {getattr(ca, k): k[3:] for k in dir(ca) if k.startswith("OP_")}

#: Each operation as CasADi's code generator prints it (``{0}``, ``{1}``: the arguments).
C_SCALAR: dict[str, str] = {
    "ADD": "({0}+{1})", "SUB": "({0}-{1})", "MUL": "({0}*{1})", "DIV": "({0}/{1})",
    "NEG": "(-{0})", "SQ": "casadi_sq({0})", "TWICE": "(2.*{0})", "INV": "(1./{0})",
    "FABS": "casadi_fabs({0})", "SQRT": "sqrt({0})", "SIN": "sin({0})", "COS": "cos({0})",
    "TAN": "tan({0})", "ASIN": "asin({0})", "ACOS": "acos({0})", "ATAN": "atan({0})",
    "SINH": "sinh({0})", "COSH": "cosh({0})", "TANH": "tanh({0})", "ASINH": "asinh({0})",
    "ACOSH": "acosh({0})", "ATANH": "atanh({0})", "EXP": "exp({0})", "LOG": "log({0})",
    "POW": "pow({0},{1})", "CONSTPOW": "pow({0},{1})", "ATAN2": "atan2({0},{1})",
    "FMIN": "casadi_fmin({0},{1})", "FMAX": "casadi_fmax({0},{1})", "FLOOR": "floor({0})",
    "CEIL": "ceil({0})", "SIGN": "casadi_sign({0})", "ERF": "erf({0})",
    "LOG1P": "casadi_log1p({0})", "EXPM1": "casadi_expm1({0})", "HYPOT": "casadi_hypot({0},{1})",
    "FMOD": "fmod({0},{1})", "COPYSIGN": "copysign({0},{1})",
    "LT": "({0}<{1})", "LE": "({0}<={1})", "EQ": "({0}=={1})", "NE": "({0}!={1})",
    "NOT": "(!{0})", "AND": "({0}&&{1})", "OR": "({0}||{1})", "IF_ELSE_ZERO": "({0}?{1}:0)",
}
#: Operations that are one call of a C math function, and that function's name.
LIBM_CALLS: dict[str, str] = {
    "SQRT": "sqrt", "SIN": "sin", "COS": "cos", "TAN": "tan", "ASIN": "asin", "ACOS": "acos",
    "ATAN": "atan", "SINH": "sinh", "COSH": "cosh", "TANH": "tanh", "ASINH": "asinh",
    "ACOSH": "acosh", "ATANH": "atanh", "EXP": "exp", "LOG": "log", "POW": "pow",
    "CONSTPOW": "pow", "ATAN2": "atan2", "FLOOR": "floor", "CEIL": "ceil", "ERF": "erf",
    "FMOD": "fmod", "COPYSIGN": "copysign",
}


@dataclass(frozen=True)
class Instruction:
    op: str                    # OP_NAMES value: "ADD", "INPUT", "OUTPUT", "CONST", ...
    ins: tuple[int, ...]       # work indices read; (input, nz) for INPUT
    out: tuple[int, ...]       # work index written; (output, nz) for OUTPUT
    value: float = math.nan    # CONST only


class UnsupportedAlgorithm(ValueError):
    """The Function is not a plain SX algorithm (an MX Function, a call, an unknown code)."""


def read(f: ca.Function) -> list[Instruction]:
    """The instructions of the SX Function ``f``, in CasADi's order."""
    if not f.is_a("SXFunction"):
        raise UnsupportedAlgorithm(f"{f.name()} is not an SX Function: it has no instruction list")
    out = []
    for k in range(f.n_instructions()):
        code = f.instruction_id(k)
        op = OP_NAMES.get(code)
        if op is None or (op not in C_SCALAR and op not in ("INPUT", "OUTPUT", "CONST")):
            raise UnsupportedAlgorithm(f"{f.name()}: instruction {k} has the operation code {code} "
                                       f"({op}), which this package does not translate")
        value = f.instruction_constant(k) if op == "CONST" else math.nan
        out.append(Instruction(op, tuple(f.instruction_input(k)), tuple(f.instruction_output(k)),
                               float(value)))
    return out


def c_constant(value: float) -> str:
    """A C literal of ``value`` that reads back to the same double."""
    if not math.isfinite(value):
        raise UnsupportedAlgorithm(f"the constant {value!r} has no C literal here")
    return repr(float(value))


def n_work(instructions: list[Instruction]) -> int:
    """Length of the work vector the instructions use."""
    used = [i for ins in instructions for i in
            ((ins.out if ins.op != "OUTPUT" else ()) + (ins.ins if ins.op != "INPUT" else ()))]
    return max(used, default=-1) + 1
