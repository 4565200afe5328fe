"""Many runs in one call: ``Model.simulate_many``.

The runs go to ``gs_batch`` (``c/batch.c``): one C call integrates all of them over a pool of
threads with the GIL released, each by the loop a single ``simulate`` calls, with the same
arguments, so that every run's numbers are bit for bit the single run's. What ``simulate``
checks in Python is checked here on arrays: the initial state (from the outputs and the
constraint rates the C call evaluates at every ``x0``) and the events along the output samples
(with ``checks``, whether or not ``outputs`` asks to return the outputs). A run that fails, in
C or at a check, is run once more on its own through ``simulate``'s code, so its message is the
single run's named error; it loses nothing of the other runs.
"""
from __future__ import annotations

import math
import numbers
import os
import threading
from collections.abc import Mapping
from dataclasses import dataclass, field, replace
from time import perf_counter

import numpy as np

from grasping_sym.errors import GraspingSymError, RunArgumentError, RunInterruptedError
from grasping_sym.runtime import c_loops, failures, friction, interrupt, modes, parameters, pool, watch
from grasping_sym.runtime import checks as checks_
from grasping_sym.runtime import outputs as outputs_
from grasping_sym.runtime import run as run_
from grasping_sym.runtime.settings import RunSettings, numbers_array, run_defaults, slip_mode

#: The methods ``simulate_many`` runs (the loops in C).
METHODS = ("radau", "dopri5", "dop853", "rk4")
#: Most threads a batch may run on.
MAX_THREADS = 1024
#: ``BatchResult.status`` values besides 0 (success) and the C loops' codes (-1 ... -9).
REFUSED, EVENT = failures.REFUSED, failures.EVENT
#: the status of a run an explicit method found stiff
_STIFF = -8
STATUS = {0: "ok", -1: "non-finite state", -2: "a contact left its contour or a joint reached a limit",
          -3: "evaluation error",
          -5: "step size too small", -6: "too many steps", -7: "projection failed",
          -8: "stiff (explicit method)", -9: "stopped (time limit)", REFUSED: "initial state refused",
          EVENT: "event along the run"}


@dataclass(repr=False)
class BatchResult:
    """The runs of ``Model.simulate_many``, row ``i`` for run ``i``.

    Attributes
    ----------
    x_final
        Final states, shape ``(N, n_states)`` (NaN where the run failed).
    status
        Per run: 0 success, else the reason's code (``STATUS``: the C loops' codes, ``-10`` an
        initial state the checks refuse, ``-11`` an event along the run).
    errors
        Per run: ``""`` on success, else the message ``simulate`` would raise for that run.
    t
        The output times, shape ``(m,)`` (``[0, t_final]`` without ``t_eval``).
    x
        With ``t_eval``: the states at ``t``, shape ``(N, m, n_states)`` (NaN after a failure);
        else None.
    outputs
        With ``outputs=True``: name -> values at the final state ``(N,)``, or at ``t``
        ``(N, m)`` with ``t_eval``.
    x0, params
        The runs' initial states ``(N, n_states)`` and run-time parameters (name -> ``(N,)``).
    stats
        Per-run integrator counters (name -> ``(N,)``), as ``simulate``'s ``stats``.
    wall_time
        Seconds for the whole call.
    events
        A model with contact modes: each run's switches (``SimulationResult.events``); else None.
    modes
        A model with contact modes: each run's modes at the output times
        (``SimulationResult.modes``; None for a run that failed); else None.
    charts
        A model whose surfaces have atlases (a body on a plane, a grasp): each run's charts at
        the output times (``SimulationResult.charts``; None for a run that failed); else None.
        Such a model's runs run by ``simulate``'s code, which switches chart at the step where a
        contact reaches a chart's edge (the batch's C loop of many runs does not), side by side on
        ``threads`` (``runtime.pool``).
    fallback
        None, or why runs ran again with radau (the model's own explicit method found them
        stiff; ``simulate_many``'s ``method`` None): those runs only, ``stats["radau"]``
        marks them; ``method`` is radau when they are all.
    """

    x_final: np.ndarray
    status: np.ndarray
    errors: np.ndarray
    t: np.ndarray
    state_names: tuple[str, ...]
    method: str
    x0: np.ndarray
    params: dict[str, np.ndarray]
    x: np.ndarray | None = None
    outputs: dict[str, np.ndarray] = field(default_factory=dict)
    stats: dict[str, np.ndarray] = field(default_factory=dict)
    wall_time: float = 0.0
    events: list | None = None
    modes: list | None = None
    charts: list | None = None
    fallback: str | None = None

    @property
    def ok(self) -> np.ndarray:
        """Per run: True where it succeeded."""
        return self.status == 0

    def __len__(self) -> int:
        return len(self.status)

    def __getitem__(self, name: str) -> np.ndarray:
        """A final state or an output by name, over the runs (``(N,)``, or ``(N, m)`` for an
        output at every output time)."""
        if name in self.state_names:
            return self.x_final[:, self.state_names.index(name)]
        if name in self.outputs:
            return self.outputs[name]
        raise KeyError(f"{name!r} is neither a state {self.state_names} nor an output "
                       f"{tuple(self.outputs)}")

    def __repr__(self) -> str:
        n, failed = len(self), int(np.sum(self.status != 0))
        why = ""
        if failed:
            codes, counts = np.unique(self.status[self.status != 0], return_counts=True)
            why = " (" + ", ".join(f"{c} {STATUS.get(int(k), k)}" for k, c in zip(codes, counts)) + ")"
        dense = f", {len(self.t)} output times" if self.x is not None else ""
        return (f"BatchResult({n} runs of {self.method}, {n - failed} ok, {failed} failed{why}"
                f"{dense}, {self.wall_time:.3g} s)")


