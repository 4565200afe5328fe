"""Batch the libm calls of generated C four at a time, for glibc's vector math library.

CasADi's C for an SX function is straight-line code with one libm call per statement
(``a12=sin(a6);``). Calls of one function that do not depend on each other can run four at
a time as one call of glibc's AVX2 vector function (``_ZGVdN4v_sin``, libmvec): about the
cost of one scalar call for four values. :func:`batch_libm_calls` rewrites every such
function of a C file in single-assignment form (``v12=sin(v6)`` style names), groups the
independent calls in fours (see ``_batch_body``) and emits each group as one macro call
(``GS_VM1_3(sin, v12, v6, v40, v33, v51, v47);``). The macros are defined at the top of the
file:

- compiled with ``-DGS_VECMATH=1`` (``codegen.compiler`` does so on an x86-64-v3 CPU whose
  glibc has libmvec, and links it) a group is one vector call;
- otherwise each macro makes the scalar calls, in the original order of the arguments: the
  code computes what it computed before, bit for bit.

Every call of a function in :data:`VECTOR_FUNCTIONS` is rewritten, a lone one too (a group
of one), so that with ``GS_VECMATH`` a value goes through the same vector function wherever
it occurs: the 4-lane right-hand side (``codegen.lanes``) uses it too, and stays
bit-identical to the scalar right-hand side. libmvec's functions are accurate to 4 ulp
(glibc's manual) instead of the scalar functions' 1; ``tests/test_vecmath.py`` measures it.

A function body with anything but assignments, declarations and guarded stores (loops,
work arrays) is left as it is.
"""
from __future__ import annotations

import heapq
import re

__all__ = ["VECTOR_FUNCTIONS", "batch_libm_calls", "vector_declarations"]

#: Functions with a 4-lane AVX2 version in glibc's libmvec (since glibc 2.35), by arity.
VECTOR_FUNCTIONS: dict[str, int] = {
    **dict.fromkeys(("sin", "cos", "tan", "asin", "acos", "atan", "sinh", "cosh", "tanh",
                     "asinh", "acosh", "atanh", "exp", "log", "log1p", "expm1", "erf"), 1),
    "atan2": 2, "pow": 2,
}
#: Largest group: four doubles in an AVX2 register.
WIDTH = 4

_BODY = re.compile(
    r"^(static int casadi_f\d+\(const casadi_real\*\* arg, casadi_real\*\* res, "
    r"casadi_int\* iw, casadi_real\* w, int mem\) \{\n)(.*?)(\n  return 0;\n\}\n)",
    re.S | re.M)
_DEF = re.compile(r"^(a\d+)=")
_CALL1 = re.compile(r"^(a\d+)=(\w+)\((a\d+)\);$")
_CALL2 = re.compile(r"^(a\d+)=(\w+)\((a\d+),(a\d+)\);$")
_STORE = re.compile(r"^if \(res\[\d+\]!=0\) res\[\d+\]\[\d+\]=a\d+;$")
_DECL = re.compile(r"^casadi_real [a\d, ]+;$")
_VAR = re.compile(r"\ba\d+\b")


def _macro(arity: int, n: int, vector: bool) -> str:
    """``GS_VM<arity>_<n>(f, r0, x0[, y0], r1, ...)``: n results from n argument tuples."""
    args = [f"x{i}" if arity == 1 else f"x{i}, y{i}" for i in range(n)]
    params = ", ".join(f"r{i}, {a}" for i, a in enumerate(args))
    head = f"#define GS_VM{arity}_{n}(f, {params})"
    if not vector:
        calls = " ".join(f"r{i} = f({a});" for i, a in enumerate(args))
        return f"{head} do {{ {calls} }} while (0)"
    pad = [f"x{min(i, n - 1)}" for i in range(WIDTH)]
    vec = f"_mm256_setr_pd({', '.join(pad)})"
    if arity == 2:
        vec2 = f"_mm256_setr_pd({', '.join(p.replace('x', 'y') for p in pad)})"
        call = f"_ZGVdN4vv_##f({vec}, {vec2})"
    else:
        call = f"_ZGVdN4v_##f({vec})"
    copies = " ".join(f"r{i} = gs_vm_o[{i}];" for i in range(n))
    return (f"{head} do {{ double gs_vm_o[4]; _mm256_storeu_pd(gs_vm_o, {call}); "
            f"{copies} }} while (0)")


def vector_declarations(names) -> str:
    """``extern`` declarations of libmvec's 4-lane versions of ``names`` (needs immintrin.h)."""
    out = []
    for f in sorted(names):
        if VECTOR_FUNCTIONS[f] == 1:
            out.append(f"extern __m256d _ZGVdN4v_{f}(__m256d);")
        else:
            out.append(f"extern __m256d _ZGVdN4vv_{f}(__m256d, __m256d);")
    return "\n".join(out)


