"""The integrators whose whole loop runs in C (``gs_rk4``, ``gs_radau5``, ``gs_dopri5``,
``gs_dop853``): argument
checks, the call into the compiled library and the translation of its return codes into results
or named errors. ``CompiledLibrary.rk4`` / ``radau5`` / ``dopri5`` / ``dop853`` are the documented
entry points;
the C calls themselves are ``CompiledLibrary._c_rk4`` and ``CompiledLibrary._call_adaptive`` (the
CPython fast path when the library has it, ctypes otherwise).
"""
from __future__ import annotations

import contextlib
import ctypes
import math
from time import perf_counter
from typing import Any

import numpy as np

from grasping_sym.errors import IntegratorError
from grasping_sym.runtime import interrupt

# Return codes of gs_rk4, gs_radau5, gs_dopri5, gs_dop853 and gs_project (see c/gs_internal.h).
_ERR_NONFINITE, _ERR_BOUNDS, _ERR_EVAL, _ERR_ARGS, _ERR_STEP, _ERR_MAXSTEPS = -1, -2, -3, -4, -5, -6
_ERR_PROJECT, _ERR_STIFF, _ERR_INTERRUPT = -7, -8, -9
#: gs_radau5, gs_dopri5, gs_dop853 stopped at a watched witness's event (c/watch.c)
_EVENT = -10
ERR_PROJECT, ERR_EVENT = _ERR_PROJECT, _EVENT
ERR_INTERRUPT, ERR_ARGS = _ERR_INTERRUPT, _ERR_ARGS
ERR_EVAL, ERR_BOUNDS, ERR_STIFF = _ERR_EVAL, _ERR_BOUNDS, _ERR_STIFF
_RK4_EXTRA_ROWS = 2
_ADAPTIVE_EXTRA_ROWS = 1
NSTATS = 16  # GS_NSTATS
_STATS = {"radau": ("n_steps", "n_rejected", "n_rhs", "n_jac", "n_lu", "n_newton"),
          "dopri5": ("n_steps", "n_rejected", "n_rhs"), "dop853": ("n_steps", "n_rejected", "n_rhs")}
#: The adaptive loops' codes in the CPython extension's ``adaptive()`` (``c/pyfast.c``).
ADAPTIVE_CODES = {"radau": 0, "dopri5": 1, "dop853": 2}
#: Where each explicit method's stiffness test fires: h |lambda| above this (c/dopri5.c,
#: c/dop853.c).
STIFF_BOUND = {"dopri5": 3.25, "dop853": 6.1}
#: Hairer's DOPRI5 default: the stiffness test runs on every 1000th accepted step.
NSTIFF = 1000
_T_OUT = "t_out must be a finite, strictly increasing 1-D array of at least two times"
_double = ctypes.c_double


@contextlib.contextmanager
def stoppable(lib, time_limit: float | None):
    """Around a C loop (or a SUNDIALS run, whose step budget reads the same deadline):
    ``time_limit`` seconds of wall time for it, or none. The deadline is set on entry either
    way, so that none left behind by an earlier run stops this one. Ctrl-C needs nothing here:
    the process's one SIGINT handler (``c/stop.c``, owned by ``runtime/interrupt.py`` and put
    back in front at every loop's start) stops the loop, which returns ``GS_ERR_INTERRUPT``;
    :func:`stop_error` says why. No Python signal handler is involved, so nothing can raise
    between the loop's return and the deadline's reset."""
    if not interrupt.in_run():  # a library's loop called directly: a Ctrl-C before it is not its
        interrupt.clear()
    elif interrupt.stopped() or interrupt.requested():  # Ctrl-C since the run began
        # (interrupt.run_scope), between two of its loops, or a batch that Ctrl-C stopped
        # (runtime.pool): no new loop
        raise interrupt.interrupted("stopped by Ctrl-C, before the run's next loop")
    c = lib._lib
    c.gs_set_time_limit(float(time_limit) if time_limit else 0.0)
    try:
        yield
    finally:
        c.gs_set_time_limit(0.0)


