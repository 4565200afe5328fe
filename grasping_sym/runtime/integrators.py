"""Integrators on the compiled functions; each returns ``(t, X, stats)``.

- ``cvodes`` (default): CasADi's CVODES (variable-order BDF, Newton with the compiled
  Jacobian ``jac_{name}_rhs``), on the compiled right-hand side loaded with
  ``casadi.external``.
- ``idas``: the same through IDAS.
- ``rk4``: classic fixed-step RK4 whose whole loop runs in C (``gs_rk4``).

Failures raise ``IntegratorError`` with the time, the state and the reason.
"""
from __future__ import annotations

import math
import re
import time

import casadi as ca
import numpy as np

from grasping_sym.errors import IntegratorError

METHODS = ("cvodes", "idas", "rk4")
_T_IN_MESSAGE = re.compile(r"t\s*=\s*([-+0-9.eE]+)")


def sundials(model, method: str, x0: np.ndarray, t_eval: np.ndarray, p: np.ndarray,
             rtol: float, atol: float, max_steps: int) -> tuple[np.ndarray, np.ndarray, dict]:
    """Integrate with CVODES or IDAS through CasADi, reporting at ``t_eval``."""
    key = (method, float(rtol), float(atol), int(max_steps), t_eval.tobytes())
    integ = model._integrators.get(key)
    if integ is None:
        opts = {"abstol": atol, "reltol": rtol, "max_num_steps": max_steps,
                "print_stats": False, "show_eval_warnings": False}
        grid = [float(t) for t in t_eval[1:]]
        integ = ca.integrator(f"{model.name}_{method}", method, model.external_rhs(),
                              float(t_eval[0]), grid, opts)
        model._integrators[key] = integ
    start = time.perf_counter()
    try:
        out = integ(x0=x0, p=p)
    except RuntimeError as exc:
        raise _failure(model, method, x0, t_eval, p, rtol, atol, str(exc)) from None
    wall = time.perf_counter() - start
    X = np.vstack([x0, np.array(out["xf"]).T])
    st = integ.stats()
    stats = {"wall_time": wall, "n_steps": int(st.get("nsteps", 0)),
             "n_rhs": int(st.get("nfevals", 0)), "n_jac": int(st.get("n_call_jacF", 0))}
    return t_eval.copy(), X, stats


def _failure(model, method, x0, t_eval, p, rtol, atol, message: str) -> IntegratorError:
    """Build the error for a SUNDIALS failure: time from the message, state just before."""
    m = _T_IN_MESSAGE.findall(message)
    t_fail = float(m[-1]) if m else float("nan")
    reason = message.strip().splitlines()[-1] if message.strip() else "unknown failure"
    x_fail = None
    if math.isfinite(t_fail) and t_fail > t_eval[0]:
        # recover the state just before the failure with a fresh, short integration
        try:
            grid = [t_eval[0] + 0.999 * (t_fail - t_eval[0])]
            short = ca.integrator("recover", method, model.external_rhs(), float(t_eval[0]),
                                  grid, {"abstol": atol, "reltol": rtol})
            x_fail = np.array(short(x0=x0, p=p)["xf"]).ravel()
        except RuntimeError:
            x_fail = None
    return IntegratorError(t_fail, x_fail, f"{method}: {reason}", model.state_names)


def rk4(model, x0: np.ndarray, t_eval: np.ndarray, p: np.ndarray | None, h: float,
        lo: np.ndarray, hi: np.ndarray) -> tuple[np.ndarray, np.ndarray, dict]:
    """Fixed-step RK4 in C; ``t_eval`` must be uniform with spacing a multiple of ``h``."""
    t0, t1 = float(t_eval[0]), float(t_eval[-1])
    n_out = len(t_eval) - 1
    if n_out < 1:
        raise ValueError("t_eval needs at least two times for rk4")
    dt_out = (t1 - t0) / n_out
    if not np.allclose(np.diff(t_eval), dt_out, rtol=1e-9, atol=1e-15):
        raise ValueError("rk4 reports on a uniform grid: give a uniformly spaced t_eval")
    stride = max(1, math.ceil(dt_out / h - 1e-9))
    h_used = dt_out / stride
    start = time.perf_counter()
    t, X = model.library.rk4(x0, t0, t1, h_used, stride=stride, p=p, lo=lo, hi=hi)
    wall = time.perf_counter() - start
    return t, X, {"wall_time": wall, "n_steps": stride * n_out, "n_rhs": 4 * stride * n_out,
                  "h": h_used}
