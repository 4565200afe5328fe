"""A model in layers: its shape's own small C, calling a compiled structure (2D: the
contours; 3D: the surfaces' jets, :func:`jets_functions`).

The structure (``codegen.structure``, compiled once and cached by ``codegen.structure_cache``)
is loaded through ``casadi.external``; the model's functions are CasADi MX functions that
evaluate the contours at the contact (``<name>_contours_<kind>``: the leaves ``L`` and their
derivatives ``dL`` that the structure's function of that kind reads) and call the
structure's. CasADi
writes their C with calls to the structure's symbols, which the model library links from the
structure's objects: a new shape compiles only this small file.

The functions keep the names and signatures of a single-piece model (``functions.sx_model``):
``<name>_rhs`` with CasADi's DAE signature, ``jac_<name>_rhs`` with the signature of
``Function.jacobian()`` (so that ``casadi.external`` and CVODES use it), ``<name>_outputs``,
``<name>_constraints`` and ``<name>_start``.
"""
from __future__ import annotations

import casadi as ca

from grasping_sym.assemble.controller import outputs_p
from grasping_sym.assemble.functions import FUNCTION_OPTIONS, _families
from grasping_sym.emit import lanes
from grasping_sym.emit.casadi_model import CasadiModel
from grasping_sym.geometry.curves import T
from grasping_sym.symbolic.contour_functions import leaf_expressions
from grasping_sym.symbolic.translate import SympyToCasadi

__all__ = ["compose_layered", "contour_functions", "contour_leaves", "lanes_glue"]


def contour_leaves(curves, n_contacts: int) -> list[list]:
    """Per contour slot (finger i's fingertip, then the object, contact by contact) the
    SymPy expression in ``T`` of every leaf, in the order of its family's ``leaves()``."""
    out = []
    for curve_pair, pair in zip(curves, _families(n_contacts)):
        for fns, curve in zip(pair, curve_pair):
            concrete = leaf_expressions(fns, curve)
            out.append([concrete[cls] for cls in fns.leaves()])
    return out


def contour_functions(leaves: list[list], slots, nx: int, name: str,
                      entries: dict[str, dict[str, list[int]]]) -> dict[str, ca.Function]:
    """Per function kind of the structure, ``<name>_contours_<kind> (x) -> (L, [dL])``: the
    contour leaves (``slots``: per slot its state index and leaf indices) and their
    derivatives along their contact parameters that the structure's function of that kind
    reads (``entries[kind]``: indices into ``L`` and ``dL``). Kinds that read the same
    entries share one function."""
    x = ca.SX.sym("x", nx)
    L, dL = [], []
    for exprs, (i, kept) in zip(leaves, slots):
        tr = SympyToCasadi({T: x[i]})
        for k in kept:
            value = tr(exprs[k])
            L.append(value)
            dL.append(ca.jacobian(value, x[i]))
    out, made = {}, {}
    for kind, idx in entries.items():
        idx = {k: v for k, v in idx.items() if k in ("L", "dL")}
        key = tuple((k, tuple(v)) for k, v in idx.items())
        if key not in made:
            parts = {"L": [L[i] for i in idx["L"]], "dL": [dL[i] for i in idx.get("dL", [])]}
            names = ["L", "dL"] if "dL" in idx else ["L"]
            made[key] = ca.Function(f"{name}_contours_{kind}", [x],
                                    [ca.vertcat(*parts[n]) if parts[n] else ca.SX(0, 1)
                                     for n in names], ["x"], names, FUNCTION_OPTIONS)
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


