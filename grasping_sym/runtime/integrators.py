"""Integrators on the compiled functions; each returns ``(t, X, stats)``.

- ``cvodes`` (default): CasADi's CVODES (variable-order BDF, Newton with the compiled
  Jacobian ``jac_{name}_rhs``), on the compiled right-hand side loaded with
  ``casadi.external``.
- ``idas``: the same through IDAS.
- ``rk4``: classic fixed-step RK4 whose whole loop runs in C (``gs_rk4``).
- ``radau``: adaptive Radau IIA of order 5 whose whole loop runs in C (``gs_radau5``),
  calling the compiled right-hand side and Jacobian directly; no CasADi/SUNDIALS
  overhead per step.
- ``dopri5``: adaptive explicit Dormand-Prince 5(4) whose whole loop runs in C
  (``gs_dopri5``), with dense output and DOPRI5's stiffness detection: a stiff problem stops
  with an ``IntegratorError`` saying so instead of crawling.
- ``dop853``: adaptive explicit Dormand-Prince 8(5,3) whose whole loop runs in C
  (``gs_dop853``), the same with eighth-order steps: fewer of them at tight tolerances.

The C loops (``rk4``, ``radau``, ``dopri5``, ``dop853``) check the contact parameters after every step and
can project every step onto the constraints (``runtime/projection.py``).
Failures raise ``IntegratorError`` with the time, the state and the reason.
"""
from __future__ import annotations

import contextlib
import io
import math
import os
import re
import sys
import tempfile
import threading
import time
import weakref
from pathlib import Path

import numpy as np

from grasping_sym.errors import IntegratorError
from grasping_sym.runtime import c_loops, interrupt

METHODS = ("cvodes", "idas", "rk4", "radau", "dopri5", "dop853")
#: The methods whose whole loop runs in C (``c/rk4.c``, ``c/radau5.c``, ``c/dopri5.c``,
#: ``c/dop853.c``).
C_LOOPS = ("rk4", "radau", "dopri5", "dop853")


#: Step budget for recovering the state just before a SUNDIALS failure (a blow-up can make
#: that stretch arbitrarily expensive; past this budget the error carries no state).
RECOVERY_MAX_STEPS = 20_000


#: CasADi integrators kept per model and thread (one per method, tolerances and output grid): the least
#: recently used beyond this many are dropped (each holds ~150 kB).
INTEGRATOR_CACHE_SIZE = 8


_THREAD = threading.local()


def _thread_cache(model) -> dict:
    """This thread's CasADi objects of ``model`` (its SUNDIALS integrators and the functions
    they integrate). A CasADi integrator holds its solver's memory: two threads calling the
    same one at once corrupt it, so every thread makes and keeps its own."""
    caches = getattr(_THREAD, "caches", None)
    if caches is None:
        caches = _THREAD.caches = weakref.WeakKeyDictionary()
    cache = caches.get(model)
    if cache is None:
        cache = caches[model] = {"integrators": {}, "dae": {}}
    return cache


#: CVODES's smallest step, relative to the run's length: at a contact leaving its contour
#: (the guarded rhs is NaN beyond) it halves its step toward the crossing and, below this,
#: fails at once instead of crawling on for ``max_steps`` steps.
MIN_STEP_RELATIVE = 1e-15


#: IDAS's first time scale (s): the initial-condition solver (IDACalcIC) is told the first
#: output time as the problem's time scale; a first output far away (``t_eval=[0, 1e4]``)
#: makes it fail (IDA_CONV_FAIL), so it is told at most this.
IDAS_FIRST_TIME = 1e-3


def _step_floor(method: str, t_eval: np.ndarray) -> dict:
    """CVODES's smallest step; IDAS's first time scale (``IDAS_FIRST_TIME``)."""
    if method == "idas":
        return {"first_time": float(t_eval[0]) + min(float(t_eval[1] - t_eval[0]), IDAS_FIRST_TIME)}
    return {"min_step_size": MIN_STEP_RELATIVE * max(1.0, float(t_eval[-1] - t_eval[0]))}


def _rhs_for(model, method: str):
    """The function a SUNDIALS method integrates (``dae_for``), cached on the model."""
    dae = _thread_cache(model)["dae"]
    if method not in dae:
        dae[method] = dae_for(model, method)
    return dae[method]


