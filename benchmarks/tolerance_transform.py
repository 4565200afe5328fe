"""radau's tolerances as given against Hairer's transformation of them (issue 28, part 2: the
cliff at tight tolerances), measured before changing anything.

    python -m benchmarks.tolerance_transform   # writes benchmarks/results/tolerance_transform.md

Hairer and Wanner's RADAU5 does not use the caller's ``rtol`` as it is: its error estimate is of
a lower order than the method, and it integrates with ``rtol' = 0.1 rtol^(2/3)``,
``atol' = rtol' atol / rtol``. The package's radau uses the caller's tolerances unchanged. Here
both are run on paper2d and paper3d (the default scenes, 3 s, ``t_eval = [0, 3]``, no outputs,
``atol = rtol / 100``), the transformation emulated by passing the transformed tolerances: the
best of three wall times, the steps and the final-state error against dop853 at 1e-12. Every
ratio's baseline is measured in the same run.
"""
from __future__ import annotations

import json
from pathlib import Path

import numpy as np

import grasping_sym as gs
from benchmarks.timing import best_per_call

RESULTS = Path(__file__).resolve().parent / "results"
RTOLS = (1e-6, 1e-8, 1e-9, 1e-10, 1e-11)
T_FINAL = 3.0


def transformed(rtol: float, atol: float) -> tuple[float, float]:
    """RADAU5's tolerances for the caller's ``rtol``, ``atol``."""
    inner = 0.1 * rtol ** (2.0 / 3.0)
    return inner, inner * atol / rtol


def main() -> dict:
    out: dict = {}
    for name in ("paper2d", "paper3d"):
        model = gs.build(getattr(gs.scenes, name)())
        ref = model.simulate(T_FINAL, method="dop853", rtol=1e-12, atol=1e-14, t_eval=[0.0, T_FINAL],
                             outputs=False, max_steps=10**7).x[-1]
        rows = []
        for rtol in RTOLS:
            row = {"rtol": rtol}
            for label, (rt, at) in (("given", (rtol, rtol / 100)), ("hairer", transformed(rtol, rtol / 100))):
                def run(rt=rt, at=at, model=model):
                    return model.simulate(T_FINAL, method="radau", rtol=rt, atol=at, t_eval=[0.0, T_FINAL],
                                          outputs=False)
                res = run()
                row[label] = {"s": best_per_call(run, number=1, repeat=3), "steps": res.stats["n_steps"],
                              "error": float(np.max(np.abs(res.x[-1] - ref)))}
            rows.append(row)
        out[name] = rows
    RESULTS.mkdir(exist_ok=True)
    (RESULTS / "tolerance_transform.json").write_text(json.dumps(out, indent=1))
    lines = ["# radau: the tolerances as given, and Hairer's transformation of them (issue 28)", "",
             "`python -m benchmarks.tolerance_transform`; 3 s runs, `t_eval = [0, 3]`, no outputs, "
             "`atol = rtol / 100`; the error is the final state's against dop853 at 1e-12. "
             "`rtol' = 0.1 rtol^(2/3)` (RADAU5's), emulated by passing it.", ""]
    for name, rows in out.items():
        lines += [f"## {name}", "", "| rtol | as given | transformed | time ratio |", "|---|---|---|---|"]
        for row in rows:
            g, h = row["given"], row["hairer"]
            lines.append(f"| {row['rtol']:.0e} | {1e3 * g['s']:.2f} ms, {g['steps']} steps, error {g['error']:.1e} | "
                         f"{1e3 * h['s']:.2f} ms, {h['steps']} steps, error {h['error']:.1e} | "
                         f"{h['s'] / g['s']:.2f} |")
        lines.append("")
    (RESULTS / "tolerance_transform.md").write_text("\n".join(lines))
    print("\n".join(lines))
    return out


if __name__ == "__main__":
    main()
