"""Wall time against final-state error for the 3 s paper2d simulation.

Error is the max-norm of (final state - reference final state), in the states' SI units
(rad, rad/s, m). Wall times exclude derivation and compilation. For the SUNDIALS methods
the integrator object is created (and cached inside the model) by the first call with a
given tolerance: that first call is timed and reported apart, the median is over the
calls after it. Every point also gets the maximum constraint residual over the run and the
energy-balance drift, from our compiled model's outputs on a dense trajectory
(``trajectory_diagnostics``), for the peers as well.

Curves named ``"<method> + projection, no Baumgarte"`` (``PROJECTED``) run ``<method>`` with
``project=True`` on the scene built with its constraint-stabilisation gains at 0.
"""
from __future__ import annotations

import math
import time

import casadi as ca
import numpy as np
from scipy.integrate import cumulative_simpson, solve_ivp

from benchmarks.timing import median
from grasping_sym.errors import GraspingSymError

T_FINAL = 3.0
T_EVAL = np.array([0.0, T_FINAL])
#: Tolerances of the adaptive methods: rtol, with atol = rtol * ATOL_FACTOR.
SUNDIALS_RTOLS = [10.0**-k for k in range(4, 13)]
QUICK_SUNDIALS_RTOLS = [1e-4, 1e-6, 1e-8, 1e-10]
ATOL_FACTOR = 1e-2
RK4_STEPS = [1e-3, 5e-4, 2e-4, 1e-4, 5e-5, 2e-5]
QUICK_RK4_STEPS = [1e-3, 2e-4, 5e-5]
#: Spacing (s) of the dense output used for constraint residual and energy drift.
DENSE_DT = 2.5e-4
#: Baseline: scipy methods and tolerances (loosest first; tighter ones are skipped once a
#: single run exceeds the time budget).
BASELINE_METHODS = ("LSODA", "Radau", "DOP853")
BASELINE_RTOLS = [10.0**-k for k in range(2, 11)]
QUICK_BASELINE = {"LSODA": [1e-5, 1e-7], "Radau": [1e-3, 1e-5], "DOP853": [1e-5]}


#: (rtol, atol) grid near final-state error 1e-8, searched for our adaptive methods and for
#: the peers alike (the sweeps tie atol to rtol; the cheapest setting reaching 1e-8 is
#: often off that line, so every side gets the same search). Settings already in a sweep
#: are not repeated.
GRID_RTOLS = (3e-3, 1e-3, 3e-4, 1e-4, 3e-5, 1e-5, 1e-6, 1e-7)
GRID_ATOLS = (1e-6, 1e-7, 1e-8, 1e-9, 1e-10)
QUICK_GRID_RTOLS, QUICK_GRID_ATOLS = (1e-4,), (1e-7,)
#: Our methods searched on the grid (plain dopri5 and rk4 are left out: the first is stiff
#: with the paper's gains, the second has no tolerances).
GRID_METHODS = ("cvodes", "idas", "radau", "radau + projection, no Baumgarte",
                "dopri5 + projection, no Baumgarte")
#: The lambdify baseline on the scene without Baumgarte stabilisation (gains 0, no
#: projection: solve_ivp has none): not stiff, so explicit methods and LSODA's Adams mode
#: run there; the constraints drift, which the residual column measures.
NO_BAUMGARTE = ", no Baumgarte"
BASELINE_NB_METHODS = ("LSODA", "DOP853")
#: The peer entry restricted to the paper's equations (informational, no figure).
PAPER_EQUATIONS_ONLY = "SymPy lambdify + solve_ivp, the paper's equations only"
#: Baseline methods searched on the grid, per formulation ('' = the paper's equations).
BASELINE_GRID_METHODS = {"": ("LSODA", "Radau"), NO_BAUMGARTE: ("LSODA", "DOP853")}

