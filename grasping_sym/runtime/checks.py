"""The named checks of ``Model.simulate``: silent failure modes turned into errors.

Each check reads the model's compiled outputs, every column of them (``model.columns``):
those the scene asked to show and those the checks need that it did not ask for, compiled
all the same (``scene.check_outputs()``, ``pipeline.with_check_outputs``), so every contact
and every constraint is checked whatever outputs a model shows:

- ``constraint_residual`` (or the 2D ``Q``, ``R``) at ``x0``: ``InconsistentInitialStateError``;
- normal multipliers ``f`` (2D) or ``f1, f2, ...`` (several fingers, 3D) must stay > 0:
  ``ContactOpenedError``;
- relative curvature, ``kappa_sum`` (2D; ``kappa_sum1, kappa_sum2, ...`` with several fingers)
  or the smaller eigenvalue ``krel_min{i}`` of ``K_f + K~_o`` (3D), must stay above
  ``KAPPA_SUM_RELATIVE`` of its initial value:
  ``RelativeCurvatureError`` (the contact update laws divide by it);
- the paper formulation's ``frame_denominator{i} = omega0.e0 + omega1.e1`` must stay above
  ``FRAME_DENOMINATOR_RELATIVE`` of its magnitude at the scene's start (the manifest's
  ``checks.frame_denominators``): ``MovingFrameSingularityError`` (its (31)-(32) are 0/0 at
  rest).

The adaptive C loops watch these at every step (``runtime.watch``), which locates an event
there. Here they are read at the output samples (the methods that do not watch, a failed
run's rows): the first event in time is raised, its time interpolated linearly between the
samples around it (``runtime.run.located`` then locates it by integrating again).
"""
from __future__ import annotations

import functools
import math
import re

import numpy as np

from grasping_sym.errors import (
    ContactOpenedError,
    InconsistentInitialStateError,
    IntegratorError,
    MovingFrameSingularityError,
    RelativeCurvatureError,
)
from grasping_sym.runtime import outputs, parameters
from grasping_sym.runtime.atlas import by_charts

#: ``kappa_sum`` / ``krel_min{i}`` may fall to this fraction of its initial value.
KAPPA_SUM_RELATIVE = 1e-3
#: ``kappa_sum * |Om|`` at ``t = 0`` must exceed this (2D).
KAPPA_SUM_INITIAL = 1e-3
#: ``max(|Q|, |R|)`` or ``constraint_residual`` (m) allowed at ``x0``.
INITIAL_RESIDUAL = 1e-8
#: ``|frame_denominator{i}|`` may fall to this fraction of its magnitude at the start: below
#: it the geodesic curvatures ``(O(|s'|) numerator) / D`` have lost six of ~16 digits.
FRAME_DENOMINATOR_RELATIVE = 1e-6


def _matching(names, pattern: str) -> list[str]:
    return list(_matching_cached(tuple(names), pattern))


@functools.lru_cache(maxsize=256)
def _matching_cached(names: tuple[str, ...], pattern: str) -> tuple[str, ...]:
    # cached: simulate() asks for the same few output names on every call
    return tuple(n for n in names if re.fullmatch(pattern, n))


def curvature_outputs(names) -> list[str]:
    return _matching(names, r"kappa_sum\d*|krel_min\d+")


def force_outputs(names) -> list[str]:
    return _matching(names, r"f\d*")


def denominator_outputs(names) -> list[str]:
    return _matching(names, r"frame_denominator\d+")


def _finger(name: str) -> str:
    """`` of finger i`` for a per-finger output ``kappa_sum{i}`` (empty for ``kappa_sum``)."""
    return f" of finger {name[9:]}" if name[9:] else ""


def _scene_size(model) -> float:
    """``|Om|`` (m): the 2D object's pivot's distance from the finger base, 0 if unknown."""
    start = model.start_params
    if "xm" not in start or "ym" not in start:
        return 0.0
    return float(np.hypot(start["xm"], start["ym"]))


