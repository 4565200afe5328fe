"""How far does the held ellipsoid sag, and is it held (3D)? A sweep over the grip force and the
stiffness of the centre spring.

``gs.sweep`` runs paper3d (two fingers, the free ellipsoid under gravity, the paper's grasp law)
for every desired grip force ``fd`` and centre-spring stiffness ``k_center`` (both run-time
parameters: one build), 3 s each, and keeps the lowest height of the object's centre and the
smallest normal force at each contact along the run. The sag is how far the centre fell
below its start; the object is held when the run succeeded (no contact opened: both normal
forces stayed > 0, which the checks watch along the outputs) and it sagged less than
``HELD_SAG``.

Run: ``python examples/sweep_paper3d.py [out.png]`` (a 12 x 12 grid, a few seconds).
"""
from __future__ import annotations

import sys
import tempfile
from pathlib import Path

import numpy as np

import grasping_sym as gs

T_FINAL = 3.0
HELD_SAG = 0.005  # m


def run(n: int = 12, store: str | Path | None = None):
    """The sweep's Dataset, the sag (m) and where the object is held, over (fd, k_center)."""
    model = gs.build(gs.scenes.paper3d(runtime=("fd", "k_center")))
    z0 = model.initial_state()[model.state_names.index("z")]
    store = store or Path(tempfile.mkdtemp()) / "sweep_paper3d.zarr"
    ds = gs.sweep(model, {"fd": np.geomspace(0.005, 3.0, n), "k_center": np.linspace(0.0, 400.0, n)},
                  T_FINAL, store=store, measures=("min:z", "min:f1", "min:f2"), samples=151,
                  method="dopri5", rtol=1e-6, atol=1e-8, progress=False)
    sag = z0 - ds["min_z"]
    held = (ds["status"] == 0) & (sag < HELD_SAG)
    return ds, sag, held


def figure(ds, sag, held, path: str | Path) -> Path:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(1, 2, figsize=(11, 4.4), constrained_layout=True)
    fd, k = ds["fd"].values, ds["k_center"].values
    m = axes[0].pcolormesh(k, fd, np.ma.masked_invalid(sag.values * 1e3), shading="nearest")
    fig.colorbar(m, ax=axes[0], label="sag of the object's centre (mm)")
    if 0 < int(held.sum()) < held.size:
        axes[0].contour(k, fd, held.values.astype(float), levels=[0.5], colors="w", linewidths=1.5)
    axes[0].set_title(f"held (sag < {HELD_SAG * 1e3:g} mm, contacts closed): inside the white line",
                      fontsize=10)
    fmin = np.minimum(ds["min_f1"].values, ds["min_f2"].values)
    m = axes[1].pcolormesh(k, fd, np.ma.masked_invalid(fmin), shading="nearest", cmap="magma")
    fig.colorbar(m, ax=axes[1], label="smallest normal force, either contact (N)")
    axes[1].set_title("the grip: min(f1, f2) over the run", fontsize=10)
    failed = ds["status"].values != 0
    for ax in axes:
        ax.set_xlabel("centre-spring stiffness k_center (N/m)")
        ax.set_ylabel("desired grip force fd (N)")
        ax.set_yscale("log")
        if failed.any():
            K, F = np.meshgrid(k, fd)
            ax.plot(K[failed], F[failed], "x", color="0.5", ms=4, label="failed (contact opened)")
            ax.legend(loc="lower right", fontsize=8)
    fig.suptitle("paper3d: how far the held ellipsoid sags in 3 s", fontsize=11)
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path


def main(argv=None) -> int:
    argv = sys.argv[1:] if argv is None else argv
    out = Path(argv[0]) if argv else Path(__file__).resolve().parent.parent / "docs/figures/sweep_paper3d.png"
    ds, sag, held = run()
    figure(ds, sag, held, out)
    print(f"held at {int(held.sum())} of {held.size} (fd, k_center); sag {float(sag.min()) * 1e3:.2f} to "
          f"{float(sag.max()) * 1e3:.2f} mm; {int((ds['status'] != 0).sum())} failed; figure {out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
