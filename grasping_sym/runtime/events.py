"""Where an event happens: the root of its witness, located on the run's trajectory.

A witness is a function of the state (e.g. a contact's cone margin ``mu f - |F_t|``),
positive before the event and not after. The time where it reaches zero is found on the
trajectory integrated again from a state before the event, by the run's own method and
tolerances (the C Radau loop for the SUNDIALS methods, as ``failures.locate_exit`` does), to
each trial time; the time is located to ``TIME_TOL`` s on the re-integrated trajectory, whose
distance from the run's own is the integrator's tolerance, and the state returned is the
re-integrated one there.

- ``locate``: the event was seen between two output samples; Brent's method
  (``scipy.optimize.brentq``) between them, each trial integrated from the first.
- ``refine``: the event was seen by the C loop itself (``c/watch.c``), inside one step, with
  the root of its dense output as a first guess and the dense output's slope: secant steps
  from it, each trial one step from the step's start, until the next would be below
  ``TIME_TOL`` or, with the bracket within ``NOISE`` times it, a trial is no nearer 0
  than the last (the witness's noise: the last taken if inside the bracket, else the
  trial); Brent's method between the watched points around it when they do not converge.
"""
from __future__ import annotations

import math
from collections.abc import Callable

import numpy as np

from grasping_sym.errors import IntegratorError
from grasping_sym.runtime import integrators
from grasping_sym.runtime import outputs as outputs_
from grasping_sym.runtime.parameters import complete

#: Absolute tolerance (s) of the located time.
TIME_TOL = 1e-14


#: ``refine`` stops where the bracket of the sign change is within this many times ``TIME_TOL``
#: and a trial is no nearer 0 than the last: the witness on the trajectory integrated again one
#: step at a time is at its noise there (the Newton iterations' tolerance; ~3e-13 of paper2d's
#: cone, 1e-13 s, at rtol 1e-10). The last trial is taken if it is inside the bracket, else this
#: one (an end of it): either is within the bracket (``c/watch.c``: ``GS_WATCH_NOISE``).
NOISE = 100

#: Most secant steps of ``refine`` before it falls back to Brent's method.
SECANT_STEPS = 8


def _brentq():
    """``scipy.optimize.brentq``, imported when an event is located by it: SciPy's optimize
    takes 0.39 s to import, the whole runtime's import otherwise 0.11 s (``gs.load``,
    ``gs.build`` of a cached model)."""
    from scipy.optimize import brentq  # noqa: PLC0415 - lazy: SciPy (0.39 s), only to locate an event

    return brentq


def state_at(model, s, sched, p, t0: float, x0: np.ndarray, t: float, one_step: bool = False,
             projection=None) -> np.ndarray:
    """The state at ``t`` integrated from ``(t0, x0)`` with the run's settings ``s`` (restarting
    at the knots of the inputs' table ``sched``, as the run did); ``one_step``: the first step
    tried is the whole interval (``t`` inside a step the run took from ``t0``); ``projection``:
    the run's (None: ``s.proj``)."""
    if t <= t0:
        return x0
    pieces = [(t0, t, None, None)] if sched is None else sched.segments(t0, t)
    x = x0
    method = s.method if s.method in integrators.C_LOOPS else "radau"
    for a0, a1, a, b in pieces:
        pk = p if sched is None else model.with_inputs(p, a, b)
        _, X, _ = integrators.c_loop(model, method, x, np.array([a0, a1]), pk, rtol=s.rtol,
                                     atol=s.atol, max_steps=s.max_steps, h=s.h,
                                     projection=s.proj if projection is None else projection,
                                     time_limit=s.time_limit, h0=a1 - a0 if one_step else 0.0)
        x = X[-1]
    return x


def _witness_at(model, p, sched, witness: Callable[[dict], float]) -> Callable[[float, np.ndarray], float]:
    """``g(t, x)``: ``witness`` of the compiled outputs at ``(t, x)`` (the inputs at ``t``, and
    ``t`` itself for a law that reads it); a NaN (a blow-up) counts as past the event."""
    plain = sched is None and not model.manifest.get("outputs_time")
    p_full = complete(model, p) if plain else None

    def g(t: float, x: np.ndarray) -> float:
        if plain:  # one compiled call, no arrays by name
            y = dict(zip(model.columns, model.library.outputs(x, p_full).tolist()))
        else:
            y = {k: float(col[0]) for k, col in
                 outputs_.along(model, np.array([t]), x[None, :], p, sched).items()}
        v = witness(y)
        return -1e300 if math.isnan(v) else v

    return g


