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

import math
from dataclasses import dataclass

import numpy as np

__all__ = ["Schedule", "constant", "piecewise_linear", "zero_order_hold"]


@dataclass(frozen=True)
class Schedule:
    """``u(t) = a[k] + b[k] t`` for ``knots[k-1] <= t < knots[k]`` (``knots`` strictly
    increasing; segment 0 from ``-inf``, the last to ``+inf``); ``a``, ``b`` of shape
    ``(len(knots) + 1, n)``."""

    knots: np.ndarray
    a: np.ndarray
    b: np.ndarray
    kind: str = "schedule"

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
        """``(start, end, a, b)`` of each segment that meets ``[t0, t1]``, in order."""
        inner = [float(k) for k in self.knots if t0 < k < t1]
        bounds = [t0, *inner, t1]
        out = []
        for s, e in zip(bounds[:-1], bounds[1:]):
            k = int(np.searchsorted(self.knots, 0.5 * (s + e), side="right"))
            out.append((s, e, self.a[k], self.b[k]))
        return out

    def __repr__(self) -> str:
        return f"Schedule({self.kind}, {self.n} inputs, {len(self.knots)} knots)"


def _values(name: str, values, n_rows: int | None = None) -> np.ndarray:
    arr = np.asarray(values)
    if arr.dtype.kind not in "fiu":
        raise TypeError(f"{name} must be numbers, got {arr.dtype} ({values!r:.80})")
    arr = arr.astype(float)
    if arr.ndim == 1 and n_rows is not None:
        arr = arr[:, None]
    if n_rows is not None and (arr.ndim != 2 or arr.shape[0] != n_rows):
        raise ValueError(f"{name} has shape {arr.shape}: give one row of input values per time "
                         f"({n_rows} rows)")
    if not np.all(np.isfinite(arr)):
        raise ValueError(f"{name} has non-finite entries: give finite input values (N m)")
    return arr


def _times(times) -> np.ndarray:
    t = _values("times", times)
    if t.ndim != 1 or len(t) < 1:
        raise ValueError(f"times must be a 1-D array of knot times, got shape {t.shape}")
    if np.any(np.diff(t) <= 0):
        raise ValueError("times must be strictly increasing")
    return t


def constant(values) -> Schedule:
    """The same inputs at every time (one value per input, N m)."""
    v = _values("u", values)
    if v.ndim != 1:
        raise ValueError(f"a constant input has one value per input, got shape {v.shape}")
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
        raise ValueError(f"u has {sched.n} inputs; the model has {n} (one joint torque per joint)")
    if not (np.all(np.isfinite(sched.a)) and np.all(np.isfinite(sched.b))
            and all(math.isfinite(k) for k in sched.knots)):
        raise ValueError("u has non-finite values")
    return sched


def _symbolic(u) -> bool:
    """Whether ``u`` is or holds a SymPy/CasADi expression."""
    items = u if isinstance(u, (list, tuple)) else [u]
    return any(hasattr(v, "free_symbols") or type(v).__module__.startswith("casadi") for v in items)
