"""The structure layer: a scene's closed loop as compiled functions of its values at the
contacts, shared by every shape.

What every structure is, 2D or 3D: a spec that keys its code (:class:`StructureSpec`: key,
digest, name), its functions with what the model glue needs to call them
(:class:`StructureFunctions`), its contact slots (:class:`Slot`) and how its functions take
the model's values (:class:`Layout`), and the cutting of their inputs to what they read
(:func:`prune_inputs`). How a structure is derived differs by kind: the planar one here, from
its template; the 3D one in ``structure3d``, from the scene with its surfaces' jets.

A planar template (``functions.Template``) is the closed loop as a function of ``(x, q, L)``,
``L`` the abstract contour functions at the contact (``derive.contour_functions``). A
*structure* fixes what the code of the closed loop depends on besides the contours:

- the template (one shared contact parameter or two, gravity, the number of fingers);
- the values of the parameters folded in as constants, and the order of the run-time
  inputs ``p`` (the scene's run-time parameters, then the start's);
- which contour leaves are exactly 0 or 1 for every shape of the scene (a unit-speed contour's
  ``speed`` and ``dspeed``, a circle's ``dkappa``), folded in too;
- the outputs.

Its functions take the remaining leaves ``L`` (and, for derivatives, their derivatives
``dL`` along the contact parameters) and the joint torques ``tau`` (the controller layer's,
``assemble.controller``) as inputs:

- ``<s>_rhs (t, x, p, L, tau) -> xdot``
- ``<s>_jac (t, x, p, L, dL, tau) -> (dxdot/dx, dxdot/dp, dxdot/dtau)``; a Jacobian of more
  than ``SPLIT_JACOBIAN`` instructions is two functions instead, ``<s>_jac`` ``-> dxdot/dx``
  (its first columns) and ``<s>_jac2`` ``-> (the other columns, dxdot/dp, dxdot/dtau)``, which
  the writer puts in separate C files, compiled side by side;
- ``<s>_outputs (x, p, L, tau) -> y``
- ``<s>_constraints (x, p, L, dL, tau) -> (C, dC/dx, Cdot, dCdot/dv)``
- ``<s>_start (x, p, L, dL, tau) -> (G, dG/dx)``

(each cut to the entries of ``L``, ``dL`` and ``tau`` it reads: ``prune_inputs``).

The derivatives through the contours are exact to first order: each leaf enters as
``L + dL (u - u*)`` with ``u*`` a copy of its contact parameter, which is set equal to ``u``
after differentiation (CasADi then drops the vanishing terms). A shape's own code
(``layered.py``) evaluates ``L`` and ``dL``; the structure is compiled once
(``<cache root>/structures/``) and linked into every model library that uses it.
"""
from __future__ import annotations

import hashlib
from dataclasses import dataclass

import casadi as ca
import sympy as sp

from grasping_sym.assemble.functions import (
    FUNCTION_OPTIONS,
    Template,
    _families,
    constraint_expressions,
    planar_constraint_names,
)

__all__ = ["CONTOUR_LEAVES", "LAYOUTS", "SURFACE_JETS", "Layout", "PlanarStructureSpec", "Slot",
           "StructureFunctions", "StructureSpec", "fold_pattern", "needed_entries", "prune_inputs",
           "structure_functions", "structure_name"]


# -- what every structure is: its spec, its functions, how they take the model's values -----

class StructureSpec:
    """What a structure's code depends on, as text: every kind of structure names itself by a
    versioned ``TAG`` and gives the rest as :meth:`body` (frozen dataclasses:
    :class:`PlanarStructureSpec`, ``structure3d.Grasp3DStructureSpec``)."""

    TAG = ""

    def body(self) -> str:
        raise NotImplementedError

    def key(self) -> str:
        return f"{self.TAG}|{self.body()}"

    def digest(self, extra: str) -> str:
        """The structure's hash, given what else its code depends on (sources, versions)."""
        return hashlib.sha256(f"{self.key()}|{extra}".encode()).hexdigest()

    def name(self, extra: str) -> str:
        """The structure's C prefix (:func:`structure_name` of its digest)."""
        return structure_name(self.digest(extra))


def structure_name(digest: str) -> str:
    """``gs_structure_<hash12>``: a symbol name never means two codes."""
    return f"gs_structure_{digest[:12]}"


