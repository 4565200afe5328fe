"""Where between two output samples an event happens: the root of its witness, located.

A check finds an event on the output samples (a witness function of the state, e.g. a
contact's cone margin ``mu f - |F_t|``, positive before and not after). ``locate`` finds the
time where the witness reaches zero: the run is integrated again from the last sample before
the event, by the run's own method and tolerances (the C Radau loop for the SUNDIALS methods,
as ``failures.locate_exit`` does), to each trial time of Brent's method (``scipy.optimize.brentq``)
on the witness. The time is located to ``TIME_TOL`` s on the re-integrated trajectory, whose
distance from the run's own is the integrator's tolerance; the state returned is the
re-integrated one there.
"""
from __future__ import annotations

import math
from collections.abc import Callable

import numpy as np
from scipy.optimize import brentq

from grasping_sym.errors import IntegratorError
from grasping_sym.runtime import integrators
from grasping_sym.runtime import outputs as outputs_
from grasping_sym.runtime.parameters import complete

#: Absolute tolerance (s) of the located time.
TIME_TOL = 1e-14


def state_at(model, s, sched, p, t0: float, x0: np.ndarray, t: float) -> np.ndarray:
    """The state at ``t`` integrated from ``(t0, x0)`` with the run's settings ``s`` (restarting
    at the knots of the inputs' table ``sched``, as the run did)."""
    if t <= t0:
        return x0
    pieces = [(t0, t, None, None)] if sched is None else sched.segments(t0, t)
    x = x0
    method = s.method if s.method in integrators.C_LOOPS else "radau"
    for a0, a1, a, b in pieces:
        pk = p if sched is None else model.with_inputs(p, a, b)
        _, X, _ = integrators.c_loop(model, method, x, np.array([a0, a1]), pk, rtol=s.rtol,
                                     atol=s.atol, max_steps=s.max_steps, h=s.h, projection=s.proj,
                                     time_limit=s.time_limit)
        x = X[-1]
    return x


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

    plain = sched is None and not model.manifest.get("outputs_time")
    p_full = complete(model, p) if plain else None

    def g(t: float) -> float:
        if plain:  # one compiled call, no arrays by name
            y = dict(zip(model.columns, model.library.outputs(x_at(t), p_full).tolist()))
        else:
            y = {k: float(col[0]) for k, col in
                 outputs_.along(model, np.array([t]), x_at(t)[None, :], p, sched).items()}
        v = witness(y)
        return -1e300 if math.isnan(v) else v  # a NaN (blow-up): past the event

    try:
        if not g(t0) > 0:
            return t0, x0
        if g(t1) > 0:
            return None
        t = brentq(g, t0, t1, xtol=TIME_TOL, maxiter=200)
    except (IntegratorError, ValueError, RuntimeError):
        return None
    return t, x_at(t)
