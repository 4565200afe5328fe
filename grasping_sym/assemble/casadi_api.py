"""A model's closed loop as CasADi Functions for optimal control and sensitivity analysis.

The scene's functions in one piece of SX (``assemble.kinds.casadi_functions(scene, layers=False)``: the
same closed loop as the compiled layers, tests check it) restated with the control inputs
as an argument of their own:

- ``ode (x, u, p) -> xdot``: the right-hand side at the inputs' values ``u``;
- ``constraints (x, p) -> C``: the contact constraints (zero on the motion);
- ``outputs (x, u, p) -> y``: the scene's outputs;
- ``cone (x, u, p, mu) -> (f, margin)``: every contact's normal force and friction-cone margin
  ``mu^2 f^2 - |F_t|^2`` (a path constraint ``f >= 0``, ``margin >= 0`` keeps every contact
  from slipping);
- ``squeeze (x, mu) -> margin`` (a 3D grasp of a free object by two contacts): per contact,
  how far the line between the contacts lies inside its friction cone, ``e . n_i -
  1/sqrt(1 + mu_i^2)`` (cosines; ``docs/conventions.md`` section 10): both >= 0 where the
  contacts can squeeze the object, where its epsilon is 0, the best two contacts reach.

``p`` is the model's run-time parameters (``param_names``); the start's values (2D: the pivot)
are those of the model's start. Being SX, every derivative of any order is exact (CasADi's
AD): ``jacobian()``, ``forward``, ``reverse``, Hessians, ``Opti``/``nlpsol`` with IPOPT and
the integrators' sensitivities. CasADi's virtual machine evaluates them; ``jit=True`` in the
options of the NLP or integrator made from them compiles the whole problem to C.
"""
from __future__ import annotations

import dataclasses
import hashlib
import re
from pathlib import Path

import casadi as ca

from grasping_sym.assemble import kinds
from grasping_sym.derive.bodies3d import object_rotation, state_slices, surface_sx
from grasping_sym.store import files as stored
from grasping_sym.store import safety
from grasping_sym.store.platform import library_tag, optimization
from grasping_sym.toolchain.compiler import compile_shared

__all__ = ["DERIVATIVE_OPTIONS", "output_rows", "public_functions"]

#: How CasADi differentiates the public functions inside a problem (measured on paper3d's
#: optimal control, docs/guide.md): many forward directions at once (an NLP's constraint
#: Jacobian) through the function's symbolic Jacobian (``jac_penalty`` 0.5: for more than about
#: half as many directions as inputs), one reverse direction (a gradient) by reverse mode, and
#: the reverse function's directions (the Hessian of the Lagrangian) through its own symbolic
#: Jacobian. CasADi's defaults (``jac_penalty`` 2: forward directions one by one) cost paper3d's
#: problem 4 times as much. (Common subexpression elimination on the derivatives,
#: ``cse``, costs its set-up 12 s and its solve nothing measurable.)
DERIVATIVE_OPTIONS = {"jac_penalty": 0.5, "reverse_options": {"jac_penalty": 0}}


def force_names(scene) -> tuple[str, ...]:
    """The contact forces' outputs of ``scene``, per contact the normal one then the tangential
    components (``f``, ``lam``; 3D ``f1``, ``lam1``, ``eta1``, ...)."""
    return tuple(k for k in scene.check_outputs() if re.fullmatch(r"(f|lam|eta)\d*", k))