@dataclass(frozen=True)
class Slot:
    """A contour slot (finger ``i``'s fingertip, then the object, contact by contact): the
    states holding its contact coordinates (2D: ``u``; 3D: ``u, v``) and the entries of its
    values the structure takes (2D: its leaves' indices in its family, those not folded; 3D:
    its whole surface jet, ``range(jet_size)``)."""

    states: tuple[int, ...]
    entries: tuple[int, ...]


@dataclass(frozen=True)
class Layout:
    """How a kind of structure's functions take what the model's own functions supply: the
    one thing composing a 2D and a 3D model in layers differs in, as data
    (``layered.compose_layered``).

    The values at the contact slots come from the model's functions
    ``<scene>_<what>_<kind>`` (``what``: ``contours``, the leaves ``L`` and their derivatives
    ``dL``; or ``jets``, the surfaces' jets ``J``); the controller's torques enter either as
    an input ``tau`` of their own, cut to the entries the function reads (``torques_in_p``
    False), or after the structure's parameters in its ``p``."""

    what: str
    #: the key of ``structure.json`` that holds what each function reads
    entries_key: str
    #: None: that key maps each function to its entries by input (``{"L": [...], "dL": [...],
    #: "tau": [...]}``) and a slot is stored as ``[state, [entries]]``; else the one input it
    #: maps each function's entries of, as a list, a slot stored as ``[states..., size]``
    single_input: str | None
    torques_in_p: bool
    #: operation counts: the controller's instructions apart (2D), or within the jets' count
    #: beside the rhs's jets (3D: as the committed manifests record them)
    controller_apart: bool


CONTOUR_LEAVES = Layout("contours", "leaf_entries", None, torques_in_p=False, controller_apart=True)
SURFACE_JETS = Layout("jets", "jet_entries", "J", torques_in_p=True, controller_apart=False)
#: by the key of ``structure.json`` that says which it is
LAYOUTS = {layout.entries_key: layout for layout in (CONTOUR_LEAVES, SURFACE_JETS)}


@dataclass
class StructureFunctions:
    """A structure's SX functions and what the model glue needs to call them."""

    name: str
    rhs: ca.Function
    jac: ca.Function | None
    outputs: ca.Function | None
    constraints: ca.Function
    start: ca.Function | None
    layout: Layout
    slots: tuple[Slot, ...]
    #: per function kind, per input it takes of the model's values (``L``, ``dL``, ``tau``;
    #: ``J``), the entries it reads (``prune_inputs``)
    reads: dict[str, dict[str, tuple[int, ...]]]
    output_names: tuple[str, ...]
    constraint_info: dict
    start_names: tuple[str, ...]
    #: how many contour values the functions take (2D: ``L``; 3D: the jets ``J``)
    n_leaves: int = 0
    #: ``(kinds, names)`` of the 4-lane rhs (``lanes.function_lanes``), None: no lanes
    lanes: tuple | None = None
    #: the second part of a split Jacobian (same inputs as ``jac``; see the module docstring)
    jac2: ca.Function | None = None

    def by_kind(self) -> tuple:
        """(kind, function) pairs, every kind, None where the structure has none."""
        return (("rhs", self.rhs), ("jac", self.jac), ("jac2", self.jac2),
                ("outputs", self.outputs), ("constraints", self.constraints),
                ("start", self.start))

    def functions(self) -> list[ca.Function]:
        return [f for _, f in self.by_kind() if f is not None]

    def kinds(self) -> dict[str, str]:
        """The C name of each function, by kind (``rhs``, ``jac``, ...)."""
        return {k: f.name() for k, f in self.by_kind() if f is not None}


def needed_entries(f: ca.Function, k: int) -> list[int]:
    """The entries of ``f``'s input ``k`` that ``f`` depends on (CasADi's structural Jacobian
    sparsity), in order."""
    outs = [f.sparsity_jac(k, o) for o in range(f.n_out()) if f.nnz_out(o)]
    return sorted(set(ca.vertcat(*outs).get_col())) if outs else []


def prune_inputs(f: ca.Function, inputs, wider: dict[int, list[int]] | None = None
                 ) -> tuple[ca.Function, dict[int, list[int]]]:
    """``f`` with each of its ``inputs`` (indices) cut to the entries ``f`` depends on
    (:func:`needed_entries`; ``wider[k]``, a superset of them, where given), and those entries
    by input index. The shape's code then computes only what each structure function reads."""
    ins = [f.sx_in(i) for i in range(f.n_in())]
    args, new_ins, kept = list(ins), list(ins), {}
    for k in inputs:
        needed = sorted((wider or {}).get(k) or needed_entries(f, k))
        sym = ca.SX.sym(f.name_in(k), len(needed))
        full = ca.SX.zeros(ins[k].numel(), 1)
        for j, c in enumerate(needed):
            full[c] = sym[j]
        args[k], new_ins[k], kept[k] = full, sym, needed
    names_in = [f.name_in(i) for i in range(f.n_in())]
    names_out = [f.name_out(i) for i in range(f.n_out())]
    return (ca.Function(f.name(), new_ins, f.call(args), names_in, names_out, FUNCTION_OPTIONS),
            kept)


