"""Peer: the same closed loop as CasADi's own functions, without compilation.

What a CasADi user gets without our C: the scene's SX graph (the one we generate C from) as
a ``casadi.Function`` evaluated by CasADi's virtual machine (a planar scene in one piece:
``assemble.kinds.casadi_functions(scene, layers=False)``, not the layers that call compiled
code), integrated by CVODES through
``casadi.integrator``, which takes its Jacobian by AD on the same graph (also interpreted).
Same equations, same start, same tolerances as our compiled cvodes: the ratio is the price
of interpreting the graph (and, for 3D, of CasADi's AD Jacobian against our differenced one).

    python -m benchmarks.peers.casadi_uncompiled   # prints a small work-precision table
"""
from __future__ import annotations

import time
from dataclasses import replace

import casadi as ca
import numpy as np

from benchmarks.timing import median
from grasping_sym.assemble.kinds import casadi_functions


def rhs_function(scene, model) -> ca.Function:
    """The scene's rhs as an uncompiled CasADi Function with the DAE signature.

    Its input ``p`` is the model's ``default_params`` (run-time and start values).
    """
    fns = casadi_functions(replace(scene, outputs=(), name=f"{scene.name}_vm"), layers=False)
    return fns.model.rhs


def simulate(rhs: ca.Function, x0: np.ndarray, t_final: float, rtol: float, atol: float,
             p=(), grid=None) -> tuple[np.ndarray, float]:
    """Final state and wall time (s, integrator call only) of CVODES on ``rhs``; with
    ``grid`` (output times from 0 to ``t_final``) the states at those times (rows) instead."""
    integ = ca.integrator("vm_cvodes", "cvodes", rhs, 0.0, [t_final] if grid is None else list(grid),
                          {"abstol": atol, "reltol": rtol, "max_num_steps": 1_000_000,
                           "disable_internal_warnings": True})
    integ(x0=x0, p=list(p))  # first call: setup (timed apart by the caller if wanted)
    t0 = time.perf_counter()
    out = integ(x0=x0, p=list(p))
    x = np.asarray(out["xf"], float)
    return (x.ravel() if grid is None else x.T), time.perf_counter() - t0


def work_precision(scene, model, x_ref: np.ndarray, rtols, *, t_final: float = 3.0,
                   atol_factor: float = 1e-2, repeats: int = 3, budget: float = 20.0) -> list[dict]:
    """Rows ``{rtol, atol, wall (median s), error}`` of the uncompiled peer; tighter tolerances
    are skipped once one run takes more than ``budget`` seconds."""
    rhs = rhs_function(scene, model)
    x0 = model.initial_state()
    rows = []
    for rtol in rtols:
        atol = rtol * atol_factor
        times, xf = [], None
        for _ in range(repeats):
            xf, wall = simulate(rhs, x0, t_final, rtol, atol, p=model.default_params)
            times.append(wall)
            if wall > budget:
                break
        rows.append({"rtol": rtol, "atol": atol, "wall": median(times),
                     "error": float(np.max(np.abs(xf - x_ref))), "runs": len(times)})
        if min(times) > budget:
            break
    return rows


if __name__ == "__main__":
    import grasping_sym as gs

    for make in (gs.scenes.paper2d, gs.scenes.paper3d):
        scene = make()
        model = gs.build(scene)
        ref = model.simulate(3.0, rtol=1e-13, atol=1e-13, t_eval=[0.0, 3.0], outputs=False).x[-1]
        for row in work_precision(scene, model, ref, [1e-6, 1e-8, 1e-10], repeats=1):
            print(scene.name, row)