RADAU_RTOLS = (1e-2, 1e-3, 3e-4, 1e-4, 1e-5, 1e-6, 1e-7, 1e-8)
QUICK_RADAU_RTOLS = (1e-3, 1e-5)
#: Suffix of a curve run with projection after every step on the scene without Baumgarte
#: stabilisation (gains 0): ``"radau" + PROJECTED``.
PROJECTED = " + projection, no Baumgarte"
#: Baseline: a run is stopped once it has taken this long (s); tighter tolerances are then
#: skipped. Constraint residual and energy drift are measured (one more, dense, run) only
#: for settings whose timed run took at most ``BASELINE_DIAG_S``.
BASELINE_BUDGET_S, QUICK_BASELINE_BUDGET_S = 10.0, 3.0
BASELINE_DIAG_S, QUICK_BASELINE_DIAG_S = 3.0, 0.5
#: Accuracy bands of the method-choice section (final-state error).
BANDS = (1e-6, 1e-8, 1e-10, 1e-12)


def variant(label: str) -> tuple[str, bool]:
    """``(integrator method, project)`` of a curve label (see ``PROJECTED``)."""
    return (label[:-len(PROJECTED)], True) if label.endswith(PROJECTED) else (label, False)


def dense_grid(step: float = DENSE_DT) -> np.ndarray:
    """Output times every ``step`` s over the 3 s run (the dense diagnostics' grid)."""
    return np.linspace(0.0, T_FINAL, round(T_FINAL / step) + 1)


def err(x: np.ndarray, x_ref: np.ndarray) -> float:
    return float(np.max(np.abs(np.asarray(x) - x_ref)))


# ---------------------------------------------------------------------- reference
def reference(model, *, quick: bool, log=print) -> dict:
    """Final state by CVODES at very tight tolerance, cross-checked by other methods.

    Full mode: CVODES at rtol = atol = 1e-14 (the reference), CVODES and IDAS at 1e-13,
    RK4 at h = 2e-6 and 5e-6 s; every pairwise max-norm difference is reported.
    Quick mode: CVODES 1e-13 against IDAS 1e-13.
    """
    runs = {}
    specs = ([("cvodes 1e-13", "cvodes", dict(rtol=1e-13, atol=1e-13)),
              ("idas 1e-13", "idas", dict(rtol=1e-13, atol=1e-13))] if quick else
             [("cvodes 1e-14", "cvodes", dict(rtol=1e-14, atol=1e-14)),
              ("cvodes 1e-13", "cvodes", dict(rtol=1e-13, atol=1e-13)),
              ("idas 1e-13", "idas", dict(rtol=1e-13, atol=1e-13)),
              ("rk4 h=2e-6", "rk4", dict(h=2e-6)),
              ("rk4 h=5e-6", "rk4", dict(h=5e-6))])
    for label, method, kw in specs:
        t0 = time.perf_counter()
        r = model.simulate(T_FINAL, method=method, t_eval=T_EVAL, outputs=False, **kw)
        runs[label] = {"x_final": r.x[-1].tolist(), "wall_s": time.perf_counter() - t0,
                       "stats": r.stats}
    labels = list(runs)
    chosen = labels[0]
    x_ref = np.array(runs[chosen]["x_final"])
    diffs = {a: {b: err(runs[a]["x_final"], runs[b]["x_final"]) for b in labels}
             for a in labels}
    check = min((b for b in labels if b != chosen), key=lambda b: diffs[chosen][b])
    log(f"  reference {chosen}; closest cross-check {check}: {diffs[chosen][check]:.2e}")
    return {"chosen": chosen, "cross_check": check, "difference": diffs[chosen][check],
            "x_ref": x_ref.tolist(), "runs": runs, "pairwise": diffs}


# ---------------------------------------------------------------------- diagnostics
def dense_diagnostics(energy_model, method: str, kw: dict) -> dict:
    """Max constraint residual and energy-balance drift from one run with dense output
    (``method`` and ``kw`` as given to ``simulate``; see ``outputs_diagnostics``)."""
    if method == "rk4":
        h = kw["h"]
        t_eval = dense_grid(max(1, round(DENSE_DT / h)) * h)
    else:
        t_eval = dense_grid()
    try:
        r = energy_model.simulate(T_FINAL, method=method, t_eval=t_eval, **kw)
    except GraspingSymError as exc:
        return {"failed": str(exc).splitlines()[0][:300]}
    return outputs_diagnostics(r.t, r)


