"""A model in layers: its scene's own small C, calling a compiled structure.

The structure (``assemble.structure``, ``assemble.structure3d``; compiled once and cached by
``assemble.structure_cache``) is loaded through ``casadi.external``; the model's functions are
CasADi MX functions that evaluate the scene's own values at the contact slots and call the
structure's. Those values come from one SX function per kind of structure function,
``<name>_<what>_<kind>``, cut to the entries that function reads (its record's ``reads``):

- 2D, ``contours`` (:func:`contour_functions`): the contour leaves ``L`` and their derivatives
  ``dL`` along the contact parameters;
- 3D, ``jets`` (:func:`jets_functions`): the surfaces' jets ``J``.

:func:`compose_layered` composes either: the two differ only in data, the structure's
``Layout`` (how its functions take the values and the controller's torques). CasADi writes
the model's C with calls to the structure's symbols, which the model library links from the
structure's objects: a new shape compiles only this small file.

The functions keep the names and signatures of a single-piece model (``functions.sx_model``):
``<name>_rhs`` with CasADi's DAE signature, ``jac_<name>_rhs`` with the signature of
``Function.jacobian()`` (so that ``casadi.external`` and CVODES use it; 2D only, the 3D
integrators difference the rhs), ``<name>_outputs``, ``<name>_constraints`` and
``<name>_start``.
"""
from __future__ import annotations

import casadi as ca

from grasping_sym.assemble.controller import outputs_p
from grasping_sym.assemble.functions import FUNCTION_OPTIONS, _families
from grasping_sym.assemble.structure import CONTOUR_LEAVES, SURFACE_JETS, Slot
from grasping_sym.assemble.structure3d import jet_values
from grasping_sym.assemble.structure_cache import StructureRecord
from grasping_sym.derive.grasp3d import surface_sx
from grasping_sym.emit import lanes
from grasping_sym.emit.casadi_model import CasadiModel
from grasping_sym.geometry.curves import T
from grasping_sym.symbolic.contour_functions import leaf_expressions
from grasping_sym.symbolic.translate import SympyToCasadi

__all__ = ["compose_layered", "contour_functions", "contour_leaves", "jets_functions", "lanes_glue"]

Reads = dict[str, dict[str, tuple[int, ...]]]


def contour_leaves(curves, n_contacts: int) -> list[list]:
    """Per contour slot (finger i's fingertip, then the object, contact by contact) the
    SymPy expression in ``T`` of every leaf, in the order of its family's ``leaves()``."""
    out = []
    for curve_pair, pair in zip(curves, _families(n_contacts)):
        for fns, curve in zip(pair, curve_pair):
            concrete = leaf_expressions(fns, curve)
            out.append([concrete[cls] for cls in fns.leaves()])
    return out


def contour_functions(leaves: list[list], slots: tuple[Slot, ...], reads: Reads, nx: int,
                      name: str) -> dict[str, ca.Function]:
    """Per function kind of a planar structure, ``<name>_contours_<kind> (x) -> (L, [dL])``:
    the contour leaves (``leaves``, :func:`contour_leaves`; of each slot those it takes) and
    their derivatives along their contact parameters that the structure's function of that
    kind reads (``reads[kind]``: indices into ``L`` and ``dL``)."""
    x = ca.SX.sym("x", nx)
    L, dL = [], []
    for exprs, slot in zip(leaves, slots):
        (i,) = slot.states
        tr = SympyToCasadi({T: x[i]})
        for k in slot.entries:
            value = tr(exprs[k])
            L.append(value)
            dL.append(ca.jacobian(value, x[i]))
    return _by_kind(x, {"L": L, "dL": dL}, reads, f"{name}_{CONTOUR_LEAVES.what}")