def dae_for(model, method: str):
    """What CVODES or IDAS integrates: the compiled rhs plus ``gs_step_budget(t)`` (``c/budget.c``,
    zero, but it fails once a run has attempted more than its ``max_steps`` steps in total).

    CVODES gets the guarded rhs (NaN outside the contours' domains: it stops at the step where a
    contact leaves). IDAS, given the same, crawls toward the boundary in ever smaller steps, so it
    gets the plain rhs and one more state, ``e' = sum(max(0, x - upper) + max(0, lower - x))``
    over the bounded states, ``e(0) = 0``: ``e`` stays exactly zero unless a step ends outside a
    domain, so an excursion between two outputs shows in ``e`` at the next one
    (``excursion_intervals``), where the C Radau loop locates it at its step."""
    import casadi as ca  # noqa: PLC0415 - lazy: CasADi only for its SUNDIALS methods

    rhs = model.external_rhs_guarded() if method == "cvodes" else model.external_rhs()
    if model.library.has_budget:
        budget = ca.external("gs_step_budget", str(model.library_path))
    else:  # a library built before c/budget.c: SUNDIALS's own per-interval limit only
        def budget(t):
            return ca.MX(0)
    ins = [ca.MX.sym(rhs.name_in(i), rhs.sparsity_in(i)) for i in range(rhs.n_in())]
    names_in = [rhs.name_in(i) for i in range(rhs.n_in())]
    names_out = [rhs.name_out(i) for i in range(rhs.n_out())]
    nx = len(model.state_names)
    bounded = [i for i in range(nx)
               if math.isfinite(model.lower[i]) or math.isfinite(model.upper[i])]
    if method == "cvodes" or not bounded:
        outs = rhs.call(ins)
        outs[0] = outs[0] + budget(ins[0])
        return ca.Function(f"{model.name}_{method}_dae", ins, outs, names_in, names_out)
    x_aug = ca.MX.sym(names_in[1], nx + 1)
    x = x_aug[:nx]
    outs = rhs.call([ins[0], x, *ins[2:]])
    excess = ca.MX(0)
    for i in bounded:
        if math.isfinite(model.upper[i]):
            excess += ca.fmax(0, x[i] - float(model.upper[i]))
        if math.isfinite(model.lower[i]):
            excess += ca.fmax(0, float(model.lower[i]) - x[i])
    ode = ca.vertcat(outs[0] + budget(ins[0]), excess)
    return ca.Function(f"{model.name}_{method}_dae", [ins[0], x_aug, *ins[2:]], [ode, *outs[1:]],
                       names_in, names_out)


def augmented(model, method: str) -> bool:
    """Whether ``dae_for(model, method)`` carries the excursion state ``e`` after the states."""
    return method == "idas" and bool(np.any(np.isfinite(model.lower) | np.isfinite(model.upper)))


def _tolerances(model, method: str, rtol: float, atol: float) -> dict:
    """SUNDIALS's tolerance options. With the excursion state (``augmented``) its weight is
    ~0 (it is an indicator, exactly 0 while the run stays inside) and the states' tolerances
    are divided by sqrt((n + 1) / n): the weighted RMS norm of the error, now over n + 1
    components, is then the same number as without the extra state, and so are the steps
    (left alone, IDAS took 25-40 % more steps on paper3d)."""
    if not augmented(model, method):
        return {"abstol": atol, "reltol": rtol}
    n = len(model.state_names)
    s = math.sqrt((n + 1) / n)
    return {"abstol": atol / s, "abstolv": [atol / s] * n + [1.0], "reltol": rtol / s}


def excursion_intervals(e: np.ndarray) -> list[int]:
    """The output intervals ``k`` (from output ``k - 1`` to ``k``) over which the excursion
    state ``e`` of ``dae_for`` grew: a step ended outside a contour's domain there."""
    return [int(k) for k in np.flatnonzero(np.diff(e) > 0) + 1]


