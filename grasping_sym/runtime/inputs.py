"""Control inputs as functions of time, for models built with ``inputs="torques"``.

A schedule is piecewise affine: ``u(t) = a_k + b_k t`` on each of its segments. The compiled
model evaluates exactly that, in C, in every integrator (the coefficients are run-time
inputs, ``model.control``); ``Model.simulate`` restarts the integration at every knot, so a
table's kinks and jumps are met exactly and never smoothed over by a step.

- :func:`constant`: one value per input;
- :func:`piecewise_linear`: linear between the knots, held at the end values outside;
- :func:`zero_order_hold`: each value held until the next knot.

(Expressions of time are a controller's business: ``gs.controllers.feedforward``.)
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from grasping_sym.errors import InputScheduleError

__all__ = ["Schedule", "constant", "piecewise_linear", "zero_order_hold"]


@dataclass(frozen=True)
class Schedule:
    """``u(t) = a[k] + b[k] t`` for ``knots[k-1] <= t < knots[k]`` (``knots`` finite and strictly
    increasing, s; segment 0 from ``-inf``, the last to ``+inf``); ``a`` (N m) and ``b``
    (N m/s) finite, of shape ``(len(knots) + 1, n)``: one row per segment, one column per input.
    Checked when made: :class:`grasping_sym.errors.InputScheduleError` names what is wrong."""

    knots: np.ndarray
    a: np.ndarray
    b: np.ndarray
    kind: str = "schedule"

    def __post_init__(self):
        knots = _array("knots", self.knots)
        if knots.ndim != 1:
            raise InputScheduleError(f"Schedule knots have shape {knots.shape}: give a 1-D array of "
                                     "knot times (s)")
        if not np.all(np.isfinite(knots)):
            raise InputScheduleError(f"Schedule knots {knots.tolist()} are not all finite: give finite "
                                     "knot times (s)")
        if np.any(np.diff(knots) <= 0):
            k = int(np.argmax(np.diff(knots) <= 0))
            raise InputScheduleError(
                f"Schedule knots must be strictly increasing: knot {k + 1} ({knots[k + 1]:g} s) "
                f"follows knot {k} ({knots[k]:g} s); sort them and merge repeated times")
        rows = len(knots) + 1
        arrays = {}
        for name in ("a", "b"):
            arr = _array(name, getattr(self, name))
            if arr.ndim != 2 or arr.shape[0] != rows:
                raise InputScheduleError(
                    f"Schedule {name} has shape {arr.shape}: give one row per segment ({rows} for "
                    f"{len(knots)} knots: before the first, between knots, after the last) and "
                    "one column per input")
            if not np.all(np.isfinite(arr)):
                raise InputScheduleError(f"Schedule {name} has non-finite entries: give finite "
                                         "input values (N m) and rates (N m/s)")
            arrays[name] = arr
        if arrays["a"].shape != arrays["b"].shape:
            raise InputScheduleError(f"Schedule a has shape {arrays['a'].shape} and b has shape "
                                     f"{arrays['b'].shape}: give both one row per segment and "
                                     "one column per input")
        if arrays["a"].shape[1] < 1:
            raise InputScheduleError("Schedule a and b have no columns: give one column per input")
        object.__setattr__(self, "knots", knots)
        object.__setattr__(self, "a", arrays["a"])
        object.__setattr__(self, "b", arrays["b"])
        object.__setattr__(self, "kind", str(self.kind))

    @property
    def n(self) -> int:
        return self.a.shape[1]

    def __call__(self, t) -> np.ndarray:
        """The inputs at the times ``t`` (shape ``(len(t), n)``, or ``(n,)`` for a scalar)."""
        tt = np.atleast_1d(np.asarray(t, dtype=float))
        k = np.searchsorted(self.knots, tt, side="right")
        out = self.a[k] + self.b[k] * tt[:, None]
        return out[0] if np.ndim(t) == 0 else out

    def segments(self, t0: float, t1: float) -> list[tuple[float, float, np.ndarray, np.ndarray]]:
        """``(start, end, a, b)`` of each segment that meets ``[t0, t1]``, in order (in NumPy:
        a run's start makes them all, and a table of 60 001 knots took it 0.2-0.5 s of Python,
        which held off a Ctrl-C on a batch's threads for over a second)."""
        knots = self.knots
        bounds = np.concatenate([[t0], knots[(knots > t0) & (knots < t1)], [t1]])
        k = np.searchsorted(knots, 0.5 * (bounds[:-1] + bounds[1:]), side="right")
        return list(zip(bounds[:-1].tolist(), bounds[1:].tolist(), self.a[k], self.b[k]))

    def __repr__(self) -> str:
        return f"Schedule({self.kind}, {self.n} inputs, {len(self.knots)} knots)"


def _array(name: str, values) -> np.ndarray:
    """``values`` as an array of floats, or an :class:`InputScheduleError` naming ``name``."""
    try:
        arr = np.asarray(values)
    except (TypeError, ValueError) as exc:  # ragged rows
        raise InputScheduleError(f"{name} is not a table of numbers ({exc}): give one row per "
                                 "time, each with one value per input") from None
    if arr.dtype.kind not in "fiu" or arr.dtype == bool:
        raise InputScheduleError(f"{name} must be numbers, got {arr.dtype} ({_show(values)})")
    return arr.astype(float)


def _show(values) -> str:
    text = repr(values)
    return text if len(text) <= 80 else f"{text[:80]}..."


def _values(name: str, values, n_rows: int | None = None) -> np.ndarray:
    arr = _array(name, values)
    if arr.ndim == 1 and n_rows is not None:
        arr = arr[:, None]
    if n_rows is not None and (arr.ndim != 2 or arr.shape[0] != n_rows):
        raise InputScheduleError(f"{name} has shape {arr.shape}: give one row of input values per "
                                 f"time ({n_rows} rows)")
    if not np.all(np.isfinite(arr)):
        what = "knot times (s)" if name == "times" else "input values (N m)"
        raise InputScheduleError(f"{name} has non-finite entries: give finite {what}")
    return arr


def _times(times) -> np.ndarray:
    t = _values("times", times)
    if t.ndim != 1 or len(t) < 1:
        raise InputScheduleError(f"times must be a 1-D array of knot times, got shape {t.shape}")
    if np.any(np.diff(t) <= 0):
        raise InputScheduleError("times must be strictly increasing")
    return t


def constant(values) -> Schedule:
    """The same inputs at every time (one value per input, N m)."""
    v = _values("u", values)
    if v.ndim != 1 or v.size < 1:
        raise InputScheduleError(f"a constant input has one value per input, got shape {v.shape}")
    return Schedule(np.zeros(0), v[None, :], np.zeros((1, v.size)), "constant")


def piecewise_linear(times, values) -> Schedule:
    """Linear between ``values[k]`` at ``times[k]`` (s) and ``values[k+1]`` at ``times[k+1]``;
    ``values[0]`` before the first knot and ``values[-1]`` after the last."""
    t = _times(times)
    v = _values("values", values, len(t))
    n = v.shape[1]
    a, b = [v[0]], [np.zeros(n)]
    for k in range(len(t) - 1):
        slope = (v[k + 1] - v[k]) / (t[k + 1] - t[k])
        a.append(v[k] - slope * t[k])
        b.append(slope)
    a.append(v[-1])
    b.append(np.zeros(n))
    return Schedule(t, np.array(a), np.array(b), "piecewise linear")


def zero_order_hold(times, values) -> Schedule:
    """``values[k]`` from ``times[k]`` (s) until the next knot; ``values[0]`` before the first."""
    t = _times(times)
    v = _values("values", values, len(t))
    a = np.vstack([v[0], v])
    return Schedule(t, a, np.zeros_like(a), "zero-order hold")


def as_schedule(u, n: int) -> Schedule:
    """``u`` (None: zeros; numbers: constant; a :class:`Schedule`) for ``n`` inputs, checked."""
    if u is None:
        return constant(np.zeros(n))
    if isinstance(u, Schedule):
        sched = u
    elif _symbolic(u):
        raise TypeError("u holds symbolic expressions: an expression of time is a controller term, "
                        "compiled with the model: build the scene with controller=gs.controllers."
                        "paper2d() + gs.controllers.feedforward([...]) (or paper3d() + ...)")
    elif callable(u) and not isinstance(u, np.ndarray):
        raise TypeError("u is a Python function: the compiled model cannot call it. Give numbers, "
                        "gs.inputs.piecewise_linear / zero_order_hold tables, or write the law as a "
                        "controller (gs.controllers.feedforward for expressions of time)")
    else:
        sched = constant(u)
    if sched.n != n:
        raise InputScheduleError(f"u has {sched.n} inputs; the model has {n} (one joint torque per "
                                 "joint)")
    return sched  # finite and well shaped: checked when it was made


def _symbolic(u) -> bool:
    """Whether ``u`` is or holds a SymPy/CasADi expression."""
    items = u if isinstance(u, (list, tuple)) else [u]
    return any(hasattr(v, "free_symbols") or type(v).__module__.startswith("casadi") for v in items)
