"""A built model: the compiled functions, their names, and simulation."""
from __future__ import annotations

import math
import numbers
from collections.abc import Mapping
from pathlib import Path

import numpy as np

from grasping_sym.errors import (
    ContactLeftContourError,
    IntegratorError,
    RunArgumentError,
)
from grasping_sym.runtime import checks as checks_
from grasping_sym.runtime import fastpath, integrators, portable, projection
from grasping_sym.runtime import start as start_
from grasping_sym.runtime.compiled import CompiledLibrary
from grasping_sym.runtime.result import SimulationResult
from grasping_sym.store import files as stored
from grasping_sym.store import safety


class Model:
    """A compiled scene, loaded from a generated directory with its manifest.

    Attributes
    ----------
    name, state_names, output_names, param_names
        As recorded at build time. ``output_names`` are the outputs the scene asked for (the
        compiled outputs also hold those the run-time checks read, ``runtime.checks``, shown
        only when asked for). ``param_names`` are the run-time parameters the user chose
        (inputs of the compiled functions); all other parameters are folded into the code.
    start_params
        The run-time values the start fixes (2D: the pivot ``xm, ym``; 3D: the centre
        spring's rest point ``r_bar0_*``), by name: inputs of the compiled functions after
        the ``param_names``, solved with the start and never folded into the code.
    library
        The loaded ``CompiledLibrary`` (fast calls, RK4 in C).
    directory
        Where the C, the manifest, the start and the compiled library live
        (``grasping_sym.load(directory)`` loads it again, in any process).
    """

    def __init__(self, directory: Path, manifest: dict, library_path: Path, start: dict,
                 scene=None):
        self.directory = Path(directory)
        #: the scene the model was built from (``gs.build``), or None (``gs.load``): kept
        #: for what draws a run, never read by the runtime
        self.scene = scene
        self.manifest = manifest
        self.start = start
        self.name: str = manifest["name"]
        self.state_names: tuple[str, ...] = tuple(manifest["state_names"])
        #: every column of the compiled outputs: the scene's outputs, then those only the
        #: checks read (the manifest's ``check_outputs``, ``pipeline.with_check_outputs``)
        self._columns: tuple[str, ...] = tuple(manifest["output_names"])
        hidden = set(manifest.get("check_outputs", ()))
        self.output_names: tuple[str, ...] = tuple(k for k in self._columns if k not in hidden)
        self.param_names: tuple[str, ...] = tuple(manifest["param_names"])
        start_names = tuple(manifest.get("start_param_names", ()))
        self.start_params: dict[str, float] = {k: float(start["start_params"][k]) for k in start_names}
        #: the control inputs (``model.control``): ``u1, u2, ...`` joint torques, or none
        self.input_names: tuple[str, ...] = tuple(manifest.get("input_names", ()))
        coefficients = (*self.input_names, *(f"{k}_rate" for k in self.input_names))
        #: every entry of the compiled functions' ``p``: ``param_names``, the start's values,
        #: then the inputs' coefficients (``u(t) = a + b t``: every ``a``, then every ``b``)
        self.p_names: tuple[str, ...] = self.param_names + start_names + coefficients
        self.default_params = np.array([*manifest["param_values"], *self.start_params.values(),
                                        *[0.0] * len(coefficients)], dtype=float)
        self._x0 = np.array(start["initial_state"], dtype=float)
        self.lower = np.array([-math.inf if v is None else v for v in manifest["lower"]])
        self.upper = np.array([math.inf if v is None else v for v in manifest["upper"]])
        self.library_path = Path(library_path)
        self.library = CompiledLibrary(self.library_path, self.state_names,
                                       default_p=self.default_params if self.p_names else None)
        self._external = None
        self._guarded = None
        self._public: dict = {}
        self._plans: dict = {}  # runtime.fastpath: settings the full path accepted
        self._checked: dict = {}  # runtime.fastpath: initial states whose checks passed
        self._pdict = dict(zip(self.param_names, map(float, self.default_params)))
        if not self.p_names:
            # bind the compiled calls directly: no Python wrapper in the way
            self.rhs = self.library.rhs
            self.rhs_batch = self.library.rhs_batch
        elif self.input_names:
            self.rhs = self._rhs_with_inputs

    def __reduce__(self):
        """Pickled as its manifest, start, C and library bytes (``runtime.portable``): another
        process makes the same model from its cache or the bytes (a model from ``gs.build``
        also from its C, ``pipeline.built``)."""
        return portable.restore, (portable.payload(self), None, Model)

    def __repr__(self) -> str:
        """One screen: what the model integrates, what can vary at run time, where it lives."""
        def join(values) -> str:
            text = ", ".join(values)
            return text if len(text) <= 90 else text[:87] + "..."

        law = (self.manifest.get("controller") or {}).get("law")
        lines = [f"Model {self.name!r}: {len(self.state_names)} states, {len(self.output_names)} "
                 f"outputs, {len(self.param_names)} run-time parameters",
                 f"  states      {join(self.state_names)}",
                 f"  outputs     {join(self.output_names) or '(none)'}"]
        if self.param_names:
            lines.append("  run-time    " + join(f"{k} = {v:g}" for k, v in
                                                 zip(self.param_names, self.default_params)))
        if self.start_params:
            lines.append("  start       " + join(f"{k} = {v:.6g}" for k, v in self.start_params.items()))
        if self.input_names:
            lines.append(f"  inputs      {join(self.input_names)}")
        lines.append(f"  controller  {law if law else 'none (open loop)'}")
        lines.append(f"  directory   {self.directory}")
        return "\n".join(lines)

    # ------------------------------------------------------------------ calls
    @property
    def path(self) -> Path:
        """Where the model is stored, its start included: ``grasping_sym.load(model.path)``
        loads the same model again, in any process (``<directory>/starts/<key>.json``)."""
        return self.directory / stored.STARTS_DIR / f"{self.start['key'][:16]}.json"

    def params(self, params: dict[str, float] | None = None) -> np.ndarray | None:
        """The compiled functions' input ``p`` (``p_names``): the scene's values of the
        run-time parameters, overridden by ``params``, then the start's values, then the
        inputs' coefficients (zero)."""
        if params and not self.param_names:
            raise RunArgumentError(
                f"parameters {sorted(params)} are folded into this model's code; build the "
                "scene with runtime=(...) naming them to vary them without a rebuild"
            )
        if params is not None and not isinstance(params, Mapping):
            raise RunArgumentError(f"params is {type(params).__name__}: give a dict of run-time "
                                   f"parameter values by name, e.g. {{{self.param_names[0]!r}: 0.5}}"
                                   if self.param_names else "params must be a dict")
        if not self.p_names:
            return None
        p = self.default_params.copy()
        rules = self.manifest.get("param_rules", {})
        for k, v in (params or {}).items():
            if k not in self.param_names:
                raise RunArgumentError(f"{k!r} is not a run-time parameter of this model "
                                       f"(run-time: {self.param_names})")
            value = real(f"params[{k!r}]", v)
            rule = rules.get(k, "finite")
            if rule == "positive" and not value > 0 or rule == "nonnegative" and not value >= 0:
                raise RunArgumentError(f"params[{k!r}] = {value!r} must be "
                                       f"{'> 0' if rule == 'positive' else '>= 0'} (as the scene requires "
                                       f"of {k}); give a physical value")
            p[self.param_names.index(k)] = value
        return p

    def initial_state(self, *, branch: str = "start", **values: float) -> np.ndarray:
        """A consistent initial state, ordered as ``state_names`` (a fresh array).

        Without arguments: the scene's start (stored with the model). With state components
        by name, e.g. ``initial_state(q1=0.6)`` or ``initial_state(theta=0.2)``:
        those values held, the other coordinates and speeds solved onto the contact
        constraints, with no rebuild (``runtime.start``; in 2D the pivot stays where the
        scene put it, so one coordinate fixes the others; in 3D see ``with_start``, which
        also moves the spring's rest point).

        The pose is the one on the branch of the scene's start: followed from the scene's
        start to the given values in small steps, so that neighbouring values give
        neighbouring poses (the same finger posture, a contact point that moves
        continuously), never a jump to another solution of the same equations.
        ``solve_start`` returns the same state with the branch and the contact point chosen.

        Raises ``UnreachableStartError`` for a pose the bodies cannot take, and its subclass
        ``StartBranchError`` for one that the scene's start's branch does not reach while
        another branch does (another posture and contact point); ``branch="any"`` accepts
        that other branch's pose instead.
        """
        if not values:
            if branch not in start_.BRANCHES:
                return start_.solve_start(self, values, branch).x  # refuses the bad branch
            return self._x0.copy()
        return start_.solve(self, values, branch)

    def solve_start(self, *, branch: str = "start", **values: float) -> start_.StartSolution:
        """``initial_state(**values)`` with what was chosen: a ``runtime.start.StartSolution``
        with the state ``x``, the coordinates ``solved``, the contact point chosen
        (``contact``: the contact parameters, ``s`` in 2D), the branch's orientation
        (``branch``, and ``start_branch`` at the scene's start: the sign of the start
        conditions' Jacobian determinant in the solved coordinates) and
        ``on_start_branch`` (False only for another branch's pose taken with
        ``branch="any"``). Without values: the scene's start."""
        return start_.solve_start(self, values, branch)

    def with_start(self, *, branch: str = "start", **values: float) -> Model:
        """This model started elsewhere: ``initial_state(**values)`` as its start, with the
        start's run-time values that it implies (3D: the centre spring's rest point moves to
        the new mean fingertip centre; 2D: the pivot stays). Same compiled library, no
        rebuild; stored beside the model, so ``grasping_sym.load(new.path)`` reloads it.
        The branch and contact point chosen (``solve_start``'s record) are in
        ``new.start["info"]["branch"]``; ``branch`` as for ``initial_state``."""
        record = start_.start_record(self, values, branch)
        starts = safety.ensure_dir(self.directory / stored.STARTS_DIR, root=self.directory)
        stored.write_json(starts / f"{record['key'][:16]}.json", record)
        model = Model(self.directory, self.manifest, self.library_path, record)
        model.build_info = {"source": "run-time start", "from": self.start["key"]}
        return model

    def rhs(self, x, p=None) -> np.ndarray:  # replaced by the compiled call when np == 0
        """Compiled closed-loop right-hand side ``xdot = f(x, p)``, shape ``(n_states,)``.

        ``p``: values of ``param_names`` (the start's values are appended), or of every
        ``p_names``; default the model's.

        The raw fast path: only the shapes are checked. The values are not (no parameter
        rules, no contour domains, no constraint checks), and a NaN or an infinity in ``x``
        or ``p`` propagates into the result. ``simulate`` checks what it is given."""
        return self.library.rhs(x, self._p(p))

    def _rhs_with_inputs(self, x, u=None, p=None) -> np.ndarray:
        """Compiled ``xdot = f(x, u, p)`` of a model with inputs: ``u`` the inputs' values
        (``input_names``; default 0), ``p`` as for ``rhs`` (the inputs' entries of a full ``p``
        are replaced by ``u``)."""
        full = self._p(p)
        if u is not None:
            uu = np.asarray(u, dtype=float).ravel()
            if uu.shape != (len(self.input_names),):
                raise RunArgumentError(f"u has shape {np.shape(u)}; give one value per input "
                                       f"{self.input_names}")
            full = self.with_inputs(full, uu)
        return self.library.rhs(x, full)

    def rhs_batch(self, X, p=None) -> np.ndarray:
        """``rhs`` for every row of ``X`` (shape ``(n, n_states)``) in one C loop; like ``rhs``
        the raw fast path (shapes checked, values not: NaN propagates)."""
        return self.library.rhs_batch(X, self._p(p))

    def outputs(self, x, p=None) -> dict[str, float]:
        """The requested outputs at one state."""
        self._need_outputs()
        y = self._all_outputs(x, p)
        return {k: y[k] for k in self.output_names}

    def outputs_batch(self, X, p=None) -> dict[str, np.ndarray]:
        """The requested outputs at every row of ``X``."""
        self._need_outputs()
        Y = self._all_outputs_batch(X, p)
        return {k: Y[k] for k in self.output_names}

    def _all_outputs(self, x, p=None) -> dict[str, float]:
        """Every compiled output at one state, those only the checks read included (empty
        for a model compiled without outputs)."""
        if not self._columns:
            return {}
        timed = bool(self.manifest.get("outputs_time"))
        y = self._output_row(x, self._p(p), 0.0 if timed else None)
        return dict(zip(self._columns, map(float, y)))

    def _all_outputs_batch(self, X, p=None) -> dict[str, np.ndarray]:
        """Every compiled output at every row of ``X`` (``_all_outputs``)."""
        if not self._columns:
            return {}
        if self.manifest.get("outputs_time"):  # a law that reads the time: at t = 0
            Y = np.array([self._output_row(x, self._p(p), 0.0) for x in np.atleast_2d(X)])
        else:
            Y = self.library.outputs_batch(X, self._p(p))
        return {k: Y[:, i].copy() for i, k in enumerate(self._columns)}

    def _p(self, p):
        """``p`` completed with the start's values (and zero inputs) when it holds only
        ``param_names``'."""
        if not self.p_names:
            return None
        if p is None:
            return self.default_params
        if np.ndim(p) == 1 and len(p) == len(self.param_names) < len(self.p_names):
            return np.concatenate([np.asarray(p, dtype=float),
                                   self.default_params[len(self.param_names):]])
        return p

    def _need_outputs(self) -> None:
        if not self.output_names:
            raise AttributeError(f"model {self.name!r} was built with no outputs: build the "
                                 "scene with outputs=(...) naming the ones you need")

    def external_rhs(self):
        """The compiled right-hand side as a CasADi Function (for CVODES/IDAS)."""
        if self._external is None:
            import casadi as ca  # noqa: PLC0415 - loading a model needs no CasADi

            has_jac = bool(self.manifest.get("driver_defines", {}).get("GS_HAS_JAC", 1))
            # without a generated Jacobian, CasADi differences the compiled rhs: forward
            # differences (nx + 1 calls) cost a quarter of its default central scheme and,
            # for a Newton matrix, lose nothing measurable (benchmarks/results/paper3d.md)
            opts = {} if has_jac else {"enable_fd": True, "fd_method": "forward"}
            self._external = ca.external(f"{self.name}_rhs", str(self.library_path), opts)
        return self._external

    def external_rhs_guarded(self):
        """``external_rhs`` that is NaN outside the contours' domains
        (``codegen.functions.guarded_rhs``; the plain one when the model has no bounds): CVODES
        cannot step past a contact leaving its contour and fails at the step where it happens,
        not at the next output time. (IDAS, given the same, crawls toward the boundary up to
        ``max_steps`` steps: it keeps the plain rhs and an excursion state instead,
        ``runtime.integrators.dae_for``.)"""
        if "rhs_guarded" not in self.manifest:
            return self.external_rhs()
        if self._guarded is None:
            import casadi as ca  # noqa: PLC0415

            has_jac = bool(self.manifest.get("driver_defines", {}).get("GS_HAS_JAC", 1))
            opts = {} if has_jac else {"enable_fd": True, "fd_method": "forward"}
            self._guarded = ca.external(self.manifest["rhs_guarded"], str(self.library_path), opts)
        return self._guarded

    # ------------------------------------------------------------------ simulate
    def simulate(self, t_final: float, *, x0=None, method: str = "radau",
                 rtol: float | None = None, atol: float | None = None, t_eval=None, h: float = 1e-4,
                 params: dict[str, float] | None = None, max_steps: int = 1_000_000,
                 outputs: bool = True, checks: bool = True,
                 project: bool | float = False,
                 time_limit: float | None = None, u=None) -> SimulationResult:
        """Integrate from ``x0`` (default ``initial_state()``) to ``t_final`` seconds.

        Parameters
        ----------
        method
            ``'radau'`` (the default: adaptive Radau IIA of order 5, whole loop in C on the
            compiled right-hand side and Jacobian; much less per-step overhead than CVODES,
            best at moderate tolerances: its default rtol 1e-6, atol 1e-9 gives a final-state
            error of 6e-12 on ``paper2d`` in under 1 ms with output every ms and the outputs;
            keep atol >= ~1e-10 since tighter absolute tolerances on near-zero velocities hit
            rounding noise), ``'cvodes'`` (adaptive implicit BDF through CasADi, the
            SUNDIALS reference), ``'idas'``, ``'rk4'`` (fixed step ``h`` s, loop in C),
            or ``'dopri5'`` (adaptive explicit Dormand-Prince 5(4), whole loop in C, dense
            output; it stops with an ``IntegratorError`` saying the system is stiff when its
            step is limited by stability rather than accuracy: on ``paper2d`` with the
            paper's CSM gains, whose constraint modes at -3000 1/s cap its step near 1.1 ms,
            that happens for rtol above ~1e-10; with the gains at 0 and ``project=True`` it is
            not stiff and takes ~200 steps at rtol 1e-6), or ``'dop853'`` (adaptive explicit
            Dormand-Prince 8(5,3), the same loop with eighth-order steps: fewer of them at
            tight tolerances; paper3d at final-state error 1e-8 takes 1.3 times fewer
            evaluations than with ``'dopri5'``).
            ``'rk4'``, ``'radau'``, ``'dopri5'`` and ``'dop853'`` check the contact
            parameters after every step.
        rtol, atol
            Tolerances of the adaptive methods; None: the method's defaults
            (``DEFAULT_TOLERANCES``: radau 1e-6 / 1e-9, dopri5 1e-8 / 1e-10, dop853 1e-8 /
            1e-10, cvodes and idas 1e-10 / 1e-12).
        max_steps
            The most steps a run may take, in total: for 'cvodes' and 'idas' the step
            attempts, counted in C as the run goes (``c/budget.c``), so a run stops as soon
            as it has taken them.
        time_limit
            Seconds of wall time the integration may take (None: no limit); past it the run
            stops with an ``IntegratorError``. Ctrl-C stops every method within a few steps
            and raises ``KeyboardInterrupt``.
        t_eval
            Output times (s); default every millisecond from 0 to ``t_final`` (and at least
            ``[0, t_final]``).
        params
            Values of run-time parameters (see ``param_names``).
        u
            The control inputs (``input_names``; a model built with ``inputs="torques"``): one
            number per input (N m, held constant), or a table of ``grasping_sym.runtime.inputs``
            (``piecewise_linear``, ``zero_order_hold``); default 0. The integration restarts at
            every knot of a table inside the run ('rk4' needs a constant input).
        outputs
            Evaluate the model's outputs along the trajectory (True or False; the outputs
            themselves are chosen when the scene is made, e.g. ``paper2d(outputs=(...))``).
        checks
            Turn silent failure modes into named errors (default True). The checks read
            compiled outputs that every model has, whichever outputs the scene asked to show
            (``pipeline.with_check_outputs``: every contact's normal force and relative
            curvature, the constraints; a model built before they were added checks what
            its outputs hold):

            - at ``x0``: ``max(|Q|, |R|) <= 1e-8`` m (outputs ``Q`` and ``R``, or
              ``constraint_residual``), else ``InconsistentInitialStateError``; and
              ``kappa_sum * |Om| > 1e-3`` (output ``kappa_sum``; ``|Om|`` the distance of the
              object's pivot from the finger base), else ``RelativeCurvatureError``;
            - along the returned trajectory, on the output samples (whether or not
              ``outputs`` asks to return them; the outputs are evaluated at every output time
              for the checks, and only ``checks=False`` saves that): every contact's
              normal multiplier (``f``; ``f1``, ``f2``, ... with several) must stay > 0
              (``ContactOpenedError``) and its relative curvature (``kappa_sum``,
              ``kappa_sum{i}``, 3D ``krel_min{i}``) above 1e-3 of its initial value
              (``RelativeCurvatureError``); the first event in time is raised, its time
              interpolated linearly between the samples around it. Events between two
              samples that do not show on either are not seen: use a denser ``t_eval``.
            - when the integrator fails, the stored part of the trajectory is checked the
              same way, so a blow-up caused by a vanishing ``kappa_sum`` or an opening
              contact is reported as such.

            The thresholds: the update law (29) moves the contact at
            ``s' = (relative rotation rate) / kappa_sum``; at 1e-3 of its initial value the
            contact point races 1000 times faster per unit of relative rotation than at the
            start and the Jacobian's conditioning degrades by the same factor (an
            integrator then either crawls or blows up within a few steps). At ``t = 0``,
            ``kappa_sum * |Om| <= 1e-3`` means that a relative rotation of 1 mrad moves the
            contact point by the size of the whole scene: the contours nearly osculate and
            the contact point is not well defined.
        project
            ``True`` (or a tolerance in m, default ``projection.PROJECT_TOL`` = 1e-13): after
            every accepted step of 'radau', 'dopri5', 'dop853' or 'rk4' (and at every output between
            steps), project the state onto the contact constraints C = 0 (Gauss-Newton,
            least-norm change of the states C depends on) and then onto Cdot = 0 (least-norm
            change of the speeds), see ``runtime/projection.py``. An alternative to the
            Baumgarte-type stabilisation: with the CSM gains at 0 the motion stays on the
            constraints to the tolerance and the closed loop is no longer stiff.

        Raises
        ------
        IntegratorError
            The integrator failed (time, state and reason in the message).
        ContactLeftContourError
            The contact point reached the end of a contour's domain.
        ContactOpenedError
            The normal force ``f`` reached 0 (``err.t``, ``err.force``): the contact opens.
        RelativeCurvatureError
            ``kappa0 + kappa1`` fell to its threshold (``err.t``, ``err.kappa_sum``).
        InconsistentInitialStateError
            ``x0`` is off the contact constraints (``err.residual`` in m).
        """
        short = (t_eval is not None and params is None and u is None and time_limit is None
                 and (not outputs or not self._columns))
        plan_key = fastpath.key(method, rtol, atol, max_steps, project, checks) if short else None
        if plan_key is not None:  # runtime.fastpath: settings a previous call accepted, straight to C
            plan = self._plans.get(plan_key)
            if plan is not None and type(t_final) in (float, int):
                res = fastpath.run(self, plan, t_final, t_eval, x0)
                if res is not None:
                    return res
        if method not in integrators.METHODS:
            raise RunArgumentError(f"method {method!r} unknown: choose one of {integrators.METHODS}")
        t_final, rtol, atol, max_steps, time_limit = run_settings(method, t_final, rtol, atol, h,
                                                                  max_steps, time_limit)
        flags(outputs=outputs, checks=checks)
        own_start = x0 is None  # the stored start: its speeds are consistent by construction
        x0 = self.initial_state() if own_start else _states("x0", x0)
        if x0.shape != (len(self.state_names),):
            raise RunArgumentError(f"x0 has shape {x0.shape}; expected ({len(self.state_names)},) "
                                   f"ordered as {self.state_names}")
        if not np.all(np.isfinite(x0)):
            raise RunArgumentError(f"x0 = {x0} has non-finite entries")
        self._check_bounds(0.0, x0)
        p = self.params(params)
        proj = projection.settings(self, project, method)
        t_eval, drop_first = _output_times(t_eval, float(t_final))
        res = self._run(t_eval, drop_first, x0, own_start, p, u, method=method, rtol=rtol,
                        atol=atol, h=h, max_steps=max_steps, outputs=outputs, checks=checks,
                        proj=proj, time_limit=time_limit)
        if short:  # the settings and x0 passed: later calls may take the short way
            fastpath.remember(self, plan_key, method, rtol, atol, max_steps, proj, checks)
            if checks:
                fastpath.checked(self, None if own_start else x0)
        return res

    def simulate_many(self, t_final: float, *, x0=None, params=None, u=None, method: str = "radau",
                      rtol: float | None = None, atol: float | None = None, t_eval=None, h: float = 1e-4,
                      max_steps: int = 1_000_000, project: bool | float = False,
                      outputs: bool = False, checks: bool = True, threads: int | None = None,
                      time_limit: float | None = None):
        """Many runs in one call: N simulations over a pool of threads in C, the GIL released
        (``runtime.batch``); returns a ``BatchResult``.

        Each run is bit for bit ``simulate(t_final, x0=x0[i], params={k: params[k][i]}, u=u[i],
        ...)`` with the same settings (the same C loop, the same arguments); a run that fails
        is recorded (``status``, and ``errors`` with the message ``simulate`` would raise) and
        loses nothing of the others.

        Parameters
        ----------
        x0
            ``(N, n_states)`` initial states, or one state for every run (default: the
            model's start; ``initial_state(...)`` solves consistent ones).
        params
            Run-time parameters (``param_names``, and the start's run-time values
            ``start_params``) by name: one number, or an array ``(N,)``.
        u
            Constant inputs, ``(n_inputs,)`` or ``(N, n_inputs)``, or one table of
            ``grasping_sym.runtime.inputs`` for every run.
        method, rtol, atol, h, max_steps, project, checks, time_limit
            As for ``simulate`` (the loops in C: 'radau', 'dopri5', 'dop853', 'rk4'); ``time_limit`` is
            for the whole batch (runs not finished by then get status -9).
        t_eval
            Output times common to every run: ``x`` (``(N, m, n_states)``) and the outputs are
            kept there; without, only the final states are.
        outputs
            Return the outputs (at the final states, or at ``t_eval``). With ``checks`` they are
            evaluated and the events along them checked as ``simulate`` does either way.
        threads
            Threads to run on (default: every core this process may use).
        """
        from grasping_sym.runtime import batch  # noqa: PLC0415

        return batch.simulate_many(self, t_final, x0=x0, params=params, u=u, method=method,
                                   rtol=rtol, atol=atol, t_eval=t_eval, h=h, max_steps=max_steps,
                                   project=project, outputs=outputs, checks=checks,
                                   threads=threads, time_limit=time_limit)

    def _run(self, t_eval, drop_first, x0, own_start, p, u, *, method, rtol, atol, h, max_steps,
             outputs, checks, proj, time_limit) -> SimulationResult:
        """``simulate`` once its arguments are checked: ``p`` is every entry of ``p_names``
        (the inputs' set from ``u``), ``t_eval`` starts at 0 (``drop_first``: the caller's did
        not, so the first row is dropped), ``proj`` is ``projection.settings``'s."""
        sched = self._schedule(u, method, t_eval)
        segments = [(0.0, float(t_eval[-1]), None, None)] if sched is None else \
            sched.segments(0.0, float(t_eval[-1]))
        p0 = p if sched is None else self.with_inputs(p, segments[0][2], segments[0][3])
        start = checks_.check_initial_state(self, x0, p0, rates=not own_start) if checks else {}
        rows_t, rows_x, stats = [], [], {}
        x_now = x0
        for k, (s0, s1, a, b) in enumerate(segments):
            pk = p if sched is None else self.with_inputs(p, a, b)
            grid = t_eval if len(segments) == 1 else np.array(
                [s0, *t_eval[(t_eval > s0) & (t_eval < s1)], s1])
            t, X, st = self._integrate(method, x_now, grid, pk, start, checks, rtol=rtol, atol=atol,
                                       max_steps=max_steps, h=h, proj=proj, time_limit=time_limit)
            rows_t.append(t if k == 0 else t[1:])
            rows_x.append(X if k == 0 else X[1:])
            x_now = X[-1]
            for key, v in st.items():
                stats[key] = stats.get(key, 0) + v if isinstance(v, (int, float)) and key != "h" else v
        t, X = np.concatenate(rows_t), np.concatenate(rows_x)
        if len(segments) > 1:
            keep = np.isin(t, t_eval)
            t, X = t[keep], X[keep]
            stats["segments"] = len(segments)
        # the checks read the compiled outputs whether or not the result shows them; a run
        # that returns none and has no event (checks.clean, on the watched columns) needs no more
        quiet = checks and not outputs and sched is None and checks_.clean(self, t, X, p)
        outs = self._outputs_along(t, X, p, sched) if (outputs or checks and not quiet) \
            and self._columns else {}
        if checks and outs:
            event = checks_.trajectory_event(self, t, X, outs, start)
            if event is not None:
                raise event
        outs = {k: outs[k] for k in self.output_names} if outputs and outs else {}
        if drop_first:
            t, X = t[1:], X[1:]
            outs = {k: v[1:].copy() for k, v in outs.items()}
        pdict = dict(zip(self.param_names, [] if p is None else map(float, p)))
        res = SimulationResult(t=t, x=X, state_names=self.state_names, outputs=outs,
                               method=method, stats=stats, params=pdict, scene=self.scene)
        return res

    def _integrate(self, method, x0, t_eval, p, start, checks, *, rtol, atol, max_steps, h, proj,
                   time_limit):
        """One integration over ``t_eval`` (one segment of the inputs) with named errors."""
        if method in integrators.C_LOOPS:
            try:
                t, X, stats = integrators.c_loop(self, method, x0, t_eval, p, rtol=rtol,
                                                 atol=atol, max_steps=max_steps, h=h,
                                                 projection=proj, time_limit=time_limit)
            except IntegratorError as exc:
                err = _blow_up(self, self._classify(exc), method, h)
                if checks:
                    checks_.raise_earlier_event(self, err, p, start)
                raise err from None
        else:
            pp = np.zeros(0) if p is None else p
            try:
                t, X, stats = integrators.sundials(self, method, x0, t_eval, pp, rtol, atol,
                                                   max_steps, time_limit)
            except IntegratorError as failed:
                exc = self._exit_at_failure(failed, t_eval, p, rtol, atol) \
                    if method == "cvodes" else failed
                if checks:
                    checks_.raise_earlier_event(self, exc, p, start)
                raise exc from None
            for k in stats.pop("excursions", ()):  # IDAS: a step ended outside a domain
                found = ContactLeftContourError(t[k], X[k], "a contact left its contour between "
                                                "the outputs", self.state_names)
                exc = self._locate_exit(found, t[k - 1], X[k - 1], t[min(k + 1, len(t) - 1)], p,
                                        rtol, atol)
                if exc is not found:
                    if checks:
                        exc.trajectory = (t[:k].copy(), X[:k].copy())
                        checks_.raise_earlier_event(self, exc, p, start)
                    raise exc from None
            for i in range(len(t)):
                try:
                    self._check_bounds(t[i], X[i], previous=(t[i - 1], X[i - 1]) if i else None)
                except ContactLeftContourError as found:
                    exc = self._locate_exit(found, t[i - 1], X[i - 1], t[i], p, rtol, atol) \
                        if i else found
                    if checks:
                        exc.trajectory = (t[:i].copy(), X[:i].copy())
                        checks_.raise_earlier_event(self, exc, p, start)
                    raise exc from None
        return t, X, stats

    # ------------------------------------------------------------------ CasADi
    # ------------------------------------------------------------------ inputs
    def _schedule(self, u, method: str, t_eval: np.ndarray):
        """The inputs' schedule (``grasping_sym.runtime.inputs``), None for a model without inputs."""
        if not self.input_names:
            if u is not None:
                raise RunArgumentError("u given, but this model has no inputs: build the scene with "
                                       "inputs='torques' (e.g. gs.scenes.paper2d(inputs='torques'))")
            return None
        from grasping_sym.runtime.inputs import as_schedule  # noqa: PLC0415

        sched = as_schedule(u, len(self.input_names))
        if method == "rk4" and any(0 < k < t_eval[-1] for k in sched.knots):
            raise RunArgumentError("rk4 reports on one uniform grid and cannot restart at the table's "
                                   "knots: use method='radau', 'dopri5' or 'cvodes' with a table input")
        return sched

    def with_inputs(self, p, a, b=None) -> np.ndarray:
        """``p`` (all of ``p_names``) with the inputs ``u(t) = a + b t`` (``b``: default 0)."""
        n = len(self.input_names)
        if not n:
            raise RunArgumentError("this model has no inputs: build the scene with inputs='torques'")
        out = np.array(self.default_params if p is None else p, dtype=float)
        k = self.p_names.index(self.input_names[0])
        out[k:k + n] = np.asarray(a, dtype=float).ravel()
        out[k + n:k + 2 * n] = 0.0 if b is None else np.asarray(b, dtype=float).ravel()
        return out

    def _outputs_along(self, t, X, p, sched) -> dict[str, np.ndarray]:
        """Every compiled output (``_all_outputs``) at the rows of ``X`` (times ``t``): the
        inputs' value at each time (``a + b t`` as ``a``), and the time itself for a law that
        reads it. Rows where the inputs are constant go to the compiled batch call, segment by
        segment."""
        timed = bool(self.manifest.get("outputs_time"))
        if sched is None and not timed:
            return self._all_outputs_batch(X, p)
        p = self._p(p)
        Y = np.empty((len(t), len(self._columns)))
        segment = np.searchsorted(sched.knots, t, side="right") if sched is not None else \
            np.zeros(len(t), dtype=int)
        for k in np.unique(segment):
            rows = np.flatnonzero(segment == k)
            if sched is not None and not timed and not np.any(sched.b[k]):
                Y[rows] = self.library.outputs_batch(X[rows], self.with_inputs(p, sched.a[k]))
                continue
            for i in rows:
                pi = p if sched is None else self.with_inputs(p, sched(float(t[i])))
                Y[i] = self._output_row(X[i], pi, t[i] if timed else None)
        return {k: Y[:, i].copy() for i, k in enumerate(self._columns)}

    def _output_row(self, x, p, t=None) -> np.ndarray:
        if t is None:
            return np.asarray(self.library.outputs(x, p))
        if getattr(self, "_timed_outputs", None) is None:
            import casadi as ca  # noqa: PLC0415

            self._timed_outputs = ca.external(f"{self.name}_outputs", str(self.library_path))
        return np.asarray(self._timed_outputs(x, np.append(p, t))).ravel()

    def _check_bounds(self, t: float, x: np.ndarray, previous=None) -> None:
        bad = np.flatnonzero((x < self.lower) | (x > self.upper))
        if bad.size == 0:
            return
        i = int(bad[0])
        t_cross, x_good = t, x
        if previous is not None:
            tp, xp = previous
            bound = self.lower[i] if x[i] < self.lower[i] else self.upper[i]
            frac = (bound - xp[i]) / (x[i] - xp[i])
            t_cross, x_good = tp + frac * (t - tp), xp
        raise ContactLeftContourError(
            t_cross, x_good,
            f"contact parameter {self.state_names[i]} = {x[i]:.6g} left the contour's domain "
            f"[{self.lower[i]:.6g}, {self.upper[i]:.6g}] (crossing at about t = {t_cross:.6g} s); "
            "extend the contour's domain or shorten the simulation",
            self.state_names,
        )

    def _exit_at_failure(self, exc: IntegratorError, t_eval: np.ndarray, p, rtol: float,
                         atol: float) -> IntegratorError:
        """A CVODES failure caused by a contact leaving its contour (the guarded rhs is NaN
        outside the domains, so CVODES cannot step past the exit and fails there), named as
        such: the Radau loop, which checks the bounds after every step, is run from the last
        recovered state across the failure time; ``exc`` itself when it finds no exit."""
        traj = getattr(exc, "trajectory", None)
        if "rhs_guarded" not in self.manifest or traj is None or not math.isfinite(exc.t):
            return exc
        t_prev, x_prev = float(traj[0][-1]), traj[1][-1]
        t_end = min(float(t_eval[-1]), exc.t + 1e-6 * max(1.0, abs(exc.t)))
        if not t_end > t_prev:
            return exc
        found = ContactLeftContourError(exc.t, exc.x, "a contact left its contour",
                                        self.state_names)
        located = self._locate_exit(found, t_prev, x_prev, t_end, p, rtol, atol)
        return located if located is not found else exc

    def _locate_exit(self, exc: ContactLeftContourError, t0: float, x0: np.ndarray, t1: float,
                     p, rtol: float, atol: float) -> ContactLeftContourError:
        """Where between the outputs ``t0`` and ``t1`` the contact left its contour: the
        interval is integrated again from ``x0`` by the C Radau loop, which checks the bounds
        after every step, so the exit is found at the step where it happens (SUNDIALS, run
        through CasADi, is seen only at the output times). Returns ``exc`` with that time and
        state (``exc`` itself if the second run does not leave the domain)."""
        try:
            self.library.radau5(x0, np.array([t0, t1]), p=p, rtol=rtol, atol=max(atol, 1e-14),
                                lo=self.lower, hi=self.upper)
        except IntegratorError as inner:
            if getattr(inner, "code", None) == -2:  # GS_ERR_BOUNDS
                bad = np.asarray(getattr(inner, "x_rejected", inner.x), dtype=float)
                out = np.flatnonzero((bad < self.lower) | (bad > self.upper))
                what = exc.reason.split(" (crossing at")[0]
                if out.size:
                    i = int(out[0])
                    what = (f"contact parameter {self.state_names[i]} left the contour's domain "
                            f"[{self.lower[i]:.6g}, {self.upper[i]:.6g}]")
                located = ContactLeftContourError(
                    inner.t, inner.x,
                    what + f" (in the Radau step from t = "
                    f"{inner.t:.9g} s, found between the outputs at {t0:.6g} and {t1:.6g} s); "
                    "extend the contour's domain or shorten the simulation",
                    self.state_names)
                located.x_rejected = getattr(inner, "x_rejected", None)
                return located
        return exc

    def _classify(self, exc: IntegratorError) -> IntegratorError:
        if "left [" in exc.reason:
            new = ContactLeftContourError(exc.t, exc.x, exc.reason + ": the contact point "
                                          "reached the end of a contour's domain",
                                          self.state_names)
            for key in ("t_rejected", "x_rejected", "trajectory", "code", "stats"):
                if hasattr(exc, key):
                    setattr(new, key, getattr(exc, key))
            return new
        return exc