def public_functions(scene, start_values: dict[str, float], *, time: bool = False) -> dict:
    """``{"ode", "constraints", "outputs", "cone"}`` of ``scene`` (module docstring); with
    ``time`` the ode, the outputs and the cone take the time first: ``(t, x, u, p)`` (for a law
    that reads it)."""
    own = tuple(scene.outputs)
    forces = force_names(scene)
    scene = dataclasses.replace(scene, outputs=(*own, *(k for k in forces if k not in own)))
    cm = kinds.casadi_functions(scene, layers=False).model
    names = scene.p_names
    nx = len(scene.state_names)
    n_u = len(scene.input_names)
    t = ca.SX.sym("t")
    x = ca.SX.sym("x", nx)
    u = ca.SX.sym("u", n_u)
    # p: the run-time parameters, then the charts of the surfaces with atlases (0 or 1 each:
    # a problem fixes each contact's chart; runtime.atlas switches them only in a run)
    charts = tuple(getattr(scene, "chart_names", ()))
    n_run = len(scene.runtime)
    p = ca.SX.sym("p", n_run + len(charts))
    entries = ca.vertsplit(p)
    p_run = ca.vertcat(*entries[:n_run]) if n_run else ca.SX(0, 1)
    p_charts = ca.vertcat(*entries[n_run:]) if charts else ca.SX(0, 1)
    full = ca.vertcat(p_run, *[ca.SX(float(start_values[k])) for k in scene.start_param_names],
                      u, ca.SX.zeros(n_u), p_charts)
    if full.numel() != len(names):
        raise AssertionError(f"p of {full.numel()} entries for {names}")
    reads_time = cm.outputs is not None and cm.outputs.nnz_in(1) == len(names) + 1
    xdot = cm.rhs(t, x, ca.SX(0, 1), full, ca.SX(0, 1))[0]
    if not time and ca.depends_on(xdot, t):
        raise ValueError(f"the controller of {scene.name} reads the time: ask for "
                         "model.casadi_function(time=True), a function of (t, x, u, p)")
    tt = t if time else ca.SX(0)
    head = [t] if time else []
    hnames = ["t"] if time else []
    out = {"ode": ca.Function(f"{scene.name}_ode", [*head, x, u, p], [xdot],
                              [*hnames, "x", "u", "p"], ["xdot"], DERIVATIVE_OPTIONS)}
    C = cm.constraints(x, full)[0]
    out["constraints"] = ca.Function(f"{scene.name}_contact_constraints", [x, p], [C],
                                     ["x", "p"], ["C"], DERIVATIVE_OPTIONS)
    y = cm.outputs(x, ca.vertcat(full, tt) if reads_time else full)
    if own:
        out["outputs"] = ca.Function(f"{scene.name}_outputs_of", [*head, x, u, p], [y[:len(own)]],
                                     [*hnames, "x", "u", "p"], ["y"], DERIVATIVE_OPTIONS)
    out["cone"] = _cone(scene, y, [*head, x, u, p], [*hnames, "x", "u", "p"])
    if _squeezes(scene):
        out["squeeze"] = _squeeze(scene, x)
    return out


def _squeezes(scene) -> bool:
    """Whether ``scene`` is a 3D grasp of a free object by two contacts (``squeeze``'s)."""
    return getattr(scene, "kind", None) == "grasp3d" and len(scene.fingers) == 2 \
        and bool(getattr(scene, "free", False))


def _squeeze(scene, x: ca.SX) -> ca.Function:
    """``squeeze (x, mu) -> margin`` (an object with an atlas: ``(x, mu, chart)``, ``chart`` the
    object's chart at each contact, ``chart_o1`` and ``chart_o2``, 0 or 1): the two contacts'
    points ``p_i`` and unit normals into
    the object ``n_i`` (the object surface's at ``(u_o{i}, v_o{i})``, carried by the object's
    pose: its centre and the rotation of its quaternion, ``bodies3d.object_rotation``, exact
    for any length), ``e = (p_2 - p_1)/|p_2 - p_1|``; per contact the
    cosine of the angle between the direction it pushes along the line (``e``, ``-e``) and
    its normal, less the cosine of its friction angle: ``e . n_1 - c_1``, ``-e . n_2 - c_2``,
    ``c_i = 1/sqrt(1 + mu_i^2)`` (``mu_i >= 0``). Both >= 0 iff the line lies in both cones
    with the contacts squeezing the object between them (Nguyen's squeeze,
    ``gs.quality.two_contacts_squeeze``, which also takes the other orientation, each contact
    pushing away from the other: a grasp from inside, impossible on a convex surface), where
    epsilon is exactly 0; smooth where the points are apart. With ``time`` it is the same
    function (it does not read the time)."""
    names = list(scene.state_names)
    at = state_slices(scene)
    R, _, _ = object_rotation(x[at["quat"]], ca.SX.zeros(3))
    centre = x[at["pos"]]
    points, normals = [], []
    atlas = getattr(scene.object_surface, "atlas", None) is not None
    chart = ca.SX.sym("chart", 2) if atlas else None
    for i in (1, 2):
        geo = surface_sx(scene.object_surface, x[names.index(f"u_o{i}")], x[names.index(f"v_o{i}")],
                         chart=None if chart is None else chart[i - 1])
        out = R @ geo["n"]
        points.append(centre + R @ geo["S"])
        normals.append(-out / ca.norm_2(out))
    d = points[1] - points[0]
    e = d / ca.norm_2(d)
    mu = ca.SX.sym("mu", 2)
    cos = 1 / ca.sqrt(1 + mu ** 2)
    margin = ca.vertcat(ca.dot(e, normals[0]) - cos[0], -ca.dot(e, normals[1]) - cos[1])
    args, arg_names = ([x, mu, chart], ["x", "mu", "chart"]) if atlas else ([x, mu], ["x", "mu"])
    return ca.Function(f"{scene.name}_squeeze", args, [margin], arg_names, ["margin"], DERIVATIVE_OPTIONS)