def compose_layered(structure: dict[str, ca.Function], meta: dict,
                    contours: dict[str, ca.Function], nx: int, np_: int, name: str,
                    ctrl, n_structure_p: int) -> CasadiModel:
    """The model's MX functions over the structure's ``external`` functions (keys ``rhs``,
    ``jac``, ``outputs``, ``constraints``, ``start``), the model's contour functions
    (:func:`contour_functions`, one per kind) and its controller (``codegen.controller``:
    ``ctrl.function (t, x, p) -> tau``). The structure reads the first ``n_structure_p`` entries of ``p``
    (the run-time parameters and the start's values; the inputs' coefficients reach it
    through ``tau``)."""
    t, x, p = ca.MX.sym("t"), ca.MX.sym("x", nx), ca.MX.sym("p", np_)
    z, u = ca.MX.sym("z", 0), ca.MX.sym("u", 0)
    empty = ca.MX(0, 1)
    ps = p[:n_structure_p]
    controller = ctrl.function
    tau = controller(t, x, p)
    entries = meta["leaf_entries"]

    def args(kind, torques=tau):
        """The contour values and the torques the structure's function ``kind`` reads."""
        leaves = contours[kind].call([x])
        kept = entries[kind].get("tau", [])
        return [*leaves, ca.vertcat(*[torques[k] for k in kept]) if kept else ca.MX(0, 1)]

    xdot = structure["rhs"](t, x, ps, *args("rhs"))
    rhs = ca.Function(f"{name}_rhs", [t, x, z, p, u], [xdot, empty, empty, empty],
                      ca.dyn_in(), ca.dyn_out())
    if "jac2" in structure:  # split in two (``structure.split_jacobian``): same inputs
        jac_args = args("jac")
        Jx_rest, Jp, Jtau = structure["jac2"](t, x, ps, *jac_args)
        Jx = ca.horzcat(structure["jac"](t, x, ps, *jac_args), Jx_rest)
    else:
        Jx, Jp, Jtau = structure["jac"](t, x, ps, *args("jac"))
    # the torques' share by the chain rule (the controller's Jacobian is its own SX's)
    Jp = ca.horzcat(Jp, ca.MX(nx, np_ - n_structure_p))  # the inputs act only through tau
    kept = entries["jac"].get("tau", [])
    if kept:
        cj = controller.jacobian()(t, x, p, tau)
        Jx = Jx + ca.mtimes(Jtau, ca.vertcat(*[cj[1][k, :] for k in kept]))
        Jp = Jp + ca.mtimes(Jtau, ca.vertcat(*[cj[2][k, :] for k in kept]))
    ins, outs = _jacobian_layout(nx, np_)
    jin = [t, x, z, p, u] + [ca.MX.sym(n, s) for n, s in ins[5:]]
    blocks = {"jac_ode_x": Jx, "jac_ode_p": Jp}
    jac = ca.Function(f"jac_{name}_rhs", jin, [blocks.get(n, ca.MX(*shape)) for n, shape in outs],
                      [n for n, _ in ins], [n for n, _ in outs])
    out_fn = None
    output_names = tuple(meta["output_names"])
    if output_names:
        # the outputs are functions of (x, p): the torques at t = 0, or at the time in a last
        # entry of p when the law reads the time (``codegen.controller.outputs_p``)
        p_out, pm, t_out = outputs_p(p, np_, ctrl.reads_time)
        y = structure["outputs"](x, pm[:n_structure_p], *args("outputs", controller(t_out, x, pm)))
        out_fn = ca.Function(f"{name}_outputs", [x, p_out], [y], ["x", "p"], ["y"])
    con = structure["constraints"](x, ps, *args("constraints"))
    constraints = ca.Function(f"{name}_constraints", [x, p], list(con),
                              ["x", "p"], ["C", "dC_dx", "Cdot", "dCdot_dv"])
    G, dG = structure["start"](x, ps, *args("start"))
    start = ca.Function(f"{name}_start", [x, p], [G, dG, empty], ["x", "p"], ["G", "dG_dx", "v"])
    ops = dict(meta.get("op_counts", {}))
    helpers = tuple({id(f): f for f in contours.values()}.values()) + (controller,)
    ops["contours_sx_instructions"] = sum(f.n_instructions() for f in helpers[:-1])
    ops["controller_sx_instructions"] = controller.n_instructions()
    return CasadiModel(rhs=rhs, jac=jac, outputs=out_fn, output_names=output_names,
                       op_counts=ops, constraints=constraints,
                       constraint_info=meta["constraint_info"], start=start,
                       start_names=tuple(meta["start_names"]), helpers=helpers)