def stop_error(lib, method: str, tf: float, x, time_limit) -> IntegratorError:
    """The error of a loop stopped from outside: KeyboardInterrupt for Ctrl-C (raised here),
    else the wall-time limit's ``IntegratorError``."""
    if lib._lib.gs_stop_cause() == 1:
        raise interrupt.interrupted(f"{method} stopped by Ctrl-C at t = {tf:.6g} s")
    err = IntegratorError(tf, x, f"{method}: the wall-time limit of {time_limit:g} s was "
                          f"reached at t = {tf:.6g} s (raise time_limit, or loosen the "
                          "tolerances)", lib.state_names)
    err.cause = "time_limit"  # type: ignore[attr-defined]  # (a batch's runs: its own code, failures.out_of_time)
    return err


def as_vector(a: Any, n: int, name: str) -> np.ndarray:
    arr = np.ascontiguousarray(a, dtype=float)
    if arr.shape != (n,):
        raise ValueError(f"{name} must have shape ({n},), got shape {arr.shape}")
    return arr


def rk4_steps(t0: float, t_final: float, h: float, stride: int) -> tuple[float, int]:
    """``(h_eff, nsteps)``: the steps of at most ``h`` from ``t0`` to ``t_final``, a multiple of
    ``stride`` of them, so that the last stored row is ``t_final`` exactly."""
    nblocks = max(1, math.ceil((t_final - t0) / (h * stride) - 1e-9))
    nsteps = nblocks * stride
    return (t_final - t0) / nsteps, nsteps


def rk4(lib, x0: Any, t0: float, t_final: float, h: float, stride: int = 1, p: Any = None,
        lo: Any = None, hi: Any = None, proj_mask: Any = None, proj_tol: float = 0.0,
        stats: dict | None = None, time_limit: float | None = None) -> tuple[np.ndarray, np.ndarray]:
    """``CompiledLibrary.rk4`` (documented there)."""
    x0a = as_vector(x0, lib.nx, "x0")
    pa = lib._p(p)
    lo_a = np.full(lib.nx, -np.inf) if lo is None else as_vector(lo, lib.nx, "lo")
    hi_a = np.full(lib.nx, np.inf) if hi is None else as_vector(hi, lib.nx, "hi")
    t0, t_final, h = float(t0), float(t_final), float(h)
    stride = int(stride)
    if not (math.isfinite(t0) and math.isfinite(t_final) and t_final > t0):
        raise ValueError(f"need finite t0 < t_final, got t0 = {t0}, t_final = {t_final}")
    if not (math.isfinite(h) and h > 0):
        raise ValueError(f"step h must be finite and > 0, got {h}")
    if stride < 1:
        raise ValueError(f"stride must be >= 1, got {stride}")
    mask = lib._mask(proj_mask, float(proj_tol))

    bad = violation(x0a, lo_a, hi_a, lib.state_names)
    if bad:
        raise IntegratorError(t0, x0a, f"initial state: {bad}", lib.state_names)

    h_eff, nsteps = rk4_steps(t0, t_final, h, stride)
    rows = nsteps // stride + 1
    out = np.empty((rows + _RK4_EXTRA_ROWS, lib.nx))
    t_fail = _double(math.nan)
    stats_a = np.zeros(NSTATS)
    with stoppable(lib, time_limit):
        rc = lib._c_rk4(
            t0, h_eff, nsteps, stride, x0a.ctypes.data, lib._ptr(pa),
            lo_a.ctypes.data, hi_a.ctypes.data, lib._ptr(mask), float(proj_tol),
            out.ctypes.data, stats_a.ctypes.data, ctypes.byref(t_fail),
        )
    if stats is not None:
        stats.update({"n_steps": int(stats_a[0]), "n_rhs": int(stats_a[2])})
        if mask is not None:
            stats.update(projection_stats(stats_a))
    if rc >= 0:
        if rc != rows:
            raise RuntimeError(f"gs_rk4 wrote {rc} rows, expected {rows}")
        t = t0 + h_eff * stride * np.arange(rows)
        t[-1] = t_final
        return t, out[:rows].copy()
    if rc == _ERR_ARGS:
        raise ValueError(f"gs_rk4 rejected its arguments (h = {h_eff}, nsteps = {nsteps}, stride = {stride})")

    tf = t_fail.value
    k = int(round((tf - t0) / h_eff))
    r = k // stride + 1
    x_good = out[r].copy()
    x_bad = out[r + 1].copy()
    if rc == _ERR_NONFINITE:
        reason = (f"{nonfinite(x_bad, lib.state_names)} became non-finite in the step to "
                  f"t = {tf + h_eff:.6g} s")
    elif rc == _ERR_BOUNDS:
        reason = violation(x_bad, lo_a, hi_a, lib.state_names) + f" in the step to t = {tf + h_eff:.6g} s"
    elif rc == _ERR_EVAL:
        reason = f"the CasADi function reported an evaluation error in the step to t = {tf + h_eff:.6g} s"
    elif rc == _ERR_PROJECT:
        reason = projection_reason(stats_a, proj_tol, f"in the step to t = {tf + h_eff:.6g} s")
    elif rc == _ERR_INTERRUPT:
        err = stop_error(lib, "rk4", tf, x_good, time_limit)
        err.trajectory = (t0 + h_eff * stride * np.arange(r), out[:r].copy())  # type: ignore[attr-defined]
        raise err
    else:
        reason = f"gs_rk4 returned unknown code {rc}"
    err = IntegratorError(tf, x_good, reason, lib.state_names)
    err.t_rejected = tf + h_eff  # type: ignore[attr-defined]
    err.x_rejected = x_bad  # type: ignore[attr-defined]
    err.code = int(rc)  # type: ignore[attr-defined]
    t_stored = t0 + h_eff * stride * np.arange(r)
    err.trajectory = (t_stored, out[:r].copy())  # type: ignore[attr-defined]
    raise err