#: Each method's tolerances ``(rtol, atol)`` when ``simulate`` / ``simulate_many`` get none.
DEFAULT_TOLERANCES = {"radau": (1e-6, 1e-9), "dopri5": (1e-8, 1e-10), "dop853": (1e-8, 1e-10),
                      "cvodes": (1e-10, 1e-12),
                      "idas": (1e-10, 1e-12), "rk4": (1e-10, 1e-12)}


def tolerances(method: str, rtol, atol) -> tuple:
    """``(rtol, atol)`` with the method's defaults where None."""
    d = DEFAULT_TOLERANCES.get(method, (1e-10, 1e-12))
    return (d[0] if rtol is None else rtol), (d[1] if atol is None else atol)


def run_settings(method: str, t_final, rtol, atol, h, max_steps, time_limit) -> tuple:
    """``(t_final, rtol, atol, max_steps, time_limit)`` of ``simulate`` / ``simulate_many``,
    checked, with the method's default tolerances where None; a bad one is refused by name."""
    rtol, atol = tolerances(method, rtol, atol)
    t_final = real("t_final", t_final, "seconds")
    if not t_final > 0:
        raise RunArgumentError(f"t_final = {t_final!r} must be > 0 (seconds)")
    if t_final < SUNDIALS_MIN_T and method in ("cvodes", "idas"):
        raise RunArgumentError(f"t_final = {t_final:g} s is shorter than {SUNDIALS_MIN_T:g} s, below "
                               f"what {method}'s step control starts on (IDAS fails, CVODES returns "
                               "x0): use method='radau', 'dopri5' or 'rk4' for so short a run")
    if time_limit is not None:
        time_limit = real("time_limit", time_limit, "seconds of wall time")
        if not time_limit > 0:
            raise RunArgumentError(f"time_limit = {time_limit!r} must be > 0 (seconds of wall time) or None")
    _positive("rtol", rtol)
    _positive("atol", atol)
    for name, value, unit in (("rtol", rtol, "a relative error of 100 %"),
                              ("atol", atol, "an error of 1 m or 1 rad in every state")):
        if not value < 1:
            raise RunArgumentError(f"{name} = {value!r} must be below 1 ({unit} or more accepts "
                                   "any step, and the run's failure would be blamed on the "
                                   "physics): give e.g. rtol=1e-6, atol=1e-9")
    if method == "rk4":
        _positive("h", h, "the RK4 step (s); stable below ~9e-4 s for paper2d's CSM gains")
    if isinstance(max_steps, (bool, np.bool_)) or not isinstance(max_steps, numbers.Integral) \
            or not 0 < max_steps <= MAX_STEPS:
        raise RunArgumentError(f"max_steps = {max_steps!r:.40} must be an integer from 1 to "
                               f"{MAX_STEPS} (2**63 - 1, the C loops' step counter)")
    if time_limit is not None and time_limit > MAX_TIME_LIMIT:
        raise RunArgumentError(f"time_limit = {time_limit:g} s is more than {MAX_TIME_LIMIT:g} s "
                               "(about 30 years): give None for no limit")
    if method == "rk4" and t_final / h > MAX_RK4_STEPS:
        raise RunArgumentError(f"h = {h:g} s over t_final = {t_final:g} s means {t_final / h:.3g} "
                               f"RK4 steps, more than {MAX_RK4_STEPS:.0e}: give a larger h (or an "
                               "adaptive method, e.g. 'radau')")
    return t_final, rtol, atol, int(max_steps), time_limit


