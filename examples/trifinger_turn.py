"""A hand read from URDF turns a superquadric: TriFinger Pro (``gs.scenes.trifinger``, its
published geometry) turns its held rounded cube by 0.3 rad about the vertical and holds it,
with the grasp's quality along the motion.

``gs.controllers.turn3d``: the paper's grasp law plus the tangential fingertip forces of a
saturated couple about the vertical through the fingertips' mean centre (three fingers at
120 degrees: the forces make a pure couple). Along the run: the turn, each contact's normal
force, and Ferrari and Canny's epsilon of the three contacts with mu = 0.5 (the exact contact
points and normals; bounds from cones of 8 edges inscribed in and circumscribed about the
friction cones, conventions section 10), which says how far the grasp is from failing.

Run: ``python examples/trifinger_turn.py [out.png]``.
"""
from __future__ import annotations

import sys

import numpy as np

import grasping_sym as gs
from grasping_sym.pipeline import solve_start
from grasping_sym.rotations import matrices as rotations

ANGLE = 0.3                        # rad, about the vertical
AXIS = (0.0, 0.0, 1.0)             # TriFinger's world: z up
GAIN, DAMPING, MAX_TORQUE = 0.05, 0.005, 0.02   # N m/rad, N m s/rad, N m
MU = 0.5                           # friction coefficient for the grasp quality
T_FINAL = 2.0


def rotation(model, X) -> np.ndarray:
    """The object's rotation matrices along the state rows ``X``."""
    k = model.state_names.index("qw")
    return rotations(X[:, k:k + 4])


def run() -> dict:
    held = gs.scenes.trifinger()
    # the cube's rotation at the consistent start (solved, no model built: a law does not move it)
    start = np.asarray(solve_start(held)["initial_state"])
    k = held.state_names.index("qw")
    R0 = rotations(start[None, k:k + 4])[0]
    law = gs.controllers.turn3d(ANGLE, GAIN, DAMPING, MAX_TORQUE, axis=AXIS, reference=R0)
    model = gs.build(gs.scenes.trifinger(controller=law))      # from the same start
    res = model.simulate(T_FINAL, t_eval=np.linspace(0.0, T_FINAL, 201))
    rel = rotation(model, res.x) @ R0.T
    phi = np.arctan2(rel[:, 1, 0], rel[:, 0, 0])
    quality = model.grasp_quality(res, mu=MU)
    limits = model.scene.joint_limits()
    room = min(min(res[n].min() - lo, hi - res[n].max()) for n, (lo, hi) in limits.items())
    return {"t": res.t, "phi": phi, "f": [res[f"f{i}"] for i in (1, 2, 3)],
            "eps_lower": quality["epsilon_lower"], "eps_upper": quality["epsilon_upper"],
            "closure": bool(np.all(quality["force_closure"])), "phi_end": float(phi[-1]),
            "f_min": float(min(f.min() for f in (res["f1"], res["f2"], res["f3"]))),
            "joint_room": float(room)}


def main(out: str | None = None) -> dict:
    r = run()
    print(f"turn after {T_FINAL} s: {r['phi_end']:.4f} rad (command {ANGLE}); normal forces >= "
          f"{r['f_min']:.3f} N; epsilon (mu = {MU}) from {r['eps_lower'].min():.4f} to "
          f"{r['eps_upper'].max():.4f}; force closure all along: {r['closure']}; the joints kept "
          f"{r['joint_room']:.3f} rad from their limits")
    if out:
        import matplotlib  # noqa: PLC0415

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt  # noqa: PLC0415

        fig, ax = plt.subplots(1, 3, figsize=(12, 3.4), constrained_layout=True)
        ax[0].plot(r["t"], r["phi"], label="turn")
        ax[0].axhline(ANGLE, ls="--", c="k", lw=0.8, label="command")
        ax[0].set(xlabel="t (s)", ylabel="rad", title="the cube's turn about z")
        ax[0].legend()
        for i, f in enumerate(r["f"], start=1):
            ax[1].plot(r["t"], f, label=f"contact {i}")
        ax[1].set(xlabel="t (s)", ylabel="N", title="normal forces")
        ax[1].legend()
        ax[2].fill_between(r["t"], r["eps_lower"], r["eps_upper"], alpha=0.4, label="bounds (8-edge cones)")
        ax[2].plot(r["t"], r["eps_lower"], lw=1)
        ax[2].set(xlabel="t (s)", ylabel="epsilon", title=f"grasp quality, mu = {MU}")
        ax[2].legend()
        fig.suptitle("TriFinger Pro (from URDF) turns a rounded cube")
        fig.savefig(out, dpi=110)
        plt.close(fig)
    return r


if __name__ == "__main__":
    main(sys.argv[1] if len(sys.argv) > 1 else None)
