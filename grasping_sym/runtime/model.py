"""A built model: the compiled functions, their names, and simulation.

``Model`` holds what was loaded and delegates each concept to its module: the run-time
parameters (``runtime.parameters``), the outputs (``runtime.outputs``), the starts
(``runtime.start``), the settings of a run (``runtime.settings``), the run itself
(``runtime.run``, its failures named by ``runtime.failures``), the short way of repeated calls
(``runtime.fastpath``), many runs at once (``runtime.batch``) and the CasADi functions of the
library (``runtime.external``).
"""
from __future__ import annotations

import math
import time
from pathlib import Path

import numpy as np

from grasping_sym.errors import IntegratorError, RunArgumentError
from grasping_sym.runtime import batch, external, fastpath, interrupt, modes, parameters, portable
from grasping_sym.runtime import friction as friction_
from grasping_sym.runtime import outputs as outputs_
from grasping_sym.runtime import run as run_
from grasping_sym.runtime import start as start_
from grasping_sym.runtime.compiled import CompiledLibrary
from grasping_sym.runtime.result import SimulationResult
from grasping_sym.runtime.settings import (  # noqa: F401 - their old home (cli, docs)
    DEFAULT_TOLERANCES,
    RunSettings,
    flags,
    real,
    run_defaults,
    run_settings,
    slip_mode,
    tolerances,
)
from grasping_sym.store import files as stored


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
                 scene=None, friction=None):
        self.directory = Path(directory)
        #: the scene the model was built from (``gs.build``), or None (``gs.load``): kept
        #: for what draws a run, never read by the runtime
        self.scene = scene
        #: the contacts' friction law (``gs.contact.Coulomb``, from the scene's ``friction``),
        #: the default of ``simulate``'s ``mu``; None: no friction limit
        self.friction = friction
        self.manifest = manifest
        self.start = start
        #: a model with modes: the base scene's rolling model, which runs the stretches where
        #: every contact rolls (the manifest's ``rolling_map``; ``gs.build`` sets it); None:
        #: the model with modes runs every stretch
        self.rolling = None
        self.name: str = manifest["name"]
        self.state_names: tuple[str, ...] = tuple(manifest["state_names"])
        #: every column of the compiled outputs: the scene's outputs, then those only the
        #: checks read (the manifest's ``check_outputs``, ``pipeline.with_check_outputs``)
        self.columns: tuple[str, ...] = tuple(manifest["output_names"])
        hidden = set(manifest.get("check_outputs", ()))
        self.output_names: tuple[str, ...] = tuple(k for k in self.columns if k not in hidden)
        self.param_names: tuple[str, ...] = tuple(manifest["param_names"])
        start_names = tuple(manifest.get("start_param_names", ()))
        self.start_params: dict[str, float] = {k: float(start["start_params"][k]) for k in start_names}
        #: the control inputs (``model.control``): ``u1, u2, ...`` joint torques, or none
        self.input_names: tuple[str, ...] = tuple(manifest.get("input_names", ()))
        coefficients = (*self.input_names, *(f"{k}_rate" for k in self.input_names))
        #: every entry of the compiled functions' ``p``: ``param_names``, the start's values,
        #: the inputs' coefficients (``u(t) = a + b t``: every ``a``, then every ``b``),
        #: then the charts of the surfaces with atlases (``runtime.atlas``: the start's, 0 unless
        #: a contact or a support point lies beyond chart 0's latitudes at the start)
        charts = tuple(manifest.get("chart_param_names", ()))
        self.p_names: tuple[str, ...] = self.param_names + start_names + coefficients + charts
        #: each chart at the start (``runtime.atlas``): 0, or the start's own where it is
        #: written in chart 1 (a body's support point at chart 0's pole, a grasp's contact near it)
        at_start = ((start.get("info") or {}).get("charts") or {})
        self.default_params = np.array([*manifest["param_values"], *self.start_params.values(),
                                        *[0.0] * len(coefficients),
                                        *[float(at_start.get(k, 0)) for k in charts]], dtype=float)
        self.lower = np.array([-math.inf if v is None else v for v in manifest["lower"]])
        self.upper = np.array([math.inf if v is None else v for v in manifest["upper"]])
        #: the joints whose bounds are their limits (a run stops there with ``JointLimitError``)
        self.joint_limits: frozenset[str] = frozenset(manifest.get("joint_limits", ()))
        self.library_path = Path(library_path)
        self.library = CompiledLibrary(self.library_path, self.state_names,
                                       default_p=self.default_params if self.p_names else None)
        self._external = None
        self._guarded = None
        #: what the run time computes once per model and keeps (``runtime.modes``: the data
        #: every run reads, the function of the outputs only a switch reads)
        self.run_cache: dict = {}
        #: the short way of repeated calls (``runtime.fastpath``): the plans and checked
        #: starts it remembers
        self.short_way = fastpath.Memory(np.array(start["initial_state"], dtype=float),
                                         dict(zip(self.param_names, map(float, self.default_params))))
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
        return parameters.values(self, params)

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
        return start_.initial_state(self, values, branch)

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
        start_.store(self, record)
        model = Model(self.directory, self.manifest, self.library_path, record, self.scene,
                      self.friction)
        model.build_info = {"source": "run-time start", "from": self.start["key"]}
        return model

    def rhs(self, x, p=None) -> np.ndarray:  # replaced by the compiled call when np == 0
        """Compiled closed-loop right-hand side ``xdot = f(x, p)``, shape ``(n_states,)``.

        ``p``: values of ``param_names`` (the start's values are appended), or of every
        ``p_names``; default the model's.

        The raw fast path: only the shapes are checked. The values are not (no parameter
        rules, no contour domains, no constraint checks), and a NaN or an infinity in ``x``
        or ``p`` propagates into the result. ``simulate`` checks what it is given."""
        return self.library.rhs(x, parameters.complete(self, p))

    def _rhs_with_inputs(self, x, u=None, p=None) -> np.ndarray:
        """Compiled ``xdot = f(x, u, p)`` of a model with inputs: ``u`` the inputs' values
        (``input_names``; default 0), ``p`` as for ``rhs`` (the inputs' entries of a full ``p``
        are replaced by ``u``)."""
        full = parameters.complete(self, p)
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
        return self.library.rhs_batch(X, parameters.complete(self, p))

    def outputs(self, x, p=None) -> dict[str, float]:
        """The requested outputs at one state."""
        outputs_.need(self)
        y = outputs_.at(self, x, p)
        return {k: y[k] for k in self.output_names}

    def outputs_batch(self, X, p=None) -> dict[str, np.ndarray]:
        """The requested outputs at every row of ``X``."""
        outputs_.need(self)
        Y = outputs_.at_rows(self, X, p)
        return {k: Y[k] for k in self.output_names}

    def casadi_function(self, which: str = "ode", *, time: bool = False, compiled: bool = False,
                        outputs=None):
        """The closed loop as a CasADi Function: it needs the scene, so it is a method of a
        model made by ``gs.build`` (``pipeline.built.BuiltModel.casadi_function``); a model
        from ``gs.load`` (or one sent to another process) names that."""
        raise ValueError("casadi_function needs the model's scene: make the model with "
                         "gs.build(scene) (a model from gs.load, or one sent to another "
                         "process, has no scene)")

    def external_rhs(self):
        """The compiled right-hand side as a CasADi Function (for CVODES/IDAS)."""
        if self._external is None:
            self._external = external.load(self, f"{self.name}_rhs")
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
            self._guarded = external.load(self, self.manifest["rhs_guarded"])
        return self._guarded

    # ------------------------------------------------------------------ simulate
    @interrupt.run_scope
    def simulate(self, t_final: float, *, x0=None, method: str | None = None,
                 rtol: float | None = None, atol: float | None = None, t_eval=None, h: float = 1e-4,
                 params: dict[str, float] | None = None, max_steps: int = 1_000_000,
                 outputs: bool = True, checks: bool = True,
                 project: bool | float | str | None = None,
                 time_limit: float | None = None, u=None, mu=None,
                 slip: str = "stop", e=None) -> SimulationResult:
        """Integrate from ``x0`` (default ``initial_state()``) to ``t_final`` seconds.

        Parameters
        ----------
        method
            None (the default): the model's own, measured the fastest reliable for its kind of
            scene (the manifest's ``defaults``, from the scene's ``simulate_defaults``:
            ``'radau'`` in 2D, ``'dop853'`` at rtol 1e-7, atol 1e-9 for a 3D grasp, 1.8 to 2.9
            times faster than radau there at the same error: ``benchmarks/results/tolerances.md``),
            with its tolerances where none are given; a run that this default finds stiff runs
            again with radau (``stats["fallback"]`` says why). Or
            ``'radau'`` (adaptive Radau IIA of order 5, whole loop in C on the
            compiled right-hand side and Jacobian; much less per-step overhead than CVODES,
            best at moderate tolerances: its default rtol 1e-6, atol 1e-9 gives a final-state
            error of 2e-11 on ``paper2d`` in about 1 ms with output every ms and the outputs;
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
            Tolerances of the adaptive methods; None: the model's with its own method, else the
            method's defaults (``DEFAULT_TOLERANCES``: radau 1e-6 / 1e-9, dopri5 1e-8 / 1e-10,
            dop853 1e-8 / 1e-10, cvodes and idas 1e-10 / 1e-12).
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
            Values of run-time parameters (see ``param_names``). A model whose surfaces have
            atlases also takes its charts here (``manifest["chart_param_names"]``, 0 or 1
            each; default the start's): the charts ``x0`` is written in, a row of a run after a
            switch being in that row's (``result.charts``).
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
        mu
            Coulomb's friction coefficient at the contacts: one number, one per contact, or a
            ``gs.contact.coulomb(...)`` (default: the scene's ``friction``; None there: no
            limit, the contacts roll whatever force they need). With a ``mu`` the outputs gain
            ``normal_force{i}``, ``tangential_force{i}``, ``cone_ratio{i}`` (``|F_t|/f``) and
            ``cone_margin{i}`` (``mu f - |F_t|``, N) for every contact ``i`` = 1, 2, ..., and
            the checks stop a run whose force leaves a cone with ``FrictionConeError``, at the
            time where the margin reaches 0, located between the output samples by
            integrating again (``runtime.events``). ``math.inf``: no limit.
        e
            Newton's restitution at impacts, in [0, 1], for a model with contact modes
            (``gs.scenes.body_on_plane``; default the scene's law's); refused for others.
        slip
            With ``mu``: ``"stop"`` (default) raises ``FrictionConeError`` where a force leaves
            its cone; ``"record"`` lets the rolling model run on and only shows the cone in the
            outputs (where the cone would have been left: ``cone_margin{i} <= 0``).
        project
            ``True`` (or a tolerance in m, default ``projection.PROJECT_TOL`` = 1e-13): after
            every accepted step of 'radau', 'dopri5', 'dop853' or 'rk4' (and at every output between
            steps), project the state onto the contact constraints C = 0 (Gauss-Newton,
            least-norm change of the states C depends on) and then onto Cdot = 0 (least-norm
            change of the speeds), see ``runtime/projection.py``. An alternative to the
            Baumgarte-type stabilisation: with the CSM gains at 0 the motion stays on the
            constraints to the tolerance and the closed loop is no longer stiff.
            ``"steps"``: the accepted steps only; the output rows between them are the dense
            output of projected steps (paper3d's defaults: within 7e-12 m and 2e-10 m/s of
            the constraints, where projecting every millisecond's row costs 4 ms of the 7).
            None (the default): the model's own, ``"steps"`` for a 3D grasp without a
            stabilisation gain (``GraspScene3D.gain = 0``, the default) with a method that
            projects (cvodes and idas are refused on it, by name: give ``project=False`` to
            run them unstabilised); False for every other model.

        Raises
        ------
        IntegratorError
            The integrator failed (time, state and reason in the message).
        ContactLeftContourError
            The contact point reached the end of a contour's domain.
        JointLimitError
            A joint reached one end of its limits (``RevoluteJoint.limits``).
        ContactOpenedError
            The normal force ``f`` reached 0 (``err.t``, ``err.force``): the contact opens.
        FrictionConeError
            With ``mu``: a contact's ``|F_t|/f`` reached ``mu`` (``err.t``, ``err.contact``,
            ``err.normal``, ``err.tangential``): the contact would slip.
        RelativeCurvatureError
            ``kappa0 + kappa1`` fell to its threshold (``err.t``, ``err.kappa_sum``).
        InconsistentInitialStateError
            ``x0`` is off the contact constraints (``err.residual`` in m).
        """
        short = (t_eval is not None and params is None and u is None and time_limit is None
                 and (outputs is False or outputs is True and not self.columns) and slip == "stop"
                 and not self.manifest.get("modes"))
        method, rtol, atol, chosen = run_defaults(self, method, rtol, atol)
        plan_key = fastpath.key(method, rtol, atol, max_steps, project, checks, mu, self.friction) \
            if short else None
        if plan_key is not None:  # runtime.fastpath: settings a previous call accepted, straight to C
            plan = self.short_way.plans.get(plan_key)
            if plan is not None and type(t_final) in (float, int):
                res = fastpath.run(self, plan, t_final, t_eval, x0)
                if res is not None:
                    return res
        # runtime.modes' short way: settings and a start a previous call accepted, rolling from it
        modes_key = fastpath.key(method, rtol, atol, max_steps, project, checks, (mu, e, outputs), self.friction) \
            if self.manifest.get("modes") and t_eval is not None and params is None and u is None \
            and time_limit is None and slip == "stop" and not self.input_names else None
        if modes_key is not None and type(t_final) in (float, int):
            res = modes.short_way(self, modes_key, t_final, t_eval, x0)
            if res is not None:
                return res
        s = RunSettings.check(self, t_final, method=method, rtol=rtol, atol=atol, t_eval=t_eval,
                              h=h, max_steps=max_steps, project=project, outputs=outputs,
                              checks=checks, time_limit=time_limit)
        if self.manifest.get("modes"):  # contact that can change: runtime.modes
            modes.refuse_unused(params=params, u=u, slip=slip, inputs=bool(self.input_names),
                                charts=parameters.charts_of(self), checks=s.checks)
            x0, own_start = run_.start_state(self, x0)
            return modes.run(self, s, x0, mu, e, u, None if modes_key is None else
                             (modes_key, b"" if own_start else x0.tobytes()), charts=params)
        if e is not None:
            raise RunArgumentError(f"e given, but model {self.name!r} has no impacts (no contact modes): "
                                   "restitution applies to a model with modes (gs.scenes.body_on_plane)")
        s.mu, s.slip = friction_.resolve(self, mu), slip_mode(slip)
        x0, own_start = run_.start_state(self, x0)
        began = time.perf_counter()
        try:
            res = run_.run(self, s, x0, own_start, self.params(params), u)
        except IntegratorError as exc:
            if not (chosen and s.method != "radau" and getattr(exc, "stiff", False)):
                raise
            # the model's own explicit method found this run stiff: radau, as the error says,
            # in the time the first try left
            left = None if time_limit is None else max(time_limit - (time.perf_counter() - began), 1e-9)
            s = RunSettings.check(self, t_final, method="radau", rtol=rtol, atol=atol, t_eval=t_eval, h=h,
                                  max_steps=max_steps, project=project, outputs=outputs, checks=checks,
                                  time_limit=left)
            s.mu, s.slip = friction_.resolve(self, mu), slip_mode(slip)
            res = run_.run(self, s, x0, own_start, self.params(params), u)
            res.stats["fallback"] = f"radau: {exc.reason}"
            return res
        # the settings and x0 passed: later calls may take the short way (which wraps a
        # coordinate in the loop, c/wrap.c, but changes no chart)
        if short and all(rec["from"] == rec["to"] for rec in res.chart_switches):
            fastpath.remember(self, plan_key, s)
            if checks:
                fastpath.checked(self, plan_key, None if own_start else x0, s.watched)
        return res

    def simulate_many(self, t_final: float, *, x0=None, params=None, u=None, method: str | None = None,
                      rtol: float | None = None, atol: float | None = None, t_eval=None, h: float = 1e-4,
                      max_steps: int = 1_000_000, project: bool | float | str | None = None,
                      outputs: bool = False, checks: bool = True, threads: int | None = None,
                      time_limit: float | None = None, mu=None, slip: str = "stop", e=None):
        """Many runs in one call: N simulations over a pool of threads in C, the GIL released
        (``runtime.batch``); returns a ``BatchResult``.

        Each run is bit for bit ``simulate(t_final, x0=x0[i], params={k: params[k][i]}, u=u[i],
        ...)`` with the same settings (the same C loop, the same arguments, the same
        ``outputs``: a run that computes its outputs at rows at most 1 ms apart reads its checks
        there, else its loop watches them at every step, ``runtime.watch``); a run that fails
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
            As for ``simulate`` (the loops in C: 'radau', 'dopri5', 'dop853', 'rk4'; None: the
            model's own, and the runs it finds stiff run again with radau, the others kept,
            ``BatchResult.fallback`` and ``stats["radau"]``); ``time_limit`` is for the whole
            batch (runs not finished by then get status -9).
        t_eval
            Output times common to every run: ``x`` (``(N, m, n_states)``) and the outputs are
            kept there; without, only the final states are.
        outputs
            Return the outputs (at the final states, or at ``t_eval``). With ``checks`` the
            events along every run are found as ``simulate`` with the same ``outputs`` finds
            them (read at rows at most 1 ms apart when the outputs are computed there, else
            watched at every step).
        threads
            Threads to run on (default: every core this process may use).
        mu
            As for ``simulate``: one value for every run, or one per run (``(N,)``, or
            ``(N, n_contacts)``); the runs that leave a cone get status ``-11`` (an event) and
            the ``FrictionConeError`` message, or with ``slip="record"`` roll on (the cone's
            outputs come with ``outputs=True``). A model with contact modes runs each run by
            ``simulate``'s code in turn (``mu`` and ``e`` one value or one per run), its
            switches in ``events``.
        """
        return batch.simulate_many(self, t_final, x0=x0, params=params, u=u, method=method,
                                   rtol=rtol, atol=atol, t_eval=t_eval, h=h, max_steps=max_steps,
                                   project=project, outputs=outputs, checks=checks,
                                   threads=threads, time_limit=time_limit, mu=mu, slip=slip, e=e)

    # ------------------------------------------------------------------ inputs
    def with_inputs(self, p, a, b=None) -> np.ndarray:
        """``p`` (all of ``p_names``) with the inputs ``u(t) = a + b t`` (``b``: default 0)."""
        return parameters.with_inputs(self, p, a, b)