#: Largest ``max_steps``: the C loops count steps in a 64-bit ``long``.
MAX_STEPS = 2**63 - 1
#: Largest ``time_limit`` (s); beyond it, give None (no limit).
MAX_TIME_LIMIT = 1e9
#: Most steps an RK4 run may take (``t_final / h``): far beyond any run that finishes, well
#: inside the C loop's step counter.
MAX_RK4_STEPS = 10**12


def flags(**values) -> None:
    """Refuse a switch of ``simulate`` / ``simulate_many`` (``outputs``, ``checks``) that is not
    True or False: a tuple of names given as ``outputs`` would read as True."""
    for name, value in values.items():
        if not isinstance(value, (bool, np.bool_)):
            hint = (": the outputs themselves are chosen when the scene is made, e.g. "
                    "gs.scenes.paper2d(outputs=('Q', 'f'))" if name == "outputs" else "")
            raise RunArgumentError(f"{name} = {value!r:.60} is {type(value).__name__}: give True "
                                   f"or False{hint}")


def real(name: str, value, what: str = "") -> float:
    """``value`` as a finite float: Python, NumPy and SymPy numbers are accepted; ``True``,
    strings and other objects are refused by name (a TypeError), as are NaN and infinities
    (a ValueError)."""
    extra = f" ({what})" if what else ""
    if isinstance(value, (bool, np.bool_, str, bytes)) or not (
            isinstance(value, numbers.Real) or getattr(value, "is_Number", False)
            and getattr(value, "is_real", False)):
        raise RunArgumentError(f"{name} = {value!r} is {type(value).__name__}: give a number{extra}")
    v = float(value)
    if not math.isfinite(v):
        raise RunArgumentError(f"{name} = {value!r} must be a finite number{extra}")
    return v


