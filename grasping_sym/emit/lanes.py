"""A 4-lane version of a generated right-hand side: one call evaluates it at four states.

Radau IIA evaluates the right-hand side at its three stage points in every Newton
iteration. An SX function is a straight-line program (``codegen.algorithm``: read through
CasADi's instruction API); here that program is written in C over GCC vector types
(``double __attribute__((vector_size(32)))``, also understood by clang), so that its
arithmetic runs on four states at once in AVX registers.

Every lane computes exactly what the scalar function computes: additions, products,
quotients and square roots are IEEE operations lane by lane (square roots four at once where
AVX is), and each libm call (``sin``, ``asinh``, ...) goes to the function the scalar code
calls for that value: with glibc's vector libm (``GS_VECMATH``, see ``codegen.vecmath``) one
call of its 4-lane version, otherwise the scalar function lane by lane. The results are
therefore bit-identical to four scalar calls (tested, both ways). On paper2d the three stage
evaluations take 0.33 µs instead of 0.52 with scalar libm (gcc 12, x86-64-v3).

Only the arithmetic operations of :data:`ARITHMETIC` and the calls of :data:`UNARY` and
:data:`BINARY` are translated; a function with anything else (comparisons, ``if_else``) gets
no lane version (:func:`rhs_lanes` says why) and the integrators call the scalar function
three times, as before.
"""
from __future__ import annotations

import casadi as ca

from grasping_sym.emit import algorithm, vecmath
from grasping_sym.emit.reciprocals import share_reciprocals

__all__ = ["ARITHMETIC", "BINARY", "UNARY", "function_lanes", "lanes_symbol", "rhs_lanes",
           "rhs_lanes_c"]

#: One-argument C functions translated lane by lane (CasADi's names).
UNARY = ("sin", "cos", "tan", "asin", "acos", "atan", "sinh", "cosh", "tanh", "asinh", "acosh",
         "atanh", "exp", "log", "log1p", "expm1", "sqrt", "erf", "floor", "ceil", "fabs",
         "casadi_fabs", "casadi_log1p", "casadi_expm1")
#: Two-argument C functions translated lane by lane.
BINARY = ("atan2", "pow", "fmod", "casadi_fmin", "casadi_fmax", "fmin", "fmax")

#: Operations written with the vector types' own operators (IEEE lane by lane).
ARITHMETIC: dict[str, str] = {
    "ADD": "({0}+{1})", "SUB": "({0}-{1})", "MUL": "({0}*{1})", "DIV": "({0}/{1})",
    "NEG": "(-{0})", "SQ": "({0}*{0})", "TWICE": "(2.*{0})", "INV": "(1./{0})",
}
#: Operations that are calls, and the lane function each becomes (``gs_l4_<name>``).
_CALLS: dict[str, str] = {
    **{op: f for op, f in algorithm.LIBM_CALLS.items() if f in UNARY or f in BINARY},
    "FABS": "casadi_fabs", "FMIN": "casadi_fmin", "FMAX": "casadi_fmax",
    "LOG1P": "casadi_log1p", "EXPM1": "casadi_expm1",
}

