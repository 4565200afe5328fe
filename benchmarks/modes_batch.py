"""Batches of models with contact modes on threads (``runtime.pool``): paper3d's grasp with
modes, 8 runs of 0.25 s at rtol 1e-8 (mu from 0.06 to 1: some slide and let go, some hold),
on one thread and on two, interleaved; and that the two give the same numbers.

    python -m benchmarks.modes_batch      # writes benchmarks/results/modes_batch.md and .json

Each run is ``simulate``'s own code (Python switches the modes between the C loop's segments,
the loops release the GIL): the ratio is what the threads buy on this machine's cores.
"""
from __future__ import annotations

import json
import os
import platform
from pathlib import Path

import numpy as np

import grasping_sym as gs
from benchmarks.timing import interleaved

RESULTS = Path(__file__).resolve().parent / "results"
ROUNDS = 7
RUNS = 8


def main() -> dict:
    model = gs.build(gs.scenes.with_modes(gs.scenes.paper3d()))
    kw = dict(mu=np.linspace(0.06, 1.0, RUNS), t_eval=np.linspace(0.0, 0.25, 126), rtol=1e-8, atol=1e-10)
    one, two = (model.simulate_many(0.25, threads=k, **kw) for k in (1, 2))
    same = bool(np.array_equal(one.x, two.x) and one.events == two.events and list(one.errors) == list(two.errors))
    wall = interleaved({k: (lambda k=k: model.simulate_many(0.25, threads=k, **kw)) for k in (1, 2)}, ROUNDS)
    out = {"machine": platform.machine(), "cores": os.cpu_count(), "runs": RUNS,
           "switches": [len(e) for e in one.events], "one_thread_s": wall[1], "two_threads_s": wall[2],
           "ratio": wall[1] / wall[2], "bit_for_bit": same}
    RESULTS.mkdir(exist_ok=True)
    (RESULTS / "modes_batch.json").write_text(json.dumps(out, indent=2) + "\n")
    lines = ["# A batch of a model with contact modes on threads", "",
             f"`python -m benchmarks.modes_batch` on {out['machine']}, {out['cores']} cores: paper3d with modes, "
             f"{RUNS} runs of 0.25 s (mu 0.06 to 1, rtol 1e-8, 126 output times; switches per run "
             f"{out['switches']}), the best of {ROUNDS} interleaved calls.", "",
             "| threads | wall (ms) |", "|---|---|",
             f"| 1 | {1e3 * wall[1]:.1f} |", f"| 2 | {1e3 * wall[2]:.1f} |", "",
             f"Two threads against one: {out['ratio']:.2f} times as fast; the runs' states, switches and "
             f"errors bit for bit the same: {same}."]
    (RESULTS / "modes_batch.md").write_text("\n".join(lines) + "\n")
    print("\n".join(lines))
    return out


if __name__ == "__main__":
    main()