def trajectory_diagnostics(energy_model, t: np.ndarray, X: np.ndarray) -> dict:
    """The same diagnostics for any trajectory (a peer's): states ``X`` (rows, in
    ``energy_model``'s state order) at times ``t``, measured by our compiled outputs."""
    out = energy_model.outputs_batch(np.ascontiguousarray(X, dtype=float))
    return outputs_diagnostics(np.asarray(t, dtype=float), out)


def outputs_diagnostics(t: np.ndarray, out) -> dict:
    """Max constraint residual (output ``constraint_residual``) and energy-balance drift.

    Energy balance (docs/conventions.md): ``d/dt (kinetic + potential) = power``; drift is
    ``max_t |E(t) - E(0) - int_0^t power dt|`` with Simpson's rule on the grid ``t`` (J).
    """
    energy = out["kinetic_energy"] + out["potential_energy"]
    work = cumulative_simpson(out["power"], x=t, initial=0.0)
    return {"max_constraint_residual": float(np.max(np.abs(out["constraint_residual"]))),
            "energy_drift_J": float(np.max(np.abs(energy - energy[0] - work))),
            "max_kinetic_energy_J": float(np.max(out["kinetic_energy"])),
            "dense_points": len(t)}


# ---------------------------------------------------------------------- compiled methods
def time_setting(model, energy_model, method: str, kw: dict, x_ref: np.ndarray, *,
                 repeats: int, label: str | None = None) -> dict:
    """First call, then ``repeats`` timed calls; error, stats and dense diagnostics.
    ``label`` names the curve (default ``method``)."""
    row: dict = {"method": label or method, **kw}
    try:
        t0 = time.perf_counter()
        r = model.simulate(T_FINAL, method=method, t_eval=T_EVAL, outputs=False, **kw)
        row["first_call_s"] = time.perf_counter() - t0
        row["first_call_integration_s"] = r.stats["wall_time"]
    except GraspingSymError as exc:
        row["failed"] = str(exc).splitlines()[0][:300]
        row["error"] = math.inf
        return row
    walls, calls = [], []
    for _ in range(repeats):
        t0 = time.perf_counter()
        r = model.simulate(T_FINAL, method=method, t_eval=T_EVAL, outputs=False, **kw)
        calls.append(time.perf_counter() - t0)
        walls.append(r.stats["wall_time"])
    row.update({
        "wall_s": median(walls), "wall_min_s": min(walls), "call_s": median(calls),
        "repeats": repeats, "error": err(r.x[-1], x_ref), "stats": r.stats,
    })
    row.update(dense_diagnostics(energy_model, method, kw))
    return row


def compiled_methods(model, energy_model, x_ref: np.ndarray, *, quick: bool,
                     proj_model=None, log=print) -> list[dict]:
    """Our curves. ``proj_model``: the scene with its stabilisation gains at 0 (built with
    the energy outputs), for the ``PROJECTED`` curves (skipped when None)."""
    repeats = 3 if quick else 9
    rows = []
    rtols = QUICK_SUNDIALS_RTOLS if quick else SUNDIALS_RTOLS
    # Radau IIA in C: atol is kept >= 1e-10 (tighter absolute tolerances on the near-zero
    # velocities hit rounding noise, see Model.simulate) and <= 1e-8.
    radau = [{"rtol": rtol, "atol": max(1e-10, min(1e-8, rtol * ATOL_FACTOR))}
             for rtol in (QUICK_RADAU_RTOLS if quick else RADAU_RTOLS)]
    adaptive = [{"rtol": rtol, "atol": rtol * ATOL_FACTOR} for rtol in rtols]
    curves = [("cvodes", adaptive), ("idas", adaptive), ("radau", radau),
              ("rk4", [{"h": h} for h in (QUICK_RK4_STEPS if quick else RK4_STEPS)]),
              ("dopri5", adaptive)]
    if proj_model is not None:
        curves += [("radau" + PROJECTED, radau), ("dopri5" + PROJECTED, adaptive)]
    for label, settings in curves:
        method, projected = variant(label)
        m = proj_model if projected else model
        for kw in settings:
            kw = {**kw, "project": True} if projected else kw
            rows.append(time_setting(m, proj_model if projected else energy_model, method, kw,
                                     x_ref, repeats=repeats, label=label))
            _log_row(rows[-1], log)
    return rows