def _states(name: str, value) -> np.ndarray:
    """An array of numbers (a TypeError for strings, booleans or objects)."""
    arr = np.asarray(value)
    if arr.dtype.kind not in "fiu":
        raise RunArgumentError(f"{name} must be numbers, got an array of {arr.dtype} ({value!r:.80})")
    return arr.astype(float)


def _positive(name: str, value, what: str = "") -> None:
    v = real(name, value, what)
    if not v > 0:
        extra = f" ({what})" if what else ""
        raise RunArgumentError(f"{name} = {value!r} must be a finite number > 0{extra}")


#: Shortest run (s) handed to SUNDIALS: below it IDAS's initial-condition step fails with
#: NaN and CVODES returns the initial state unchanged; the C loops integrate any length.
SUNDIALS_MIN_T = 1e-12
#: Most output rows of the default grid (one per ms); beyond, pass ``t_eval``.
MAX_DEFAULT_OUTPUTS = 10_000_000


def _output_times(t_eval, t_final: float) -> tuple[np.ndarray, bool]:
    """Validated output times from 0 to ``t_final``; a leading 0 is added if missing."""
    if t_eval is None:
        n = max(2, math.ceil(t_final * 1000 - 1e-9) + 1)
        if n > MAX_DEFAULT_OUTPUTS:
            raise RunArgumentError(f"t_final = {t_final:g} s with the default output every ms means {n} "
                                   f"output rows (more than {MAX_DEFAULT_OUTPUTS}): pass t_eval with the "
                                   "times you need, e.g. np.linspace(0, t_final, 1001)")
        return np.linspace(0.0, t_final, n), False
    t_eval = _states("t_eval", t_eval)
    if t_eval.ndim != 1 or len(t_eval) < 1:
        raise RunArgumentError(f"t_eval must be a 1-D array of output times, got shape {t_eval.shape}")
    if not np.all(np.isfinite(t_eval)):
        bad = np.flatnonzero(~np.isfinite(t_eval))
        listed = ", ".join(map(str, bad[:10])) + (f", ... ({len(bad)} in all)" if len(bad) > 10 else "")
        raise RunArgumentError(f"t_eval has non-finite entries at indices [{listed}]: give "
                               "finite times")
    if np.any(np.diff(t_eval) <= 0):
        raise RunArgumentError("t_eval must be strictly increasing")
    if t_eval[0] < 0:
        raise RunArgumentError(f"t_eval starts at {t_eval[0]} < 0: the initial state is at t = 0")
    if abs(t_eval[-1] - t_final) > 1e-12 * max(1.0, t_final):
        raise RunArgumentError(f"t_eval ends at {t_eval[-1]!r} but t_final = {t_final!r}: make the "
                               "last output time equal to t_final")
    if t_eval[0] > 0:
        return np.concatenate([[0.0], t_eval]), True
    if len(t_eval) < 2:
        raise RunArgumentError("t_eval needs a time after 0")
    return t_eval, False