# -- the planar structure: its spec and its derivation from a template -----------------------

def fold_pattern(concrete: list[dict]) -> tuple[tuple[tuple[int, int], ...], ...]:
    """Per contour slot (``concrete``: each slot's leaf -> SymPy expression, in the order of
    its family's ``leaves()``), the leaves that are exactly 0 or 1: ``(index, value)``."""
    out = []
    for leaves in concrete:
        fixed = []
        for k, expr in enumerate(leaves):
            e = sp.sympify(expr)
            if e.is_Number and e in (sp.Integer(0), sp.Integer(1)):
                fixed.append((k, int(e)))
        out.append(tuple(fixed))
    return tuple(out)


@dataclass(frozen=True)
class PlanarStructureSpec(StructureSpec):
    """What a planar structure's code depends on (see the module's docstring)."""

    TAG = "planar-structure-v2"

    shared: bool
    gravity: bool
    n_fingers: int
    inputs: tuple[str, ...]
    constants: tuple[tuple[str, float], ...]
    folded: tuple[tuple[tuple[int, int], ...], ...]
    outputs: tuple[str, ...]
    #: a free object (its mass centre a state); pivoted structures keep their old keys
    free: bool = False

    def body(self) -> str:
        consts = ";".join(f"{k}={float(v)!r}" for k, v in self.constants)
        return "|".join([repr((self.shared, self.gravity, self.n_fingers)), ",".join(self.inputs),
                         consts, repr(self.folded), ",".join(self.outputs),
                         *(["free"] if self.free else [])])