def default_threads() -> int:
    """The cores this process may run on."""
    try:
        return len(os.sched_getaffinity(0))
    except AttributeError:  # not Linux
        return os.cpu_count() or 1


@interrupt.run_scope
def simulate_many(model, t_final: float, *, x0=None, params: Mapping | None = None, u=None,
                  method: str | None = None, rtol: float | None = None, atol: float | None = None, t_eval=None,
                  h: float = 1e-4, max_steps: int = 1_000_000, project: bool | float | str | None = None,
                  outputs: bool = False, checks: bool = True, threads: int | None = None,
                  time_limit: float | None = None, mu=None, slip: str = "stop", e=None) -> BatchResult:
    """``Model.simulate_many`` (documented there)."""
    given = dict(x0=x0, params=params, u=u, rtol=rtol, atol=atol, t_eval=t_eval, h=h, max_steps=max_steps,
                 project=project, outputs=outputs, checks=checks, threads=threads, time_limit=time_limit,
                 mu=mu, slip=slip, e=e)
    method, rtol, atol, chosen = run_defaults(model, method, rtol, atol)
    res = _simulate_many(model, t_final, method=method, **{**given, "rtol": rtol, "atol": atol})
    stiff = np.flatnonzero(res.status == _STIFF)
    if chosen and method != "radau" and stiff.size:
        # the model's own explicit method found runs stiff: those runs again with radau
        start = perf_counter()
        sub = _runs_of(given, stiff, len(res))
        if time_limit is not None:  # the limit is the whole call's: what is left of it
            sub["time_limit"] = max(float(time_limit) - res.wall_time, 1e-9)
        again = _simulate_many(model, t_final, method="radau", **{**sub, "rtol": rtol, "atol": atol})
        res = _merged(res, again, stiff)
        res.wall_time += perf_counter() - start
        if stiff.size == len(res):
            res.method = "radau"
        res.fallback = (f"radau: {method} found {stiff.size} runs stiff (of {len(res)}; "
                        "stats['radau'] marks them)")
    return res


def _runs_of(given: dict, idx: np.ndarray, n: int) -> dict:
    """``simulate_many``'s arguments ``given`` for the runs ``idx`` of ``n``: the per-run
    arrays (``x0`` (N, n_states), ``params``' and ``mu``'s (N,...), ``u`` (N, m)) cut to them,
    the shared values as they are."""
    def rows(v, ndim: int):
        return np.asarray(v)[idx] if v is not None and np.ndim(v) == ndim and len(v) == n else v

    out = dict(given)
    out["x0"] = rows(given["x0"], 2)
    params = given["params"]
    if isinstance(params, Mapping):
        out["params"] = {k: rows(v, 1) for k, v in params.items()}
    u = given["u"]
    out["u"] = u if u is None or hasattr(u, "segments") else rows(u, 2)
    mu = given["mu"]
    if mu is not None and not isinstance(mu, (tuple, numbers.Real)) and not hasattr(mu, "per_contact") \
            and np.ndim(mu) >= 1:
        out["mu"] = np.asarray(mu)[idx]
    return out


def _merged(res: BatchResult, again: BatchResult, idx: np.ndarray) -> BatchResult:
    """``res`` with its runs ``idx`` replaced by ``again``'s (the same runs, in order); the
    counters of either method kept (0 where a run's method has none), ``stats['radau']``
    marking the runs replaced."""
    res.x_final[idx] = again.x_final
    res.status[idx] = again.status
    res.errors[idx] = again.errors
    if res.x is not None and again.x is not None:
        res.x[idx] = again.x
    for k, v in again.outputs.items():
        if k not in res.outputs:  # every run of res failed: none made it
            res.outputs[k] = np.full((len(res), *np.shape(v)[1:]), np.nan)
        res.outputs[k][idx] = v
    if res.charts is not None and again.charts is not None:
        for j, i in enumerate(idx):
            res.charts[i] = again.charts[j]
    n = len(res)
    for k, v in again.stats.items():
        if k not in res.stats:
            res.stats[k] = np.zeros((n, *np.shape(v)[1:]), dtype=np.asarray(v).dtype)
        res.stats[k][idx] = v
    for k in res.stats:
        if k not in again.stats:
            res.stats[k][idx] = 0
    res.stats["radau"] = np.isin(np.arange(n), idx)
    return res


