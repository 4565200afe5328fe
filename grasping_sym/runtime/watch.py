"""What the C loops watch along a run (``c/watch.c``), and the run-time checks located at the step.

The adaptive C loops (radau, dop853, dopri5) evaluate a set of witnesses, each a linear
combination of the compiled outputs less the length of a vector of them, at each accepted
step's end and at points of its dense output at most ``WATCH_DT`` apart (a point is left
unwatched while every witness is far from 0 by ``WATCH_SAFETY`` times its rate: see the
constants). A witness that reaches 0 stops the loop at its step; its time is then located on
the trajectory integrated again from the step's start (``gs_watch_refine``, else
``runtime.events.refine``) to ``events.TIME_TOL`` s. The runs with contact modes watch their
switches' witnesses so (``runtime.modes``); every checked run of those loops watches its
checks' so (``checks``, ``event_error``), whatever its output times: a contact that opens and
closes again between two rows a user asked for is not missed, and its time is the root's,
not a line between rows.

The checks' witnesses, all > 0 while the run is sound (``runtime.checks``):

- each normal force ``f`` / ``f{i}``: ``ContactOpenedError`` at its zero;
- each relative curvature (``kappa_sum{i}``, ``krel_min{i}``) less ``KAPPA_SUM_RELATIVE`` of
  its value at the start: ``RelativeCurvatureError``;
- each frame denominator of the paper formulation, times its sign at the start, less its
  threshold: ``MovingFrameSingularityError``;
- with ``mu`` (and ``slip='stop'``), each contact's cone margin ``mu f - |F_t|``:
  ``FrictionConeError``.
"""
from __future__ import annotations

import math

import numpy as np

from grasping_sym.errors import IntegratorError
from grasping_sym.runtime import checks as checks_
from grasping_sym.runtime import events, friction
from grasping_sym.runtime import outputs as outputs_

#: s, the longest interval between two points of one step's dense output at which the C loop
#: watches the witnesses (with the steps' ends), whatever ``t_eval``: a sign change and its
#: return within it can be missed, one that lasts longer cannot.
WATCH_DT = 1e-3
#: A point (a step's end, a point of its dense output) is left unwatched while every witness
#: would still be above 0 there by this many times what its rate and the change of its rate
#: (from its last three watched points) take off it: never the run's end, never more than 16
#: ``WATCH_DT`` after the last watched point, at most 16 steps' ends in a row, which are kept
#: (``c/watch.c``). A sign change and its return within them can be missed, as within
#: ``WATCH_DT``; one that lasts is found at the next watched point (or at a failure) and
#: located in its step from the ends kept. 0: every point is watched.
WATCH_SAFETY = 8.0
#: s, the checks' bound on the time a point may be left unwatched after the last watched one:
#: none (0). A check's point is left while the prediction says it stays above 0 by
#: ``WATCH_SAFETY`` times what its rate and the change of its rate take off it (at most 16
#: steps' ends in a row); the contact modes' witnesses are also looked at every 16
#: ``WATCH_DT`` (``runtime.modes``). That bound cost a cheap run of paper2d half its speed
#: (about 190 looks in 3 s, where the prediction asks for about 20).
CHECK_SPAN = 0.0


def input_slots(model) -> tuple[int, int]:
    """The inputs' ``(a, b)`` slots in ``p``: ``(first, how many)``, ``(0, 0)`` for none."""
    if not model.input_names:
        return 0, 0
    return model.p_names.index(model.input_names[0]), len(model.input_names)