def _prelude(used: set[str]) -> str:
    lines = ["/* ---- libm calls in groups of up to four (grasping_sym.codegen.vecmath): with",
             " * GS_VECMATH one call of glibc's libmvec per group, else the scalar calls. ---- */",
             "#ifndef GS_VECMATH", "#define GS_VECMATH 0", "#endif", "#include <math.h>",
             "#if GS_VECMATH", "#include <immintrin.h>", vector_declarations(used)]
    lines += [_macro(a, n, True) for a in (1, 2) for n in range(1, WIDTH + 1)]
    lines += ["#else"]
    lines += [_macro(a, n, False) for a in (1, 2) for n in range(1, WIDTH + 1)]
    lines += ["#endif", ""]
    return "\n".join(lines)


def _batch_body(stmts: list[str], used: set[str]) -> list[str] | None:
    """The statements in single-assignment form with the libm calls grouped, or None when
    the body is not plain straight-line code.

    CasADi reuses its variables (``a6=cos(a6);``) and loads inputs just before their
    first use, so the calls are grouped on the dependency graph: every assignment gets its
    own variable; a call's *depth* is the largest number of vector-function calls on a
    dependency path ending at it (itself included), so calls of one function at one depth
    never depend on each other; those are grouped (in fours, in their original order), and
    the statements are emitted in a topological order that keeps the original order where
    it can (each group at once, when the last argument of its members is known).
    """
    version: dict[str, str] = {}
    nodes = []  # (text with {0}, {1}... for the used variables, uses, target, call)
    depth: dict[str, int] = {}
    n_calls = 0
    for s in stmts:
        if not s or _DECL.match(s):
            continue
        store = _STORE.match(s)
        d = _DEF.match(s)
        if (store is None and d is None) or not s.endswith(";") or s.count(";") != 1:
            return None
        rhs = s if store else s.partition("=")[2]
        uses = [version[v] for v in _VAR.findall(rhs) if v in version]
        if len(uses) != len(_VAR.findall(rhs)):
            return None  # a variable read before it is assigned: not CasADi's usual code
        tmpl = _VAR.sub("{}", rhs.replace("{", "{{").replace("}", "}}"))
        target = None
        call = None
        if d is not None:
            target = f"v{len(nodes)}"
            m = _CALL1.match(s) or _CALL2.match(s)
            if m and VECTOR_FUNCTIONS.get(m.group(2)) == len(m.groups()) - 2:
                call = m.group(2)
                n_calls += 1
            depth[target] = max((depth[u] for u in uses), default=0) + (1 if call else 0)
            version[d.group(1)] = target
        nodes.append((tmpl, uses, target, call))
    if not n_calls:
        return None
    # groups: calls of one function at one depth, in fours, in program order
    groups: dict[tuple[str, int], list[list[int]]] = {}
    for i, (_, _, target, call) in enumerate(nodes):
        if call:
            gl = groups.setdefault((call, depth[target]), [[]])
            if len(gl[-1]) == WIDTH:
                gl.append([])
            gl[-1].append(i)
    unit = list(range(len(nodes)))  # node -> its scheduling unit (a group's first member)
    members: dict[int, list[int]] = {}
    for gl in groups.values():
        for g in gl:
            members[g[0]] = g
            for i in g:
                unit[i] = g[0]
    defined_by = {target: i for i, (_, _, target, _) in enumerate(nodes) if target}
    deps: dict[int, set[int]] = {u: set() for u in set(unit)}
    users: dict[int, set[int]] = {u: set() for u in deps}
    for i, (_, uses, _, _) in enumerate(nodes):
        for v in uses:
            a, b = unit[defined_by[v]], unit[i]
            if a != b:
                deps[b].add(a)
                users[a].add(b)
    ready = [u for u, ds in deps.items() if not ds]
    heapq.heapify(ready)
    names = [target for _, _, target, _ in nodes if target]
    out = [f"casadi_real {', '.join(names[k:k + 12])};" for k in range(0, len(names), 12)]
    n_decl = len(out)
    while ready:
        u = heapq.heappop(ready)
        if u in members:
            g = members[u]
            fname = nodes[u][3]
            used.add(fname)
            parts = ", ".join(", ".join([nodes[i][2], *nodes[i][1]]) for i in g)
            out.append(f"GS_VM{VECTOR_FUNCTIONS[fname]}_{len(g)}({fname}, {parts});")
        else:
            tmpl, uses, target, _ = nodes[u]
            text = tmpl.format(*uses)
            out.append(f"{target}={text}" if target else text)
        for w in users[u]:
            deps[w].discard(u)
            if not deps[w]:
                heapq.heappush(ready, w)
    if len(out) - n_decl != len(deps):  # a cycle: cannot arise (see above), but never emit
        return None                     # a partial body
    return out


def batch_libm_calls(code: str) -> str:
    """``code`` (a CasADi-generated C file) with the libm calls of its functions grouped
    (see the module's docstring) and the macros' prelude inserted before the first function;
    ``code`` itself when nothing was grouped."""
    used: set[str] = set()

    def one(m: re.Match) -> str:
        stmts = [ln.strip() for ln in m.group(2).split("\n")]
        new = _batch_body(stmts, used)
        if new is None:
            return m.group(0)
        return m.group(1) + "\n".join("  " + s for s in new) + m.group(3)

    out = _BODY.sub(one, code)
    if not used:
        return code
    first = _BODY.search(out)
    return out[:first.start()] + _prelude(used) + "\n" + out[first.start():]
