"""What ``gs.build`` returns: the runtime's ``Model`` with the scene it was built from, and
what needs the scene or the compiler: the closed loop as CasADi functions
(``casadi_function``), and, when it is pickled to another process or machine, its C compiled
there when that platform cannot load the library sent (``runtime.portable``).
"""
from __future__ import annotations

import copy
from pathlib import Path

from grasping_sym.pipeline.quality_along import grasp_quality as _grasp_quality
from grasping_sym.runtime import portable
from grasping_sym.runtime.model import Model
from grasping_sym.store import safety


class BuiltModel(Model):
    """A model made by ``gs.build``: a runtime ``Model`` that also knows its scene."""

    def __init__(self, directory: Path, manifest: dict, library_path: Path, start: dict, scene=None,
                 friction=None):
        super().__init__(directory, manifest, library_path, start, scene,
                         friction if scene is None else getattr(scene, "friction", None))
        self._public: dict = {}  # the CasADi functions made, by (which, time, compiled)

    def __reduce__(self):
        """Pickled as the runtime model is (``runtime.portable``), with a layered model's
        structure files, its friction law and a model with modes' rolling model
        (``Model.rolling``), and restored by ``restore``: it compiles the C where the
        receiver's platform cannot load the library sent."""
        return restore, (portable.payload(self, structure=_structure_files(self.manifest)),
                         self.friction, self.rolling)

    def casadi_function(self, which: str = "ode", *, time: bool = False, compiled: bool = False,
                        outputs=None):
        """The closed loop as a CasADi Function with exact derivatives of any order
        (``assemble.casadi_api``): ``"ode"`` ``(x, u, p) -> xdot`` (default),
        ``"constraints"`` ``(x, p) -> C``, ``"outputs"`` ``(x, u, p) -> y`` or ``"cone"``
        ``(x, u, p, mu) -> (f, margin)`` (every contact's normal force and friction-cone margin
        ``mu^2 f^2 - |F_t|^2``: a path constraint ``f >= 0``, ``margin >= 0`` keeps the contacts
        from slipping, ``mu`` one per contact), or ``"squeeze"`` ``(x, mu) -> margin`` (a 3D
        grasp of a free object by two contacts: per contact ``e . n_i - 1/sqrt(1 + mu_i^2)``,
        both >= 0 where the contacts can squeeze the object along the line between them, where
        its grasp quality epsilon is 0, the best two contacts reach; conventions section 10);
        ``u`` the inputs
        (``input_names``; empty without), ``p`` the run-time parameters (``param_names``), then,
        for surfaces with atlases, their charts (``chart_names``: 0 or 1 each, the chart a
        contact's coordinates are in; a problem keeps them, a run switches them; ``"squeeze"``
        of an object with an atlas takes its charts at the two contacts as a third argument
        ``chart``), the start's values the model's. With ``time`` the ode and outputs take the time first.
        ``outputs`` (with ``"outputs"``): the names of the outputs to give, in that order (the
        others, and their derivatives, are never evaluated: what a problem that constrains a
        few of them needs).

        The functions tell CasADi how to differentiate them inside a problem
        (``casadi_api.DERIVATIVE_OPTIONS``): called once per collocation point, not through
        ``Function.map``, they take the constraint Jacobian and the Hessian of the Lagrangian
        through symbolic Jacobians (``examples/ocp_paper3d.py``).

        ``compiled=True``: the same functions evaluated by C compiled from them, with their
        Jacobian, forward, reverse and forward-over-reverse derivatives
        (``assemble.casadi_api.compiled_functions``: what ``Opti``/IPOPT with exact Hessians
        and the integrators' sensitivities call), compiled once and kept beside the model
        (use them in ``Opti`` without ``expand``, which would inline the SX again).
        Needs the scene: a model from ``gs.build``, not from ``gs.load``."""
        from grasping_sym.assemble import casadi_api  # noqa: PLC0415 - lazy: SymPy and CasADi, only for a function asked for
        scene = self.scene
        if self.manifest.get("modes"):
            raise ValueError(f"casadi_function: {self.name!r} is a model with contact modes, whose right-"
                             "hand side changes with each contact's mode at events: build the scene "
                             "without modes (its rolling model) for optimal control, and keep its "
                             "contacts in their cones with casadi_function('cone')")
        if scene is None:  # restored in another process: no scene was sent
            return super().casadi_function(which, time=time, compiled=compiled, outputs=outputs)
        picked = _picked_outputs(self, which, outputs)
        key = (which, time, bool(compiled), picked)
        if key in self._public:
            return self._public[key]
        whole = (which, time, False, None)
        if whole not in self._public:
            for k, f in casadi_api.public_functions(scene, self.start_params, time=time).items():
                self._public[(k, time, False, None)] = f
        if whole not in self._public:
            raise ValueError(f"which = {which!r}: choose 'ode', 'constraints', 'cone', 'outputs' "
                             "(a model with outputs) or 'squeeze' (a 3D grasp of a free object by "
                             "two contacts)")
        fn = self._public[whole]
        if picked is not None:
            fn = casadi_api.output_rows(fn, list(picked),
                                        [self.output_names.index(k) for k in picked])
        if compiled:
            where = safety.ensure_dir(self.directory / "casadi_api", root=self.directory)
            fn = casadi_api.compiled_functions({which: fn}, where)[which]
        self._public[key] = fn
        return fn

    def grasp_quality(self, result, mu=None, *, length: float | None = None, edges: int | None = None):
        """Grasp quality at every output time of ``result``, a run of this grasp of a free
        object (3D, or 2D with ``support="free"``)
        (``pipeline.quality_along``): Ferrari and Canny's epsilon of the exact contact points
        and normals (``gs.quality``: ``epsilon_lower``, ``epsilon_upper``), ``force_closure``
        and, from the run's outputs, the smallest cone margin ``mu f - |F_t|``
        (``cone_margin_min``, N)."""
        kw = {} if edges is None else {"edges": edges}
        return _grasp_quality(self, result, mu, length=length, **kw)