def output_rows(fn: ca.Function, names: list[str], rows: list[int]) -> ca.Function:
    """``fn`` (an ``outputs`` function, SX) with only the outputs ``rows`` (named ``names``):
    the others, and their derivatives, are never evaluated."""
    args = [ca.SX.sym(fn.name_in(i), fn.sparsity_in(i)) for i in range(fn.n_in())]
    y = fn.call(args)[0][rows]
    tag = hashlib.sha256(",".join(names).encode()).hexdigest()[:8]
    return ca.Function(f"{fn.name()}_{tag}", args, [y], fn.name_in(), fn.name_out(),
                       DERIVATIVE_OPTIONS)


def _cone(scene, y: ca.SX, args: list, names: list) -> ca.Function:
    """``cone (x, u, p, mu) -> (f, margin)``: per contact the normal force ``f`` (N) and the
    friction cone's smooth margin ``mu^2 f^2 - |F_t|^2`` (N^2), ``mu`` one per contact: the
    force is inside the cone where ``f >= 0`` and ``margin >= 0`` (``runtime.friction``'s
    ``cone_margin`` = ``mu f - |F_t|`` has the same sign there; its square form is smooth
    where ``F_t = 0``, which an optimiser's derivatives need)."""
    order = list(scene.outputs)
    at = {k: y[order.index(k)] for k in force_names(scene)}
    normals = [k for k in at if k.startswith("f")]
    mu = ca.SX.sym("mu", len(normals))
    f, margin = [], []
    for i, k in enumerate(normals):
        tail = k[1:]
        tang = [at[n] for n in (f"lam{tail}", f"eta{tail}") if n in at]
        f.append(at[k])
        margin.append(mu[i] ** 2 * at[k] ** 2 - sum(t ** 2 for t in tang))
    return ca.Function(f"{scene.name}_cone", [*args, mu], [ca.vertcat(*f), ca.vertcat(*margin)],
                       [*names, "mu"], ["f", "margin"], DERIVATIVE_OPTIONS)


def derivative_functions(g: ca.Function) -> list[ca.Function]:
    """What is compiled of ``g``, under the names ``casadi.external`` looks up for derivatives:
    ``g``, ``jac_g``, ``fwd1_g``, ``adj1_g`` and ``fwd1_adj1_g`` (the forward derivative of the
    reverse one: the Hessian-vector products IPOPT's exact Hessian takes). Other derivatives
    are not in the library, and CasADi refuses them by name."""
    adj = g.reverse(1)
    return [g, g.jacobian(), g.forward(1), adj, adj.forward(1)]


def compiled_functions(fns: dict[str, ca.Function], directory, say=lambda m: None) -> dict:
    """``fns`` evaluated by compiled C: their C and their derivatives'
    (:func:`derivative_functions`) written, one file each (compiled side by side), into one
    library in ``directory`` (named by the functions and the hash of the C, the compiler and
    the instruction set;
    its SHA-256 recorded beside it and checked before every load), loaded through
    ``casadi.external``."""
    texts = []
    for g in fns.values():
        for d in derivative_functions(g):
            cg = ca.CodeGenerator(f"{d.name()}.c", {"with_header": False,
                                                     "casadi_int": "long long int"})
            cg.add(d)
            texts.append((d.name(), cg.dump()))
    whole = "\n".join(f"{name}\n{text}" for name, text in texts)
    digest = hashlib.sha256(f"{whole}|{library_tag()}".encode()).hexdigest()[:20]
    directory = Path(directory)
    stem = f"api-{'-'.join(fns)}-{digest}"
    lib = directory / f"{stem}.so"
    record = directory / f"{stem}.json"
    safety.check_tree(directory, (lib.name, record.name))
    want = (stored.read_json(record) or {}).get("sha256")  # None: absent or unreadable
    if want is None or not lib.exists() or safety.sha256_file(lib) != want:
        say(f"compiling {len(fns)} CasADi functions and their derivatives "
            f"({len(whole) // 1000} kB of C in {len(texts)} files)")
        sources = [safety.write_text(directory / f"{stem}-{i}.c", text)
                   for i, (_, text) in enumerate(texts)]
        # -O1 at the full level (these derivatives are large and called a few hundred times
        # per solve), the level's own flag else (-Og, -O0); a failure keeps the C, to read
        compile_shared(sources, lib, extra_flags=("-O1",) if optimization() == "full" else ())
        for src in sources:
            src.unlink(missing_ok=True)
        stored.write_json(record, {"sha256": safety.sha256_file(lib)})
    return {k: ca.external(g.name(), str(lib)) for k, g in fns.items()}