def jets_functions(surfaces, slots: tuple[Slot, ...], reads: Reads, nx: int, name: str,
                   body: tuple[float, ...] = (), charts: dict[int, int] | None = None,
                   np_: int = 0) -> dict[str, ca.Function]:
    """Per function kind of a 3D structure, ``<name>_jets_<kind> (x) -> J``: the entries of
    the contour slots' jets (``structure3d.jet_values``; slot ``s`` of surface ``surfaces[s]``
    at its states ``u, v``), then of the object's mass properties ``body``
    (``structure3d.body_values``), that the structure's function of that kind reads
    (``reads[kind]["J"]``). ``charts``: the slots whose surface has an atlas
    (``geometry.atlas``), each with the index of its chart in the model's ``p`` (of
    ``np_`` entries); with any, the functions take ``(x, p)``."""
    x = ca.SX.sym("x", nx)
    p = ca.SX.sym("p", np_) if charts else None
    jets = []
    for k, (surface, slot) in enumerate(zip(surfaces, slots)):
        u, v = (x[i] for i in slot.states)
        chart = p[charts[k]] if charts and k in charts else None
        jets.append(jet_values(surface_sx(surface, u, v, chart=chart), u, v))
    return _by_kind(x, {"J": ca.vertcat(*jets, ca.DM(list(body)))}, reads, f"{name}_{SURFACE_JETS.what}", p)


def _by_kind(x: ca.SX, values: dict, reads: Reads, prefix: str, p: ca.SX | None = None) -> dict[str, ca.Function]:
    """Per function kind, ``<prefix>_<kind> (x) ->`` (``(x, p)``, given ``p``) the entries of
    each of ``values`` (by input name) that kind reads; kinds that read the same entries share
    one function."""
    out, made = {}, {}
    ins, in_names = ([x], ["x"]) if p is None else ([x, p], ["x", "p"])
    for kind, by_input in sorted(reads.items(), key=lambda item: item[0] != "rhs"):  # named after the rhs
        names = [n for n in by_input if n in values]
        key = tuple((n, tuple(by_input[n])) for n in names)
        if key not in made:
            made[key] = ca.Function(
                f"{prefix}_{kind}", ins,
                [ca.vertcat(*[values[n][i] for i in by_input[n]]) if by_input[n] else ca.SX(0, 1)
                 for n in names], in_names, names, FUNCTION_OPTIONS)
        out[kind] = made[key]
    return out


def _jacobian_layout(nx: int, np_: int):
    """Names and shapes of ``rhs.jacobian()`` for a DAE rhs with ``nx`` states, ``np_``
    parameters and empty z, u, alg, quad, zero."""
    sx = ca.SX.sym
    empty = ca.SX(0, 1)
    ref = ca.Function("r", [sx("t"), sx("x", nx), empty, sx("p", np_), empty],
                      [ca.SX.zeros(nx), empty, empty, empty], ca.dyn_in(), ca.dyn_out())
    jac = ref.jacobian()
    ins = [(jac.name_in(i), jac.sparsity_in(i)) for i in range(jac.n_in())]
    outs = [(jac.name_out(i), jac.size_out(i)) for i in range(jac.n_out())]
    return ins, outs