def grid_settings(quick: bool, taken: set | None = None) -> list[dict]:
    """The (rtol, atol) grid near error 1e-8, minus the settings in ``taken``."""
    taken = taken or set()
    return [{"rtol": r, "atol": a}
            for r in (QUICK_GRID_RTOLS if quick else GRID_RTOLS)
            for a in (QUICK_GRID_ATOLS if quick else GRID_ATOLS)
            if not any(math.isclose(r, tr) and math.isclose(a, ta) for tr, ta in taken)]


def taken_settings(rows: list[dict], method: str) -> set:
    """The (rtol, atol) pairs of ``method`` already in ``rows``."""
    return {(r["rtol"], r["atol"]) for r in rows if r.get("method") == method and "rtol" in r}


def compiled_grid(model, energy_model, x_ref: np.ndarray, sweep_rows: list[dict], *,
                  quick: bool, proj_model=None, log=print) -> list[dict]:
    """Our ``GRID_METHODS`` on the (rtol, atol) grid (rows marked ``grid``)."""
    repeats = 3 if quick else 9
    rows = []
    for label in GRID_METHODS:
        method, projected = variant(label)
        if projected and proj_model is None:
            continue
        m = proj_model if projected else model
        for kw in grid_settings(quick, taken_settings(sweep_rows, label)):
            kw = {**kw, "project": True} if projected else kw
            row = time_setting(m, proj_model if projected else energy_model, method, kw,
                               x_ref, repeats=repeats, label=label)
            row["grid"] = True
            rows.append(row)
            _log_row(row, log)
    return rows


def _log_row(row: dict, log) -> None:
    setting = f"h={row['h']:g}" if "h" in row else f"rtol={row['rtol']:g} atol={row['atol']:g}"
    if "failed" in row:
        log(f"  {row['method']:7s} {setting:12s} FAILED: {row['failed'][:100]}")
    else:
        log(f"  {row['method']:7s} {setting:12s} {row['wall_s'] * 1e3:9.3f} ms  "
            f"err {row['error']:.2e}  first call {row['first_call_s'] * 1e3:.2f} ms  "
            f"residual {row.get('max_constraint_residual', math.nan):.1e}  "
            f"drift {row.get('energy_drift_J', math.nan):.1e} J")


# ---------------------------------------------------------------------- where the time goes
def sundials_breakdown(model, casadi_model, rows: list[dict], *, quick: bool) -> list[dict]:
    """Re-run each SUNDIALS setting with CasADi's ``record_time`` to split the wall time.

    The integrator is created with the same options as ``grasping_sym.runtime.integrators``
    plus ``record_time``. Reported: time inside the right-hand side and Jacobian callbacks
    (``t_wall_daeF``, ``t_wall_jacF``), the rest (SUNDIALS + CasADi's linear algebra and call
    overhead), counters, and per-step / per-call costs. For cvodes at rtol 1e-8 the same
    integration on CasADi's own SX virtual machine (no compiled code) is timed for comparison.
    """
    out = []
    for row in rows:
        if row["method"] not in ("cvodes", "idas") or "failed" in row:
            continue
        opts = {"abstol": row["atol"], "reltol": row["rtol"], "max_num_steps": 1_000_000,
                "print_stats": False, "show_eval_warnings": False, "record_time": True}
        integ = ca.integrator("bench", row["method"], model.external_rhs(), 0.0, [T_FINAL], opts)
        x0 = model.initial_state()
        integ(x0=x0, p=model.default_params)  # the pivot: a run-time input
        st = integ.stats()
        steps = max(1, st["nsteps"])
        total = st["t_wall_total"]
        rhs_t, jac_t = st["t_wall_daeF"], st["t_wall_jacF"]
        out.append({
            "method": row["method"], "rtol": row["rtol"], "atol": row["atol"],
            "total_s": total, "rhs_s": rhs_t, "jac_s": jac_t, "other_s": total - rhs_t - jac_t,
            "n_steps": st["nsteps"], "n_rhs": st["n_call_daeF"], "n_jac": st["n_call_jacF"],
            "n_newton": st["nniters"], "n_lin_setups": st["nlinsetups"],
            "n_err_test_fails": st["netfails"],
            "us_per_step": total / steps * 1e6,
            "us_per_rhs_call": rhs_t / max(1, st["n_call_daeF"]) * 1e6,
            "us_per_jac_call": jac_t / max(1, st["n_call_jacF"]) * 1e6,
        })
    # the same integration on CasADi's SX virtual machine (nothing compiled)
    opts = {"abstol": 1e-10, "reltol": 1e-8, "max_num_steps": 1_000_000,
            "print_stats": False, "show_eval_warnings": False}
    integ = ca.integrator("bench_sx", "cvodes", casadi_model.rhs, 0.0, [T_FINAL], opts)
    x0 = model.initial_state()
    integ(x0=x0, p=np.zeros(0))  # the SX function folds the pivot in (build_stages)
    walls = []
    for _ in range(3 if quick else 7):
        t0 = time.perf_counter()
        integ(x0=x0, p=np.zeros(0))
        walls.append(time.perf_counter() - t0)
    out.append({"method": "cvodes on SX function (not compiled)", "rtol": 1e-8, "atol": 1e-10,
                "total_s": median(walls), "n_steps": integ.stats()["nsteps"]})
    return out


