"""Where does the paper's controller settle the object (2D)? A sweep over the object's starting
angle and the grip force.

``gs.sweep`` runs paper2d (the paper's controller, eq. 32) from every starting angle
``theta_0`` (the start solved with the object turned, the finger rolled onto it: no rebuild)
and every desired grip force ``fd`` (a run-time parameter), 3 s each, and keeps the settling
time of theta (from which on it stays within 1 mrad of its final value) and the smallest
normal force along the run. A run has settled when it is still 0.5 s before the end and the
object has stopped (|dtheta| < 1e-3 rad/s).

Every start is on the branch of the scene's start (``Model.solve_start``): the joints and the
contact point move continuously with theta_0, with no switch to the finger's other posture; a
start that branch does not reach would be a failed point (status ``START``), drawn as a cross.
The dark row near theta_0 = 0.41 rad is the equilibrium where the object stops: a start near
it settles at once.

Run: ``python examples/sweep_paper2d.py [out.png]`` (a 40 x 40 grid, about a second).
"""
from __future__ import annotations

import sys
import tempfile
from pathlib import Path

import numpy as np

import grasping_sym as gs
from grasping_sym.sweeps import START

T_FINAL = 3.0
MARGIN = 0.5  # s before the end by which a settled run has settled


def run(n: int = 40, store: str | Path | None = None):
    """The sweep's Dataset and where it settled (a boolean DataArray over the grid)."""
    model = gs.build(gs.scenes.paper2d(runtime=("fd",)))
    store = store or Path(tempfile.mkdtemp()) / "sweep_paper2d.zarr"
    ds = gs.sweep(model, {"theta_0": np.linspace(-1.2, 1.2, n), "fd": np.linspace(0.05, 1.5, n)},
                  T_FINAL, store=store, measures=("settle:theta", "min:f"), progress=False)
    settled = (ds["status"] == 0) & (ds["settle_theta"] < T_FINAL - MARGIN) & (abs(ds["dtheta"]) < 1e-3)
    return ds, settled


def figure(ds, settled, path: str | Path) -> Path:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(1, 2, figsize=(11, 4.4), constrained_layout=True)
    th, fd = ds["theta_0"].values, ds["fd"].values
    m = axes[0].pcolormesh(fd, th, np.ma.masked_invalid(ds["settle_theta"].values), shading="nearest")
    fig.colorbar(m, ax=axes[0], label="settling time of theta (s)")
    axes[0].contour(fd, th, settled.values.astype(float), levels=[0.5], colors="w", linewidths=1.5)
    axes[0].set_title(f"settled within {T_FINAL - MARGIN:g} s: inside the white line", fontsize=10)
    m = axes[1].pcolormesh(fd, th, np.ma.masked_invalid(ds["min_f"].values), shading="nearest",
                           cmap="magma")
    fig.colorbar(m, ax=axes[1], label="smallest normal force along the run (N)")
    axes[1].set_title("the grip: min f over the run", fontsize=10)
    for ax in axes:
        ax.set_xlabel("desired grip force fd (N)")
        ax.set_ylabel("starting object angle theta_0 (rad)")
    if settled.any():  # where the object stops: starts near it settle at once
        stop = float(np.nanmedian(ds["theta"].where(settled).values))
        for ax in axes:
            ax.axhline(stop, color="w", ls=":", lw=1)
        axes[0].annotate(f"equilibrium {stop:.3f} rad", (fd[-1], stop), xytext=(-4, 4),
                         textcoords="offset points", ha="right", fontsize=8, color="w")
    status = ds["status"].values
    F, T = np.meshgrid(fd, th)
    for which, marker, label in ((status == START, "x", "start refused"),
                                 ((status != 0) & (status != START), "+", "run failed")):
        if which.any():
            axes[0].plot(F[which], T[which], marker, color="0.4", ms=3, label=label)
            axes[0].legend(loc="lower right", fontsize=8)
    fig.suptitle("paper2d: where the paper's controller settles the object", fontsize=11)
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path


def main(argv=None) -> int:
    argv = sys.argv[1:] if argv is None else argv
    out = Path(argv[0]) if argv else Path(__file__).resolve().parent.parent / "docs/figures/sweep_paper2d.png"
    ds, settled = run()
    figure(ds, settled, out)
    n = settled.size
    print(f"{int(settled.sum())} of {n} (theta_0, fd) settled within {T_FINAL - MARGIN:g} s; "
          f"{int((ds['status'] != 0).sum())} failed; figure {out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
