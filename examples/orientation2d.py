"""Orientation control by rolling (2D): the finger turns the paper's pivoted object to a
commanded angle and holds it there.

``gs.controllers.orientation2d``: the paper's law (32) (hold the contact closed, pull toward
the pivot) plus a saturated push of the fingertip about the pivot, driven by the object's
angle error. Two commands in a row: 0.3 rad, then, from where it stopped, -0.2 rad
(``model.with_start`` keeps the compiled model; a new target is a new law, which compiles
only the scene's small C file).

Run: ``python examples/orientation2d.py [out.png]``.
"""
from __future__ import annotations

import sys

import grasping_sym as gs

TARGETS = (0.3, -0.2)   # rad
GAIN, DAMPING, MAX_FORCE = 50.0, 0.3, 0.2   # N/rad, N s/rad, N
T_EACH = 1.5            # s per command


def run() -> dict:
    pieces, x0 = [], None
    for k, target in enumerate(TARGETS):
        law = gs.controllers.orientation2d(target, GAIN, DAMPING, MAX_FORCE)
        model = gs.build(gs.scenes.paper2d(controller=law))
        res = model.simulate(T_EACH, x0=x0, method="radau", rtol=1e-8, atol=1e-12)
        pieces.append((k * T_EACH + res.t, res["theta"], res["f"], target))
        x0 = res.x[-1]
    return {"pieces": pieces,
            "errors": [float(theta[-1] - target) for _, theta, _, target in pieces],
            "f_min": min(float(f.min()) for _, _, f, _ in pieces)}


def main(out: str | None = None) -> dict:
    r = run()
    for (_, theta, _, target), err in zip(r["pieces"], r["errors"]):
        print(f"target {target:+.2f} rad: theta after {T_EACH} s = {theta[-1]:+.5f} rad "
              f"(offset {err:+.1e} rad)")
    print(f"normal force stays >= {r['f_min']:.3f} N")
    if out:
        import matplotlib  # noqa: PLC0415

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt  # noqa: PLC0415

        fig, ax = plt.subplots(2, 1, figsize=(7, 5.5), sharex=True)
        for t, theta, f, target in r["pieces"]:
            ax[0].plot(t, theta, c="C0")
            ax[0].hlines(target, t[0], t[-1], colors="k", linestyles=":")
            ax[1].plot(t, f, c="C1")
        ax[0].set_ylabel("object angle θ (rad)")
        ax[1].set_ylabel("normal force f (N)")
        ax[1].set_xlabel("t (s)")
        ax[1].set_ylim(bottom=0)
        fig.suptitle("paper2d: the finger turns the object to 0.3 rad, then to -0.2 rad, by rolling")
        fig.tight_layout()
        fig.savefig(out, dpi=110)
    return r


if __name__ == "__main__":
    main(sys.argv[1] if len(sys.argv) > 1 else None)
