"""CasADi functions of a derived system: closed-loop right-hand side, Jacobian, outputs.

Names (also the C symbols): ``{name}_rhs`` with CasADi's DAE signature
``(t, x, z, p, u) -> (ode, alg, quad, zero)`` so that CVODES/IDAS can use the compiled code
directly; ``jac_{name}_rhs`` (CasADi's naming rule for a compiled function's Jacobian);
``{name}_outputs`` ``(x, p) -> y``, only when outputs were requested;
``{name}_constraints`` ``(x, p) -> (C, dC_dx, Cdot, dCdot_dv)``, the position constraints, their
total time derivative along the closed loop and the Jacobians the projection of the C
integration loops uses (``runtime/projection.py``): ``dC_dx``, and ``dCdot_dv``, the columns of
dCdot/dx for the speeds (zero elsewhere; the others would cost second derivatives).
"""
from __future__ import annotations

from dataclasses import dataclass

import casadi as ca
import sympy as sp

from grasping_sym.derive.system import ConstrainedSystem, assemble
from grasping_sym.emit.casadi_model import CasadiModel
from grasping_sym.geometry.curves import T
from grasping_sym.symbolic.contour_functions import OBJECT, fingertip_functions, leaf_expressions
from grasping_sym.symbolic.translate import SympyToCasadi

#: CasADi Function options: eliminate common subexpressions in the SX graph, also in the
#: derivative functions CasADi makes from it (``rhs.jacobian()``: without it paper2d's
#: Jacobian has 5707 instructions instead of 4939).
FUNCTION_OPTIONS = {"cse": True, "der_options": {"cse": True}}
#: The planar contact constraints (template outputs, m): Q (paper (14)) and R (paper (24));
#: with several fingers ``Q1, R1, Q2, R2, ...``.
PLANAR_CONSTRAINTS = ("Q", "R")


def _casadi_backend():
    return dict(
        solve=ca.solve,
        vcat=lambda parts: ca.vertcat(*parts),
        mul=lambda a, b: a * b,
        transpose=lambda a: a.T,
    )


@dataclass
class Template:
    """A scene structure's closed loop as CasADi functions of ``(x, q, L)``.

    ``q`` holds every parameter (``param_names``), ``L`` the values at the contact of the
    abstract contour functions (``contour_functions``), contact by contact: finger ``i``'s
    fingertip's at ``x[contact_index[i][0]]`` then the object's at ``x[contact_index[i][1]]``.
    ``compose`` turns it into one
    scene's functions; the shape enters only there, so a new shape needs no derivation.
    """

    rhs: ca.Function                  # (x, q, L) -> xdot
    outputs: ca.Function              # (x, q, L) -> every output
    state_names: tuple[str, ...]
    param_names: tuple[str, ...]
    output_names: tuple[str, ...]
    contact_index: tuple[tuple[int, int], ...]

    def to_json(self) -> dict:
        return {"rhs": self.rhs.serialize(), "outputs": self.outputs.serialize(),
                "state_names": list(self.state_names), "param_names": list(self.param_names),
                "output_names": list(self.output_names),
                "contact_index": [list(c) for c in self.contact_index]}

    @classmethod
    def from_json(cls, d: dict) -> Template:
        return cls(rhs=ca.Function.deserialize(d["rhs"]),
                   outputs=ca.Function.deserialize(d["outputs"]),
                   state_names=tuple(d["state_names"]), param_names=tuple(d["param_names"]),
                   output_names=tuple(d["output_names"]),
                   contact_index=tuple(tuple(c) for c in d["contact_index"]))