def denominator_thresholds(model) -> dict[str, float]:
    """Thresholds of the paper formulation's frame denominators: a fraction of their values
    at the model's own start (evaluated once per model by the compiled outputs)."""
    cached = getattr(model, "_denominator_thresholds", None)
    if cached is None:
        names = denominator_outputs(model.columns)
        y = outputs.at(model, model.initial_state()) if names else {}
        cached = {k: FRAME_DENOMINATOR_RELATIVE * abs(y[k]) for k in names}
        model._denominator_thresholds = cached
    return cached


def frame_error(model, name: str, t: float, x, value: float, threshold: float, extra: str = ""):
    """The named error of frame denominator ``name`` at ``value`` (rad/s), fallen to
    ``threshold`` at ``t`` (state ``x``); ``extra`` is appended to its message."""
    err = MovingFrameSingularityError(
        t, x,
        f"moving-frame formulation singular: |{name}| = |omega0.e0 + omega1.e1| = {abs(value):.3e} "
        f"rad/s fell to {threshold:.3e} rad/s ({FRAME_DENOMINATOR_RELATIVE:g} of its value at the "
        f"start) at about t = {t:.6g} s: the contact has (nearly) stopped, the trace direction b "
        "and the geodesic curvatures (31)-(32) are 0/0 there; this is where a grasp comes to rest. "
        "Use the regular formulation (formulation='regular', the default), or pass checks=False "
        "to integrate past it: the frames turn at kg s' = (numerator)/(kn0 + kn1), which stays "
        "finite, so the bodies' motion stays accurate while b and e lose their meaning; only "
        "D = 0 exactly (e.g. a start at rest) gives 0/0 = NaN" + extra,
        model.state_names)
    err.denominator, err.threshold, err.contact = float(value), float(threshold), name
    return err


#: Largest max|Cdot| (m/s) accepted at ``x0``: the speeds must satisfy the velocity
#: constraints (rolling without slip, the contact kept), not only the positions.
INITIAL_RATE = 1e-8


def _check_initial_rates(model, x0: np.ndarray, p) -> None:
    lib = model.library
    if not lib.has_constraints:
        return
    _, _, cdot, _ = lib.constraints(x0, p)
    rate = float(np.max(np.abs(cdot))) if cdot.size else 0.0
    if not rate <= INITIAL_RATE:
        raise InconsistentInitialStateError(
            rate,
            f"x0's speeds violate the velocity constraints: max|Cdot| = {rate:.6g} m/s > "
            f"{INITIAL_RATE:g} m/s (the bodies would slide or separate at the contact); start "
            "from model.initial_state() (at rest) or give speeds that roll without slipping, or "
            "pass checks=False to integrate anyway")