def _simulate_many(model, t_final: float, *, x0, params, u, method: str, rtol, atol, t_eval, h, max_steps,
                   project, outputs, checks, threads, time_limit, mu, slip, e) -> BatchResult:
    """``simulate_many`` with its method chosen."""
    start = perf_counter()
    if method not in METHODS:
        raise RunArgumentError(f"simulate_many runs the loops in C, method one of {METHODS}; got {method!r} "
                               "(cvodes and idas run through CasADi one at a time: loop over simulate)")
    s = RunSettings.check(model, t_final, method=method, rtol=rtol, atol=atol,
                          t_eval=[0.0, t_final] if t_eval is None else t_eval, h=h,
                          max_steps=max_steps, project=project, outputs=outputs, checks=checks,
                          time_limit=time_limit)
    threads = _threads(threads)
    dense = t_eval is not None
    if model.manifest.get("atlas") and not model.manifest.get("modes"):  # run by run: they switch
        if e is not None:
            raise RunArgumentError(f"e given, but model {model.name!r} has no impacts (no contact modes): "
                                   "restitution applies to a model with modes (gs.scenes.body_on_plane)")
        return _with_atlases(model, s, x0, params, u, mu, slip, dense, start, threads)
    if model.manifest.get("modes"):  # contact that can change: run by run (runtime.modes)
        modes.refuse_unused(params=params, u=u, slip=slip, inputs=bool(model.input_names),
                            charts=parameters.charts_of(model), checks=s.checks)
        return _with_modes(model, s, t_final, x0, mu, e, u, dense, start, charts=params, threads=threads)
    if e is not None:
        raise RunArgumentError(f"e given, but model {model.name!r} has no impacts (no contact modes): "
                               "restitution applies to a model with modes (gs.scenes.body_on_plane)")
    if outputs and not model.output_names:
        raise RunArgumentError(f"outputs=True, but model {model.name!r} was built with no outputs: build "
                               "the scene with outputs=(...) naming the ones you need")

    n_runs = _count(model, x0, params, u, None if isinstance(mu, tuple) else mu)
    MU = friction.per_run(model, mu, n_runs)
    s.slip = slip_mode(slip)
    X0 = _initial_states(model, x0, n_runs)
    P, pdict = _parameters(model, params, n_runs)
    sched, U = _inputs(model, u, n_runs, method, s.t_eval)
    if U is not None:
        k = model.p_names.index(model.input_names[0])
        P[:, k:k + len(model.input_names)] = U
    watched = _watched(model, s, X0, P, sched, MU if s.slip == "stop" else None)
    if watched is None:
        _refuse_mu_without_t_eval(MU, checks, dense)

    # the checks read the compiled outputs whether or not the result shows them: watched by
    # the C loops at every step, else read at the output rows
    evaluate = (outputs or checks and watched is None) and bool(model.columns)
    res = _integrate(model, s, X0, P, sched, dense, evaluate, threads, watched)
    status = np.where(res["status"] == res["ok_code"], 0, res["status"]).astype(np.int64)
    status[status == c_loops.ERR_EVENT] = EVENT  # a watched check's event (c/watch.c)
    if checks and n_runs:
        _check(model, s, res, status, dense, own_start=x0 is None,
               mu=MU if s.slip == "stop" else None, watched=watched)
    errors = _errors(model, s, status, X0, x0 is None, P, U, sched, MU)
    return _result(model, s, res, status, errors, dense, X0=X0, pdict=pdict,
                   wall=perf_counter() - start, mu=MU)


def _watched(model, s: RunSettings, X0, P, sched, MU) -> tuple | None:
    """What the C loops of the batch watch (``runtime.watch``): ``(terms, coef, inputs, dt,
    safety, span)`` as ``CompiledLibrary.batch`` takes them, every run's checks from its own start
    (and ``MU``, its friction coefficients, or None); None where the checks are not watched
    (no checks, rk4, a library without the batch's watch, outputs at rows at most
    ``WATCH_DT`` apart): they read the output rows."""
    lib = model.library
    if not s.checks or s.method == "rk4" or not model.columns or not getattr(lib, "can_watch_batch", False):
        return None
    if s.outputs and run_.rows_dense(s.t_eval):  # computed at rows as close as the watch's points
        return None
    names = [*checks_.curvature_outputs(model.columns), *checks_.denominator_thresholds(model)]
    start = {}
    if names and len(X0):
        Y = _start_outputs(model, s, X0, P, sched)
        start = {k: Y[:, model.columns.index(k)] for k in names if k in model.columns}
    terms, coef = watch.witnesses(model, start, MU, len(X0))
    if not terms:
        return None
    coef[~np.isfinite(coef)] = 0.0  # a start whose outputs are not finite: refused (_check)
    return ([t for _, _, t, _ in terms], coef, watch.input_slots(model), watch.WATCH_DT, watch.WATCH_SAFETY,
            watch.CHECK_SPAN)