# ---------------------------------------------------------------------- baseline
def baseline(reference_model, x0: np.ndarray, x_ref: np.ndarray, *, quick: bool,
             energy_model=None, methods=BASELINE_METHODS, suffix: str = "",
             log=print) -> list[dict]:
    """SymPy lambdify (``ReferenceModel.rhs``) + ``scipy.integrate.solve_ivp``.

    Tolerances loosest first, atol = rtol * ATOL_FACTOR. A run is stopped once it has taken
    ``BASELINE_BUDGET_S`` (quick: ``QUICK_BASELINE_BUDGET_S``) and the method's tighter
    tolerances are then skipped (a row says so). Median of 3 runs when a run takes under
    2 s, else a single run. With ``energy_model``, settings whose run took at most
    ``BASELINE_DIAG_S`` get one more run with dense output for the constraint residual and
    energy drift. ``suffix`` is appended to the method labels (``NO_BAUMGARTE`` when
    ``reference_model`` is the scene without stabilisation).
    """
    budget = QUICK_BASELINE_BUDGET_S if quick else BASELINE_BUDGET_S
    run = _BaselineRunner(reference_model, x0, x_ref, quick=quick, energy_model=energy_model)
    rows = []
    for method in methods:
        rtols = QUICK_BASELINE.get(method, [1e-5]) if quick else BASELINE_RTOLS
        label = f"lambdify+{method}{suffix}"
        for rtol in rtols:
            row, first = run(label, method, rtol, rtol * ATOL_FACTOR)
            rows.append(row)
            log(f"  {label:30s} rtol={rtol:g} {first:8.3f} s  "
                f"err {row['error']:.2e}  nfev {row['nfev']}  {row.get('failed', '')}")
            if first > budget or row.get("over_budget"):
                skipped = [r for r in rtols if r < rtol]
                if skipped:
                    log(f"  {label}: over the {budget:g} s budget, skipping rtol {skipped}")
                    rows.append(skipped_row(label, skipped,
                                            f"a run at rtol={rtol:g} took {first:.1f} s "
                                            f"(≥ {budget:g} s budget)"))
                break
    return rows


def baseline_grid(reference_model, x0: np.ndarray, x_ref: np.ndarray, sweep_rows: list[dict],
                  *, quick: bool, energy_model=None, methods=(), suffix: str = "",
                  log=print) -> list[dict]:
    """The baseline's ``methods`` on the (rtol, atol) grid (rows marked ``grid``), measured
    as in ``baseline``; settings already in ``sweep_rows`` are not repeated."""
    run = _BaselineRunner(reference_model, x0, x_ref, quick=quick, energy_model=energy_model)
    rows = []
    for method in methods:
        label = f"lambdify+{method}{suffix}"
        for kw in grid_settings(quick, taken_settings(sweep_rows, label)):
            row, first = run(label, method, kw["rtol"], kw["atol"])
            row["grid"] = True
            rows.append(row)
            log(f"  {label:30s} rtol={kw['rtol']:g} atol={kw['atol']:g} {first:8.3f} s  "
                f"err {row['error']:.2e}  {row.get('failed', '')}")
    return rows