def check_initial_state(model, x0: np.ndarray, p, rates: bool = True) -> dict[str, float]:
    """Refuse an ``x0`` off the constraints, at a vanishing relative curvature or, in the paper
    formulation, with a (nearly) stopped contact. Returns the initial value of every
    curvature output (the reference of their thresholds along the run) and of every frame
    denominator."""
    names = set(model.columns)
    watched = {"Q", "R", "constraint_residual"} | set(curvature_outputs(names)) | set(denominator_outputs(names))
    if not names & watched:
        if rates:
            _check_initial_rates(model, x0, p)
        return {}
    y = outputs.at(model, x0, p)
    if "Q" in y and "R" in y:
        residual = max(abs(y["Q"]), abs(y["R"]))
        what = f"max(|Q|, |R|) = max({abs(y['Q']):.3g}, {abs(y['R']):.3g})"
    elif "constraint_residual" in y:
        residual = abs(y["constraint_residual"])
        what = "constraint_residual"
    else:
        residual, what = 0.0, ""
    if not residual <= INITIAL_RESIDUAL:
        charts = parameters.charts_of(model)
        raise InconsistentInitialStateError(
            residual,
            f"x0 is off the contact constraints: {what} = {residual:.6g} m > "
            f"{INITIAL_RESIDUAL:g} m; start from model.initial_state() or a state on the "
            "constraint manifold (the surfaces touch and are tangent), or pass "
            "checks=False to integrate anyway (the constraint stabilisation then pulls the "
            "state back, with a transient)" + (
                f"; a row of a run is written in that row's charts: give them, params={{name: "
                f"result.charts[name][i]}} for {charts}" if charts else ""),
        )
    if rates:  # the speeds, once the positions are on the constraints
        _check_initial_rates(model, x0, p)
    start = {}
    for name in curvature_outputs(y):
        k0 = y[name]
        if name.startswith("kappa_sum"):
            size = _scene_size(model)
            threshold = KAPPA_SUM_INITIAL / size if size > 0 else 0.0
            why = (f"relative curvature kappa0 + kappa1 = {k0:.6g} 1/m at the initial contact"
                   f"{_finger(name)} is at "
                   f"or below {threshold:.6g} 1/m (= {KAPPA_SUM_INITIAL:g} / |Om|, |Om| = "
                   f"{size:.6g} m): the contours nearly osculate there, the update law (29) divides "
                   "by it and the contact point would race along the contours; start from a "
                   "contact where the fingertip is clearly more curved than the object's hollow")
        else:
            threshold = 0.0
            why = (f"relative curvature K_f + K~_o at contact {name[8:]} has smallest eigenvalue "
                   f"{k0:.6g} 1/m <= 0 at the start: the surfaces osculate (flat on flat, matched "
                   "concave on convex) or interpenetrate there and the contact rates are "
                   "undefined; start from a contact where the fingertip is more curved than the "
                   "object's hollow in every direction")
        if not k0 > threshold:
            err = RelativeCurvatureError(0.0, x0, why, model.state_names)
            err.kappa_sum, err.threshold = k0, threshold
            raise err
        start[name] = k0
    for name, thr in denominator_thresholds(model).items():
        if name in y and not abs(y[name]) > thr:
            raise frame_error(model, name, 0.0, x0, y[name], thr,
                               "; the paper formulation cannot start at rest: give the scene "
                               "initial speeds (dq0) that move every contact")
        if name in y:
            start[name] = y[name]  # its sign: the watch's witness (runtime.watch)
    return start


def first_crossing(t: np.ndarray, v: np.ndarray, level: float):
    """First sample index with ``v <= level`` (or NaN), and the interpolated crossing time."""
    bad = np.flatnonzero(~(v > level))
    if bad.size == 0:
        return None
    i = int(bad[0])
    if i == 0:
        return 0, float(t[0])
    a, b = float(v[i - 1]), float(v[i])
    frac = (a - level) / (a - b) if math.isfinite(b) and a != b else 1.0
    frac = min(max(frac, 0.0), 1.0)
    return i, float(t[i - 1] + frac * (t[i] - t[i - 1]))


def _watched(model) -> tuple:
    """What :func:`clean` reads, once per model: the compiled outputs' columns the checks
    read (forces, curvatures, frame denominators), the share of its first value each of the
    first two kinds must stay above (0 and ``KAPPA_SUM_RELATIVE``), the denominators'
    thresholds."""
    cached = getattr(model, "_watched_columns", None)
    if cached is None:
        cols = {k: i for i, k in enumerate(model.columns)}
        force = [cols[k] for k in force_outputs(cols)]
        curvature = [cols[k] for k in curvature_outputs(cols)]
        denominators = {cols[k]: thr for k, thr in denominator_thresholds(model).items()
                        if k in cols}
        cached = (np.array(force + curvature + list(denominators), dtype=np.intp),
                  [0.0] * len(force) + [KAPPA_SUM_RELATIVE] * len(curvature),
                  list(denominators.values()))
        model._watched_columns = cached
    return cached


#: Up to this many output samples :func:`clean` compares Python floats, beyond it arrays.
_LIST_ROWS = 16