def _start_outputs(model, s: RunSettings | None, X0, P, sched, t0: float = 0.0) -> np.ndarray:
    """The compiled outputs at every run's start (``(N, n_columns)``; NaN where they cannot be
    had), as ``simulate``'s initial checks read them: the inputs' first segment (``sched``, or
    None: ``P`` as it is), and the time ``t0`` for a law that reads it."""
    if sched is not None:  # the inputs at t = 0
        P = np.array([model.with_inputs(row, sched.segments(0.0, float(s.t_eval[-1]))[0][2]) for row in P])
    timed = bool(model.manifest.get("outputs_time"))
    if not timed and (P is None or not len(P) or np.all(P == P[0])):
        try:
            return model.library.outputs_batch(X0, None if P is None or not P.shape[1] else P[0])
        except (RuntimeError, FloatingPointError, ValueError):
            pass  # a start the outputs cannot be had at: run by run, NaN there (refused)
    Y = np.full((len(X0), len(model.columns)), np.nan)
    for i, (x, p) in enumerate(zip(X0, P if P is not None else [None] * len(X0))):
        try:
            Y[i] = outputs_.row(model, x, p, t0 if timed else None)
        except (RuntimeError, FloatingPointError, ValueError):
            pass
    return Y


def _refuse_mu_without_t_eval(MU, checks: bool, dense: bool) -> None:
    if MU is not None and checks and not dense:
        raise RunArgumentError("mu given with checks, but no t_eval: the friction cone is checked at the "
                               "output times, and without t_eval a batch keeps only the start and the "
                               "end; give t_eval (e.g. np.linspace(0, t_final, 301)), or checks=False")


def _with_modes(model, s: RunSettings, t_final, x0, mu, e, u, dense: bool, start: float,
                charts: dict | None = None, threads: int = 1) -> BatchResult:
    """``simulate_many`` of a model with contact modes: ``modes.run_many``; ``u`` as for a model
    without modes (constant inputs ``(n_inputs,)`` or ``(N, n_inputs)``, or one table for every
    run), each run's by ``simulate``'s own reading."""
    sizes = {len(v) for v in (mu, e) if v is not None and not hasattr(v, "per_contact") and np.ndim(v) >= 1}
    if x0 is not None and np.ndim(x0) == 2:
        sizes.add(len(x0))
    if u is not None and not hasattr(u, "segments") and np.ndim(u) == 2:
        sizes.add(len(u))
    sizes |= {len(v) for v in (charts or {}).values() if np.ndim(v) >= 1}
    if len(sizes) > 1:
        raise RunArgumentError(f"simulate_many: x0, mu, e, u and the charts in params give different numbers of "
                               f"runs {sorted(sizes)}: give every per-run array the same length N")
    n = sizes.pop() if sizes else 1
    X0 = _initial_states(model, x0, n)
    start_charts = {k: np.array([parameters.chart_value(k, c) for c in np.broadcast_to(np.asarray(v), (n,))])
                    for k, v in (charts or {}).items()}       # checked before any run
    got = modes.run_many(model, s, X0, mu, e, _inputs_by_run(model, s, u, n), start_charts=start_charts,
                         threads=threads)
    t_out = (s.t_eval[1:] if s.drop_first else s.t_eval) if dense else np.array([0.0, s.t_final])
    return BatchResult(x_final=got["x_final"], status=got["status"], errors=got["errors"], t=t_out,
                       state_names=model.state_names, method=s.method, x0=X0, params=got["params"],
                       x=got["x"], outputs=got["outputs"], wall_time=perf_counter() - start,
                       events=got["events"], modes=got["modes"],
                       charts=got["charts"] if model.manifest.get("atlas") else None)


