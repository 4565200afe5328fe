"""Cost of one evaluation of the closed-loop right-hand side, along every call path."""
from __future__ import annotations

import numpy as np

from benchmarks.rhs_loop import rhs_loop_ns
from benchmarks.timing import best_per_call


def rhs_costs(model, casadi_model, reference, X_traj: np.ndarray, *, quick: bool,
              log=print) -> dict:
    """Nanoseconds / microseconds per evaluation.

    Parameters
    ----------
    model
        The built ``Model``.
    casadi_model
        ``CasadiModel`` of the same scene (its ``rhs`` is the uncompiled SX Function).
    reference
        ``ReferenceModel`` of the same scene (SymPy lambdify + NumPy).
    X_traj
        States along a reference trajectory (rows), used for evaluation points and for
        the agreement check between the compiled and the lambdified right-hand sides.
    """
    rep = 3 if quick else 7
    x = np.ascontiguousarray(X_traj[len(X_traj) // 3])
    out: dict = {"state": x.tolist()}
    n_loop = 200_000 if quick else 2_000_000
    out["c_loop_ns"] = min(rhs_loop_ns(model, x, n_loop) for _ in range(rep))
    out["python_rhs_us"] = best_per_call(lambda: model.rhs(x), number=20_000, repeat=rep) * 1e6
    batch = {}
    for n in (1, 10, 100, 10_000):
        X = np.ascontiguousarray(np.resize(X_traj, (n, X_traj.shape[1])))
        number = max(1, 200_000 // n) if not quick else max(1, 20_000 // n)
        per_call = best_per_call(lambda X=X: model.rhs_batch(X), number=number, repeat=rep)
        batch[str(n)] = {"us_per_call": per_call * 1e6, "us_per_state": per_call * 1e6 / n}
    out["rhs_batch"] = batch
    sx = casadi_model.rhs
    ext = model.external_rhs()
    # the SX function (build_stages: derive_planar) folds the pivot in; the compiled model
    # takes it as its run-time input p
    empty, p = np.zeros(0), model.default_params
    out["casadi_sx_call_us"] = best_per_call(lambda: sx(0.0, x, empty, empty, empty),
                                             number=2_000, repeat=rep) * 1e6
    out["casadi_external_call_us"] = best_per_call(lambda: ext(0.0, x, empty, p, empty),
                                                   number=2_000, repeat=rep) * 1e6
    out["lambdify_reference_us"] = best_per_call(lambda: reference.rhs(x), number=200,
                                                 repeat=rep) * 1e6
    # agreement of the two evaluations of the same equations along the trajectory
    diffs = [float(np.max(np.abs(reference.rhs(xi) - model.rhs(xi)))) for xi in X_traj]
    scale = [float(np.max(np.abs(model.rhs(xi)))) for xi in X_traj]
    out["compiled_vs_lambdify_max_abs_diff"] = max(diffs)
    out["compiled_vs_lambdify_at_max_rhs"] = diffs[int(np.argmax(scale))]
    out["max_abs_rhs"] = max(scale)
    log(f"  C loop {out['c_loop_ns']:.0f} ns/eval; model.rhs {out['python_rhs_us']:.2f} us; "
        f"lambdify {out['lambdify_reference_us']:.1f} us")
    return out
