"""What folding constants saves: paper2d with every dynamic parameter folded (the default)
against the same scene with all of them kept as run-time inputs (a sweep needs no rebuild)."""
from __future__ import annotations

import numpy as np

from benchmarks.rhs_loop import rhs_loop_ns
from benchmarks.timing import best_per_call, median


def folding(quick: bool, log=print) -> dict:
    import grasping_sym as gs
    from grasping_sym.model.planar import RUNTIME_ALLOWED

    rep = 3 if quick else 7
    out: dict = {"runtime_params": list(RUNTIME_ALLOWED)}
    te = np.array([0.0, 3.0])
    finals = {}
    for label, scene in (("folded", gs.scenes.paper2d()),
                         ("runtime", gs.scenes.paper2d(runtime=RUNTIME_ALLOWED))):
        model = gs.build(scene)
        x = model.simulate(1.0, t_eval=[0.0, 1.0], outputs=False).x[-1]
        ops = model.manifest["op_counts"]
        sim = [model.simulate(3.0, rtol=1e-8, atol=1e-10, t_eval=te, outputs=False)
               for _ in range(rep + 1)][1:]
        finals[label] = sim[-1].x[-1]
        out[label] = {
            "rhs_sx_instructions": ops["rhs_sx_instructions"],
            "jac_sx_instructions": ops["jac_sx_instructions"],
            "c_loop_ns": min(rhs_loop_ns(model, x, 200_000, model.params())
                             for _ in range(rep)),
            "python_rhs_us": best_per_call(lambda m=model, x=x: m.rhs(x), number=20_000,
                                           repeat=rep) * 1e6,
            "cvodes_3s_ms_rtol_1e-8": median([r.stats["wall_time"] for r in sim]) * 1e3,
        }
    out["final_state_max_abs_diff"] = float(np.max(np.abs(finals["folded"] - finals["runtime"])))
    f, r = out["folded"], out["runtime"]
    log(f"  folded: {f['rhs_sx_instructions']} instr, {f['c_loop_ns']:.0f} ns; run-time params: "
        f"{r['rhs_sx_instructions']} instr, {r['c_loop_ns']:.0f} ns; same final state to "
        f"{out['final_state_max_abs_diff']:.1e}")
    return out