def _with_atlases(model, s: RunSettings, x0, params, u, mu, slip, dense: bool, start: float,
                  threads: int = 1) -> BatchResult:
    """``simulate_many`` of a grasp whose surfaces have atlases: each run by ``simulate``'s own
    code (``run.run``, which switches chart at the step where a contact reaches a chart's edge;
    the batch's C loops do not), on ``threads`` threads (``runtime.pool``), within the batch's
    ``time_limit``; a run
    that stops by name is recorded with ``simulate``'s message and the batch's code for it,
    the others go on. The rows' charts in ``BatchResult.charts``, each run's counters in
    ``stats``."""
    n = _count(model, x0, params, u, None if isinstance(mu, tuple) else mu)
    MU = friction.per_run(model, mu, n)
    if s.method == "rk4" or not getattr(model.library, "can_watch_batch", False):  # (run.watched_checks)
        _refuse_mu_without_t_eval(MU, s.checks, dense)
    s.slip = slip_mode(slip)
    X0 = _initial_states(model, x0, n)
    P, pdict = _parameters(model, params, n)
    us = _inputs_by_run(model, s, u, n)
    m = len(s.t_eval) - (1 if s.drop_first else 0)
    x_final = np.full((n, len(model.state_names)), np.nan)
    X = np.full((n, m, len(model.state_names)), np.nan)
    outs: dict = {}
    stats: dict = {}
    status = np.zeros(n, dtype=np.int64)
    errors = np.full(n, "", dtype=object)
    charts: list = [None] * n
    deadline = None if s.time_limit is None else start + s.time_limit
    lock = threading.Lock()  # the outputs' and counters' arrays: made by the first run that has them

    def one(i: int) -> None:
        left = None if deadline is None else deadline - perf_counter()
        if left is not None and left <= 0:
            status[i], errors[i] = c_loops.ERR_INTERRUPT, failures.out_of_time(s.time_limit)
            return
        si = replace(s, mu=None if MU is None else MU[i], time_limit=left)
        try:
            res = run_.run(model, si, X0[i], x0 is None, P[i], us[i])
        except (RunArgumentError, RunInterruptedError):
            raise  # the call's, not the run's
        except (GraspingSymError, ValueError) as exc:
            status[i], errors[i] = failures.batch_entry(exc, s.time_limit)
            return
        x_final[i], X[i] = res.x[-1], res.x
        with lock:
            for k, v in res.outputs.items():
                outs.setdefault(k, np.full((n, m), np.nan))[i] = v
            for k, v in res.stats.items():
                if isinstance(v, numbers.Real):
                    stats.setdefault(k, np.zeros(n))[i] = v
        charts[i] = res.charts if dense else {k: v[-1:] for k, v in res.charts.items()}

    pool.each(n, threads, one)
    t_out = (s.t_eval[1:] if s.drop_first else s.t_eval) if dense else np.array([0.0, s.t_final])
    return BatchResult(x_final=x_final, status=status, errors=errors, t=t_out, state_names=model.state_names,
                       method=s.method, x0=X0, params=pdict, x=X if dense else None,
                       outputs=outs if dense else {k: v[:, -1] for k, v in outs.items()}, stats=stats,
                       wall_time=perf_counter() - start, charts=charts)


def _inputs_by_run(model, s: RunSettings, u, n: int) -> list:
    """Each of the ``n`` runs' ``u`` for a batch run by ``simulate``'s code: one row each of
    ``(N, n_inputs)``, else ``u`` (constant inputs, one table, or None) for every run; a bad
    ``u`` is the call's error, raised once, not each run's."""
    per_run = u is not None and not hasattr(u, "segments") and np.ndim(u) == 2
    try:
        us = list(np.asarray(u, dtype=float)) if per_run else [u] * n
    except ValueError as exc:
        raise RunArgumentError(f"u = {u!r}: give numbers, (n_inputs,) or (N, n_inputs), or one table") from exc
    for u_i in us if per_run else us[:1]:
        run_.schedule(model, u_i, s.method, s.t_eval)
    return us


def _threads(threads) -> int:
    """``threads`` checked (None: every core this process may use)."""
    threads = default_threads() if threads is None else threads
    if isinstance(threads, (bool, np.bool_)) or not isinstance(threads, numbers.Integral) \
            or not 1 <= threads <= MAX_THREADS:
        raise RunArgumentError(f"threads = {threads!r:.40} must be an integer from 1 to {MAX_THREADS} "
                               f"(None: every core this process may use, {default_threads()} here)")
    return threads


def _check(model, s: RunSettings, res: dict, status: np.ndarray, dense: bool, own_start: bool,
           mu: np.ndarray | None = None, watched: tuple | None = None) -> None:
    """Mark in ``status`` the runs whose initial state the checks refuse (``REFUSED``) and those
    with an event along their output samples (``EVENT``: with ``mu`` (``(N, n_contacts)``)
    a force outside its friction cone among them), as ``simulate`` checks them; with
    ``watched`` (``_watched``: the C loops watched the checks), those with one past its event
    at the start (the loops never arm it), the samples not read."""
    refused = ~checks_.initial_ok(model, res.get("Y0"), res.get("CD0"), rates=not own_start)
    started = res["stats"][:, 6] >= 0  # (c/batch.c marks runs a stopped batch never began)
    Y0 = res.get("Y0")
    if watched is not None and Y0 is not None:  # whatever the loop did after: simulate stops there
        status[~np.all(watch.values(watched[0], Y0, watched[1]) > 0, axis=1) & started] = EVENT
    status[refused & started] = REFUSED  # simulate refuses before it integrates
    Y = res.get("Y")
    if Y is not None:
        Y0 = res.get("Y0")
        ys = outputs_.by_name(model, Y if dense else np.stack([Y0, Y], axis=1))
        hit = ~checks_.trajectory_clean(model, s.t_eval, ys, initial=outputs_.by_name(model, Y0))
        if mu is not None:
            hit |= ~friction.clean(model, ys, mu)
        status[hit & (status == 0)] = EVENT


