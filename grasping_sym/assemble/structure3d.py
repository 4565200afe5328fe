"""The structure layer of a 3D grasping scene: its closed loop compiled once, for any surfaces.

A 3D scene's closed loop (``derive.grasp3d``) reads each contour slot's surface through a
few quantities at the contact coordinates ``(u, v)``: the point ``S`` and the Montana frame
``x, y, n``, and the forms ``M, K, T`` (``derive.grasp3d.surface_sx``). The loop then
differentiates them by CasADi's AD: the constraint Jacobians once, the Baumgarte term
``bhat`` twice for ``S`` and the frame, once for the forms (they enter through the contact
rates).

The structure takes those quantities as inputs ``J``, as a *jet* per slot: their values and
their derivatives in ``(u, v)`` to second order (``S`` and the frame) or first order (the
forms). Each enters the derivation as its Taylor polynomial about a copy ``(u*, v*)`` of the
slot's coordinates; once every derivative is taken, ``(u*, v*)`` is set to ``(u, v)``, and the
polynomial's vanishing terms drop out. The result is exact: the derivatives the loop takes
are the jets' own.

A scene's own small C (``<name>_jets``, ``assemble.layered``) evaluates the jets of its
surfaces; the structure is compiled once (``assemble.structure_cache``) per everything else
the code depends on (:func:`structure_key`).
"""
from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache

import casadi as ca
import numpy as np

from grasping_sym.assemble.functions import sx_model
from grasping_sym.assemble.structure import (
    SURFACE_JETS,
    Slot,
    StructureFunctions,
    StructureSpec,
    needed_entries,
    prune_inputs,
)
from grasping_sym.derive.grasp3d import derive_grasp3d, surface_sx
from grasping_sym.geometry.surface_library import sphere
from grasping_sym.model.inertia import inertia_pattern

__all__ = ["JET_FIRST", "JET_SECOND", "Grasp3DStructureSpec", "body_values", "inertia_pattern",
           "jet_size", "jet_values", "structure3d_functions"]

#: Quantities the loop differentiates twice: second-order jets.
JET_SECOND = ("S", "x", "y", "n")
#: Quantities it differentiates once: first-order jets.
JET_FIRST = ("M", "K", "T")


@lru_cache(maxsize=1)
def _shapes() -> dict[str, tuple[int, int]]:
    """The shape of each quantity of ``surface_sx`` (read from a sphere)."""
    d = surface_sx(sphere(0.01), ca.SX.sym("u"), ca.SX.sym("v"))
    return {k: d[k].shape for k in (*JET_SECOND, *JET_FIRST)}


def _sizes() -> tuple[int, int]:
    sh = _shapes()
    n2 = sum(sh[k][0] * sh[k][1] for k in JET_SECOND)
    n1 = sum(sh[k][0] * sh[k][1] for k in JET_FIRST)
    return n2, n1


def jet_size() -> int:
    """Entries of one slot's jet: values, gradients and (for the second-order ones) the
    Hessians' ``uu, uv, vv`` entries."""
    n2, n1 = _sizes()
    return 6 * n2 + 3 * n1


def jet_values(d: dict, u, v) -> ca.SX:
    """One slot's jet, from its concrete quantities ``d`` (``surface_sx`` at ``(u, v)``), in
    the order :func:`_taylor` reads it."""
    uv = ca.vertcat(u, v)
    second = ca.vertcat(*[ca.vec(d[k]) for k in JET_SECOND])
    first = ca.vertcat(*[ca.vec(d[k]) for k in JET_FIRST])
    g2 = ca.jacobian(second, uv)
    hess = []
    for i in range(second.numel()):
        h = ca.jacobian(g2[i, :], uv)
        hess += [h[0, 0], h[0, 1], h[1, 1]]
    g1 = ca.jacobian(first, uv)
    return ca.vertcat(second, ca.vec(g2), ca.vertcat(*hess), first, ca.vec(g1))