def compose_layered(structure: dict[str, ca.Function], record: StructureRecord,
                    own: dict[str, ca.Function], nx: int, np_: int, name: str,
                    ctrl, n_structure_p: int) -> CasadiModel:
    """The model's MX functions over the structure's ``external`` functions (by kind:
    ``rhs``, ``jac`` and ``jac2`` if any, ``outputs``, ``constraints``, ``start`` if any;
    ``record`` its record), the model's own functions of its contact values by kind
    (:func:`contour_functions` or :func:`jets_functions`) and its controller
    (``assemble.controller``: ``ctrl.function (t, x, p) -> tau``).

    Each structure function's inputs are given by name: ``t, x, z, u``; its values at the
    contacts (``L, dL`` or ``J``, from ``own[kind]``); ``p``, the model's first
    ``n_structure_p`` entries (its run-time parameters and the start's values; the inputs'
    coefficients reach the structure through the torques), followed by the torques where
    the record's layout has them there, else ``tau``, the torques the function reads. The
    rhs and its Jacobian read the torques at ``t``, the outputs at ``t = 0`` or at a time
    in ``p`` (``controller.outputs_p``), the constraints and the start at ``t = 0``."""
    layout = record.layout
    t, x, p = ca.MX.sym("t"), ca.MX.sym("x", nx), ca.MX.sym("p", np_)
    z, u = ca.MX.sym("z", 0), ca.MX.sym("u", 0)
    empty = ca.MX(0, 1)
    ps = p[:n_structure_p] if n_structure_p else ca.MX(0, 1)  # (p[:0] of a longer p is 1x0)
    controller = ctrl.function
    tau = controller(t, x, p)

    def args(kind, p_structure=ps, torques=tau, p_model=p):
        """The inputs of the structure's function ``kind``, in its order (``p_model``: the
        model's ``p``, where the contact values read their charts)."""
        f = structure[kind]
        mine = own[kind]
        values = dict(zip(mine.name_out(), mine.call([x] if mine.n_in() == 1 else [x, p_model])))
        kept = record.reads[kind].get("tau", ())
        given = {"t": t, "x": x, "z": z, "u": u, **values,
                 "p": ca.vertcat(p_structure, torques) if layout.torques_in_p else p_structure,
                 "tau": ca.vertcat(*[torques[k] for k in kept]) if kept else ca.MX(0, 1)}
        return [given[f.name_in(i)] for i in range(f.n_in())]

    def padded(outs, n):
        return [*outs, *[empty] * (n - len(outs))]

    rhs = ca.Function(f"{name}_rhs", [t, x, z, p, u], padded(structure["rhs"].call(args("rhs")), 4),
                      ca.dyn_in(), ca.dyn_out())
    jac = _jacobian(structure, args("jac"), record.reads["jac"].get("tau", ()), controller,
                    (t, x, z, p, u, tau), np_ - n_structure_p, name) if "jac" in structure else None
    out_fn = None
    if record.output_names:
        # the outputs are functions of (x, p): the torques at t = 0, or at the time in a last
        # entry of p when the law reads the time (``assemble.controller.outputs_p``)
        p_out, pm, t_out = outputs_p(p, np_, ctrl.reads_time)
        y = structure["outputs"].call(args("outputs", pm[:n_structure_p] if n_structure_p else ca.MX(0, 1),
                                           controller(t_out, x, pm), pm))
        out_fn = ca.Function(f"{name}_outputs", [x, p_out], y, ["x", "p"], ["y"])
    tau0 = controller(0, x, p)
    constraints = ca.Function(f"{name}_constraints", [x, p],
                              structure["constraints"].call(args("constraints", ps, tau0)),
                              ["x", "p"], ["C", "dC_dx", "Cdot", "dCdot_dv"])
    start = None
    if "start" in structure:
        start = ca.Function(f"{name}_start", [x, p],
                            padded(structure["start"].call(args("start", ps, tau0)), 3),
                            ["x", "p"], ["G", "dG_dx", "v"])
    distinct = tuple({id(f): f for f in own.values()}.values())
    helpers = (*distinct, controller)
    ops = dict(record.op_counts)
    n_own = sum(f.n_instructions() for f in distinct)
    if layout.controller_apart:
        ops[f"{layout.what}_sx_instructions"] = n_own
        ops["controller_sx_instructions"] = controller.n_instructions()
    else:
        ops[f"{layout.what}_sx_instructions"] = n_own + controller.n_instructions()
        ops[f"rhs_{layout.what}_sx_instructions"] = own["rhs"].n_instructions()
    return CasadiModel(rhs=rhs, jac=jac, outputs=out_fn, output_names=record.output_names,
                       op_counts=ops, constraints=constraints,
                       constraint_info=record.constraint_info, start=start,
                       start_names=record.start_names, helpers=helpers)


def _jacobian(structure: dict[str, ca.Function], jac_args: list, kept: tuple[int, ...],
              controller: ca.Function, dae: tuple, n_inputs: int, name: str) -> ca.Function:
    """``jac_<name>_rhs``: the structure's Jacobian (whole, or split in two,
    ``structure.split_jacobian``: the same inputs ``jac_args``) with the torques' share by the
    chain rule (the controller's Jacobian is its own SX's); the ``n_inputs`` last entries of
    ``p`` act only through the torques."""
    t, x, z, p, u, tau = dae
    nx, np_ = x.numel(), p.numel()
    if "jac2" in structure:
        Jx_rest, Jp, Jtau = structure["jac2"].call(jac_args)
        Jx = ca.horzcat(structure["jac"].call(jac_args)[0], Jx_rest)
    else:
        Jx, Jp, Jtau = structure["jac"].call(jac_args)
    Jp = ca.horzcat(Jp, ca.MX(nx, n_inputs))
    if kept:
        cj = controller.jacobian()(t, x, p, tau)
        Jx = Jx + ca.mtimes(Jtau, ca.vertcat(*[cj[1][k, :] for k in kept]))
        Jp = Jp + ca.mtimes(Jtau, ca.vertcat(*[cj[2][k, :] for k in kept]))
    ins, outs = _jacobian_layout(nx, np_)
    jin = [t, x, z, p, u] + [ca.MX.sym(n, s) for n, s in ins[5:]]
    blocks = {"jac_ode_x": Jx, "jac_ode_p": Jp}
    return ca.Function(f"jac_{name}_rhs", jin, [blocks.get(n, ca.MX(*shape)) for n, shape in outs],
                       [n for n, _ in ins], [n for n, _ in outs])