def sundials(model, method: str, x0: np.ndarray, t_eval: np.ndarray, p: np.ndarray,
             rtol: float, atol: float, max_steps: int,
             time_limit: float | None = None) -> tuple[np.ndarray, np.ndarray, dict]:
    """Integrate with CVODES or IDAS through CasADi, reporting at ``t_eval``.

    ``max_steps`` bounds the step attempts of the whole run (``c/budget.c``; SUNDIALS's own
    limit, per output interval, is set to the same); ``time_limit`` (s of wall time) and Ctrl-C
    stop the run. ``stats["excursions"]`` (IDAS): the output intervals over which a step ended
    outside a contour's domain (``dae_for``)."""
    import casadi as ca  # noqa: PLC0415 - only the SUNDIALS methods need CasADi at run time

    key = (method, float(rtol), float(atol), int(max_steps), t_eval.tobytes())
    cache = _thread_cache(model)["integrators"]
    integ = cache.pop(key, None)
    if integ is None:
        opts = {**_tolerances(model, method, rtol, atol), "max_num_steps": max_steps,
                "disable_internal_warnings": True, **_step_floor(method, t_eval)}
        grid = [float(t) for t in t_eval[1:]]
        integ = ca.integrator(f"{model.name}_{method}", method, _rhs_for(model, method),
                              float(t_eval[0]), grid, opts)
    cache[key] = integ  # most recently used last
    while len(cache) > INTEGRATOR_CACHE_SIZE:
        cache.pop(next(iter(cache)))
    xa = np.append(x0, 0.0) if augmented(model, method) else x0
    lib = model.library
    start = time.perf_counter()
    with c_loops.stoppable(lib, time_limit):
        lib.budget_begin(max_steps)
        try:
            out = integ(x0=xa, p=p)
        except RuntimeError as exc:
            failure = exc
        else:
            failure = None
    if failure is not None:
        if interrupt.requested() or lib.budget_hit() == 2 and lib._lib.gs_stop_cause() == 1:
            raise interrupt.interrupted(f"{method} stopped by Ctrl-C") from None
        if lib.budget_hit() == 2 and time_limit:
            raise IntegratorError(lib.budget_last_t(), None, f"{method}: the wall-time limit "
                                  f"of {time_limit:g} s was reached (raise time_limit, or "
                                  "loosen the tolerances)", model.state_names) from None
        if lib.budget_hit() == 1:
            raise _failure(model, method, x0, t_eval, p, rtol, atol, max_steps, str(failure),
                           at=(lib.budget_last_t(), f"more than max_steps = {max_steps} step "
                               "attempts in total (raise max_steps, or loosen rtol/atol)")
                           ) from None
        raise _failure(model, method, x0, t_eval, p, rtol, atol, max_steps, str(failure),
                       t_hint=lib.budget_last_t()) from None
    wall = time.perf_counter() - start
    X = np.vstack([xa, np.array(out["xf"]).T])
    st = integ.stats()
    stats = {"wall_time": wall, "n_steps": int(st.get("nsteps", 0)),
             "n_rhs": int(st.get("nfevals", 0)), "n_jac": int(st.get("n_call_jacF", 0)),
             "n_attempts": lib.budget_count()}
    nx = len(model.state_names)
    if X.shape[1] > nx:
        stats["excursions"] = excursion_intervals(X[:, nx])
        X = X[:, :nx]
    if stats["n_steps"] > max_steps:
        raise IntegratorError(float(t_eval[-1]), X[-1], f"{method}: {stats['n_steps']} steps, "
                              f"more than max_steps = {max_steps} (raise max_steps or loosen "
                              "rtol/atol)", model.state_names)
    return t_eval.copy(), X, stats