def _taylor(jet: ca.SX, du, dv) -> dict[str, ca.SX]:
    """The quantities as Taylor polynomials in ``(du, dv)`` from one slot's jet."""
    n2, n1 = _sizes()
    k = 0
    val2 = jet[k:k + n2]
    k += n2
    g2 = ca.reshape(jet[k:k + 2 * n2], n2, 2)
    k += 2 * n2
    h2 = ca.reshape(jet[k:k + 3 * n2], 3, n2).T
    k += 3 * n2
    val1 = jet[k:k + n1]
    k += n1
    g1 = ca.reshape(jet[k:k + 2 * n1], n1, 2)
    second = (val2 + g2[:, 0] * du + g2[:, 1] * dv
              + 0.5 * h2[:, 0] * du * du + h2[:, 1] * du * dv + 0.5 * h2[:, 2] * dv * dv)
    first = val1 + g1[:, 0] * du + g1[:, 1] * dv
    out, sh = {}, _shapes()
    for keys, vec in ((JET_SECOND, second), (JET_FIRST, first)):
        j = 0
        for key in keys:
            r, c = sh[key]
            out[key] = ca.reshape(vec[j:j + r * c], r, c)
            j += r * c
    return out


def body_values(mass: float, inertia) -> list[float]:
    """The object's mass properties as the structure reads them, after the slots' jets in
    ``J``: its mass, then its inertia's diagonal, then (a full inertia) ``xy, xz, yz``."""
    H = np.asarray(inertia, dtype=float)
    off = [H[0, 1], H[0, 2], H[1, 2]]
    return [float(mass), *map(float, np.diag(H)), *(map(float, off) if inertia_pattern(H) == "full" else ())]


def _body(J: ca.SX, pattern: str) -> tuple[ca.SX, ca.SX]:
    """``(mass, inertia)`` from the body entries of ``J`` (:func:`body_values`)."""
    m, d = J[0], J[1:4]
    if pattern == "diagonal":
        return m, ca.diag(d)
    xy, xz, yz = J[4], J[5], J[6]
    return m, ca.vertcat(ca.horzcat(d[0], xy, xz), ca.horzcat(xy, d[1], yz), ca.horzcat(xz, yz, d[2]))


@dataclass(frozen=True)
class Grasp3DStructureSpec(StructureSpec):
    """What a 3D structure's code depends on: the scene's code key without its name, its
    surfaces and its object's mass properties (:meth:`model.grasp3d.GraspScene3D.structure_key`)."""

    TAG = "grasp3d-structure-v3"

    text: str

    def body(self) -> str:
        return self.text


