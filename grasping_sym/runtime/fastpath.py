"""The short way through ``Model.simulate`` for the calls a loop makes again and again.

A call with output times given, no outputs, no inputs, no run-time parameters given and no time
limit, whose settings (method, tolerances, ``max_steps``, ``project``, ``checks``, ``mu``) a previous
call of the full path accepted, goes straight to the C loop (``gs_radau5`` / ``gs_dopri5`` / ``gs_dop853``
through the library's CPython extension): the settings were validated then and are kept here as
a *plan*; the initial checks of an ``x0`` (a pure function of ``x0`` and ``p``) are
remembered for the last few states, with the checks the C loop watches from it
(``runtime.watch``); the events along the run are watched at every step as the full way
watches them, or checked on the output samples where the full way checks those (a run with
an event goes the full way, which names it).
The C loop validates the output times and ``x0`` itself; a run that fails, or arguments this
path does not take, go the full way, which names the problem. The numbers are the full
path's, bit for bit (the same call with the same arrays).
"""
from __future__ import annotations

import math
from time import perf_counter

import numpy as np

from grasping_sym.runtime import checks as checks_
from grasping_sym.runtime import friction, interrupt, parameters, watch
from grasping_sym.runtime.atlas import Atlases
from grasping_sym.runtime.c_loops import (
    ADAPTIVE_CODES,
    ERR_INTERRUPT,
    NSTATS,
    NSTIFF,
    STIFF_BOUND,
    adaptive_stats,
)
from grasping_sym.runtime.result import SimulationResult
from grasping_sym.runtime.settings import RunSettings

#: Initial states whose checks passed, remembered per model (the oldest dropped beyond this).
CHECKED_STATES = 64


class Memory:
    """A model's short way: the plans its full path accepted (by ``key``), and what a run on
    the short way reads of the model (its stored start ``x_start`` and run-time parameters by
    name ``pdict``; ``atlases``, its ``runtime.atlas.Atlases``, made at its first run on the short
    way, or None). ``Model.short_way`` holds one."""

    __slots__ = ("plans", "x_start", "pdict", "atlases")

    def __init__(self, x_start: np.ndarray, pdict: dict[str, float]):
        self.plans: dict = {}
        self.x_start = x_start
        self.pdict = pdict
        self.atlases = None


class Plan:
    """What the full path decided for one set of settings (a ``runtime.settings.RunSettings``),
    and the initial states whose checks passed with them (``checked``, the most recent
    ``CHECKED_STATES``, each with the checks the C loop watches from it:
    ``RunSettings.watched``)."""

    __slots__ = ("method", "code", "rtol", "atol", "max_steps", "nstiff", "mask", "proj_tol",
                 "checks", "projected", "mu", "checked")

    def __init__(self, s: RunSettings):
        self.method, self.code = s.method, ADAPTIVE_CODES[s.method]
        self.rtol, self.atol, self.max_steps = float(s.rtol), float(s.atol), int(s.max_steps)
        self.nstiff = NSTIFF if s.method in STIFF_BOUND else 0
        self.mask, self.proj_tol = s.proj
        self.projected = self.mask is not None
        self.checks = bool(s.checks)
        self.mu = s.mu  # each contact's friction coefficient, checked on the samples (or None)
        self.checked: dict = {}


def typed(value):
    """``value`` with the type of each of its parts (tuples entry by entry), for a key:
    ``True``, ``1`` and ``1.0`` are equal but not the same argument, and the full way refuses
    some of them."""
    if isinstance(value, tuple):
        return tuple(typed(v) for v in value)
    return type(value), value


def key(method, rtol, atol, max_steps, project, checks, mu=None, friction=None):
    """The settings' key of a plan (None when one of them cannot be a key): with the run's
    ``mu`` and the model's friction law, which the plan's cone check reads; each with its
    type (``typed``)."""
    try:
        k = typed((method, rtol, atol, max_steps, project, checks, mu, friction))
        hash(k)
    except TypeError:
        return None
    return k


def plain_times(t_eval, t_final) -> np.ndarray | None:
    """``t_eval`` as a new float array when it plainly is output times from 0 to ``t_final``
    (real numbers, finite, strictly increasing), else None: the full way checks it and names
    what is wrong."""
    t = np.asarray(t_eval)
    if t.dtype.kind not in "fiu" or t.ndim != 1 or t.size < 2:
        return None
    t = t.astype(float)  # a copy
    if not (t[0] == 0.0 and t[-1] == t_final and 0.0 < t_final < math.inf):
        return None
    if t.size > 2 and not (t[1:] > t[:-1]).all():  # a NaN fails it too
        return None
    return t