def clean(model, t: np.ndarray, X: np.ndarray, p) -> bool:
    """True when :func:`trajectory_event` cannot find an event along the samples ``X`` (times
    ``t``, run-time parameters ``p`` as the model takes them): every force > 0, every relative
    curvature above its share of its first value, every frame denominator above its
    threshold in magnitude (a NaN fails), on the watched columns of the compiled outputs
    only; about a microsecond for a few samples. False means: look with
    ``trajectory_event``."""
    columns, share, thresholds = _watched(model)
    if not columns.size:
        return True
    if model.manifest.get("outputs_time"):
        outs = outputs.along(model, t, X, p, None)
        return trajectory_event(model, t, X, outs, {}) is None
    V = model.library.outputs_batch(X, parameters.complete(model, p)).take(columns, axis=1)
    k = len(share)
    if len(V) <= _LIST_ROWS:
        rows = V.tolist()
        lows = [v * f for v, f in zip(rows[0], share)]
        for row in rows:
            for v, lo in zip(row, lows):
                if not v > lo:
                    return False
            for d, thr in zip(row[k:], thresholds):
                if not abs(d) > thr:
                    return False
        return True
    lows = np.concatenate([V[0, :k] * share, thresholds])
    V[:, k:] = np.abs(V[:, k:])
    return bool((V > lows).all())


def curvature_error(model, name: str, t: float, x, value: float, threshold: float, k_ref: float,
                    where: str, note: str = "") -> RelativeCurvatureError:
    """The named error of curvature output ``name`` falling to ``threshold`` (1/m;
    ``KAPPA_SUM_RELATIVE`` of its initial ``k_ref``) at ``t`` (state ``x``), where it is
    ``value``; ``where`` says how ``t`` was found."""
    if name.startswith("kappa_sum"):
        what = (f"relative curvature kappa0 + kappa1{_finger(name)}", "the contours nearly osculate or cross "
                "(curvatures of opposite convexity), the update law (29) divides by it",
                "choose a fingertip more curved than the object's hollows along the path")
    else:
        what = (f"relative curvature K_f + K~_o (smaller eigenvalue) at contact {name[8:]}",
                "the surfaces nearly osculate, Montana's contact rates divide by it",
                "choose a fingertip more curved than the object's hollows along the path")
    err = RelativeCurvatureError(
        t, x,
        f"{what[0]} fell to {threshold:.6g} 1/m ({KAPPA_SUM_RELATIVE:g} of its initial {k_ref:.6g} 1/m) "
        f"at {where}: {what[1]} and the state would blow up; {what[2]}" + note,
        model.state_names,
    )
    err.kappa_sum, err.threshold = float(value), threshold
    return err


def force_error(model, name: str, t: float, x, value: float, before: float, where: str,
                note: str = "") -> ContactOpenedError:
    """The named error of normal force output ``name`` reaching 0 at ``t`` (state ``x``),
    where it is ``value`` (N; ``before`` the last positive value seen); ``where`` says how
    ``t`` was found (``crosses 0 ...``)."""
    err = ContactOpenedError(
        t, x,
        f"normal force {name}{' of contact ' + name[1:] if name[1:] else ''} {where}: "
        "a unilateral contact cannot pull, the contact would open and the model "
        "(rolling contact kept by a constraint) no longer holds; raise fd or lower "
        "the speeds that pull the finger away" + note,
        model.state_names,
    )
    err.force, err.force_before = float(value), float(before)
    return err


