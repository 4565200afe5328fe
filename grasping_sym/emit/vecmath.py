"""Batch the libm calls of generated C four at a time, for glibc's vector math library.

An SX function is a straight-line program with one libm call per call instruction
(``codegen.algorithm``, read through CasADi's instruction API; CasADi prints it as
``a12=sin(a6);``). Calls of one function that do not depend on each other can run four at a
time as one call of glibc's AVX2 vector function (``_ZGVdN4v_sin``, libmvec): about the cost
of one scalar call for four values. :func:`batch_libm_calls` writes the body of every such
function of a C file anew from its instructions, in single-assignment form (``v12=sin(v6)``
style names), groups the independent calls in fours (see ``_batch_body``) and emits each
group as one macro call (``GS_VM1_3(sin, v12, v6, v40, v33, v51, v47);``). The macros are
defined at the top of the file:

- compiled with ``-DGS_VECMATH=1`` (``codegen.compiler`` does so on an x86-64-v3 CPU whose
  glibc has libmvec, and links it) a group is one vector call;
- otherwise each macro makes the scalar calls, in the original order of the arguments: the
  code computes what it computed before, bit for bit.

Every call of a function in :data:`VECTOR_FUNCTIONS` is rewritten, a lone one too (a group
of one), so that with ``GS_VECMATH`` a value goes through the same vector function wherever
it occurs: the 4-lane right-hand side (``codegen.lanes``) uses it too, and stays
bit-identical to the scalar right-hand side. libmvec's functions are accurate to 4 ulp
(glibc's manual) instead of the scalar functions' 1; ``tests/test_vecmath.py`` measures it.

CasADi's file gives each function's body in a ``casadi_f<k>`` that its exported wrapper
names; the rewrite replaces those bodies, and refuses (``VecmathError``) when the file does
not hold a body and a wrapper per function, rather than falling back silently to the scalar
code. A function that calls other functions (call nodes, e.g. splines) keeps CasADi's body.
"""
from __future__ import annotations

import heapq
import re
from typing import TYPE_CHECKING

from grasping_sym.emit import algorithm
from grasping_sym.emit.reciprocals import share_reciprocals
from grasping_sym.store.platform import VECTOR_FUNCTIONS

if TYPE_CHECKING:  # the rewrite reads CasADi's functions; the runtime (compiler flags) does not
    from grasping_sym.emit import algorithm

__all__ = ["VECTOR_FUNCTIONS", "VecmathError", "batch_libm_calls", "vector_declarations"]

#: Largest group: four doubles in an AVX2 register.
WIDTH = 4

#: The exported wrapper of a function, naming the ``casadi_f<k>`` that holds its body.
_WRAPPER = re.compile(r"^CASADI_SYMBOL_EXPORT int (\w+)\(const casadi_real\*\* arg, casadi_real\*\* res, "
                      r"casadi_int\* iw, casadi_real\* w, int mem\)\{\n  return casadi_f(\d+)\(", re.M)
#: Where CasADi's file puts the body of its k-th function (only located, never parsed).
_BODY = re.compile(
    r"^(static int casadi_f(\d+)\(const casadi_real\*\* arg, casadi_real\*\* res, "
    r"casadi_int\* iw, casadi_real\* w, int mem\) \{\n)(.*?)(\n  return 0;\n\}\n)",
    re.S | re.M)


class VecmathError(RuntimeError):
    """CasADi's file does not have the layout the rewrite places bodies into."""


def _macro(arity: int, n: int, vector: bool) -> str:
    """``GS_VM<arity>_<n>(f, r0, x0[, y0], r1, ...)``: n results from n argument tuples."""
    args = [f"x{i}" if arity == 1 else f"x{i}, y{i}" for i in range(n)]
    params = ", ".join(f"r{i}, {a}" for i, a in enumerate(args))
    head = f"#define GS_VM{arity}_{n}(f, {params})"
    if not vector:
        calls = " ".join(f"r{i} = f({a});" for i, a in enumerate(args))
        return f"{head} do {{ {calls} }} while (0)"
    pad = [f"x{min(i, n - 1)}" for i in range(WIDTH)]
    vec = f"((gs_v4d){{{', '.join(pad)}}})"
    if arity == 2:
        vec2 = f"((gs_v4d){{{', '.join(p.replace('x', 'y') for p in pad)}}})"
        call = f"_ZGVdN4vv_##f({vec}, {vec2})"
    else:
        call = f"_ZGVdN4v_##f({vec})"
    copies = " ".join(f"r{i} = gs_vm_o[{i}];" for i in range(n))
    return f"{head} do {{ gs_v4d gs_vm_o = {call}; {copies} }} while (0)"


#: Four doubles in an AVX register, as GCC and clang's vector extension writes them (the
#: type of ``__m256d``, without ``immintrin.h``: 64k lines that cost gcc 0.15 s per file).
V4D_TYPEDEF = ("#ifndef GS_V4D_DEFINED\n#define GS_V4D_DEFINED\n"
               "typedef double gs_v4d __attribute__((vector_size(32)));\n#endif")


def vector_declarations(names) -> str:
    """``extern`` declarations of libmvec's 4-lane versions of ``names`` (and the vector type
    ``gs_v4d`` they take)."""
    out = [V4D_TYPEDEF]
    for f in sorted(names):
        if VECTOR_FUNCTIONS[f] == 1:
            out.append(f"extern gs_v4d _ZGVdN4v_{f}(gs_v4d);")
        else:
            out.append(f"extern gs_v4d _ZGVdN4vv_{f}(gs_v4d, gs_v4d);")
    return "\n".join(out)