def _picked_outputs(model, which: str, outputs) -> tuple[str, ...] | None:
    """``outputs`` checked: None, or a tuple of the model's output names (with ``"outputs"``)."""
    if outputs is None:
        return None
    if which != "outputs":
        raise ValueError(f"outputs= picks rows of the 'outputs' function, not of {which!r}: "
                         "ask casadi_function('outputs', outputs=[...])")
    names = (outputs,) if isinstance(outputs, str) else tuple(outputs)
    unknown = [k for k in names if k not in model.output_names]
    if unknown or not names:
        raise ValueError(f"outputs = {list(names)!r}: give one or more of the model's outputs "
                         f"{list(model.output_names)}")
    return names


def restore(data: dict, friction=None, rolling=None) -> BuiltModel:
    """The model ``data`` describes (``runtime.portable.restore``), compiled here if need be,
    with the friction law it was sent with (a copy of the one this process restored when the
    laws differ: the law is read at run time, the compiled model is shared) and its rolling
    model (a model with modes)."""
    model = portable.restore(data, _compile_here, BuiltModel)
    if model.friction != friction:
        model = copy.copy(model)
        model.friction = friction
    if rolling is not None:
        model.rolling = rolling
    return model


def _structure_files(manifest: dict) -> dict | None:
    """A model in layers links its structure's objects: the structure's C and record, so that
    a receiver without it can compile them. The structure cache (and CasADi with it) is
    imported only for such a model, without the derivation, the emitter's rewrites or the
    compiler's library (``pipeline.making``)."""
    entry = manifest.get("structure")
    if not entry:
        return None
    from grasping_sym.assemble import structure_cache  # noqa: PLC0415 - lazy: CasADi, only to send a model in layers
    meta, directory = structure_cache.locate(entry)
    names = [*meta.files, structure_cache.META]
    return {"entry": entry, "files": {f: (directory / f).read_bytes() for f in names}}


def _compile_here(directory: Path, manifest: dict, data: dict) -> dict:
    """``pipeline.making.compile_here``: the C sent compiled here (a receiver whose platform
    cannot load the library sent), the compiler imported only then."""
    from grasping_sym.pipeline.making import compile_here  # noqa: PLC0415 - lazy: the compiler only where the library cannot load
    return compile_here(directory, manifest, data)