def build_template(system: ConstrainedSystem) -> Template:
    """Translate a derived system into a ``Template``.

    ``system.params`` and then ``system.constants``' symbols become ``q``; every outputs of
    ``system.outputs`` is kept.
    """
    names = [str(s) for s in system.state]
    nx = len(names)
    contacts = _contact_states(names)
    qsyms = [*system.params, *system.constants]
    x = ca.SX.sym("x", nx)
    q = ca.SX.sym("q", len(qsyms))
    families = _families(len(contacts))
    L = ca.SX.sym("L", sum(len(f.leaves()) for pair in families for f in pair))
    symbols = {s: x[i] for i, s in enumerate(system.state)}
    symbols.update({s: q[i] for i, s in enumerate(qsyms)})
    slots = []  # (leaf class, its contact state index), in the order of L
    for (i0, i1), pair in zip(contacts, families):
        for fns, i in zip(pair, (i0, i1)):
            for cls in fns.leaves():
                symbols[cls(system.state[i])] = L[len(slots)]
                slots.append((cls, i))
    tr = SympyToCasadi(symbols)
    pieces = [None if mat is None else tr(mat) for mat in system.pieces()]
    if system.acc_jac is None:
        pieces[4], pieces[5] = _acceleration_terms(system, tr, x, L, slots)
    v = x[system.n:2 * system.n]
    xdot, mu = assemble(system.n, v, pieces, **_casadi_backend())
    for i, m in enumerate(system.multipliers):
        tr.memo[m] = mu[i]
    out_names = tuple(system.outputs)
    y = ca.vertcat(*[tr(system.outputs[k]) for k in out_names]) if out_names else ca.SX(0, 1)
    return Template(
        rhs=ca.Function("template_rhs", [x, q, L], [xdot], ["x", "q", "L"], ["xdot"]),
        outputs=ca.Function("template_outputs", [x, q, L], [y], ["x", "q", "L"], ["y"]),
        state_names=tuple(names), param_names=tuple(str(s) for s in qsyms),
        output_names=out_names, contact_index=tuple(contacts),
    )


def _acceleration_terms(system: ConstrainedSystem, tr: SympyToCasadi, x: ca.SX, L: ca.SX,
                        slots: list) -> tuple[ca.SX, ca.SX]:
    """``Ahat = dC'/dv`` and ``bhat = dC'/dz z'`` (speeds held) by CasADi's AD of the
    translated ``C'``: along ``z' = (v, sigma)`` each contour leaf ``L[k]`` at contact
    parameter ``u`` moves by its Frenet derivative (``contour_functions``) times ``u'``."""
    n = system.n
    Cdot = tr(system.constraint_rate)
    sigma = tr(system.contact_rates)
    zdir = ca.vertcat(x[n:2 * n], ca.SX.zeros(n), sigma)
    dL = []
    for k, (cls, i) in enumerate(slots):
        u = system.state[i]
        try:
            d = tr(sp.diff(cls(u), u))
        except NotImplementedError:
            if ca.depends_on(Cdot, L[k]):
                raise
            d = ca.SX(0)
        dL.append(d * zdir[i])
    v = x[n:2 * n]
    bhat = ca.jtimes(Cdot, x, zdir) + ca.jtimes(Cdot, L, ca.vertcat(*dL))
    return ca.jacobian(Cdot, v), bhat


def _contact_states(names: list[str]) -> list[tuple[int, int]]:
    """State indices of (fingertip, object) contact parameter of each contact, in order."""
    if names[-1] == "s":
        return [(len(names) - 1, len(names) - 1)]
    if names[-2:] == ["u0", "u1"]:
        return [(len(names) - 2, len(names) - 1)]
    pairs, i = [], 1
    while f"u0_{i}" in names:
        pairs.append((names.index(f"u0_{i}"), names.index(f"u1_{i}")))
        i += 1
    if not pairs:
        raise ValueError(f"no contact parameters among the states {names}")
    return pairs


def _families(n_contacts: int):
    """The (fingertip, object) abstract-function families of each contact."""
    return [(fingertip_functions(i), OBJECT) for i in range(1, n_contacts + 1)]


