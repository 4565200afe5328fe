"""One run of a model: its start checked, its segments over the inputs' schedule integrated,
a failure named, the events along it checked, the result assembled (``Model.simulate``).

A model with inputs restarts the integration at every knot of their table inside the run
(``runtime.inputs``), so a table's kinks and jumps are met exactly. The integrators live in
``runtime.integrators``; the failures are named by ``runtime.failures``; the checks are
``runtime.checks``'s.
"""
from __future__ import annotations

import dataclasses
from time import perf_counter

import numpy as np

from grasping_sym.errors import (
    ContactLeftContourError,
    IntegratorError,
    RunArgumentError,
    StateLeftDomainError,
)
from grasping_sym.runtime import checks as checks_
from grasping_sym.runtime import events, failures, friction, integrators
from grasping_sym.runtime import outputs as outputs_
from grasping_sym.runtime import watch as watch_
from grasping_sym.runtime.atlas import Atlases, by_charts, name_charts, repeated
from grasping_sym.runtime.inputs import as_schedule
from grasping_sym.runtime.result import SimulationResult
from grasping_sym.runtime.settings import RunSettings, numbers_array


def start_state(model, x0) -> tuple[np.ndarray, bool]:
    """``(x0, own_start)``: the state a run starts from, checked (shape, finite, inside the
    contours' domains); ``own_start`` when it is the model's stored start (``x0`` None), whose
    speeds are consistent by construction."""
    own_start = x0 is None
    x0 = model.initial_state() if own_start else numbers_array("x0", x0)
    if x0.shape != (len(model.state_names),):
        raise RunArgumentError(f"x0 has shape {x0.shape}; expected ({len(model.state_names)},) "
                               f"ordered as {model.state_names}")
    if not np.all(np.isfinite(x0)):
        raise RunArgumentError(f"x0 = {x0} has non-finite entries")
    failures.check_bounds(model, 0.0, x0)
    return x0, own_start


def schedule(model, u, method: str, t_eval: np.ndarray):
    """The inputs' schedule (``grasping_sym.runtime.inputs``), None for a model without inputs."""
    if not model.input_names:
        if u is not None:
            raise RunArgumentError("u given, but this model has no inputs: build the scene with "
                                   "inputs='torques' (e.g. gs.scenes.paper2d(inputs='torques'))")
        return None
    sched = as_schedule(u, len(model.input_names))
    if method == "rk4" and any(0 < k < t_eval[-1] for k in sched.knots):
        raise RunArgumentError("rk4 reports on one uniform grid and cannot restart at the table's "
                               "knots: use method='radau', 'dopri5' or 'cvodes' with a table input")
    return sched


def run(model, s: RunSettings, x0: np.ndarray, own_start: bool, p, u) -> SimulationResult:
    """``simulate`` once its arguments are checked (``s``; ``x0`` by ``start_state``): ``p`` is
    every entry of ``p_names`` (the inputs' set from ``u``); a failure or an event raises its
    named error."""
    t_eval = s.t_eval
    sched = schedule(model, u, s.method, t_eval)
    segments = [(0.0, float(t_eval[-1]), None, None)] if sched is None else \
        sched.segments(0.0, float(t_eval[-1]))
    charted = _Charted(model)
    try:
        return _on_charts(model, s, x0, p, sched, segments, own_start, charted)
    except IntegratorError as err:  # on atlases: its state's charts named (the start's checks' too)
        charted.name(err, p)
        raise