def lanes_glue(name: str, contours: ca.Function, structure_lanes: str | None,
               n_leaves: int, controller: ca.Function, tau_kept: list[int]) -> tuple[str | None, str]:
    """C of ``<name>_rhs_lanes`` (the driver's 4-lane rhs, ``codegen.lanes``): the contours
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


def jets_functions(surfaces, slots, nx: int, name: str, entries: dict[str, list[int]]
                   ) -> dict[str, ca.Function]:
    """Per function kind, ``<name>_jets_<kind> (x) -> J[entries[kind]]``: the entries of the
    3D contour slots' jets (``codegen.structure3d``; slot ``s`` of surface ``surfaces[s]`` at
    ``x[slots[s][0]], x[slots[s][1]]``) that the structure's function of that kind takes.
    Kinds that take the same entries share one function."""
    from grasping_sym.assemble.structure3d import jet_values  # noqa: PLC0415
    from grasping_sym.derive.grasp3d import surface_sx  # noqa: PLC0415

    x = ca.SX.sym("x", nx)
    jets = []
    for surface, (iu, iv, _size) in zip(surfaces, slots):
        u, v = x[iu], x[iv]
        jets.append(jet_values(surface_sx(surface, u, v), u, v))
    J = ca.vertcat(*jets)
    out, made = {}, {}
    for kind, idx in entries.items():
        key = tuple(idx)
        if key not in made:
            made[key] = ca.Function(f"{name}_jets_{kind}", [x],
                                    [ca.vertcat(*[J[i] for i in idx]) if idx else ca.SX(0, 1)],
                                    ["x"], ["J"], FUNCTION_OPTIONS)
        out[kind] = made[key]
    return out


def compose_layered_3d(structure: dict[str, ca.Function], meta: dict,
                       jets: dict[str, ca.Function], nx: int, np_: int, name: str,
                       ctrl, n_structure_p: int) -> CasadiModel:
    """A 3D model's MX functions over its structure's ``external`` functions (each takes the
    structure's ``p``: the model's first ``n_structure_p`` entries, then the joint torques of
    the controller ``ctrl``; and the jet entries ``J`` it needs) and its jets functions."""
    t, x, p = ca.MX.sym("t"), ca.MX.sym("x", nx), ca.MX.sym("p", np_)
    z, u = ca.MX.sym("z", 0), ca.MX.sym("u", 0)
    controller = ctrl.function

    def J(kind):
        return jets[kind](x)

    def ps(time=t, pm=p):
        return ca.vertcat(pm[:n_structure_p], controller(time, x, pm))

    rhs = ca.Function(f"{name}_rhs", [t, x, z, p, u],
                      list(structure["rhs"](t, x, z, ps(), u, J("rhs"))), ca.dyn_in(), ca.dyn_out())
    out_fn = None
    output_names = tuple(meta["output_names"])
    if output_names:
        p_out, pm, t_out = outputs_p(p, np_, ctrl.reads_time)
        out_fn = ca.Function(f"{name}_outputs", [x, p_out],
                             [structure["outputs"](x, ps(t_out, pm), J("outputs"))], ["x", "p"], ["y"])
    constraints = ca.Function(f"{name}_constraints", [x, p],
                              list(structure["constraints"](x, ps(0), J("constraints"))),
                              ["x", "p"], ["C", "dC_dx", "Cdot", "dCdot_dv"])
    start = None
    if "start" in structure:
        start = ca.Function(f"{name}_start", [x, p], list(structure["start"](x, ps(0), J("start"))),
                            ["x", "p"], ["G", "dG_dx", "v"])
    ops = dict(meta.get("op_counts", {}))
    helpers = tuple({id(f): f for f in jets.values()}.values()) + (controller,)
    ops["jets_sx_instructions"] = sum(f.n_instructions() for f in helpers)
    ops["rhs_jets_sx_instructions"] = jets["rhs"].n_instructions()
    return CasadiModel(rhs=rhs, jac=None, outputs=out_fn, output_names=output_names,
                       op_counts=ops, constraints=constraints,
                       constraint_info=meta["constraint_info"], start=start,
                       start_names=tuple(meta["start_names"]), helpers=helpers)