def structure_functions(template: Template, spec: PlanarStructureSpec, name: str) -> StructureFunctions:
    """The structure ``spec`` of ``template`` as SX functions named ``<name>_*``."""
    nx = len(template.state_names)
    x = ca.SX.sym("x", nx)
    t = ca.SX.sym("t")
    p = ca.SX.sym("p", len(spec.inputs))
    torques = [k for k in template.param_names if k.startswith("tau_")]
    tau = ca.SX.sym("tau", len(torques))
    constants = dict(spec.constants)
    missing = [k for k in template.param_names
               if k not in spec.inputs and k not in constants and k not in torques]
    if missing:
        raise ValueError(f"no value for template parameters {missing}")
    q = ca.vertcat(*[p[spec.inputs.index(k)] if k in spec.inputs else
                     tau[torques.index(k)] if k in torques else ca.SX(constants[k])
                     for k in template.param_names])
    families = _families(len(template.contact_index))
    slot_states = [i for pair in template.contact_index for i in pair]
    slot_sizes = [len(fns.leaves()) for pair in families for fns in pair]
    if len(spec.folded) != len(slot_states):
        raise ValueError(f"fold pattern for {len(spec.folded)} contour slots; the template has "
                         f"{len(slot_states)}")
    slots = []
    for i, size, fixed in zip(slot_states, slot_sizes, spec.folded):
        held = dict(fixed)
        slots.append(Slot((i,), tuple(k for k in range(size) if k not in held)))
    n_leaves = sum(len(slot.entries) for slot in slots)
    L = ca.SX.sym("L", n_leaves)
    dL = ca.SX.sym("dL", n_leaves)
    u_copy = ca.SX.sym("u_copy", len(slots))
    taylor, j = [], 0
    for s, (slot, size, fixed) in enumerate(zip(slots, slot_sizes, spec.folded)):
        (i,), held = slot.states, dict(fixed)
        for k in range(size):
            if k in held:
                taylor.append(ca.SX(held[k]))
            else:
                taylor.append(L[j] + dL[j] * (x[i] - u_copy[s]))
                j += 1
    Lt = ca.vertcat(*taylor)
    same = ca.vertcat(*[x[slot.states[0]] for slot in slots])

    def exact(*exprs):
        return ca.substitute(list(exprs), [u_copy], [same])

    xdot_t = template.rhs(x, q, Lt)
    y_t = template.outputs(x, q, Lt)

    def out(k: str):
        return y_t[template.output_names.index(k)]

    (xdot,) = exact(xdot_t)
    Jx, Jp, Jtau = exact(ca.jacobian(xdot_t, x), ca.jacobian(xdot_t, p), ca.jacobian(xdot_t, tau))
    rhs = ca.Function(f"{name}_rhs", [t, x, p, L, tau], [xdot], ["t", "x", "p", "L", "tau"],
                      ["xdot"], FUNCTION_OPTIONS)
    jac = ca.Function(f"{name}_jac", [t, x, p, L, dL, tau], [Jx, Jp, Jtau],
                      ["t", "x", "p", "L", "dL", "tau"], ["dxdot_dx", "dxdot_dp", "dxdot_dtau"],
                      FUNCTION_OPTIONS)
    outputs = None
    if spec.outputs:
        (y,) = exact(ca.vertcat(*[out(k) for k in spec.outputs]))
        outputs = ca.Function(f"{name}_outputs", [x, p, L, tau], [y], ["x", "p", "L", "tau"],
                              ["y"], FUNCTION_OPTIONS)
    names = planar_constraint_names(template.output_names)
    C_t = ca.vertcat(*[out(k) for k in names])
    con, info = constraint_expressions(x, xdot_t, C_t, names)
    constraints = ca.Function(f"{name}_constraints", [x, p, L, dL, tau], exact(*con),
                              ["x", "p", "L", "dL", "tau"], ["C", "dC_dx", "Cdot", "dCdot_dv"],
                              FUNCTION_OPTIONS)
    tangency = tuple(k for k in template.output_names if k.startswith("tangency_defect"))
    G_t = ca.vertcat(C_t, *[out(k) for k in tangency])
    start = ca.Function(f"{name}_start", [x, p, L, dL, tau],
                        exact(G_t, ca.densify(ca.jacobian(G_t, x))),
                        ["x", "p", "L", "dL", "tau"], ["G", "dG_dx"], FUNCTION_OPTIONS)
    reads: dict[str, dict[str, tuple[int, ...]]] = {}
    pruned = {}
    for kind, f, leaf_inputs in (("rhs", rhs, (3, 4)), ("jac", jac, (3, 4, 5)),
                                 ("outputs", outputs, (2, 3)), ("constraints", constraints, (2, 3, 4)),
                                 ("start", start, (2, 3, 4))):
        if f is None:
            continue
        pruned[kind], kept = prune_inputs(f, leaf_inputs)
        reads[kind] = {f.name_in(k): tuple(kept[k]) for k in leaf_inputs}
    jac, jac2 = split_jacobian(pruned["jac"])
    return StructureFunctions(name=name, rhs=pruned["rhs"], jac=jac, jac2=jac2,
                              outputs=pruned.get("outputs"), constraints=pruned["constraints"],
                              start=pruned["start"], layout=CONTOUR_LEAVES, slots=tuple(slots),
                              reads=reads,
                              output_names=tuple(spec.outputs), constraint_info=info,
                              start_names=names + tangency, n_leaves=n_leaves,
                              lanes=(("t", "lane", "shared", "lane", "lane"),
                                     ("t", "x", "p", "L", "tau", "xdot")))


#: A structure's Jacobian of more SX instructions than this is split in two (gcc takes about
#: 0.13 s per 1000 of them at -O2, and the rest of the structure compiles in less than half).
SPLIT_JACOBIAN = 8000


def split_jacobian(jac: ca.Function) -> tuple[ca.Function, ca.Function | None]:
    """``jac`` ``-> (dxdot/dx, dxdot/dp, dxdot/dtau)`` as it is, or, above ``SPLIT_JACOBIAN``
    instructions, as two functions of the same inputs: ``<name>`` ``-> dxdot/dx[:, :k]`` and
    ``<name>2`` ``-> (dxdot/dx[:, k:], dxdot/dp, dxdot/dtau)``, ``k`` half the states."""
    if jac.n_instructions() <= SPLIT_JACOBIAN:
        return jac, None
    ins = [jac.sx_in(i) for i in range(jac.n_in())]
    names_in = [jac.name_in(i) for i in range(jac.n_in())]
    Jx, Jp, Jtau = jac.call(ins)
    k = Jx.shape[1] // 2
    first = ca.Function(jac.name(), ins, [Jx[:, :k]], names_in, ["dxdot_dx_first"], FUNCTION_OPTIONS)
    second = ca.Function(f"{jac.name()}2", ins, [Jx[:, k:], Jp, Jtau], names_in,
                         ["dxdot_dx_rest", "dxdot_dp", "dxdot_dtau"], FUNCTION_OPTIONS)
    return first, second