def _on_charts(model, s: RunSettings, x0, p, sched, segments, own_start: bool, charted) -> SimulationResult:
    """``run``'s checks of the start, integration, checks and result, across the charts of
    ``charted``."""
    p0 = p if sched is None else model.with_inputs(p, segments[0][2], segments[0][3])
    start = checks_.check_initial_state(model, x0, p0, rates=not own_start) if s.checks else {}
    s.watched = watched_checks(model, s, start)
    t, X, stats = _segments(model, s, segments, sched, x0, p, start, charted)
    pieces = charted.pieces(t, p)  # the rows between switches, each with its p
    # the checks read the compiled outputs whether or not the result shows them: the C loop
    # watched them at every step (runtime.watch), else they are read at the rows; a run that
    # returns none and has no event there (checks.clean, on the watched columns) needs no more
    rows_checked = s.checks and not s.watched
    quiet = not rows_checked or not s.outputs and sched is None and s.mu is None and not charted.switches \
        and checks_.clean(model, t, X, p)  # (clean reads its rows against the first: one chart)
    outs = _outputs_along(model, t, X, sched, pieces) if (s.outputs or s.checks and not quiet) \
        and model.columns else {}
    cone = friction.quantities(model, outs, s.mu) if outs and s.mu is not None else {}
    if s.checks and outs:
        event = checks_.trajectory_event(model, t, X, outs, start)
        if event is not None:
            event = located(model, s, sched, pieces, t, X, event)
        if cone and s.slip == "stop":
            event = cone_event(model, s, sched, pieces, t, X, outs, cone, event)
        if event is not None:
            raise event
    outs = {**{k: outs[k] for k in model.output_names}, **cone} if s.outputs and outs else {}
    charts = charted.rows(t, p)
    if s.drop_first:
        t, X = t[1:], X[1:]
        outs = {k: v[1:].copy() for k, v in outs.items()}
        charts = {k: v[1:] for k, v in charts.items()}
    if charted.atlases is not None:
        stats["chart_switches"] = len(charted.switches)
    pdict = dict(zip(model.param_names, [] if p is None else map(float, p)))
    return SimulationResult(t=t, x=X, state_names=model.state_names, outputs=outs,
                            method=s.method, stats=stats, params=pdict, scene=model.scene,
                            charts=charts, chart_switches=charted.switches)


def _outputs_along(model, t, X, sched, pieces) -> dict:
    """The outputs at the rows, each piece of rows (between chart switches) with its ``p``."""
    if len(pieces) == 1:
        return outputs_.along(model, t, X, pieces[0][2], sched)
    parts = [outputs_.along(model, t[a:b], X[a:b], pk, sched) for a, b, pk in pieces]
    return {k: np.concatenate([part[k] for part in parts]) for k in parts[0]}


#: The methods that switch chart at the step (the adaptive C loops; rk4 reports on one uniform
#: grid and SUNDIALS is seen only at the output times: they stop at a chart's edge, by name).
SWITCHING = ("radau", "dop853", "dopri5")


def _no_switch(model, err: ContactLeftContourError, method: str) -> ContactLeftContourError:
    """``err`` (a contact at its chart's edge) for a method that cannot switch chart there."""
    new = ContactLeftContourError(err.t, err.x, f"{err.reason}: a surface with an atlas switches chart at "
                                  f"the step, which {method} cannot do; use method='radau', 'dop853' or "
                                  "'dopri5'", model.state_names)
    for key in ("x_rejected", "trajectory", "code", "stats"):
        if hasattr(err, key):
            setattr(new, key, getattr(err, key))
    return new