def refine(model, s, sched, p, t_step: float, x_step: np.ndarray, t_lo: float, t_hi: float,
           t_guess: float, slope: float, witness: Callable[[dict], float],
           projection=(None, 0.0)) -> tuple[float, np.ndarray] | None:
    """``(t, x)`` where ``witness`` reaches zero in ``[t_lo, t_hi]``, inside the step the run
    took from ``(t_step, x_step)``, the dense output's root ``t_guess`` and slope ``slope``
    given (module docstring); None when the trajectory integrated again does not change sign
    there."""
    g_at = _witness_at(model, p, sched, witness)
    cache: dict[float, np.ndarray] = {}

    def x_at(t: float) -> np.ndarray:
        if t not in cache:
            cache[t] = state_at(model, s, sched, p, t_step, x_step, t, one_step=True,
                                projection=projection)
        return cache[t]

    def g(t: float) -> float:
        return g_at(t, x_at(t))

    try:
        a, b = t_lo, t_hi  # g(a) > 0 >= g(b) on the dense output
        t1 = min(max(t_guess, a), b)
        g1 = g(t1)
        if g1 > 0:
            a = t1
        else:
            b = t1
        t2 = t1 - g1 / slope if slope < 0 and math.isfinite(slope) else 0.5 * (a + b)
        if abs(t2 - t1) <= TIME_TOL and a <= t2 <= b:  # the dense output's root was the root
            return t1, x_at(t1)
        for _ in range(SECANT_STEPS):
            if g1 == 0 or b - a <= TIME_TOL:
                return t1, x_at(t1)
            if not a <= t2 <= b or t2 == t1:
                t2 = 0.5 * (a + b)
            g2 = g(t2)
            if g2 > 0:
                a = t2
            else:
                b = t2
            if b - a <= NOISE * TIME_TOL and not abs(g2) < abs(g1):  # at the witness's noise
                return (t1, x_at(t1)) if a <= t1 <= b else (t2, x_at(t2))  # inside the bracket
            t3 = t2 - g2 * (t2 - t1) / (g2 - g1) if g2 != g1 else 0.5 * (a + b)
            if g2 == 0 or abs(t3 - t2) <= TIME_TOL:  # the next secant step would be below TIME_TOL
                return t2, x_at(t2)
            t1, g1, t2 = t2, g2, t3
        # no convergence: Brent's method between the sides found
        if not (g(a) > 0 and not g(b) > 0):
            return None
        t = _brentq()(g, a, b, xtol=TIME_TOL, maxiter=200)
    except (IntegratorError, ValueError, RuntimeError):
        return None
    return t, x_at(t)


def locate(model, s, sched, p, t0: float, x0: np.ndarray, t1: float,
           witness: Callable[[dict], float]) -> tuple[float, np.ndarray] | None:
    """``(t, x)`` where ``witness`` (a function of one state's compiled outputs by name) reaches
    zero between the samples ``t0`` (state ``x0``, witness > 0) and ``t1`` (witness <= 0),
    or None when the integration again does not reproduce the sign change (then the caller
    keeps the samples' estimate)."""
    cache: dict[float, np.ndarray] = {}

    def x_at(t: float) -> np.ndarray:
        if t not in cache:
            cache[t] = state_at(model, s, sched, p, t0, x0, t)
        return cache[t]

    g_at = _witness_at(model, p, sched, witness)

    def g(t: float) -> float:
        return g_at(t, x_at(t))

    try:
        if not g(t0) > 0:
            return t0, x0
        if g(t1) > 0:
            return None
        t = _brentq()(g, t0, t1, xtol=TIME_TOL, maxiter=200)
    except (IntegratorError, ValueError, RuntimeError):
        return None
    return t, x_at(t)