def adaptive(lib, method: str, x0: Any, t_out: Any, p: Any, rtol: float, atol: float,
             h0: float, max_steps: int, lo: Any, hi: Any, proj_mask: Any, proj_tol: float,
             nstiff: int = 0, time_limit: float | None = None) -> tuple[np.ndarray, np.ndarray, dict]:
    """``CompiledLibrary.radau5`` (``method='radau'``), ``dopri5`` or ``dop853`` (documented there).

    The checks here are the cheap ones (shapes, scalars); the C code validates ``t_out``
    (finite, strictly increasing) and the initial state (finite, inside the bounds) itself,
    and a rejection is explained afterwards, so that a short run does not pay for NumPy
    reductions over them.
    """
    x0a = as_vector(x0, lib.nx, "x0")
    pa = lib._p(p)
    t_arr = np.ascontiguousarray(t_out, dtype=float)
    if t_arr.ndim != 1 or t_arr.size < 2:
        raise ValueError(_T_OUT)
    lo_a = None if lo is None else as_vector(lo, lib.nx, "lo")
    hi_a = None if hi is None else as_vector(hi, lib.nx, "hi")
    rtol, atol, h0, proj_tol = float(rtol), float(atol), float(h0), float(proj_tol)
    if not (math.isfinite(rtol) and rtol > 0 and math.isfinite(atol) and atol >= 0):
        raise ValueError(f"need finite rtol > 0 and atol >= 0, got rtol = {rtol}, atol = {atol}")
    if not (math.isfinite(h0) and h0 >= 0):
        raise ValueError(f"h0 must be finite and >= 0 (0 = automatic), got {h0}")
    max_steps = int(max_steps)
    if max_steps < 1:
        raise ValueError(f"max_steps must be >= 1, got {max_steps}")
    mask = lib._mask(proj_mask, proj_tol)
    m = t_arr.size
    out = np.empty((m + _ADAPTIVE_EXTRA_ROWS, lib.nx))
    stats_a = np.zeros(NSTATS)
    start = perf_counter()
    with stoppable(lib, time_limit):
        rc, tf = lib._call_adaptive(method, t_arr, x0a, pa, rtol, atol, h0, max_steps,
                                    int(nstiff), lo_a, hi_a, mask, proj_tol, out, stats_a)
    wall = perf_counter() - start
    stats = adaptive_stats(method, stats_a.tolist(), wall, mask is not None)
    c_name = "gs_radau5" if method == "radau" else f"gs_{method}"
    if rc >= 0:
        if rc != m:
            raise RuntimeError(f"{c_name} returned {rc}, expected {m}")
        return t_arr.copy(), out[:m], stats  # out is ours: a view of it, no copy
    if rc == _EVENT:  # the rows before it, its state, its step's start (c/watch.c)
        r = int(stats_a[6])
        stats["event"] = {"t": tf, "x": out[r].copy(), "x_step": out[r + 1].copy()}
        return t_arr[:r].copy(), out[:r], stats
    if rc == _ERR_ARGS:
        if not (np.all(np.isfinite(t_arr)) and np.all(np.diff(t_arr) > 0)):
            raise ValueError(_T_OUT)
        raise ValueError(f"{c_name} rejected its arguments (rtol = {rtol}, atol = {atol}, "
                         f"h0 = {h0}, max_steps = {max_steps}, proj_tol = {abs(proj_tol)})")
    bad = violation(x0a, lo_a, hi_a, lib.state_names) if stats_a[0] == 0 else ""
    if bad:  # the C code refused the initial state itself
        raise IntegratorError(float(t_arr[0]), x0a, f"initial state: {bad}", lib.state_names)
    if rc == _ERR_INTERRUPT:
        r = int(stats_a[6])
        err = stop_error(lib, method, tf, out[r].copy(), time_limit)
        err.trajectory = (t_arr[:r].copy(), out[:r].copy())  # type: ignore[attr-defined]
        err.stats = stats  # type: ignore[attr-defined]
        raise err
    raise _failure(lib, method, c_name, rc, tf, t_arr, out, stats, stats_a, lo_a, hi_a,
                   max_steps, proj_tol)