class _Charted:
    """A run's chart switches (``runtime.atlas``; nothing for a model without atlases): where
    a contact reaches its chart's edge, the state is carried to the other chart at that step
    and the integration goes on from there with the new chart in ``p``."""

    def __init__(self, model):
        self.model = model
        self.atlases = Atlases(model) if model.manifest.get("atlas") else None
        #: every switch's record (``Atlases.switch``), in time order
        self.switches: list[dict] = []

    def integrate(self, s: RunSettings, x0, t_eval, p, start, sched=None):
        """``integrate`` across the chart switches: ``(t, X, stats, p)``, ``p`` the last
        chart's. ``max_steps`` and ``time_limit`` bound the whole, whatever its restarts."""
        if self.atlases is None:
            return (*integrate(self.model, s, x0, t_eval, p, start, sched=sched), p)
        rows_t, rows_x, stats, x, grid, h0 = [], [], {}, x0, t_eval, 0.0
        began, now = perf_counter(), s
        while True:
            wrapped: list = []  # the wraps and charts' changes the C loop made (c/wrap.c), before any stop
            try:
                t, X, st = integrate(self.model, now, x, grid, p, start, h0, sched, (self.atlases, wrapped))
            except IntegratorError as err:  # (slot_of: a contact at its chart's edge, else None)
                made = self.atlases.wrapped(wrapped)
                self.switches += made
                p = self.atlases.after(made, p)  # the charts the loop changed
                k = self.atlases.slot_of(err)
                if k is None:
                    raise
                if s.method not in SWITCHING or getattr(err, "trajectory", None) is None:
                    raise _no_switch(self.model, err, s.method) from None
                t, X = err.trajectory
                st = getattr(err, "stats", {})
                # on from the step size the loop had reached (the one it tried past the edge):
                # a restart from a chosen first step would climb back to it over several steps
                h0 = float(st.get("h_last", 0.0))
                x, p, record = self.atlases.switch(k, err.t, err.x, p)
                self._keep(record, err)
                grid = np.concatenate([[err.t], t_eval[t_eval > err.t]])
            else:
                made = self.atlases.wrapped(wrapped)
                self.switches += made
                p = self.atlases.after(made, p)
                grid = None
            rows_t.append(t)
            rows_x.append(X)
            for key, v in st.items():  # the counters add up; the others (h_last, ...) are the last
                counted = isinstance(v, (int, float)) and (key.startswith("n_") or key == "wall_time")
                stats[key] = stats.get(key, 0) + v if counted else v
            if grid is None:
                break
            now = dataclasses.replace(s, max_steps=max(s.max_steps - int(stats.get("n_steps", 0)), 1),
                                      time_limit=None if s.time_limit is None else
                                      max(s.time_limit - (perf_counter() - began), 1e-9))
        t, X = np.concatenate(rows_t), np.concatenate(rows_x)
        keep = np.isin(t, t_eval)        # the switches' times are no output times
        _, first = np.unique(t[keep], return_index=True)
        return t[keep][first], X[keep][first], stats, p

    def name(self, err, p) -> None:
        """``err`` named with the charts its state is written in (``runtime.atlas.name_charts``):
        ``p``'s, as the switches up to its time left them."""
        if self.atlases is not None and p is not None:
            at = self.atlases.after([rec for rec in self.switches if rec["t"] <= err.t], p)
            name_charts(err, self.atlases.charts(at))

    def _keep(self, record: dict, err) -> None:
        if repeated(self.switches, record):
            raise err
        self.switches.append(record)

    def pieces(self, t, p) -> list[tuple[int, int, np.ndarray]]:
        """The rows ``[a, b)`` between changes of chart, each with its ``p`` (``p`` with that
        stretch's charts)."""
        return by_charts(self.model.p_names, t, p, self.switches)

    def rows(self, t, p) -> dict:
        """Per chart parameter, each row's chart."""
        if self.atlases is None:
            return {}
        pieces = self.pieces(t, p)
        out = {}
        for entry, i, _ in self.atlases.slots:
            if i is None:
                continue
            col = np.empty(len(t), dtype=int)
            for a, b, pk in pieces:
                col[a:b] = int(pk[i])
            out[entry["param"]] = col
        return out


def located(model, s: RunSettings, sched, pieces, t, X, event):
    """``event`` (``checks.trajectory_event``'s, seen at an output sample after the start) at
    the time located between the samples around it by integrating again (``runtime.events``),
    as the friction cone's; as it was when integrating again does not reproduce it."""
    check, t_sample = getattr(event, "check", None), getattr(event, "t_sample", None)
    i = -1 if t_sample is None else int(np.searchsorted(t, t_sample))
    if check is None or not 0 < i < len(t) or t[i] != t_sample:
        return event
    kind, name, level = check
    p = next(pk for a, b, pk in pieces if a <= i - 1 < b)

    def w(y: dict) -> float:
        return (abs(y[name]) if kind == "denominator" else y[name]) - level

    found = events.locate(model, s, sched, p, float(t[i - 1]), X[i - 1], float(t[i]), w)
    if found is None:
        return event
    tc, xc = float(found[0]), np.asarray(found[1], dtype=float)
    value = outputs_.along(model, np.array([tc]), xc[None, :], p, sched)[name][0]
    where = f"t = {tc:.10g} s (located between the outputs at {t[i - 1]:.6g} and {t[i]:.6g} s)"
    if kind == "force":
        new = checks_.force_error(model, name, tc, xc, value, event.force_before, f"crosses 0 at {where}")
    elif kind == "curvature":
        new = checks_.curvature_error(model, name, tc, xc, value, level, level / checks_.KAPPA_SUM_RELATIVE, where)
    else:
        new = checks_.frame_error(model, name, tc, xc, value, level, " (located between the outputs)")
    new.t_sample, new.check = t_sample, check
    return new