def trajectory_event(model, t: np.ndarray, X: np.ndarray, outs: dict, start: dict,
                     *, force: bool = True, note: str = "") -> IntegratorError | None:
    """The first event along the samples (module docstring); ``note`` is appended to it. Each
    error carries the sample where it was seen (``t_sample``) and ``check``: ``(kind, output,
    level)``, what falls to ``level`` (a frame denominator in magnitude)."""
    events = []
    if not len(t):
        return None
    for name in curvature_outputs(outs):
        k = outs[name]
        k_ref = start.get(name, float(k[0]))
        threshold = KAPPA_SUM_RELATIVE * k_ref
        hit = first_crossing(t, k, threshold)
        if hit is None:
            continue
        i, tc = hit
        err = curvature_error(model, name, tc, X[i - 1] if i else X[0], float(k[i]), threshold, k_ref,
                              f"about t = {tc:.6g} s (sample t = {t[i]:.6g} s: {k[i]:.6g} 1/m)",
                              " (state at the last sample before)" + note)
        err.t_sample, err.check = float(t[i]), ("curvature", name, threshold)
        events.append((tc, 0, err))
    for name, thr in denominator_thresholds(model).items():
        if name not in outs:
            continue
        hit = first_crossing(t, np.abs(outs[name]), thr)
        if hit is not None:
            i, tc = hit
            err = frame_error(model, name, tc, X[i - 1] if i else X[0], outs[name][i], thr,
                               " (state at the last sample before)" + note)
            err.t_sample, err.check = float(t[i]), ("denominator", name, thr)
            events.append((tc, 0, err))
    for name in force_outputs(outs) if force else ():
        f = outs[name]
        hit = first_crossing(t, f, 0.0)
        if hit is None:
            continue
        i, tc = hit
        before = float(f[i - 1]) if i else float("nan")
        where = (f"crosses 0 at about t = {tc:.6g} s ({name} = {before:.6g} N at "
                 f"t = {t[i - 1]:.6g} s, {f[i]:.6g} N at t = {t[i]:.6g} s)" if i else
                 f"is {f[0]:.6g} N <= 0 at t = {t[0]:.6g} s, the start")
        err = force_error(model, name, tc, X[i - 1] if i else X[0], float(f[i]), before, where,
                          " (state at the last sample before)" + note)
        err.t_sample, err.check = float(t[i]), ("force", name, 0.0)
        events.append((tc, 1, err))
    if not events:
        return None
    return min(events, key=lambda e: (e[0], e[1]))[2]


def _at_rows_in_charts(model, t: np.ndarray, X: np.ndarray, p, changes) -> dict:
    """``outputs.at_rows`` with each row read in the charts it was written in
    (``runtime.atlas.by_charts``: ``p`` up to the first of ``changes``, then each change's)."""
    parts = [outputs.at_rows(model, X[a:b], pk) for a, b, pk in by_charts(model.p_names, t, p, changes)]
    return parts[0] if len(parts) == 1 else {k: np.concatenate([part[k] for part in parts]) for k in parts[0]}


def raise_earlier_event(model, exc: IntegratorError, p, start: dict, changes: tuple = ()) -> None:
    """On a failed run: raise the curvature or moving-frame event instead when it came before
    ``exc.t`` (the cause of the blow-up). The sign of ``f`` is not checked here: near a
    numerical blow-up ``f`` swings wildly and "contact opens" would name a symptom.
    ``changes``: the charts the loop changed (``runtime.atlas`` records, in time order; ``p``
    the start's charts): each row is read in its own."""
    names = model.columns
    if not (curvature_outputs(names) or denominator_outputs(names)):
        return
    rows_t, rows_x = [], []
    trajectory = getattr(exc, "trajectory", None)
    if trajectory is not None:
        tt, XX = (np.asarray(a, dtype=float) for a in trajectory)
        if tt.ndim == 1 and XX.ndim == 2 and len(tt) == len(XX):
            rows_t.append(tt)
            rows_x.append(XX)
    x_fail = exc.x
    if x_fail is not None and math.isfinite(exc.t):
        x_fail = np.asarray(x_fail, dtype=float)
        if x_fail.shape == (len(model.state_names),):
            rows_t.append(np.array([exc.t]))
            rows_x.append(x_fail[None, :])
    if not rows_t:
        return
    t = np.concatenate(rows_t)
    X = np.vstack(rows_x)
    keep = np.all(np.isfinite(X), axis=1)
    if len(t) > 1:
        keep[1:] &= np.diff(t) > 0
    t, X = t[keep], X[keep]
    if len(t) == 0:
        return
    outs = _at_rows_in_charts(model, t, X, p, changes)
    note = f"; the integrator then failed at t = {exc.t:.6g} s: {exc.reason}"
    event = trajectory_event(model, t, X, outs, start, force=False, note=note)
    if event is not None and event.t <= exc.t:
        event.cause_error = exc
        raise event from exc
    k_start = start.get("kappa_sum")
    if k_start and exc.x is not None:  # the last row is the state recovered at the failure
        k_last = float(outs["kappa_sum"][-1])
        if k_last < 0.1 * k_start:  # name a likely cause the threshold did not catch yet
            err = IntegratorError(
                exc.t, exc.x, f"{exc.reason}; kappa0 + kappa1 had fallen to {k_last:.3g} 1/m "
                f"({k_last / k_start:.2g} of its initial value): the contact update law (29) "
                "divides by it", model.state_names)
            err.kappa_sum = k_last
            err.trajectory = getattr(exc, "trajectory", None)
            raise err from exc