_PRELUDE = """
/* ---- 4-lane right-hand side (grasping_sym.emit.lanes): {symbol}(t, x, p, xdot)
 * evaluates {rhs} at the four states x[0..3] (times t[0..3]) with parameters p;
 * bit-identical to four calls of {rhs}. ---- */
#include <math.h>
typedef double gs_lane4 __attribute__((vector_size(32)));
#define GS_L4_SPLAT(c) ((gs_lane4){{(c), (c), (c), (c)}})
#define GS_L4_1(f) static inline gs_lane4 gs_l4_##f(gs_lane4 a) {{ \\
    return (gs_lane4){{f(a[0]), f(a[1]), f(a[2]), f(a[3])}}; }}
#define GS_L4_2(f) static inline gs_lane4 gs_l4_##f(gs_lane4 a, gs_lane4 b) {{ \\
    return (gs_lane4){{f(a[0], b[0]), f(a[1], b[1]), f(a[2], b[2]), f(a[3], b[3])}}; }}
#ifndef GS_VECMATH
#define GS_VECMATH 0
#endif
#if GS_VECMATH /* libmvec, as the scalar functions' batched calls (codegen.vecmath) */
#define GS_L4_V1(f) static inline gs_lane4 gs_l4_##f(gs_lane4 a) {{ \\
    return (gs_lane4)_ZGVdN4v_##f((gs_v4d)a); }}
#define GS_L4_V2(f) static inline gs_lane4 gs_l4_##f(gs_lane4 a, gs_lane4 b) {{ \\
    return (gs_lane4)_ZGVdN4vv_##f((gs_v4d)a, (gs_v4d)b); }}
{declarations}
#else
#define GS_L4_V1(f) GS_L4_1(f)
#define GS_L4_V2(f) GS_L4_2(f)
#endif
"""


#: Square roots four at a time where AVX is (IEEE, so bit-identical to sqrt per lane).
_SQRT = """#ifdef __AVX__
static inline gs_lane4 gs_l4_sqrt(gs_lane4 a) { return __builtin_ia32_sqrtpd256(a); }
#else
GS_L4_1(sqrt)
#endif"""


def lanes_symbol(rhs: ca.Function) -> str:
    """The C name of the lane version of ``rhs``."""
    return f"{rhs.name()}_lanes"


def _translate(program: list[algorithm.Instruction], used: set[str],
               kinds: tuple[str, ...], names: tuple[str, ...]) -> list[str]:
    """The statements over lanes; raises ``UnsupportedAlgorithm`` at an operation outside
    the supported subset or an input of kind ``"none"``.

    ``kinds[k]`` says how input ``k`` (C parameter ``names[k]``) is passed: ``"t"`` one value
    per lane (``t[s]``), ``"lane"`` one array per lane (``x[s][i]``), ``"shared"`` one array
    for all lanes (``p[i]``), ``"none"`` not at all (an empty input). Output ``k`` is
    written lane by lane into the parameter ``names[len(kinds) + k]`` (``xdot[s][i]``).
    """
    out = []
    for ins in program:
        if ins.op == "INPUT":
            k, i = ins.ins
            kind, a = kinds[k], names[k]
            if kind == "t":
                value = f"((gs_lane4){{{a}[0], {a}[1], {a}[2], {a}[3]}})"
            elif kind == "lane":
                value = f"((gs_lane4){{{a}[0][{i}], {a}[1][{i}], {a}[2][{i}], {a}[3][{i}]}})"
            elif kind == "shared":
                value = f"GS_L4_SPLAT({a}[{i}])"
            else:
                raise algorithm.UnsupportedAlgorithm(f"input {k} (only t, x and p are lanes)")
            out.append(f"a{ins.out[0]}={value};")
        elif ins.op == "OUTPUT":
            k, i = ins.out
            if k + len(kinds) >= len(names):
                raise algorithm.UnsupportedAlgorithm(f"output {k} (only ode is written)")
            v, r = f"a{ins.ins[0]}", names[len(kinds) + k]
            out.append(f"{r}[0][{i}] = {v}[0]; {r}[1][{i}] = {v}[1]; "
                       f"{r}[2][{i}] = {v}[2]; {r}[3][{i}] = {v}[3];")
        elif ins.op == "CONST":
            out.append(f"a{ins.out[0]}=GS_L4_SPLAT({algorithm.c_constant(ins.value)});")
        elif ins.op in ARITHMETIC:
            out.append(f"a{ins.out[0]}=" + ARITHMETIC[ins.op].format(*(f"a{i}" for i in ins.ins)) + ";")
        elif ins.op in _CALLS:
            name = _CALLS[ins.op]
            used.add(name)
            out.append(f"a{ins.out[0]}=gs_l4_{name}({','.join(f'a{i}' for i in ins.ins)});")
        else:
            raise algorithm.UnsupportedAlgorithm(f"operation {ins.op} has no lane version")
    return out


