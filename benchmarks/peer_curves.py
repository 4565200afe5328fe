"""Peers measured in the benchmark run, as work-precision rows like our own.

- CasADi's own functions without compilation (``peers/casadi_uncompiled.py``): the scene's
  SX graph on CasADi's virtual machine, CVODES through ``casadi.integrator`` (both scenes);
- PyDy Cython (``peers/pydy_paper2d.py``): KanesMethod + PyDy's Cython code, integrated by
  odeint, LSODA and Radau (paper2d).

Each row: ``method``, ``peer``, ``rtol``, ``atol`` (= rtol * 1e-2), ``wall_s`` (median
integration wall time of the 3 s run), ``repeats``, ``error`` (final state against our
reference, our state order), and from one more run with dense output (every 0.25 ms) mapped
to our state order: ``max_constraint_residual`` and ``energy_drift_J`` evaluated by our
compiled model's outputs (``work_precision.trajectory_diagnostics``). Slow settings are
bounded: once a run exceeds the time budget the tighter tolerances are skipped (a row with
``skipped_rtols`` says so).
"""
from __future__ import annotations

import math
import time

import numpy as np

from benchmarks import work_precision as wp

CASADI = "CasADi uncompiled"
PYDY = "PyDy Cython"
CASADI_METHOD = "CasADi (uncompiled)+cvodes"
PYDY_METHODS = ("odeint", "LSODA", "Radau")


def casadi_rows(scene, model, energy_model, x_ref: np.ndarray, rtols, *, quick: bool,
                log=print) -> list[dict]:
    """The uncompiled CasADi peer on ``scene`` (``model``: the built scene, for its start)."""
    from benchmarks.peers import casadi_uncompiled as cu

    budget = 2.0 if quick else 5.0
    found = cu.work_precision(scene, model, x_ref, rtols, t_final=wp.T_FINAL,
                              atol_factor=wp.ATOL_FACTOR, repeats=1 if quick else 3,
                              budget=budget)
    rhs = cu.rhs_function(scene, model)
    x0 = model.initial_state()
    grid = wp.dense_grid()
    rows = []
    for f in found:
        X, _ = cu.simulate(rhs, x0, wp.T_FINAL, f["rtol"], f["atol"], p=model.default_params, grid=grid)
        row = {"method": CASADI_METHOD, "peer": CASADI, "rtol": f["rtol"], "atol": f["atol"],
               "wall_s": f["wall"], "repeats": f["runs"], "error": f["error"],
               **wp.trajectory_diagnostics(energy_model, grid, X)}
        rows.append(row)
        _log(row, log)
    skipped = [r for r in rtols if r < found[-1]["rtol"]] if found else list(rtols)
    if skipped:
        rows.append(wp.skipped_row(CASADI_METHOD, skipped,
                                   f"a run at rtol={found[-1]['rtol']:g} took > {budget:g} s "
                                   "(time budget)"))
    return rows


def pydy_rows(energy_model, x_ref: np.ndarray, *, quick: bool, log=print) -> tuple[list, dict]:
    """The PyDy Cython peer of paper2d: rows, and its build timings (or why it is missing)."""
    try:
        from benchmarks.peers import pydy_paper2d as pp

        t0 = time.perf_counter()
        peer = pp.build()
        info = {**peer.timings, "build_s": time.perf_counter() - t0,
                "state_names": list(peer.state_names)}
    except Exception as exc:  # noqa: BLE001 - pydy/cython missing or the compiler failed
        reason = f"not available: {type(exc).__name__}: {str(exc).splitlines()[0][:200]}"
        log(f"  PyDy peer {reason}")
        return [{"method": "PyDy+odeint", "peer": PYDY, "failed": reason,
                 "error": math.inf}], {"failed": reason}
    log(f"  PyDy build: derivation {info['derivation']:.2f} s, Cython codegen + compile "
        f"{info['codegen_compile']:.2f} s")
    tols = (1e-6, 1e-8, 1e-10) if quick else tuple(10.0**-k for k in range(4, 13))
    budget = 0.5 if quick else 2.0
    measure = _PydySetting(peer, energy_model, x_ref, repeats=3 if quick else 5)
    rows = []
    for method in PYDY_METHODS:
        label = f"PyDy+{method}"
        for i, tol in enumerate(tols):
            rows.append(measure(label, method, tol, tol * wp.ATOL_FACTOR))
            _log(rows[-1], log)
            if rows[-1].get("wall_s", 0.0) > budget and tols[i + 1:]:
                rows.append(wp.skipped_row(label, list(tols[i + 1:]),
                                           f"a run at rtol={tol:g} took "
                                           f"{rows[-1]['wall_s']:.2f} s (> {budget:g} s budget)"))
                break
    # the same (rtol, atol) grid near error 1e-8 as our methods
    for method in PYDY_METHODS:
        label = f"PyDy+{method}"
        for kw in wp.grid_settings(quick, wp.taken_settings(rows, label)):
            rows.append({**measure(label, method, kw["rtol"], kw["atol"]), "grid": True})
            _log(rows[-1], log)
    return rows, info


class _PydySetting:
    """Times one PyDy setting (median of ``repeats`` after an untimed run) and measures its
    dense run: one peer row."""

    def __init__(self, peer, energy_model, x_ref, *, repeats: int):
        self.peer, self.energy_model, self.x_ref = peer, energy_model, x_ref
        self.repeats = repeats
        self.grid = wp.dense_grid()

    def __call__(self, label: str, method: str, rtol: float, atol: float) -> dict:
        from benchmarks.peers import pydy_paper2d as pp

        details: list = []
        try:
            (r,) = pp.work_precision(self.x_ref, [rtol], method=method, peer=self.peer,
                                     model=self.energy_model, atol=atol,
                                     repeats=self.repeats, t_final=wp.T_FINAL, details=details)
            dense = self.peer.simulate(wp.T_FINAL, rtol=rtol, atol=atol, method=method,
                                       t_eval=self.grid)
        except RuntimeError as exc:
            return {"method": label, "peer": PYDY, "rtol": rtol, "atol": atol,
                    "failed": str(exc).splitlines()[0][:300], "error": math.inf}
        d = details[0]
        return {"method": label, "peer": PYDY, "rtol": rtol, "atol": atol, "wall_s": r.wall_s,
                "repeats": self.repeats, "error": r.error, "nfev": d["nfev"],
                **wp.trajectory_diagnostics(self.energy_model, dense.t, dense.x),
                # the peer's own max(|Q|, |R|) on its dense run (the same definition)
                "max_constraint_residual": r.max_constraint_residual,
                "pydy_max_gap_m": d["pydy_max_gap_m"],
                "pydy_max_tangency_rad": d["pydy_max_tangency_rad"]}


def _log(row: dict, log) -> None:
    if "failed" in row:
        log(f"  {row['method']:26s} rtol={row['rtol']:g} atol={row['atol']:g} FAILED: "
            f"{row['failed'][:100]}")
        return
    log(f"  {row['method']:26s} rtol={row['rtol']:g} atol={row['atol']:g} "
        f"{row['wall_s'] * 1e3:9.3f} ms  "
        f"err {row['error']:.2e}  residual {row['max_constraint_residual']:.1e}  "
        f"drift {row['energy_drift_J']:.1e} J")