def compose(template: Template, fingertip, object_, *, runtime: tuple[str, ...],
            constants: dict[str, float], outputs: tuple[str, ...], name: str,
            controller=None) -> CasadiModel:
    """One scene's CasADi functions from a template, the contours and the parameters.

    ``fingertip`` is one contour, or a sequence of them (one per finger, in order).

    ``runtime`` parameters become the input ``p`` (in that order); ``constants`` give the
    value of every other template parameter, folded into the code. The template's joint
    torques (``tau_*``) are the controller layer's (``codegen.controller.ControllerFunction``;
    its ``p`` is the model's), or, without one, constants too.
    """
    nx = len(template.state_names)
    x = ca.SX.sym("x", nx)
    t = ca.SX.sym("t")
    np_ = controller.function.nnz_in(2) if controller is not None else len(runtime)
    p = ca.SX.sym("p", np_)
    torques = [k for k in template.param_names if k.startswith("tau_")] if controller else []
    tau = controller.function(t, x, p) if controller is not None else None
    missing = [k for k in template.param_names
               if k not in runtime and k not in constants and k not in torques]
    if missing:
        raise ValueError(f"no value for template parameters {missing}")
    q = ca.vertcat(*[p[runtime.index(k)] if k in runtime else
                     tau[torques.index(k)] if k in torques else ca.SX(constants[k])
                     for k in template.param_names])
    tips = list(fingertip) if isinstance(fingertip, (list, tuple)) else [fingertip]
    if len(tips) != len(template.contact_index):
        raise ValueError(f"{len(tips)} fingertip contour(s) for a template of "
                         f"{len(template.contact_index)} contact(s)")
    L = []
    for tip, (i0, i1), pair in zip(tips, template.contact_index, _families(len(tips))):
        for fns, curve, i in zip(pair, (tip, object_), (i0, i1)):
            tr = SympyToCasadi({T: x[i]})
            concrete = leaf_expressions(fns, curve)
            L += [tr(concrete[cls]) for cls in fns.leaves()]
    L = ca.vertcat(*L)
    xdot = template.rhs(x, q, L)
    y_all = template.outputs(x, q, L)
    y = {k: y_all[template.output_names.index(k)] for k in outputs}
    names = planar_constraint_names(template.output_names)
    C = ca.vertcat(*[y_all[template.output_names.index(k)] for k in names])
    tangency = tuple(k for k in template.output_names if k.startswith("tangency_defect"))
    G = ca.vertcat(C, *[y_all[template.output_names.index(k)] for k in tangency])
    return sx_model(x, p, xdot, y, name, constraints=C, constraint_names=names,
                    start_conditions=G, start_names=names + tangency, t=t,
                    outputs_time=bool(controller and controller.reads_time))


def planar_constraint_names(output_names: tuple[str, ...]) -> tuple[str, ...]:
    """The contact constraints among a planar template's outputs: ``(Q, R)`` for one finger,
    ``(Q1, R1, Q2, R2, ...)`` for several."""
    if "Q" in output_names:
        return PLANAR_CONSTRAINTS
    names: list[str] = []
    while f"Q{len(names) // 2 + 1}" in output_names:
        i = len(names) // 2 + 1
        names += [f"Q{i}", f"R{i}"]
    if not names or any(k not in output_names for k in names):
        raise ValueError(f"no contact constraints (Q, R) among the template's outputs {output_names}")
    return tuple(names)


