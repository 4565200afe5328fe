"""Divide by a shared denominator once: ``a/d, b/d, ...`` become ``r = 1/d; a*r, b*r, ...``.

A closed loop differentiated by CasADi's AD divides many values by few denominators: the
derivatives of ``x/y`` are ``1/y`` and ``-(x/y)/y``, so every direction that passes through a
division divides by the same ``y`` again. paper3d's structure right-hand side divides 338
times by 26 distinct values. A double-precision division costs about 4 to 5 cycles of
throughput and 13 of latency on current x86-64 CPUs, a multiplication 0.5 and 3.

CasADi's SX cannot say this: it folds ``a * (1/d)`` back into ``a/d`` as it builds the
expression. So :func:`share_reciprocals` rewrites the straight-line program read through
CasADi's instruction API (``codegen.algorithm``), and the C written from that program uses
it: the scalar bodies (``codegen.vecmath``) and the 4-lane right-hand side
(``codegen.lanes``), which therefore stay bit-identical to each other.

``a*(1/d)`` may differ from ``a/d`` in the last bit (two roundings instead of one), so the
compiled functions may differ from CasADi's own evaluation by about one rounding per
division on a path; they are deterministic. A denominator divided by once keeps its
division.
"""
from __future__ import annotations

from collections import Counter

from grasping_sym.emit.algorithm import Instruction, n_work

__all__ = ["share_reciprocals"]


def share_reciprocals(program: list[Instruction], min_uses: int = 2) -> list[Instruction]:
    """``program`` with each denominator that it divides by at least ``min_uses`` times
    inverted once (``INV`` into a work index of its own, past the program's), at its first
    division, and each of those divisions a product with the inverse.

    A value is identified by its work index and how many times that index had been written
    before (CasADi reuses a work index for later values); two passes over the program, the
    first counting the divisions by each value."""
    version: dict[int, int] = {}
    uses: Counter = Counter()
    for ins in program:
        if ins.op == "DIV":
            d = ins.ins[1]
            uses[(d, version.get(d, 0))] += 1
        if ins.op != "OUTPUT":
            version[ins.out[0]] = version.get(ins.out[0], 0) + 1
    shared = {d for d, n in uses.items() if n >= min_uses}
    if not shared:
        return program
    fresh = n_work(program)
    inverse: dict[tuple[int, int], int] = {}
    version.clear()
    out = []
    for ins in program:
        if ins.op == "DIV":
            d = (ins.ins[1], version.get(ins.ins[1], 0))
            if d in shared:
                if d not in inverse:
                    inverse[d] = fresh
                    out.append(Instruction("INV", (ins.ins[1],), (fresh,)))
                    fresh += 1
                ins = Instruction("MUL", (ins.ins[0], inverse[d]), ins.out)
        if ins.op != "OUTPUT":
            version[ins.out[0]] = version.get(ins.out[0], 0) + 1
        out.append(ins)
    return out