def lanes_glue(name: str, contours: ca.Function, structure_lanes: str | None,
               n_leaves: int, controller: ca.Function, tau_kept: list[int]) -> tuple[str | None, str]:
    """C of ``<name>_rhs_lanes`` (the driver's 4-lane rhs, ``emit.lanes``): the contours
    and the controller's torques at the four states (four at once where they have a lane
    version, else one by one), then the structure's 4-lane rhs
    ``structure_lanes`` (which reads the torques ``tau_kept``); or None and why not."""
    if structure_lanes is None:
        return None, "not made: the structure has no 4-lane rhs"
    nl = max(1, n_leaves)
    nt = max(1, controller.nnz_out(0))
    nk = max(1, len(tau_kept))
    c_lanes, status = lanes.function_lanes(contours, f"{name}_contours_lanes", ("lane",),
                                           ("x", "L"))
    head = [f"int {structure_lanes}(const double* t, const double* const* x, const double* p, "
            "const double* const* L, const double* const* tau, double* const* xdot);"]

    def declare(f):
        return (f"int {f.name()}(const double** arg, double** res, long long int* iw, double* w, "
                "int mem);")

    def work(f):
        sz = {k: max(1, int(getattr(f, k)())) for k in ("sz_arg", "sz_res", "sz_iw", "sz_w")}
        return [f"    const double* arg[{sz['sz_arg']}]; double* res[{sz['sz_res']}];",
                f"    long long int iw[{sz['sz_iw']}]; double w[{sz['sz_w']}];"]

    head.insert(0, declare(controller))
    body = [f"int {name}_rhs_lanes(const double* t, const double* const* x, const double* p, "
            "double* const* xdot) {",
            f"  double L0[{nl}], L1[{nl}], L2[{nl}], L3[{nl}];",
            "  double* L[4] = {L0, L1, L2, L3};",
            f"  double full[4][{nt}], T0[{nk}], T1[{nk}], T2[{nk}], T3[{nk}];",
            "  double* tau[4] = {T0, T1, T2, T3};"]
    if c_lanes is not None:
        body.append(f"  {name}_contours_lanes(x, L);")
    else:
        head.insert(0, declare(contours))
        body += ["  {", *work(contours),
                 "    for (int s = 0; s < 4; ++s) {",
                 "      arg[0] = x[s]; res[0] = L[s];",
                 f"      if ({contours.name()}(arg, res, iw, w, 0)) return 1;",
                 "    }", "  }"]
    ctrl_lanes, ctrl_status = lanes.function_lanes(controller, f"{name}_controller_lanes",
                                                   ("t", "lane", "shared"), ("t", "x", "p", "tau"))
    if ctrl_lanes is not None:
        body += ["  double* F[4] = {full[0], full[1], full[2], full[3]};",
                 f"  {name}_controller_lanes(t, x, p, F);",
                 "  for (int s = 0; s < 4; ++s) {",
                 *[f"    tau[s][{j}] = full[s][{k}];" for j, k in enumerate(tau_kept)],
                 "  }"]
    else:
        body += ["  {", *work(controller),
                 "    for (int s = 0; s < 4; ++s) {",
                 "      arg[0] = t + s; arg[1] = x[s]; arg[2] = p; res[0] = full[s];",
                 f"      if ({controller.name()}(arg, res, iw, w, 0)) return 1;",
                 *[f"      tau[s][{j}] = full[s][{k}];" for j, k in enumerate(tau_kept)],
                 "    }", "  }"]
    body += [f"  return {structure_lanes}(t, x, p, (const double* const*)L, "
             "(const double* const*)tau, xdot);", "}"]
    text = (c_lanes or "") + (ctrl_lanes or "") + "\n".join(head + body) + "\n"
    how = "contours four at a time" if c_lanes is not None else f"contours one lane at a time ({status})"
    how_ctrl = ("the controller four at a time" if ctrl_lanes is not None
                else f"the controller one lane at a time ({ctrl_status})")
    return text, f"applied ({how}, {how_ctrl}, then the structure's 4-lane rhs)"