def _errors(model, s: RunSettings, status, X0, own_start, P, U, sched, mu=None) -> np.ndarray:
    """Per run: ``""``, or the message of the named error ``simulate`` raises for it."""
    errors = np.full(len(status), "", dtype=object)
    for i in np.flatnonzero(status != 0):
        if status[i] == c_loops.ERR_INTERRUPT:  # the batch's time limit: not the run's doing
            errors[i] = failures.out_of_time(s.time_limit)
            continue
        u = sched if sched is not None else (None if U is None else U[i])
        si = s if mu is None else replace(s, mu=mu[i])
        errors[i] = _message(model, si, X0[i], own_start, P[i], u, int(status[i]))
    return errors


def _result(model, s: RunSettings, res, status, errors, dense, *, X0, pdict, wall,
            mu=None) -> BatchResult:
    """The ``BatchResult``: the failed runs' rows NaN, the first output time dropped where the
    caller's ``t_eval`` did not hold it."""
    X, Y = res["X"], res.get("Y")
    bad = status != 0
    X[bad] = np.nan
    x_final = X[:, -1, :].copy() if dense else X
    outs = {}
    if s.outputs and Y is not None:
        Y[bad] = np.nan
        outs = outputs_.by_name(model, Y, shown=True)
        if mu is not None:
            outs.update(friction.quantities(model, outputs_.by_name(model, Y), mu))
    t_out, x_all = s.t_eval, (X if dense else None)
    if dense and s.drop_first:
        t_out, x_all = s.t_eval[1:], X[:, 1:]
        outs = {k: v[:, 1:] for k, v in outs.items()}
    stats = _stats(s.method, res["stats"], s.proj[0] is not None)
    return BatchResult(x_final=x_final, status=status, errors=errors,
                       t=t_out if dense else np.array([0.0, s.t_final]),
                       state_names=model.state_names, method=s.method, x0=X0, params=pdict,
                       x=x_all, outputs=outs, stats=stats, wall_time=wall)


def _count(model, x0, params, u, mu=None) -> int:
    """N: the rows of ``x0`` (2-D), of the parameters' arrays and of a per-run ``u``, which
    must agree (1 when everything is shared)."""
    sizes = {}
    if x0 is not None and np.ndim(x0) == 2:
        sizes["x0"] = np.shape(x0)[0]
    for k, v in (params or {}).items() if isinstance(params, Mapping) else ():
        if np.ndim(v) == 1:
            sizes[f"params[{k!r}]"] = len(v)
        elif np.ndim(v) > 1:
            raise RunArgumentError(f"params[{k!r}] has shape {np.shape(v)}: give one number, or one per "
                                   "run (shape (N,))")
    if u is not None and not hasattr(u, "segments") and np.ndim(u) == 2:
        sizes["u"] = np.shape(u)[0]
    if mu is not None and not hasattr(mu, "per_contact") and np.ndim(mu) >= 1:
        sizes["mu"] = np.shape(mu)[0]
    if len(set(sizes.values())) > 1:
        raise RunArgumentError("simulate_many: the number of runs differs between "
                               + ", ".join(f"{k} ({v} rows)" for k, v in sizes.items())
                               + ": give every per-run array the same length N")
    n = next(iter(sizes.values()), 1)
    if n == 0:
        raise RunArgumentError("simulate_many: no runs (" + ", ".join(sizes) + " empty): give at "
                               "least one row, or call nothing")
    return n


def _initial_states(model, x0, n: int) -> np.ndarray:
    nx = len(model.state_names)
    if x0 is None:
        return np.tile(model.initial_state(), (n, 1))
    X0 = numbers_array("x0", x0)
    if X0.ndim == 1:
        X0 = np.tile(X0, (n, 1))
    if X0.shape != (n, nx):
        raise RunArgumentError(f"x0 has shape {np.shape(x0)}; give ({nx},) for every run or (N, {nx}), "
                               f"columns ordered as {model.state_names}")
    bad = np.flatnonzero(~np.all(np.isfinite(X0), axis=1))
    if bad.size:
        raise RunArgumentError(f"x0 has non-finite entries in {bad.size} row(s), the first row {int(bad[0])}: "
                               "give finite initial states")
    return np.ascontiguousarray(X0)