def adaptive_stats(method: str, st: list, wall: float, projected: bool) -> dict:
    """``simulate``'s ``stats`` of a radau / dopri5 / dop853 run from its GS_NSTATS counters (``st``: the
    array's ``tolist()``, Python floats being cheaper to pick from)."""
    stats: dict = dict(zip(_STATS[method], map(int, st)))
    stats["h_last"] = st[7]
    stats["wall_time"] = wall
    if projected:
        stats.update(projection_stats(st))
    if method == "radau":  # the rows its linear systems were reduced by (c/radau5.c)
        stats["second_order_rows"] = int(st[15])
    if method in STIFF_BOUND:
        stats["h_lambda"] = st[13]
        stats["n_stiff_tests"] = int(st[14])
    return stats


def _failure(lib, method: str, c_name: str, rc: int, tf: float, t_arr: np.ndarray,
             out: np.ndarray, stats: dict, stats_a: np.ndarray, lo_a: np.ndarray | None,
             hi_a: np.ndarray | None, max_steps: int, proj_tol: float) -> IntegratorError:
    """The ``IntegratorError`` of an adaptive run that returned ``rc < 0``."""
    r = int(stats_a[6])
    x_good = out[r].copy()
    x_bad = out[r + 1].copy()
    after = f"after t = {tf:.6g} s"
    if rc == _ERR_NONFINITE:
        if np.all(np.isfinite(x_bad)):
            reason = (f"{method}: the right-hand side became non-finite at the end of the "
                      f"step {after} (state {x_bad.tolist()})")
        else:
            reason = f"{method}: {nonfinite(x_bad, lib.state_names)} became non-finite in the step {after}"
    elif rc == _ERR_BOUNDS:
        reason = f"{method}: " + violation(x_bad, lo_a, hi_a, lib.state_names) + f" in the step {after}"
    elif rc == _ERR_EVAL:
        reason = f"{method}: the CasADi function reported an evaluation error in the step {after}"
    elif rc == _ERR_STEP:
        why = ("Newton iteration or error test failed repeatedly" if method == "radau"
               else "error test failed repeatedly or the right-hand side is non-finite "
                    "inside the steps")
        reason = (f"{method}: step size fell below the minimum at t = {tf:.6g} s ({why}: "
                  "a blow-up, a singularity, or tolerances too tight)")
    elif rc == _ERR_MAXSTEPS:
        reason = (f"{method}: too many steps ({max_steps}) before reaching t = {t_arr[-1]:.6g} s "
                  f"(stopped at t = {tf:.6g} s; raise max_steps or loosen rtol/atol)")
    elif rc == _ERR_PROJECT:
        reason = f"{method}: " + projection_reason(stats_a, proj_tol, after)
    elif rc == _ERR_STIFF:
        reason = (f"{method}: the system is stiff at t = {tf:.6g} s: the explicit method's step "
                  f"is limited by its stability, not by accuracy (h |lambda| = "
                  f"{stats_a[13]:.3g} > {STIFF_BOUND[method]} on 15 steps, h = {stats_a[7]:.3g} s; "
                  f"{method.upper()}'s stiffness test), so it would crawl: use method='radau' or "
                  "'cvodes'")
    else:
        reason = f"{method}: {c_name} returned unknown code {rc}"
    err = IntegratorError(tf, x_good, reason, lib.state_names)
    err.code = int(rc)  # type: ignore[attr-defined]
    err.stats = stats  # type: ignore[attr-defined]
    err.stiff = rc == _ERR_STIFF  # type: ignore[attr-defined]
    if rc in (_ERR_NONFINITE, _ERR_BOUNDS, _ERR_PROJECT):
        err.x_rejected = x_bad  # type: ignore[attr-defined]
    err.trajectory = (t_arr[:r].copy(), out[:r].copy())  # type: ignore[attr-defined]
    return err