class _BaselineRunner:
    """Times one lambdify + solve_ivp setting: ``(row, wall of the first run)``."""

    def __init__(self, reference_model, x0, x_ref, *, quick: bool, energy_model=None):
        self.ref, self.x0, self.x_ref = reference_model, x0, x_ref
        self.quick, self.energy_model = quick, energy_model
        self.budget = QUICK_BASELINE_BUDGET_S if quick else BASELINE_BUDGET_S
        self.diag_limit = QUICK_BASELINE_DIAG_S if quick else BASELINE_DIAG_S
        self.deadline = math.inf

    def _f(self, t, y):
        if time.perf_counter() > self.deadline:
            raise _OverBudget(t)
        return self.ref.rhs(y)

    def solve(self, method, rtol, atol, t_eval):
        self.deadline = time.perf_counter() + self.budget
        try:
            return solve_ivp(self._f, (0.0, T_FINAL), self.x0, method=method, rtol=rtol,
                             atol=atol, t_eval=t_eval)
        except _OverBudget as exc:
            return _Failed(f"stopped after the {self.budget:g} s time budget at t = "
                           f"{exc.args[0]:.3g} s of {T_FINAL:g}", over_budget=True)
        except (np.linalg.LinAlgError, ValueError, FloatingPointError) as exc:
            return _Failed(f"{type(exc).__name__}: {exc}")

    def __call__(self, label: str, method: str, rtol: float, atol: float) -> tuple[dict, float]:
        walls, sol = [], None
        while True:
            t0 = time.perf_counter()
            sol = self.solve(method, rtol, atol, T_EVAL)
            walls.append(time.perf_counter() - t0)
            if self.quick or walls[0] > 2.0 or len(walls) >= 3 or not sol.success:
                break
        row = {"method": label, "rtol": rtol, "atol": atol, "repeats": len(walls),
               "nfev": int(sol.nfev), "njev": int(getattr(sol, "njev", 0) or 0),
               "success": bool(sol.success)}
        if sol.success:
            row["wall_s"] = median(walls)
            row["error"] = err(sol.y[:, -1], self.x_ref)
            if self.energy_model is not None and walls[0] <= self.diag_limit:
                dense = self.solve(method, rtol, atol, dense_grid())
                if dense.success:
                    row.update(trajectory_diagnostics(self.energy_model, dense.t, dense.y.T))
            elif self.energy_model is not None:
                row["note"] = (f"residual and drift not measured (run > {self.diag_limit:g} "
                               "s, no dense run)")
        else:
            row["error"] = math.inf
            row["failed"] = sol.message
            row["stopped_after_s"] = walls[0]
            row["over_budget"] = bool(getattr(sol, "over_budget", False))
        return row, walls[0]


def skipped_row(method: str, rtols: list[float], reason: str) -> dict:
    """A table row saying that ``method``'s tolerances ``rtols`` were not run, and why."""
    return {"method": method, "skipped_rtols": list(rtols), "reason": reason}


class _OverBudget(Exception):
    """Raised by the baseline's right-hand side once a run exceeds its time budget."""


class _Failed:
    """Stands in for a ``solve_ivp`` result when the right-hand side raised."""

    success = False
    nfev = 0
    njev = 0

    def __init__(self, message: str, *, over_budget: bool = False):
        self.message = message
        self.over_budget = over_budget


# ---------------------------------------------------------------------- equal-error comparison
def time_at_error(points: list[tuple[float, float]], target: float) -> dict | None:
    """Wall time at which a method reaches final-state error ``target``.

    ``points`` are (error, time) of one method. On the Pareto front (each point more
    accurate than every cheaper one) the time is interpolated linearly in log-log between the
    last point with error > target and the first with error <= target; if the cheapest
    point already reaches the target, its time is used (no extrapolation). ``None`` when no
    point reaches the target. ``measured`` is the cheapest measured point with
    error <= target.
    """
    pts = sorted((t, e) for e, t in points if math.isfinite(e) and e > 0)
    front: list[tuple[float, float]] = []
    for t, e in pts:
        if not front or e < front[-1][1]:
            front.append((t, e))
    ok = [(t, e) for t, e in front if e <= target]
    if not ok:
        return None
    t_ok, e_ok = ok[0]
    i = front.index(ok[0])
    if i == 0:
        return {"time_s": t_ok, "measured_s": t_ok, "measured_error": e_ok, "interpolated": False}
    t_a, e_a = front[i - 1]
    frac = (math.log(target) - math.log(e_a)) / (math.log(e_ok) - math.log(e_a))
    t_int = math.exp(math.log(t_a) + frac * (math.log(t_ok) - math.log(t_a)))
    return {"time_s": t_int, "measured_s": t_ok, "measured_error": e_ok, "interpolated": True}


