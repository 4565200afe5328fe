"""Turning a held object (3D): two fingers turn paper3d's free ellipsoid by 0.2 rad about the
horizontal axis across the grasp, and hold it, while gravity pulls on it.

``gs.controllers.turn3d``: the paper's grasp law plus the tangential fingertip forces of a
saturated couple about the axis, driven by the object's turn since the start. (About the
grasp line itself, the line through the two contacts, rolling fingertips cannot turn an
object: that is the grasp's free spin, coupled only by the torsional friction.)

Run: ``python examples/turn3d.py [out.png]``.
"""
from __future__ import annotations

import sys

import numpy as np

import grasping_sym as gs
from grasping_sym.rotations import matrices as rotations

ANGLE = 0.2                       # rad
AXIS = (0.0, 0.0, 1.0)            # across the grasp (the grasp line runs along x)
GAIN, DAMPING, MAX_TORQUE = 1.0, 0.02, 0.05   # N m/rad, N m s/rad, N m
T_FINAL = 3.0


def rotation(model, X) -> np.ndarray:
    """The object's rotation matrices along the state rows ``X``."""
    k = model.state_names.index("qw")
    return rotations(X[:, k:k + 4])


def run() -> dict:
    start = gs.build(gs.scenes.paper3d())
    R0 = rotation(start, start.initial_state()[None, :])[0]
    law = gs.controllers.turn3d(ANGLE, GAIN, DAMPING, MAX_TORQUE, axis=AXIS, reference=R0)
    model = gs.build(gs.scenes.paper3d(controller=law))
    res = model.simulate(T_FINAL, method="radau", rtol=1e-6, atol=1e-9)
    rel = rotation(model, res.x) @ R0.T
    phi = np.arctan2(rel[:, 1, 0], rel[:, 0, 0])      # the turn about z
    ix = model.state_names.index("x")
    centre = res.x[:, ix:ix + 3]
    return {"t": res.t, "phi": phi, "f1": res["f1"], "f2": res["f2"],
            "sag": centre[:, 1] - centre[0, 1], "drift": np.linalg.norm(centre - centre[0], axis=1),
            "phi_end": float(phi[-1]), "f_min": float(min(res["f1"].min(), res["f2"].min()))}


def main(out: str | None = None) -> dict:
    r = run()
    print(f"turn after {T_FINAL} s: {r['phi_end']:.5f} rad (command {ANGLE}); normal forces >= "
          f"{r['f_min']:.3f} N; the centre moved at most {r['drift'].max() * 1e3:.2f} mm")
    if out:
        import matplotlib  # noqa: PLC0415

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt  # noqa: PLC0415

        fig, ax = plt.subplots(3, 1, figsize=(7, 7), sharex=True)
        ax[0].plot(r["t"], r["phi"])
        ax[0].axhline(ANGLE, ls=":", c="k")
        ax[0].set_ylabel("turn about z (rad)")
        ax[1].plot(r["t"], r["f1"], label="f1")
        ax[1].plot(r["t"], r["f2"], label="f2")
        ax[1].set_ylabel("normal force (N)")
        ax[1].legend(loc="lower right")
        ax[2].plot(r["t"], r["drift"] * 1e3)
        ax[2].set_ylabel("centre moved (mm)")
        ax[2].set_xlabel("t (s)")
        fig.suptitle("paper3d: two fingers turn the held ellipsoid by 0.2 rad")
        fig.tight_layout()
        fig.savefig(out, dpi=110)
    return r


if __name__ == "__main__":
    main(sys.argv[1] if len(sys.argv) > 1 else None)
