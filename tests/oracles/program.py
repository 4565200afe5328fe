"""An interpreter of a CasADi SX algorithm (``codegen.algorithm``'s instruction list), in
doubles or in 60-digit arithmetic: the oracle of the rewrites of the generated programs
(``codegen.reciprocals``) and the exact value double-precision evaluations are judged by."""
from __future__ import annotations

import math

import mpmath
import numpy as np

_OPS = {
    "ADD": lambda a, b: a + b, "SUB": lambda a, b: a - b, "MUL": lambda a, b: a * b,
    "DIV": lambda a, b: a / b, "NEG": lambda a: -a, "SQ": lambda a: a * a,
    "TWICE": lambda a: 2.0 * a, "INV": lambda a: 1.0 / a, "SQRT": math.sqrt, "SIN": math.sin,
    "COS": math.cos, "FABS": abs, "ATAN2": math.atan2, "ASINH": math.asinh,
    "FMAX": max, "FMIN": min,
}


_EXACT = {**_OPS, "SQRT": mpmath.sqrt, "SIN": mpmath.sin, "COS": mpmath.cos,
          "ATAN2": mpmath.atan2, "ASINH": mpmath.asinh}


def run(program, args, n_out_nz, exact: bool = False):
    """An independent interpreter of an instruction list (the work vector of CasADi's C), in
    doubles or (``exact``) in 60-digit arithmetic."""
    ops, num = (_EXACT, mpmath.mpf) if exact else (_OPS, float)
    w: dict[int, float] = {}
    out = [[0.0] * n for n in n_out_nz]
    with mpmath.workdps(60):
        for ins in program:
            if ins.op == "INPUT":
                w[ins.out[0]] = num(float(args[ins.ins[0]][ins.ins[1]]))
            elif ins.op == "OUTPUT":
                out[ins.out[0]][ins.out[1]] = float(w[ins.ins[0]])
            elif ins.op == "CONST":
                w[ins.out[0]] = num(ins.value)
            else:
                w[ins.out[0]] = ops[ins.op](*(w[i] for i in ins.ins))
    return [np.array(o) for o in out]