def cone_event(model, s: RunSettings, sched, pieces, t, X, outs, cone, event):
    """The earlier of ``event`` (another check's, or None) and the first exit of a contact's
    force from its friction cone along the samples (``runtime.friction``), that one located
    between the samples around it (``runtime.events``); ``cone``: ``friction.quantities``;
    ``pieces``: the rows' ``p`` (``_Charted.pieces``)."""
    margins = np.column_stack([v for k, v in cone.items() if k.startswith("cone_margin")])
    hit = friction.first_exit(margins)
    if hit is None:
        return event
    i, c = hit
    if event is not None and i and event.t < t[i - 1]:
        return event
    if i == 0:
        y = {k: float(v[0]) for k, v in outs.items()}
        cone = friction.cone_error(model, float(t[0]), X[0], y, s.mu, c, "at the start")
    else:
        p = next(pk for a, b, pk in pieces if a <= i - 1 < b)
        found = events.locate(model, s, sched, p, float(t[i - 1]), X[i - 1], float(t[i]),
                              friction.witness(model, s.mu, c))
        if found is not None:
            tc, xc = found
            how = f"located between the outputs at {t[i - 1]:.6g} and {t[i]:.6g} s"
        else:  # not reproduced by the second integration: the samples' linear estimate
            m = margins[i - 1:i + 1, c]
            frac = m[0] / (m[0] - m[1]) if np.all(np.isfinite(m)) and m[0] != m[1] else 1.0
            tc, xc = float(t[i - 1] + frac * (t[i] - t[i - 1])), X[i - 1]
            how = "interpolated between the outputs (state at the last one before)"
        y = outputs_.along(model, np.array([tc]), np.asarray(xc)[None, :], p, sched)
        cone = friction.cone_error(model, tc, xc, {k: float(v[0]) for k, v in y.items()},
                                   s.mu, c, how)
    # a tie with the normal force's zero (a start with f <= 0): the contact opens, a cone of a
    # force that pulls means nothing
    return cone if event is None or cone.t < event.t else event


def _segments(model, s: RunSettings, segments, sched, x0, p, start, charted):
    """``(t, X, stats)`` over every segment of the inputs, at the output times (across the
    charts of ``charted``, a ``_Charted``)."""
    t_eval = s.t_eval
    rows_t, rows_x, stats = [], [], {}
    x_now = x0
    for k, (s0, s1, a, b) in enumerate(segments):
        pk = p if sched is None else model.with_inputs(p, a, b)
        grid = t_eval if len(segments) == 1 else np.array(
            [s0, *t_eval[(t_eval > s0) & (t_eval < s1)], s1])
        t, X, st, p_end = charted.integrate(s, x_now, grid, pk, start, sched)
        if charted.switches and p is not None:  # the next segment goes on in the last charts
            p = np.array(p, dtype=float)
            for _entry, i, _ in charted.atlases.slots:
                if i is not None:
                    p[i] = p_end[i]
        if len(segments) == 1:  # one segment: its rows and counters as they are
            return t, X, st
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
    return t, X, stats


def integrate(model, s: RunSettings, x0, t_eval, p, start, h0: float = 0.0, sched=None, wraps=None):
    """One integration over ``t_eval`` (one segment of the inputs, ``p`` with its inputs;
    ``sched`` the table, or None) with the settings ``s`` and named errors: ``(t, X, stats)``;
    ``h0``: a C loop's first step (0: chosen). With ``s.checks``, the adaptive C loops watch
    the checks at every step (``runtime.watch``) and raise the first event, located there.
    ``wraps``: None, or ``(atlases, into)``: the adaptive C loops wrap the atlases' coordinates
    and change their charts at the step (``runtime.atlas.Atlases.wrap_slots``) and append their
    records to ``into`` (``CompiledLibrary.wrapping``); an error or event after a change is
    read with the charts it left."""
    method, checks, rtol, atol, h = s.method, s.checks, s.rtol, s.atol, s.h
    if method in integrators.C_LOOPS:
        watched = s.watched
        if watched:  # a check past its event where the loop starts: it would never arm it
            row = outputs_.along_rows(model, t_eval[:1], np.asarray(x0, dtype=float)[None, :], p, sched)[0]
            if watch_.first_past(watched, row.tolist()) is not None:
                raise watch_.start_error(model, s, float(t_eval[0]), x0, dict(zip(model.columns, map(float, row))))
            watch_.start(model.library, watched, watch_.input_slots(model))
        atlases, into = (None, []) if wraps is None or method == "rk4" else wraps
        try:
            with model.library.wrapping(None if atlases is None else atlases.wrap_slots, into):
                t, X, st = integrators.c_loop(model, method, x0, t_eval, p, rtol=rtol, atol=atol,
                                              max_steps=s.max_steps, h=h, projection=s.proj,
                                              time_limit=s.time_limit, h0=h0)
        except IntegratorError as exc:
            changed = [] if atlases is None else [rec for rec in atlases.wrapped(into) if rec["from"] != rec["to"]]
            err = failures.blow_up(model, failures.classify(model, exc), method, h)
            if checks:  # (each row read in the charts it was written in)
                checks_.raise_earlier_event(model, err, p, start, changed)
            raise err from None
        finally:
            if watched:
                model.library.unwatch()
        if "event" in st:
            p = p if atlases is None else atlases.after(atlases.wrapped(into), p)
            raise watch_.event_error(model, s, sched, p, watched, st.pop("event"), t, X)
        return t, X, st
    pp = np.zeros(0) if p is None else p
    try:
        t, X, stats = integrators.sundials(model, method, x0, t_eval, pp, rtol, atol, s.max_steps,
                                           s.time_limit)
    except IntegratorError as failed:
        exc = failures.exit_at_failure(model, failed, t_eval, p, rtol, atol) \
            if method == "cvodes" else failed
        if checks:
            checks_.raise_earlier_event(model, exc, p, start)
        raise exc from None
    _sundials_exits(model, t, X, stats.pop("excursions", ()), p, start, checks, rtol, atol)
    return t, X, stats


