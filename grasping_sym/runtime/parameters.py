"""A model's run-time parameters: the compiled functions' input ``p``, checked and completed.

``p`` holds every entry of ``model.p_names``: the run-time parameters the user chose
(``param_names``), the start's values (``start_params``), then the inputs' coefficients
(``u(t) = a + b t``: every ``a``, then every ``b``).
"""
from __future__ import annotations

from collections.abc import Mapping

import numpy as np

from grasping_sym.errors import RunArgumentError
from grasping_sym.runtime.settings import real


def charts_of(model) -> tuple[str, ...]:
    """The chart parameters of ``model``'s surfaces with atlases (``runtime.atlas``)."""
    return tuple(model.manifest.get("chart_param_names", ()))


def chart_value(k: str, v) -> float:
    """The chart ``k`` given in ``params``: 0 or 1, else a named error."""
    value = real(f"params[{k!r}]", v)
    if value not in (0.0, 1.0):
        raise RunArgumentError(f"params[{k!r}] = {value!r}: a chart is 0 or 1 (the chart the state's "
                               "contact coordinates are written in: a row's own is result.charts[...])")
    return value


def values(model, params: Mapping[str, float] | None = None) -> np.ndarray | None:
    """``Model.params``: the scene's values of the run-time parameters overridden by
    ``params`` (checked against the scene's rules), then the start's values, then the inputs'
    coefficients (zero), then the charts (the start's, or those ``params`` names: an ``x0``
    written in other charts, a row of a run after a switch); None for a model without ``p``."""
    charts = charts_of(model)
    if params and not model.param_names and not set(params) <= set(charts):
        raise RunArgumentError(
            f"parameters {sorted(params)} are folded into this model's code; build the "
            "scene with runtime=(...) naming them to vary them without a rebuild"
        )
    if params is not None and not isinstance(params, Mapping):
        raise RunArgumentError(f"params is {type(params).__name__}: give a dict of run-time "
                               f"parameter values by name, e.g. {{{model.param_names[0]!r}: 0.5}}"
                               if model.param_names else "params must be a dict")
    if not model.p_names:
        return None
    p = model.default_params.copy()
    rules = model.manifest.get("param_rules", {})
    for k, v in (params or {}).items():
        if k in charts:
            p[model.p_names.index(k)] = chart_value(k, v)
            continue
        if k not in model.param_names:
            raise RunArgumentError(f"{k!r} is not a run-time parameter of this model "
                                   f"(run-time: {model.param_names}{', charts: ' + str(charts) if charts else ''})")
        value = real(f"params[{k!r}]", v)
        rule = rules.get(k, "finite")
        if rule == "positive" and not value > 0 or rule == "nonnegative" and not value >= 0:
            raise RunArgumentError(f"params[{k!r}] = {value!r} must be "
                                   f"{'> 0' if rule == 'positive' else '>= 0'} (as the scene requires "
                                   f"of {k}); give a physical value")
        p[model.param_names.index(k)] = value
    return p


def complete(model, p):
    """``p`` completed with the start's values (and zero inputs) when it holds only
    ``param_names``'; the model's own for None (None for a model without ``p``)."""
    if not model.p_names:
        return None
    if p is None:
        return model.default_params
    if np.ndim(p) == 1 and len(p) == len(model.param_names) < len(model.p_names):
        return np.concatenate([np.asarray(p, dtype=float),
                               model.default_params[len(model.param_names):]])
    return p


def with_inputs(model, p, a, b=None) -> np.ndarray:
    """``p`` (all of ``p_names``) with the inputs ``u(t) = a + b t`` (``b``: default 0)."""
    n = len(model.input_names)
    if not n:
        raise RunArgumentError("this model has no inputs: build the scene with inputs='torques'")
    out = np.array(model.default_params if p is None else p, dtype=float)
    k = model.p_names.index(model.input_names[0])
    out[k:k + n] = np.asarray(a, dtype=float).ravel()
    out[k + n:k + 2 * n] = 0.0 if b is None else np.asarray(b, dtype=float).ravel()
    return out