def _parameters(model, params, n: int) -> tuple[np.ndarray, dict[str, np.ndarray]]:
    """Every run's ``p`` (``(N, len(p_names))``) and the run-time parameters by name. ``params``
    may name the run-time parameters and the start's run-time values (``model.start_params``:
    e.g. the 3D spring's rest point of a start set with ``with_start``)."""
    if params is not None and not isinstance(params, Mapping):
        raise RunArgumentError(f"params is {type(params).__name__}: give a dict name -> number or array (N,)")
    P = np.tile(model.default_params, (n, 1)) if model.p_names else np.zeros((n, 0))
    charts = parameters.charts_of(model)
    allowed = (*model.param_names, *model.start_params, *charts)
    rules = model.manifest.get("param_rules", {})
    for k, v in (params or {}).items():
        if k in charts:  # the charts each run's x0 is written in: 0 or 1
            P[:, model.p_names.index(k)] = [parameters.chart_value(k, c) for c in np.broadcast_to(v, (n,))]
            continue
        if k not in allowed:
            folded = "" if model.param_names else " (this model has none: build the scene with runtime=(...))"
            raise RunArgumentError(f"{k!r} is not a run-time parameter of this model{folded}; run-time: "
                                   f"{model.param_names}, start values: {tuple(model.start_params)}")
        arr = np.asarray(v)
        if arr.dtype.kind not in "fiu":
            raise RunArgumentError(f"params[{k!r}] must be numbers, got {arr.dtype} ({v!r:.60})")
        arr = np.broadcast_to(arr.astype(float), (n,))
        rule = rules.get(k, "finite")
        bad = ~np.isfinite(arr) | ((arr <= 0) if rule == "positive" else (arr < 0) if rule == "nonnegative"
                                   else np.zeros(n, dtype=bool))
        if bad.any():
            i = int(np.flatnonzero(bad)[0])
            need = {"positive": "finite and > 0", "nonnegative": "finite and >= 0"}.get(rule, "finite")
            raise RunArgumentError(f"params[{k!r}] must be {need} (as the scene requires of {k}); run {i} "
                                   f"has {arr[i]!r} ({int(bad.sum())} run(s) bad)")
        P[:, model.p_names.index(k)] = arr
    pdict = {k: P[:, model.p_names.index(k)].copy() for k in model.param_names}
    return P, pdict


def _inputs(model, u, n: int, method: str, grid: np.ndarray):
    """``(schedule, U)``: a table shared by every run (``grasping_sym.runtime.inputs``, the runs restart
    at its knots, as ``simulate``'s), or constant inputs ``U`` of shape ``(N, n_inputs)``."""
    if not model.input_names:
        if u is not None:
            raise RunArgumentError("u given, but this model has no inputs: build the scene with "
                                   "inputs='torques'")
        return None, None
    k = len(model.input_names)
    if u is not None and hasattr(u, "segments"):
        sched = run_.schedule(model, u, method, grid)
        if len(sched.segments(0.0, float(grid[-1]))) == 1:
            return None, np.tile(sched(0.0), (n, 1))
        return sched, None
    arr = np.zeros(k) if u is None else np.asarray(u)
    if arr.dtype.kind not in "fiu":
        raise RunArgumentError(f"u must be numbers (one per input {model.input_names}, or (N, {k})) or a "
                               "table of grasping_sym.runtime.inputs")
    arr = arr.astype(float)
    if arr.shape not in ((k,), (n, k)) and not (arr.ndim == 0 and k == 1):
        raise RunArgumentError(f"u has shape {arr.shape}; give ({k},) for every run or (N, {k}), "
                               f"ordered as {model.input_names}")
    U = np.broadcast_to(arr.reshape(-1, k) if arr.ndim else arr.reshape(1, 1), (n, k)).copy()
    if not np.all(np.isfinite(U)):
        raise RunArgumentError("u has non-finite entries: give finite torques (N m)")
    return None, U


def _integrate(model, s: RunSettings, X0, P, sched, dense, outputs, threads, watched=None) -> dict:
    """The C batch over the output grid ``s.t_eval`` (segment by segment for a table of inputs),
    its runs watching ``watched`` (``_watched``), or nothing."""
    lib = model.library
    grid, method, checks = s.t_eval, s.method, s.checks
    timed = bool(model.manifest.get("outputs_time"))
    in_c = not timed and sched is None  # outputs the compiled batch can evaluate itself
    kw = dict(threads=threads, rtol=s.rtol, atol=s.atol, max_steps=s.max_steps,
              nstiff=c_loops.NSTIFF if method in c_loops.STIFF_BOUND else 0, lo=model.lower, hi=model.upper,
              proj_mask=s.proj[0], proj_tol=s.proj[1], time_limit=s.time_limit,
              rk4=_rk4_grid(grid, s.h) if method == "rk4" else None)
    if sched is None:
        res = lib.batch(method, grid, X0, P, keep=dense, outputs=outputs and in_c,
                        initial=checks, initial_outputs=not timed, watch=watched, **kw)
    else:
        res = _segments(model, method, grid, X0, P, sched, dense, checks, not timed, kw, watched)
    res["ok_code"] = len(grid)
    if checks and timed and model.columns:  # a law that reads the time: at t = 0
        first = P if sched is None else np.array(
            [model.with_inputs(row, *sched.segments(0.0, float(grid[-1]))[0][2:]) for row in P])
        res["Y0"] = np.array([outputs_.row(model, x, p, 0.0) for x, p in zip(X0, first)])
    if outputs and not in_c:  # outputs that read the time or a table's ramps: run by run
        rows = res["X"] if dense else res["X"][:, None, :]
        tt = grid if dense else grid[-1:]
        Y = np.full((*rows.shape[:2], len(model.columns)), np.nan)
        for i in np.flatnonzero(res["status"] == res["ok_code"]):
            outs = outputs_.along(model, tt, rows[i], P[i], sched)
            Y[i] = np.column_stack([outs[k] for k in model.columns])
        res["Y"] = Y if dense else Y[:, 0, :]
    return res