def _failure(model, method, x0, t_eval, p, rtol, atol, max_steps: int,
             message: str, at: tuple[float, str] | None = None,
             t_hint: float = math.nan) -> IntegratorError:
    """Build the error for a SUNDIALS failure: the reason, the time and the state there.

    SUNDIALS prints the failure time ("At t = ...") from C but CasADi's exception does not
    carry it, so the failing run is repeated once with SUNDIALS' messages captured at the
    file-descriptor level; the trajectory is then recovered on the output grid up to just
    before that time, with a bounded step budget (``err.trajectory``, ``err.x`` its last
    state). This only runs on the failure path. ``at``: the failure's time and reason when
    known (the step budget's), which spares the repeated run; ``t_hint``: the time of the last
    step attempted (``c/budget.c``), the failure's time when SUNDIALS prints none.
    """
    import casadi as ca  # noqa: PLC0415 - lazy: CasADi only for its SUNDIALS methods
    opts = {**_tolerances(model, method, rtol, atol), "max_num_steps": max_steps,
            **_step_floor(method, t_eval)}
    xa = np.append(x0, 0.0) if augmented(model, method) else x0
    if at is not None:
        t_fail, reason = at
    else:
        reason = _sundials_reason(message)
        grid = [float(t) for t in t_eval[1:]]
        integ = ca.integrator("failing", method, _rhs_for(model, method), float(t_eval[0]), grid,
                              opts)
        with _captured_fds() as captured:
            model.library.budget_begin(max_steps)
            try:
                integ(x0=xa, p=p)
            except RuntimeError:
                pass
        times = re.findall(r"t\s*=\s*([-+0-9.eE]+)", captured.read())
        if not times and not math.isfinite(t_hint):
            return IntegratorError(float("nan"), None, f"{method}: {reason} (time not reported)",
                                   model.state_names)
        t_fail = float(times[0]) if times else t_hint
    if t_fail <= t_eval[0]:
        return IntegratorError(t_fail, np.asarray(x0, dtype=float), f"{method}: {reason}",
                               model.state_names)
    x_fail, trajectory = None, None
    t0 = float(t_eval[0])
    for back in (1e-9, 1e-7, 1e-5, 1e-3):  # the stretch just before a blow-up can be costly
        t_end = t_fail - back * max(1.0, abs(t_fail))
        if t_end <= t0:
            continue
        grid = [float(t) for t in t_eval[1:] if t < t_end] + [t_end]
        rec = ca.integrator("recover", method, _rhs_for(model, method), t0, grid,
                            {**opts, "max_num_steps": RECOVERY_MAX_STEPS,
                             "disable_internal_warnings": True})
        model.library.budget_begin(RECOVERY_MAX_STEPS)
        try:
            X = np.vstack([xa, np.array(rec(x0=xa, p=p)["xf"]).T])[:, :len(model.state_names)]
        except RuntimeError:
            continue
        x_fail, trajectory = X[-1], (np.array([t0, *grid]), X)
        reason += f" (state recovered at t = {t_end:.9g} s)"
        break
    err = IntegratorError(t_fail, x_fail, f"{method}: {reason}", model.state_names)
    if trajectory is not None:
        err.trajectory = trajectory
    return err


class _Captured:
    text = ""

    def read(self) -> str:
        return self.text


@contextlib.contextmanager
def _captured_fds():
    """Capture stdout and stderr, both Python's streams (CasADi prints through them) and
    the process's file descriptors (C libraries print there)."""
    sys.stdout.flush()
    sys.stderr.flush()
    py = io.StringIO()
    with tempfile.TemporaryDirectory() as tmp, contextlib.redirect_stdout(py), \
            contextlib.redirect_stderr(py):
        path = Path(tmp) / "sundials.txt"
        captured = _Captured()
        with open(path, "w") as sink:
            saved = [os.dup(1), os.dup(2)]
            try:
                os.dup2(sink.fileno(), 1)
                os.dup2(sink.fileno(), 2)
                yield captured
            finally:
                os.dup2(saved[0], 1)
                os.dup2(saved[1], 2)
                for fd in saved:
                    os.close(fd)
        captured.text = path.read_text(errors="replace") + py.getvalue()


def _sundials_reason(message: str) -> str:
    m = re.search(r'returned "?([A-Z_]+)"?', message)
    known = {
        "CV_TOO_MUCH_WORK": "too many steps (raise max_steps or loosen rtol/atol)",
        "IDA_TOO_MUCH_WORK": "too many steps (raise max_steps or loosen rtol/atol)",
        "CV_CONV_FAILURE": "Newton iteration failed repeatedly (stiff blow-up or a singular "
                           "contact: check kappa0 + kappa1 and the state)",
        "CV_ERR_FAILURE": "error test failed repeatedly (the solution is not smooth here)",
        "CV_RHSFUNC_FAIL": "the right-hand side returned non-finite values",
        "IDA_CONV_FAIL": "Newton iteration failed repeatedly (stiff blow-up or a singular "
                         "contact: check kappa0 + kappa1 and the state)",
        "IDA_ERR_FAIL": "error test failed repeatedly (the solution is not smooth here)",
        "IDA_REP_RES_ERR": "the right-hand side failed repeatedly (non-finite values)",
    }
    if m:
        code = m.group(1)
        return f"{code}: {known.get(code, 'see the SUNDIALS documentation')}"
    lines = [ln for ln in message.strip().splitlines() if ln.strip()]
    return lines[-1] if lines else "unknown failure"