def sx_model(x: ca.SX, p: ca.SX, xdot: ca.SX, outputs: dict[str, ca.SX], name: str, *,
             jacobian: bool = True, constraints: ca.SX | None = None,
             constraint_names: tuple[str, ...] | None = None,
             start_conditions: ca.SX | None = None, start_names: tuple[str, ...] = (),
             start_values: ca.SX | None = None,
             exact=None, t: ca.SX | None = None, outputs_time: bool = False,
             internal: dict[str, ca.SX] | None = None) -> CasadiModel:
    """The generated functions of a closed loop ``xdot(x, p)`` and its ``outputs`` (any model).

    ``{name}_rhs`` with CasADi's DAE signature, its Jacobian (unless ``jacobian=False``: the
    integrators then difference the compiled rhs), ``{name}_outputs`` (only when ``outputs``
    is not empty) and, given the position ``constraints`` C(x, p) (a column, zero on the
    motion), ``{name}_constraints`` ``(x, p) -> (C, dC_dx, Cdot, dCdot_dv)`` with
    ``Cdot = jtimes(C, x, xdot)`` (the total time derivative along the closed loop), ``dC_dx``
    and ``dCdot_dv`` (the columns of dCdot/dx for the velocity states, zero elsewhere) as dense
    ``nc x nx`` matrices; with the SX instruction counts before and after CSE.

    ``exact(*exprs) -> list`` (optional) rewrites every expression once all derivatives are
    taken, before the functions are made (a structure's vanishing Taylor terms,
    ``codegen.structure3d``).

    ``t``: the time symbol of ``xdot`` (a law that reads it); with ``outputs_time`` the outputs
    read it too, as one more last entry of their ``p`` (``codegen.controller.outputs_p``).
    Elsewhere (constraints, start) the time must not appear.

    ``internal``: outputs only the run time reads, at a switch: ``{name}_internal``, with the
    outputs' arguments, a helper (``CasadiModel.internal_names``), not computed with the
    outputs at every output time.
    """
    if exact is not None and jacobian:
        raise ValueError("exact= rewrites the rhs after differentiation: its Jacobian would "
                         "miss the rewritten terms; pass jacobian=False")
    fix = exact or (lambda *exprs: list(exprs))
    t = ca.SX.sym("t") if t is None else t
    empty = ca.SX(0, 1)
    dyn_in = [t, x, empty, p, empty]
    (xdot_exact,) = fix(xdot)
    raw = ca.Function(f"{name}_rhs", dyn_in, [xdot_exact, empty, empty, empty],
                      ca.dyn_in(), ca.dyn_out())
    rhs = ca.Function(f"{name}_rhs", dyn_in, [xdot_exact, empty, empty, empty],
                      ca.dyn_in(), ca.dyn_out(), FUNCTION_OPTIONS)
    jac = rhs.jacobian() if jacobian else None
    op_counts = {
        "rhs_sx_instructions_before_cse": raw.n_instructions(),
        "rhs_sx_instructions": rhs.n_instructions(),
    }
    if jac is not None:
        op_counts["jac_sx_instructions"] = jac.n_instructions()
    out_fn = None
    if outputs:
        # dense: an output that is structurally zero (a pivoted object's speed) must still
        # take its place in the buffer, or every later column is read shifted
        (y,) = fix(ca.densify(ca.vertcat(*outputs.values())))
        if not outputs_time:
            y = ca.substitute(y, t, ca.SX(0))
        out_fn = ca.Function(f"{name}_outputs", [x, ca.vertcat(p, t) if outputs_time else p], [y],
                             ["x", "p"], ["y"], FUNCTION_OPTIONS)
        op_counts["outputs_sx_instructions"] = out_fn.n_instructions()
    helpers = ()
    if internal:
        (z,) = fix(ca.densify(ca.vertcat(*internal.values())))
        if not outputs_time:
            z = ca.substitute(z, t, ca.SX(0))
        helpers = (ca.Function(f"{name}_internal", [x, ca.vertcat(p, t) if outputs_time else p], [z],
                               ["x", "p"], ["y"], FUNCTION_OPTIONS),)
        op_counts["internal_sx_instructions"] = helpers[0].n_instructions()
    con_fn, con_info = None, {}
    if constraints is not None:
        con_fn, con_info = _constraints_function(x, p, xdot, constraints, constraint_names, name,
                                                 fix)
        op_counts["constraints_sx_instructions"] = con_fn.n_instructions()
    start_fn = None
    if start_conditions is not None:
        v = ca.SX(0, 1) if start_values is None else fix(start_values)[0]
        start_fn = ca.Function(f"{name}_start", [x, p],
                               [*fix(start_conditions, ca.densify(ca.jacobian(start_conditions, x))), v],
                               ["x", "p"], ["G", "dG_dx", "v"], FUNCTION_OPTIONS)
        op_counts["start_sx_instructions"] = start_fn.n_instructions()
    return CasadiModel(rhs=rhs, jac=jac, outputs=out_fn, output_names=tuple(outputs),
                       op_counts=op_counts, constraints=con_fn, constraint_info=con_info,
                       start=start_fn, start_names=tuple(start_names), helpers=helpers,
                       internal_names=tuple(internal or ()))


def _constraints_function(x: ca.SX, p: ca.SX, xdot: ca.SX, C: ca.SX,
                          names: tuple[str, ...] | None, name: str,
                          fix=None) -> tuple[ca.Function, dict]:
    """``{name}_constraints`` ``(x, p) -> (C, dC_dx, Cdot, dCdot_dv)`` and which states the
    projection may change (``constraint_expressions``)."""
    outs, info = constraint_expressions(x, xdot, C, names)
    if fix is not None:
        outs = fix(*outs)
    fn = ca.Function(f"{name}_constraints", [x, p], outs,
                     ["x", "p"], ["C", "dC_dx", "Cdot", "dCdot_dv"], FUNCTION_OPTIONS)
    return fn, info