#: Fraction of a contour's domain crossed in one rejected step that names a blow-up.
BLOW_UP_JUMP = 0.25


def _blow_up(model: Model, err: IntegratorError, method: str, h: float) -> IntegratorError:
    """A "left the contour's domain" whose rejected step overshot the domain by more than
    1e3 times its width, jumped across more than ``BLOW_UP_JUMP`` of the domain's width in
    that one step (a contact reaching the end of its contour creeps up to it), or went
    non-finite is a numerical blow-up: name it as such (an explicit method beyond its
    stability limit, i.e. a stiff system)."""
    if not isinstance(err, ContactLeftContourError):
        return err
    x_bad = getattr(err, "x_rejected", None)
    if x_bad is None:
        return err
    x_bad = np.asarray(x_bad, dtype=float)
    width = np.where(np.isfinite(model.upper - model.lower), model.upper - model.lower, np.inf)
    over = np.maximum(model.lower - x_bad, x_bad - model.upper)
    jumped = False
    if err.x is not None:
        jump = np.abs(x_bad - np.asarray(err.x, dtype=float))
        jumped = bool(np.any((over > 0) & (jump > BLOW_UP_JUMP * width)))
    if not (np.any(~np.isfinite(x_bad)) or np.any(over > 1e3 * width) or jumped):
        return err
    with np.errstate(invalid="ignore", divide="ignore"):
        ratio = np.where(np.isfinite(width), over / width, -np.inf)
    i = int(np.argmax(np.where(np.isfinite(x_bad), ratio, np.inf)))
    step = f" at h = {h:g} s" if method == "rk4" else ""
    new = IntegratorError(
        err.t, err.x,
        f"{method}: the state blew up (non-finite or exploding values: "
        f"{model.state_names[i]} = {x_bad[i]:.6g} in the rejected step): the method is unstable"
        f"{step} because the system is stiff (large CSM gains); reduce h or use 'radau' or "
        "'cvodes'", model.state_names)
    for key in ("t_rejected", "x_rejected", "trajectory", "code", "stats"):
        if hasattr(err, key):
            setattr(new, key, getattr(err, key))
    return new