# ---------------------------------------------------------------- many runs at once
def initial_ok(model, Y0: np.ndarray | None, CD0: np.ndarray | None, rates: bool) -> np.ndarray:
    """``check_initial_state`` over many runs (``Model.simulate_many``): per run, False where it
    would raise, from the outputs ``Y0`` (``(N, ny)``) and the max|Cdot| ``CD0`` (``(N,)``) at
    each run's ``x0``. The same thresholds and comparisons (NaN fails), so a run passes here
    exactly when it passes there."""
    n = len(CD0) if CD0 is not None else len(Y0) if Y0 is not None else 0
    ok = np.ones(n, dtype=bool)
    if rates and CD0 is not None:
        ok &= CD0 <= INITIAL_RATE
    names = model.columns
    watched = {"Q", "R", "constraint_residual"} | set(curvature_outputs(names)) | set(denominator_outputs(names))
    if Y0 is None or not set(names) & watched:
        return ok
    y = {k: Y0[:, i] for i, k in enumerate(names)}
    if "Q" in y and "R" in y:
        ok &= np.maximum(np.abs(y["Q"]), np.abs(y["R"])) <= INITIAL_RESIDUAL
    elif "constraint_residual" in y:
        ok &= np.abs(y["constraint_residual"]) <= INITIAL_RESIDUAL
    for name in curvature_outputs(names):
        if name.startswith("kappa_sum"):
            size = _scene_size(model)
            threshold = KAPPA_SUM_INITIAL / size if size > 0 else 0.0
        else:
            threshold = 0.0
        ok &= y[name] > threshold
    for name, thr in denominator_thresholds(model).items():
        if name in y:
            ok &= np.abs(y[name]) > thr
    return ok


def trajectory_clean(model, t: np.ndarray, outs: dict, initial: dict) -> np.ndarray:
    """``trajectory_event`` over many runs: per run, True where it finds no event, from the
    outputs ``outs`` (name -> ``(N, m)`` at the times ``t``) and their values at each run's
    start ``initial`` (name -> ``(N,)``: the curvatures' references)."""
    n = len(next(iter(outs.values()))) if outs else 0
    clean = np.ones(n, dtype=bool)
    for name in curvature_outputs(outs):
        k_ref = initial.get(name, outs[name][:, 0])
        clean &= np.all(outs[name] > (KAPPA_SUM_RELATIVE * k_ref)[:, None], axis=1)
    for name, thr in denominator_thresholds(model).items():
        if name in outs:
            clean &= np.all(np.abs(outs[name]) > thr, axis=1)
    for name in force_outputs(outs):
        clean &= np.all(outs[name] > 0.0, axis=1)
    return clean