def witnesses(model, start: dict, mu, n: int) -> tuple[tuple, np.ndarray]:
    """The run-time checks' witnesses of ``model`` for N runs (module docstring):
    ``(watched, coef)``, ``watched`` a ``(kind, name, terms, level)`` each (``terms`` as
    ``CompiledLibrary.watch`` takes them, column ``-1`` the constant; ``level`` the threshold the
    output falls to, of the first run), ``coef`` ``(N, n_terms)`` every run's coefficients of
    the terms in order. ``start``: each curvature and frame denominator's values at the runs'
    starts (name -> ``(N,)``; ``checks.check_initial_state``'s, those missing not watched);
    ``mu``: each run's coefficient per contact ``(N, n_contacts)``, or None (a contact whose
    ``mu`` is ``inf`` never leaves its cone: its witness is the constant 1). Empty for a model
    whose outputs the checks do not read."""
    cols = {k: i for i, k in enumerate(model.columns)}
    watched, coef = [], []
    for name in checks_.force_outputs(cols):
        watched.append(("force", name, ((cols[name], 1.0),), 0.0))
        coef.append(np.ones(n))
    for name in checks_.curvature_outputs(cols):
        if name in start:
            levels = checks_.KAPPA_SUM_RELATIVE * np.asarray(start[name], dtype=float)
            watched.append(("curvature", name, ((cols[name], 1.0), (-1, -levels[0])), levels[0]))
            coef += [np.ones(n), -levels]
    for name, thr in checks_.denominator_thresholds(model).items():
        if name in cols and name in start:
            signs = np.where(np.asarray(start[name], dtype=float) > 0, 1.0, -1.0)
            watched.append(("denominator", name, ((cols[name], signs[0]), (-1, -thr)), thr))
            coef += [signs, np.full(n, -thr)]
    if mu is not None:
        mu = np.asarray(mu, dtype=float).reshape(n, -1)
        for c, (f, tang) in enumerate(friction.contacts(model)):
            never = np.isinf(mu[:, c])
            terms = ((cols[f], mu[0, c]), (-1, 0.0), *((cols[k], 1.0, True) for k in tang))
            watched.append(("cone", c, terms, 0.0))
            coef += [np.where(never, 0.0, mu[:, c]), never.astype(float)] + [(~never).astype(float)] * len(tang)
    if not watched:
        return (), np.zeros((n, 0))
    coef = np.column_stack(coef)
    first = iter(coef[0].tolist())  # the first run's coefficients in the terms
    watched = tuple((kind, name, tuple((term[0], next(first), *term[2:]) for term in terms), level)
                    for kind, name, terms, level in watched)
    return watched, coef


def checks(model, start: dict, mu) -> tuple:
    """``witnesses``' ``watched`` for one run (``start``: name -> value; ``mu``: per contact, or
    None)."""
    one = {k: np.array([v], dtype=float) for k, v in start.items()}
    return witnesses(model, one, None if mu is None else np.asarray(mu, dtype=float)[None, :], 1)[0]


def start(lib, watched, inputs: tuple[int, int]) -> None:
    """Watch ``watched`` (``checks``) in this thread's next C loops (until ``lib.unwatch()``)."""
    lib.watch([terms for _, _, terms, _ in watched], [0.0] * len(watched), inputs=inputs, dt=WATCH_DT,
              safety=WATCH_SAFETY, span=CHECK_SPAN)


def values(terms, Y: np.ndarray, coef: np.ndarray | None = None) -> np.ndarray:
    """Every witness (``terms``: each one's, as ``CompiledLibrary.watch`` takes them) at the
    compiled outputs ``Y`` (``(..., n_columns)``), on the last axis; ``coef``: the terms'
    coefficients in order (``(..., n_terms)``, e.g. one row per run of a batch; None: the
    terms' own). NaN stays NaN (past its event)."""
    out, j = [], 0
    for t in terms:
        lin = sq = np.zeros(Y.shape[:-1])
        for term in t:
            c = term[1] if coef is None else coef[..., j]
            v = c if term[0] < 0 else c * Y[..., term[0]]
            j += 1
            if len(term) > 2 and term[2]:
                sq = sq + v * v
            else:
                lin = lin + v
        out.append(lin - np.sqrt(sq))
    return np.stack(out, axis=-1) if out else np.zeros((*Y.shape[:-1], 0))


def first_past(watched, row) -> int | None:
    """The first witness of ``watched`` at or below 0 (NaN too) at one state's compiled outputs
    ``row`` (a list by column), None when every one is above 0."""
    for k, (_, _, terms, _) in enumerate(watched):
        lin = sq = 0.0
        for term in terms:
            v = term[1] if term[0] < 0 else term[1] * row[term[0]]
            if len(term) > 2 and term[2]:
                sq += v * v
            else:
                lin += v
        if not lin - math.sqrt(sq) > 0:
            return k
    return None