def c_loop(model, method: str, x0: np.ndarray, t_eval: np.ndarray, p: np.ndarray | None, *,
           rtol: float, atol: float, max_steps: int, h: float,
           projection: tuple[np.ndarray | None, float] = (None, 0.0),
           time_limit: float | None = None, h0: float = 0.0) -> tuple[np.ndarray, np.ndarray, dict]:
    """Integrate with one of ``C_LOOPS``, bounds ``model.lower`` / ``model.upper`` checked
    after every step, projecting when ``projection[0]`` (the mask) is given; Ctrl-C and
    ``time_limit`` (s of wall time) stop the loop within a few steps. ``h``: rk4's step;
    ``h0``: the adaptive loops' first step (0: chosen)."""
    lo, hi = model.lower, model.upper
    if method == "rk4":
        return rk4(model, x0, t_eval, p, h, lo, hi, projection, time_limit)
    if method == "radau":
        return radau(model, x0, t_eval, p, rtol, atol, max_steps, lo, hi, h0=h0,
                     projection=projection, time_limit=time_limit)
    if method in c_loops.STIFF_BOUND:  # the explicit loops
        return explicit(model, method, x0, t_eval, p, rtol, atol, max_steps, lo, hi, h0=h0,
                        projection=projection, time_limit=time_limit)
    raise ValueError(f"method {method!r} has no C loop: choose one of {C_LOOPS}")


def rk4(model, x0: np.ndarray, t_eval: np.ndarray, p: np.ndarray | None, h: float,
        lo: np.ndarray, hi: np.ndarray,
        projection: tuple[np.ndarray | None, float] = (None, 0.0),
        time_limit: float | None = None) -> tuple[np.ndarray, np.ndarray, dict]:
    """Fixed-step RK4 in C; ``t_eval`` must be uniform with spacing a multiple of ``h``."""
    t0, t1 = float(t_eval[0]), float(t_eval[-1])
    n_out = len(t_eval) - 1
    if n_out < 1:
        raise ValueError("t_eval needs at least two times for rk4")
    dt_out = (t1 - t0) / n_out
    if not np.allclose(np.diff(t_eval), dt_out, rtol=1e-9, atol=1e-15):
        raise ValueError("rk4 reports on a uniform grid: give a uniformly spaced t_eval")
    stride = max(1, math.ceil(dt_out / h - 1e-9))
    h_used = dt_out / stride
    stats: dict = {}
    start = time.perf_counter()
    t, X = model.library.rk4(x0, t0, t1, h_used, stride=stride, p=p, lo=lo, hi=hi,
                             proj_mask=projection[0], proj_tol=projection[1], stats=stats,
                             time_limit=time_limit)
    stats.update(wall_time=time.perf_counter() - start, h=h_used)
    return t, X, stats


def radau(model, x0: np.ndarray, t_eval: np.ndarray, p: np.ndarray | None, rtol: float,
          atol: float, max_steps: int, lo: np.ndarray, hi: np.ndarray,
          h0: float = 0.0, projection: tuple[np.ndarray | None, float] = (None, 0.0),
          time_limit: float | None = None) -> tuple[np.ndarray, np.ndarray, dict]:
    """Adaptive Radau IIA (order 5) in C, reporting at ``t_eval`` (dense output).

    The contact parameters are checked against ``lo`` / ``hi`` after every accepted step;
    failures raise ``IntegratorError`` (see ``CompiledLibrary.radau5``).
    """
    start = time.perf_counter()
    t, X, stats = model.library.radau5(x0, t_eval, p=p, rtol=rtol, atol=atol, h0=h0,
                                       max_steps=max_steps, lo=lo, hi=hi,
                                       proj_mask=projection[0], proj_tol=projection[1],
                                       time_limit=time_limit)
    stats["wall_time"] = time.perf_counter() - start
    return t, X, stats


def explicit(model, method: str, x0: np.ndarray, t_eval: np.ndarray, p: np.ndarray | None,
             rtol: float, atol: float, max_steps: int, lo: np.ndarray, hi: np.ndarray,
             h0: float = 0.0, projection: tuple[np.ndarray | None, float] = (None, 0.0),
             time_limit: float | None = None) -> tuple[np.ndarray, np.ndarray, dict]:
    """Adaptive Dormand-Prince 5(4) (``method='dopri5'``) or 8(5,3) (``'dop853'``) in C,
    reporting at ``t_eval`` (continuous extension).

    Bounds checked after every accepted step as ``radau``; a stiff problem stops with an
    ``IntegratorError`` (see ``CompiledLibrary.dopri5``).
    """
    start = time.perf_counter()
    loop = model.library.dopri5 if method == "dopri5" else model.library.dop853
    t, X, stats = loop(x0, t_eval, p=p, rtol=rtol, atol=atol, h0=h0,
                                       max_steps=max_steps, lo=lo, hi=hi,
                                       proj_mask=projection[0], proj_tol=projection[1],
                                       time_limit=time_limit)
    stats["wall_time"] = time.perf_counter() - start
    return t, X, stats