def remember(model, k, s: RunSettings) -> None:
    """After the full path ran with the settings ``s`` (key ``k``): keep them as a plan
    (C-loop methods with the fast extension only)."""
    if k is None or s.method not in ADAPTIVE_CODES or not model.library.fast:
        return
    if k not in model.short_way.plans:  # (the same key: the same settings, and its states kept)
        model.short_way.plans[k] = Plan(s)


def forget(model) -> None:
    """Drop every plan of ``model``: its next calls take the full path (benchmarks)."""
    model.short_way.plans.clear()


def checked(model, k, x0: np.ndarray | None, watched: tuple) -> None:
    """Remember that ``x0`` (None: the model's start) passed the initial checks with the
    model's own ``p`` and the plan of key ``k``, and the checks the C loop watched from it
    (``RunSettings.watched``)."""
    plan = model.short_way.plans.get(k)
    if plan is None:
        return
    memo = plan.checked
    memo[b"" if x0 is None else x0.tobytes()] = watched
    if len(memo) > CHECKED_STATES:
        del memo[next(iter(memo))]


def run(model, plan: Plan, t_final, t_eval, x0) -> SimulationResult | None:
    """The run on the short way, or None when it must go the full way (arguments it does not
    take, checks not yet passed for this ``x0``, or a failed run)."""
    t = plain_times(t_eval, t_final)
    if t is None:
        return None
    memory = model.short_way
    if x0 is None:
        x = memory.x_start
        watched = plan.checked.get(b"")
    else:
        x = np.asarray(x0)
        if x.dtype.kind not in "fiu":  # the full way names what else it is
            return None
        x = np.ascontiguousarray(x, dtype=float)
        if x.shape != memory.x_start.shape:
            return None
        watched = plan.checked.get(x.tobytes())
    if plan.checks and watched is None:
        return None
    watched = watched if plan.checks else ()
    m = t.size
    lib = model.library
    out = np.empty((m + 1, lib.nx))
    stats = np.zeros(NSTATS)
    if watched:
        watch.start(lib, watched, watch.input_slots(model))
    if model.manifest.get("atlas") and memory.atlases is None:
        memory.atlases = Atlases(model)
    wrapped: list = []  # the coordinates the loop wraps at the step (c/wrap.c): recorded
    p = model.default_params if model.p_names else None
    start = perf_counter()
    try:
        with lib.wrapping(None if memory.atlases is None else memory.atlases.wrap_only, wrapped):
            rc, _ = lib._ext.adaptive(plan.code, t, x, p, plan.rtol, plan.atol, 0.0, plan.max_steps,
                                      plan.nstiff, model.lower, model.upper, plan.mask, plan.proj_tol, out,
                                      stats)
    finally:
        if watched:
            lib.unwatch()
    wall = perf_counter() - start
    if rc != m:
        if rc == ERR_INTERRUPT and lib._lib.gs_stop_cause() == 1:  # Ctrl-C: stop, not run again
            raise interrupt.interrupted(f"{plan.method} stopped by Ctrl-C")
        return None  # a failure, or a watched check's event (ERR_EVENT): the full way names it
    if plan.checks and not watched and model.columns and not checks_.clean(
            model, t, out[:m], model.default_params if model.p_names else None):
        return None  # an event along the run: the full way raises it, named
    if plan.checks and not watched and plan.mu is not None and not friction.inside(model, out[:m], plan.mu):
        return None  # a force leaves its cone: the full way locates it and names it
    info = adaptive_stats(plan.method, stats.tolist(), wall, plan.projected)
    charts = {}
    switches = []
    if model.manifest.get("atlas"):  # an atlas's run that changed no chart: its start's charts
        charts = {k: np.full(m, int(model.default_params[model.p_names.index(k)]))
                  for k in parameters.charts_of(model)}
        switches = memory.atlases.wrapped(wrapped)
        info["chart_switches"] = len(switches)
    return SimulationResult(t, out[:m], model.state_names, {}, plan.method, info, dict(memory.pdict),
                            model.scene, charts=charts, chart_switches=switches)