def _prelude(used: set[str]) -> str:
    lines = ["/* ---- libm calls in groups of up to four (grasping_sym.emit.vecmath): with",
             " * GS_VECMATH one call of glibc's libmvec per group, else the scalar calls. ---- */",
             "#ifndef GS_VECMATH", "#define GS_VECMATH 0", "#endif", "#include <math.h>",
             "#if GS_VECMATH", vector_declarations(used)]
    lines += [_macro(a, n, True) for a in (1, 2) for n in range(1, WIDTH + 1)]
    lines += ["#else"]
    lines += [_macro(a, n, False) for a in (1, 2) for n in range(1, WIDTH + 1)]
    lines += ["#endif", ""]
    return "\n".join(lines)


def _nodes(program: list[algorithm.Instruction]):
    """One node per instruction: ``(C text with {} for the variables used, the variables used,
    the variable defined or None for a store, the vector function called or None)``, every
    definition a new variable (``v<k>``), and each variable's call depth."""
    version: dict[int, str] = {}   # work index -> current variable
    depth: dict[str, int] = {}
    nodes = []
    for ins in program:
        call = None
        if ins.op == "OUTPUT":
            k, i = ins.out
            nodes.append((f"if (res[{k}]!=0) res[{k}][{i}]={{}};", [version[ins.ins[0]]], None, None))
            continue
        if ins.op == "INPUT":
            k, i = ins.ins
            text, uses = f"arg[{k}]? arg[{k}][{i}] : 0", []
        elif ins.op == "CONST":
            text, uses = algorithm.c_constant(ins.value), []
        else:
            uses = [version[w] for w in ins.ins]
            text = algorithm.C_SCALAR[ins.op].format(*["{}"] * len(uses))
            fname = algorithm.LIBM_CALLS.get(ins.op)
            if fname in VECTOR_FUNCTIONS and VECTOR_FUNCTIONS[fname] == len(uses):
                call = fname
        target = f"v{len(nodes)}"
        depth[target] = max((depth[u] for u in uses), default=0) + (1 if call else 0)
        version[ins.out[0]] = target
        nodes.append((text, uses, target, call))
    return nodes, depth


def _batch_body(program: list[algorithm.Instruction], used: set[str],
                force: bool = False) -> list[str] | None:
    """The function's statements in single-assignment form with the libm calls grouped, or
    None when it calls no vector function (and ``force`` is false).

    CasADi reuses its work variables and loads inputs just before their first use, so the
    calls are grouped on the dependency graph: every assignment gets its own variable; a
    call's *depth* is the largest number of vector-function calls on a dependency path ending
    at it (itself included), so calls of one function at one depth never depend on each
    other; those are grouped (in fours, in their original order), and the statements are
    emitted in a topological order that keeps the original order where it can (each group at
    once, when the last argument of its members is known).
    """
    nodes, depth = _nodes(program)
    if not force and not any(call for *_, call in nodes):
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
            out.append(f"{target}={text};" if target else text)
        for w in users[u]:
            deps[w].discard(u)
            if not deps[w]:
                heapq.heappush(ready, w)
    if len(out) - n_decl != len(deps):  # a cycle: cannot arise (see above), but never emit
        return None                     # a partial body
    return out


def batch_libm_calls(code: str, functions) -> tuple[str, dict[str, int]]:
    """``code`` (a CasADi-generated C file holding ``functions``) with the libm calls of each
    function grouped (see the module's docstring) and the macros' prelude inserted before the
    first function; and, per function name, the number of vector-function calls now in
    groups (0: none to group, or calls of other functions: its body left as CasADi wrote it).
    """

    bodies = {m.group(2): m for m in _BODY.finditer(code)}
    index = {m.group(1): m.group(2) for m in _WRAPPER.finditer(code)}
    missing = [f.name() for f in functions if index.get(f.name()) not in bodies]
    if missing:
        raise VecmathError(
            f"CasADi's C has no wrapper and body (casadi_f<k>) for {missing}: its layout changed; "
            "turn the rewrite off with GRASPING_SYM_VECMATH=off and report it")
    used: set[str] = set()
    report: dict[str, int] = {}
    new_bodies: dict[str, list[str]] = {}
    for f in functions:
        try:
            program = algorithm.read(f)
            shared = share_reciprocals(program)
            stmts = _batch_body(shared, used, force=shared is not program)
        except algorithm.UnsupportedAlgorithm:
            stmts = None
        report[f.name()] = 0 if stmts is None else sum(
            int(re.match(r"GS_VM\d_(\d)", t).group(1)) for t in stmts if t.startswith("GS_VM"))
        if stmts is not None:
            new_bodies[index[f.name()]] = stmts
    out, last = [], 0
    for k, m in sorted(bodies.items(), key=lambda item: item[1].start()):
        out.append(code[last:m.start()])
        stmts = new_bodies.get(k)
        out.append(m.group(0) if stmts is None else
                   m.group(1) + "\n".join("  " + t for t in stmts) + m.group(4))
        last = m.end()
    out.append(code[last:])
    text = "".join(out)
    if not used:  # bodies rewritten for their reciprocals only (codegen.reciprocals)
        return text, report
    first = _BODY.search(text)
    return text[:first.start()] + _prelude(used) + "\n" + text[first.start():], report