def structure3d_functions(scene, name: str) -> StructureFunctions:
    """The structure of the 3D ``scene`` (regular formulation) as SX functions ``<name>_*``:
    the model's signatures with a last input ``J``, the entries each takes of the slots' jets
    (slot ``2 i``: contact ``i``'s fingertip, ``2 i + 1`` the object there) and, after them,
    of the object's mass properties (:func:`body_values`)."""
    n_slots = 2 * scene.n_contacts
    size = jet_size()
    pattern = inertia_pattern(scene.inertia)
    n_body = len(body_values(scene.mass, scene.inertia))
    J = ca.SX.sym("J", n_slots * size + n_body)
    ustar = ca.SX.sym("uv_copy", 2 * n_slots)
    coords = [None] * (2 * n_slots)

    def provider(slot, surface, u, v, extra):
        if extra:
            raise ValueError("the structure layer covers the regular formulation only")
        coords[2 * slot], coords[2 * slot + 1] = u, v
        return _taylor(J[slot * size:(slot + 1) * size], u - ustar[2 * slot], v - ustar[2 * slot + 1])

    system = derive_grasp3d(scene, surface_fn=provider, torque_inputs=True,
                            mass_properties=_body(J[n_slots * size:], pattern))
    same = ca.vertcat(*coords)

    def exact(*exprs):
        return ca.substitute(list(exprs), [ustar], [same])

    names = tuple(f"{q}{i}" for i in range(1, scene.n_contacts + 1) for q in ("Qn", "Qb", "Qe"))
    G = system.start_conditions
    implied = system.start_values if G and scene.start_param_names else None
    cm = sx_model(system.x, ca.vertcat(system.p, J), system.xdot,
                  {k: system.outputs[k] for k in scene.outputs}, name, jacobian=False,
                  constraints=system.constraint, constraint_names=names,
                  start_conditions=ca.vertcat(*G.values()) if G else None,
                  start_names=tuple(G), start_values=implied, exact=exact)
    index = {str(system.x[i]): i for i in range(system.x.numel())}
    slots = tuple(Slot((index[str(coords[2 * s])], index[str(coords[2 * s + 1])]), tuple(range(size)))
                  for s in range(n_slots))
    n_p = system.p.numel()
    split = {kind: _split(f, k_in, n_p) for kind, f, k_in in
             (("rhs", cm.rhs, 3), ("outputs", cm.outputs, 1), ("constraints", cm.constraints, 1),
              ("start", cm.start, 1)) if f is not None}
    needed = {kind: needed_entries(f, f.n_in() - 1) for kind, f in split.items()}
    if "outputs" in needed and _widen(needed["rhs"], needed["outputs"]):
        needed["rhs"] = needed["outputs"]
    pruned, reads = {}, {}
    for kind, f in split.items():
        pruned[kind], kept = prune_inputs(f, (f.n_in() - 1,), {f.n_in() - 1: needed[kind]})
        reads[kind] = {"J": tuple(kept[f.n_in() - 1])}
    return StructureFunctions(name=name, rhs=pruned["rhs"], jac=None, outputs=pruned.get("outputs"),
                              constraints=pruned["constraints"], start=pruned.get("start"),
                              layout=SURFACE_JETS, slots=slots, reads=reads,
                              output_names=tuple(scene.outputs), constraint_info=cm.constraint_info,
                              start_names=cm.start_names, n_leaves=n_slots * size + n_body)


#: The rhs reads the outputs' jet entries where they are all of its own and at most this
#: share more (paper3d's: 4 more than its 264; TriFinger's: 6 more than its 394).
WIDEN_SHARE = 0.05


def _widen(rhs: list[int], outputs: list[int]) -> bool:
    """Whether the rhs should read the outputs' jet entries (``WIDEN_SHARE``): the scene's
    rhs and outputs then share one jets function, whose C (a third of a new object's) is
    compiled once, not twice; the rhs computes the few entries more."""
    return set(rhs) <= set(outputs) and len(outputs) - len(rhs) <= WIDEN_SHARE * len(outputs)


def _split(f: ca.Function, k_in: int, n_p: int) -> ca.Function:
    """``f`` with its input ``k_in`` (``[p; J]``) split into the ``n_p`` parameters and, as a
    last input ``J``, the jet entries; cut by ``structure.prune_inputs`` to those it reads
    (their indices in the whole jet are the record's ``reads``): the scene's jets function
    then computes only those (the rhs needs about two thirds of them) and passes them
    without a copy."""
    ins = [f.sx_in(i) for i in range(f.n_in())]
    pe = ins[k_in]
    p, J = ca.SX.sym(f.name_in(k_in), n_p), ca.SX.sym("J", pe.numel() - n_p)
    args = list(ins)
    args[k_in] = ca.vertcat(p, J)
    new_ins = [*ins[:k_in], p, *ins[k_in + 1:], J]
    names_in = [f.name_in(i) for i in range(f.n_in())] + ["J"]
    names_out = [f.name_out(i) for i in range(f.n_out())]
    return ca.Function(f.name(), new_ins, f.call(args), names_in, names_out)