def equal_error_comparison(compiled_rows: list[dict], baseline_rows: list[dict],
                           target: float = 1e-8) -> dict:
    """Fastest compiled method vs fastest baseline method at error <= ``target``."""
    def per_method(rows):
        by: dict[str, list] = {}
        for r in rows:
            if "error" in r and "wall_s" in r:
                by.setdefault(r["method"], []).append((r["error"], r["wall_s"]))
        return {m: time_at_error(p, target) for m, p in by.items()}

    ours, theirs = per_method(compiled_rows), per_method(baseline_rows)

    def fastest(d, key):
        ok = {m: v for m, v in d.items() if v is not None}
        if not ok:
            return None, None
        m = min(ok, key=lambda k: ok[k][key])
        return m, ok[m]

    res: dict = {"target_error": target, "compiled": ours, "baseline": theirs}
    for key in ("time_s", "measured_s"):
        mo, vo = fastest(ours, key)
        mb, vb = fastest(theirs, key)
        res[key] = {"compiled_method": mo, "compiled_s": vo and vo[key],
                    "baseline_method": mb, "baseline_s": vb and vb[key],
                    "ratio": (vb[key] / vo[key]) if vo and vb else None}
    return res


def peers_at_equal_error(ours: list[dict], peers: dict[str, list[dict]],
                         target: float = 1e-8) -> dict:
    """Per peer (name -> its rows, one or more methods): ``equal_error_comparison`` of our
    fastest method against the peer's fastest at final-state error ``target``."""
    return {name: equal_error_comparison(ours, rows, target) for name, rows in peers.items()}


def same_formulation(ours: list[dict], baseline_rows: list[dict],
                     target: float = 1e-8) -> dict:
    """``equal_error_comparison`` with both sides on one formulation: the paper's equations
    (our curves without projection against lambdify on the scene), and no Baumgarte (our
    projection curves against lambdify on the scene with the gains at 0)."""
    mine = {"the paper's equations (Baumgarte)": [r for r in ours if not variant(r["method"])[1]],
            "no Baumgarte": [r for r in ours if variant(r["method"])[1]]}
    theirs = {"the paper's equations (Baumgarte)":
              [r for r in baseline_rows if not r["method"].endswith(NO_BAUMGARTE)],
              "no Baumgarte": [r for r in baseline_rows if r["method"].endswith(NO_BAUMGARTE)]}
    return {k: equal_error_comparison(mine[k], theirs[k], target) for k in mine}


# ---------------------------------------------------------------------- method choice
_BRIEF = ("method", "rtol", "atol", "h", "project", "wall_s", "error", "max_constraint_residual",
          "energy_drift_J")


def method_choice(rows: list[dict], bands=BANDS) -> list[dict]:
    """Per accuracy band: each of our methods' cheapest measured setting with final-state
    error <= band, fastest first (``ranked``); ``failures``: the failed settings per method."""
    out = []
    for band in bands:
        best: dict[str, dict] = {}
        for r in rows:
            if "wall_s" in r and r.get("error", math.inf) <= band and (
                    r["method"] not in best or r["wall_s"] < best[r["method"]]["wall_s"]):
                best[r["method"]] = r
        ranked = sorted(best.values(), key=lambda r: r["wall_s"])
        out.append({"band": band, "ranked": [{k: r[k] for k in _BRIEF if k in r}
                                             for r in ranked]})
    return out


def failures(rows: list[dict]) -> dict[str, list[dict]]:
    """Failed settings per method (rows with ``failed``), in the order run."""
    out: dict[str, list[dict]] = {}
    for r in rows:
        if "failed" in r:
            out.setdefault(r["method"], []).append(r)
    return out