def watched_checks(model, s: RunSettings, start: dict) -> tuple:
    """The checks the C loop watches in a run with the settings ``s`` (``runtime.watch``):
    none without ``s.checks``, when the run computes its outputs at rows at most ``WATCH_DT``
    apart (they are read there), for a loop that cannot watch (rk4: one uniform grid), or for a
    library built before the checks were watched (no ``gs_watch_batch``, whose watch has no
    constant terms: its rows are read); the cone's with ``mu`` and ``slip='stop'``."""
    if not s.checks or s.method not in SWITCHING or not getattr(model.library, "can_watch_batch", False):
        return ()
    if s.outputs and rows_dense(s.t_eval):  # the outputs are computed at rows as close as the
        return ()  # watch's points: read there, an event located between two of them (located)
    mu = s.mu if s.slip == "stop" else None
    key = (tuple(start.items()), None if mu is None else tuple(mu.tolist()))
    # a run from the same start and mu: its witnesses again (10-30 us); a dict of its own,
    # replaced whole when full (threads of one process share the model)
    kept = model.run_cache.get("watched")
    if kept is None or len(kept) >= 64:
        kept = model.run_cache["watched"] = {}
    found = kept.get(key)
    if found is None:
        found = kept[key] = watch_.checks(model, start, mu)
    return found


def rows_dense(t_eval: np.ndarray) -> bool:
    """Whether the output times are at most ``watch.WATCH_DT`` apart (the default grid's are):
    the checks read at them see what the watch would."""
    return len(t_eval) > 1 and float(np.max(np.diff(t_eval))) <= watch_.WATCH_DT * (1.0 + 1e-9)


def _sundials_exits(model, t, X, excursions, p, start, checks, rtol, atol) -> None:
    """Raise the first exit from a contour's domain of a SUNDIALS run, located between its
    outputs: a step IDAS reports outside a domain (``excursions``), or an output outside one."""
    for k in excursions:  # IDAS: a step ended outside a domain
        found = ContactLeftContourError(t[k], X[k], "a contact left its contour between "
                                        "the outputs", model.state_names)
        exc = failures.locate_exit(model, found, t[k - 1], X[k - 1], t[min(k + 1, len(t) - 1)],
                                   p, rtol, atol)
        if exc is not found:
            _raise(model, exc, t[:k], X[:k], p, start, checks)
    for i in range(len(t)):
        try:
            failures.check_bounds(model, t[i], X[i], previous=(t[i - 1], X[i - 1]) if i else None)
        except StateLeftDomainError as found:
            exc = failures.locate_exit(model, found, t[i - 1], X[i - 1], t[i], p, rtol, atol) \
                if i else found
            _raise(model, exc, t[:i], X[:i], p, start, checks)


def _raise(model, exc, t, X, p, start, checks):
    """Raise ``exc`` (an earlier event along ``t, X`` first, with ``checks``)."""
    if checks:
        exc.trajectory = (t.copy(), X.copy())
        checks_.raise_earlier_event(model, exc, p, start)
    raise exc from None