def constraint_expressions(x: ca.SX, xdot: ca.SX, C: ca.SX,
                           names: tuple[str, ...] | None) -> tuple[list[ca.SX], dict]:
    """``[C, dC_dx, Cdot, dCdot_dv]`` and which states the projection may change.

    Position states: those C depends on. Velocity states: those Cdot depends on and C does
    not, on which Cdot depends affinely (no column of dCdot/dx among them depends on any of
    them): the speeds. A frame angle that enters Cdot nonlinearly through the contact rates
    (3D ``psi``) is a configuration variable, not a speed, and is left alone.

    Only the Jacobians the projection uses are made: ``dC_dx`` (its non-zero columns are the
    position states) and ``dCdot_dv``, the velocity states' columns of dCdot/dx, zero
    elsewhere.  The position columns of dCdot/dx would need the second derivatives of the
    contact kinematics: half of the function's instructions (paper2d: 1381 against 698),
    paid after every integration step.
    """
    nc = C.numel()
    if names is None:
        names = tuple(f"C{i}" for i in range(nc))
    if len(names) != nc:
        raise ValueError(f"{len(names)} constraint names for {nc} constraints")
    Cdot = ca.jtimes(C, x, xdot)
    JC, JCd = ca.jacobian(C, x), ca.jacobian(Cdot, x)
    position = sorted(set(JC.sparsity().get_col()))
    candidates = sorted(set(JCd.sparsity().get_col()) - set(position))
    # affine in each one alone, then jointly (drop any whose column depends on another's)
    velocity = [i for i in candidates if not ca.depends_on(JCd[:, i], x[i])]
    while velocity:
        xs = ca.vertcat(*[x[i] for i in velocity])
        kept = [i for i in velocity if not ca.depends_on(JCd[:, i], xs)]
        if kept == velocity:
            break
        velocity = kept
    JCv = ca.SX.zeros(JCd.shape)  # dense; only the speeds' columns are computed
    for i in velocity:
        JCv[:, i] = JCd[:, i]
    return ([C, ca.densify(JC), Cdot, ca.densify(JCv)],
            {"names": list(names), "position_states": position, "velocity_states": velocity})


def build_casadi(system: ConstrainedSystem, fingertip, object_, name: str) -> CasadiModel:
    """A scene's CasADi functions straight from its derived system (template + compose)."""
    template = build_template(system)
    constants = {str(k): v for k, v in system.constants.items()}
    return compose(template, fingertip, object_, runtime=tuple(str(s) for s in system.params),
                   constants=constants, outputs=tuple(system.outputs), name=name)


def sympy_op_counts(system: ConstrainedSystem) -> dict[str, int]:
    """Operation counts of the SymPy pieces before and after SymPy's CSE."""
    exprs = [e for mat in system.pieces() if mat is not None for e in mat]
    before = sum(sp.count_ops(e) for e in exprs)
    repl, reduced = sp.cse(exprs, optimizations=None)
    after = sum(sp.count_ops(r) for _, r in repl) + sum(sp.count_ops(e) for e in reduced)
    return {"sympy_ops_before_cse": int(before), "sympy_ops_after_cse": int(after)}


def guarded_rhs(cm: CasadiModel, lower, upper, name: str) -> list[ca.Function]:
    """``<name>_rhs_guarded``: the rhs, NaN outside the states' bounds (``lower``/``upper``,
    None: unbounded), and ``jac_<name>_rhs_guarded`` (the same Jacobian), for SUNDIALS: a step
    that would leave a contour's domain fails there and SUNDIALS cuts it, so a contact that
    leaves its contour is found at the step where it happens, not at the next output time.
    Empty when no state is bounded."""
    bounded = [(i, lo, hi) for i, (lo, hi) in enumerate(zip(lower, upper))
               if lo is not None or hi is not None]
    if not bounded:
        return []
    rhs = cm.rhs
    ins = [ca.MX.sym(rhs.name_in(i), rhs.sparsity_in(i)) for i in range(rhs.n_in())]
    outs = rhs.call(ins)
    x = ins[1]
    inside = ca.MX(1)
    for i, lo, hi in bounded:
        if lo is not None:
            inside = ca.logic_and(inside, x[i] >= lo)
        if hi is not None:
            inside = ca.logic_and(inside, x[i] <= hi)
    nan = ca.MX(ca.DM.nan(outs[0].shape[0], outs[0].shape[1]))
    names_in = [rhs.name_in(i) for i in range(rhs.n_in())]
    names_out = [rhs.name_out(i) for i in range(rhs.n_out())]
    fns = [ca.Function(f"{name}_rhs_guarded", ins, [ca.if_else(inside, outs[0], nan), *outs[1:]],
                       names_in, names_out)]
    if cm.jac is not None:
        jac = cm.jac
        jins = [ca.MX.sym(jac.name_in(i), jac.sparsity_in(i)) for i in range(jac.n_in())]
        fns.append(ca.Function(f"jac_{name}_rhs_guarded", jins, jac.call(jins),
                               [jac.name_in(i) for i in range(jac.n_in())],
                               [jac.name_out(i) for i in range(jac.n_out())]))
    return fns
