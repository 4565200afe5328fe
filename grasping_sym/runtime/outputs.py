"""A model's compiled outputs, at one state, at many, and along a run.

The compiled outputs hold every column of ``model.columns``: the outputs the scene asked for
(``model.output_names``), then those only the run-time checks read (``runtime.checks``). A law
that reads the time (the manifest's ``outputs_time``) takes it as the last entry of ``p``,
called through CasADi; a model with inputs takes their value ``u(t) = a + b t`` at each time.
"""
from __future__ import annotations

import weakref

import numpy as np

from grasping_sym.runtime.parameters import complete

#: Per model: the compiled outputs that read the time (a CasADi ``external``, loaded once).
_TIMED: weakref.WeakKeyDictionary = weakref.WeakKeyDictionary()


def need(model) -> None:
    """Refuse a model built with no outputs (an ``AttributeError`` naming the fix)."""
    if not model.output_names:
        raise AttributeError(f"model {model.name!r} was built with no outputs: build the "
                             "scene with outputs=(...) naming the ones you need")


def row(model, x, p, t=None) -> np.ndarray:
    """The compiled outputs at one state ``x`` with the full ``p`` (``model.p_names``), and at
    the time ``t`` (s) for a law that reads it (None: the plain compiled call)."""
    if t is None:
        return np.asarray(model.library.outputs(x, p))
    fn = _TIMED.get(model)
    if fn is None:
        import casadi as ca  # noqa: PLC0415 - casadi only for a law that reads the time

        fn = _TIMED[model] = ca.external(f"{model.name}_outputs", str(model.library_path))
    return np.asarray(fn(x, np.append(p, t))).ravel()


def at(model, x, p=None) -> dict[str, float]:
    """Every compiled output at one state, those only the checks read included (empty for a
    model compiled without outputs); ``p`` as for ``Model.rhs``."""
    if not model.columns:
        return {}
    timed = bool(model.manifest.get("outputs_time"))
    y = row(model, x, complete(model, p), 0.0 if timed else None)
    return dict(zip(model.columns, map(float, y)))


def at_rows(model, X, p=None) -> dict[str, np.ndarray]:
    """Every compiled output at every row of ``X`` (``at``)."""
    if not model.columns:
        return {}
    return by_name(model, _rows(model, X, p))


def _rows(model, X, p=None) -> np.ndarray:
    """``at_rows``' outputs, one row per row of ``X``."""
    if model.manifest.get("outputs_time"):  # a law that reads the time: at t = 0
        return np.array([row(model, x, complete(model, p), 0.0) for x in np.atleast_2d(X)])
    return model.library.outputs_batch(X, complete(model, p))


def along(model, t, X, p, sched) -> dict[str, np.ndarray]:
    """Every compiled output (``at``) at the rows of ``X`` (times ``t``): the inputs' value at
    each time (``a + b t`` as ``a``; ``sched`` a ``runtime.inputs`` table or None), and the time
    itself for a law that reads it. Rows where the inputs are constant go to the compiled batch
    call, segment by segment."""
    return by_name(model, along_rows(model, t, X, p, sched)) if model.columns else {}


def along_rows(model, t, X, p, sched) -> np.ndarray:
    """``along``'s outputs, one row per time (every column, ``model.columns``)."""
    timed = bool(model.manifest.get("outputs_time"))
    if sched is None and not timed:
        return _rows(model, X, p)
    p = complete(model, p)
    Y = np.empty((len(t), len(model.columns)))
    segment = np.searchsorted(sched.knots, t, side="right") if sched is not None else \
        np.zeros(len(t), dtype=int)
    for k in np.unique(segment):
        rows = np.flatnonzero(segment == k)
        if sched is not None and not timed and not np.any(sched.b[k]):
            Y[rows] = model.library.outputs_batch(X[rows], model.with_inputs(p, sched.a[k]))
            continue
        for i in rows:
            pi = p if sched is None else model.with_inputs(p, sched(float(t[i])))
            Y[i] = row(model, X[i], pi, t[i] if timed else None)
    return Y


def by_name(model, Y: np.ndarray | None, shown: bool = False) -> dict[str, np.ndarray]:
    """The columns of ``Y`` (every compiled output, ``model.columns``, on its last axis) by
    name; ``shown``: only those the model shows (``model.output_names``)."""
    if Y is None:
        return {}
    keep = set(model.output_names) if shown else None
    return {k: np.ascontiguousarray(Y[..., i]) for i, k in enumerate(model.columns)
            if keep is None or k in keep}