def _segments(model, method, grid, X0, P, sched, dense, initial, initial_outputs, kw, watched=None) -> dict:
    """A table of inputs: every run restarts at its knots, as ``simulate``'s runs do, each
    segment one C batch over the runs still going (on the single run's grid: the same
    numbers)."""
    lib = model.library
    n, nx = X0.shape
    x_now = X0.copy()
    status = np.full(n, len(grid), dtype=np.int64)
    t_fail = np.full(n, np.nan)
    stats = np.zeros((n, c_loops.NSTATS))
    rows_t, rows_x, out = [], [], {}
    for k, (s0, s1, a, b) in enumerate(sched.segments(0.0, float(grid[-1]))):
        go = np.flatnonzero(status == len(grid))
        g = np.array([s0, *grid[(grid > s0) & (grid < s1)], s1])
        Xk = np.full((n, len(g), nx), np.nan)
        if len(go) and k and watched is not None:  # a check past its event at the knot (its
            # loop would never arm it): the run stops there, as simulate's does
            Y = _start_outputs(model, None, x_now[go], np.array([model.with_inputs(row, a + b * s0) for row in P[go]]),
                               None, s0)
            past = ~np.all(watch.values(watched[0], Y, watched[1][go]) > 0, axis=1)
            status[go[past]], t_fail[go[past]] = c_loops.ERR_EVENT, s0
            go = go[~past]
        if len(go):
            Pk = np.array([model.with_inputs(row, a, b) for row in P[go]])
            wk = None if watched is None else (watched[0], watched[1][go], *watched[2:])
            res = lib.batch(method, g, np.ascontiguousarray(x_now[go]), Pk, keep=True,
                            initial=initial and k == 0, initial_outputs=initial_outputs, watch=wk, **kw)
            if k == 0 and initial:
                out = {"Y0": res.get("Y0"), "CD0": res.get("CD0")}
            ok = res["status"] == len(g)
            status[go[~ok]] = res["status"][~ok]
            t_fail[go[~ok]] = res["t_fail"][~ok]
            stats[go] += res["stats"]
            Xk[go] = res["X"]
            x_now[go[ok]] = res["X"][ok, -1]
        rows_t.append(g if k == 0 else g[1:])
        rows_x.append(Xk if k == 0 else Xk[:, 1:])
    keep = np.isin(np.concatenate(rows_t), grid)
    X = np.concatenate(rows_x, axis=1)[:, keep]
    return {**out, "X": np.ascontiguousarray(X if dense else X[:, -1]), "status": status,
            "t_fail": t_fail, "stats": stats}


def _rk4_grid(grid: np.ndarray, h: float) -> tuple[float, int, int]:
    """``(h, nsteps, stride)`` of ``gs_rk4`` for the uniform ``grid``, as a single run takes them
    (``integrators.rk4``, ``c_loops.rk4``)."""
    t0, t1 = float(grid[0]), float(grid[-1])
    n_out = len(grid) - 1
    dt_out = (t1 - t0) / n_out
    if not np.allclose(np.diff(grid), dt_out, rtol=1e-9, atol=1e-15):
        raise RunArgumentError("rk4 reports on a uniform grid: give a uniformly spaced t_eval")
    stride = max(1, math.ceil(dt_out / h - 1e-9))
    h_eff, nsteps = c_loops.rk4_steps(t0, t1, dt_out / stride, stride)
    return h_eff, nsteps, stride


def _message(model, s: RunSettings, x0, own_start, p, u, status: int) -> str:
    """Run one run once more on its own, by ``simulate``'s code: its named error's message."""
    try:
        run_.run(model, s, x0, own_start, p, u)
    except (GraspingSymError, ValueError) as exc:
        return f"{type(exc).__name__}: {exc}"
    return (f"status {status} ({STATUS.get(status, 'unknown')}) in the batch, but the run alone "
            "succeeded: please report this")


def _stats(method: str, st: np.ndarray, projected: bool) -> dict[str, np.ndarray]:
    names = c_loops._STATS.get(method, ("n_steps", "n_rejected", "n_rhs"))
    out = {k: st[:, j].astype(np.int64) for j, k in enumerate(names)}
    if method == "rk4":
        out = {"n_steps": st[:, 0].astype(np.int64), "n_rhs": st[:, 2].astype(np.int64)}
    if projected:
        out.update(n_constraint_evals=st[:, 8].astype(np.int64), max_drift=st[:, 9].copy(),
                   max_drift_rate=st[:, 10].copy())
    return out