def violation(x: np.ndarray, lo: np.ndarray | None, hi: np.ndarray | None,
              names=None) -> str:
    """Empty string if ``x`` is finite and in bounds (``None``: unbounded), else the reason,
    naming the state (``names``, the state names)."""
    if (np.isfinite(x).all() and (lo is None or (x >= lo).all())
            and (hi is None or (x <= hi).all())):
        return ""
    if not np.isfinite(x).all():
        return f"{nonfinite(x, names)} are non-finite"
    lo = np.full(x.shape, -np.inf) if lo is None else lo
    hi = np.full(x.shape, np.inf) if hi is None else hi
    i = int(np.flatnonzero((x < lo) | (x > hi))[0])
    name = names[i] if names is not None and i < len(names) else "value"
    return f"{name} = {x[i]:.6g} left [{lo[i]:g}, {hi[i]:g}]"


def nonfinite(x: np.ndarray, names=None) -> str:
    """The non-finite entries of ``x`` by state name (at most ten listed), or, without the
    state names, ``state component(s) [i, ...]``."""
    idx = np.flatnonzero(~np.isfinite(x)).tolist()
    more = f", ... {len(idx)} in all" if len(idx) > 10 else ""
    if names is not None and len(names) == len(x):
        return ", ".join(names[i] for i in idx[:10]) + more
    return f"state component(s) {idx[:10]}"[:-1] + more + "]"


def projection_stats(stats_a) -> dict:
    """The projection's entries of the GS_NSTATS array (or its ``tolist()``)."""
    return {"n_constraint_evals": int(stats_a[8]), "max_drift": float(stats_a[9]),
            "max_drift_rate": float(stats_a[10])}


def projection_reason(stats_a: np.ndarray, tol: float, after: str) -> str:
    what = ("the position constraints C" if stats_a[11] == 1
            else "the velocity constraints Cdot")
    where = f" {after}" if after else ""
    return (f"the projection onto {what} failed{where}: max residual {stats_a[12]:.3g} > "
            f"tolerance {abs(tol):.3g} after Gauss-Newton (not converging, a singular constraint "
            "Jacobian, or non-finite values): the contact configuration is singular, or the "
            "tolerance is below the rounding level of the constraints (use a larger "
            "projection tolerance, e.g. simulate(..., project=1e-10))")