def rhs_lanes_c(rhs: ca.Function) -> str | None:
    """``rhs_lanes(rhs)``'s C source, or None when ``rhs`` has no lane version."""
    code, _ = rhs_lanes(rhs)
    return code


def rhs_lanes(rhs: ca.Function) -> tuple[str | None, str]:
    """C source of ``int <rhs>_lanes(const double* t, const double* const* x,
    const double* p, double* const* xdot)`` (four states ``x[0..3]`` at times ``t[0..3]``,
    results into ``xdot[0..3]``; returns 0) and ``"applied"``; or None and the reason why
    ``rhs`` has no lane version (an operation outside the supported subset, see the module's
    docstring).

    ``rhs`` has CasADi's DAE signature ``(t, x, z, p, u) -> (ode, alg, quad, zero)`` with
    empty z, u, alg, quad and zero, as ``functions.sx_model`` makes it.
    """
    if (rhs.n_in() != 5 or rhs.n_out() != 4 or any(rhs.nnz_in(k) for k in (2, 4))
            or any(rhs.nnz_out(k) for k in (1, 2, 3)) or not rhs.sparsity_out(0).is_dense()):
        return None, "not a DAE right-hand side (t, x, z, p, u) -> ode with empty z, u, alg"
    return function_lanes(rhs, lanes_symbol(rhs), ("t", "lane", "none", "shared", "none"),
                          ("t", "x", "z", "p", "u", "xdot"))


def _once(g: str, helper: str) -> str:
    """``helper`` (the lane version of ``g``) defined once per C file, however many lane
    functions the file holds."""
    return f"#ifndef GS_L4_HAVE_{g}\n#define GS_L4_HAVE_{g}\n{helper}\n#endif"


def function_lanes(f: ca.Function, symbol: str, kinds: tuple[str, ...],
                   names: tuple[str, ...]) -> tuple[str | None, str]:
    """C source of ``int <symbol>(...)``: ``f`` at four points at once (see ``_translate``
    for ``kinds`` and ``names``; inputs of kind ``"none"`` are not parameters, outputs past
    ``names`` are not written) and ``"applied"``; or None and why ``f`` has no lane version.
    """
    used: set[str] = set()
    try:
        program = share_reciprocals(algorithm.read(f))
        body = _translate(program, used, kinds, names)
    except algorithm.UnsupportedAlgorithm as exc:
        return None, str(exc)
    n = algorithm.n_work(program)
    decls = [f"gs_lane4 {', '.join(f'a{k}' for k in range(j, min(j + 12, n)))};" for j in range(0, n, 12)]
    body = decls + body
    helpers = []
    vec = {g for g in used if g in vecmath.VECTOR_FUNCTIONS}
    helpers += [_once(g, _SQRT if g == "sqrt" else f"GS_L4_{'V' if g in vec else ''}1({g})")
                for g in UNARY if g in used]
    helpers += [_once(g, f"GS_L4_{'V' if g in vec else ''}2({g})") for g in BINARY if g in used]
    ctype = {"t": "const double* ", "shared": "const double* ", "lane": "const double* const* "}
    params = [ctype[k] + a for k, a in zip(kinds, names) if k != "none"]
    params += [f"double* const* {a}" for a in names[len(kinds):]]
    sig = f"int {symbol}({', '.join(params)})"
    prelude = _PRELUDE.format(symbol=symbol, rhs=f.name(),
                              declarations=vecmath.vector_declarations(vec))
    return (prelude + "\n".join(helpers) + "\n"
            + sig + " {\n" + "\n".join("  " + s for s in body) + "\n  return 0;\n}\n"), "applied"