def start_error(model, s, t0: float, x0: np.ndarray, y: dict) -> IntegratorError | None:
    """The named error of a check already at or past its event where a C loop starts (``t0``:
    the run's start, an input table's knot, a chart switch; its compiled outputs ``y``, name ->
    value): a witness the loop would never arm (it arms one once it is seen above 0); None
    when every one is above 0."""
    row = np.array([y[k] for k in model.columns])
    where = "the start" if t0 == 0.0 else "where the integration restarts (an input's knot or a chart switch)"
    for (kind, name, _, level), g in zip(s.watched, values([t for _, _, t, _ in s.watched], row)):
        if g > 0:
            continue
        if kind == "force":
            return checks_.force_error(model, name, t0, x0, y[name], math.nan,
                                       f"is {y[name]:.6g} N <= 0 at t = {t0:.10g} s, {where}")
        if kind == "curvature":
            return checks_.curvature_error(model, name, t0, x0, y[name], level,
                                           level / checks_.KAPPA_SUM_RELATIVE, f"t = {t0:.10g} s, {where}")
        if kind == "denominator":
            return checks_.frame_error(model, name, t0, x0, y[name], level, f" (at {where})")
        return friction.cone_error(model, t0, x0, y, s.mu, name, "at the start" if t0 == 0.0 else f"at {where}")
    return None


def event_error(model, s, sched, p, watched, event: dict, t_rows, X_rows) -> IntegratorError:
    """The named error of the check the C loop stopped at (``event``: its ``stats["event"]``;
    ``watched``: ``checks``' witnesses), at the time located on the trajectory integrated again
    from its step's start; ``t_rows``, ``X_rows``: the run's rows before it."""
    lib = model.library
    hit = lib.watch_result()
    kind, name, terms, level = watched[hit["which"]]
    x_step = np.asarray(event["x_step"], dtype=float)
    found = lib.watch_refine(s.method, x_step, p, s.rtol, s.atol, s.max_steps, model.lower, model.upper,
                             events.TIME_TOL, events.SECANT_STEPS)
    if found is None:  # Python's secants, then Brent's method
        cols = model.columns

        def w(y: dict) -> float:
            return float(values([terms], np.array([y[k] for k in cols]))[0])

        found = events.refine(model, s, sched, p, hit["t_step"], x_step, hit["t_lo"], hit["t_hi"], event["t"],
                              hit["slope"], w, projection=s.proj)
    if found is None:
        # at a loose tolerance the check can sit at the integration's noise: the dense output's
        # root, said so, and the check's own error (as the rows' path gives, ``run.located``)
        tc, xc = float(event["t"]), np.asarray(event["x"], dtype=float)
        at = ("on the integration's dense output (integrating again from the step's start does not "
              "reproduce the sign change: the check is at this tolerance's noise; give tighter "
              "tolerances to locate it at the step)")
    else:
        tc, xc = float(found[0]), np.asarray(found[1], dtype=float)
        at = "at the step"
    y = {k: float(v[0]) for k, v in outputs_.along(model, np.array([tc]), xc[None, :], p, sched).items()}
    where = f"t = {tc:.10g} s (located {at}, after t = {hit['t_lo']:.10g} s)"
    if kind == "force":
        before = outputs_.along(model, np.array([hit["t_step"]]), x_step[None, :], p, sched)[name][0]
        err = checks_.force_error(model, name, tc, xc, y[name], float(before), f"crosses 0 at {where}")
    elif kind == "curvature":
        err = checks_.curvature_error(model, name, tc, xc, y[name], level,
                                      level / checks_.KAPPA_SUM_RELATIVE, where)
    elif kind == "denominator":
        err = checks_.frame_error(model, name, tc, xc, y[name], level, f" (located {at})")
    else:
        err = friction.cone_error(model, tc, xc, y, s.mu, name, f"located {at}")
    err.trajectory = (np.asarray(t_rows, dtype=float).copy(), np.asarray(X_rows, dtype=float).copy())
    return err

