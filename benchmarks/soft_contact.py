"""The case against soft contact, measured: two grasps in grasping_sym (rigid rolling contact)
and in MuJoCo (soft contact), side by side (issue 16):

- **paper3d**: two fingers, one of them tilted out of the plane, hold the ellipsoid;
- **planar pinch** (``pinch_scene``): the same fingers and ellipsoid with every joint and the
  object in the xy plane, gravity in it: a 2D pinch. grasping_sym's 2D models turn their
  object about a fixed pivot, where a free object is what a pinch holds against gravity, so
  the pinch is the 3D model kept in the plane (the table reports how far its out-of-plane
  states stray: z, finger 2's first joint and the quaternion's x and y).

    python -m benchmarks.soft_contact    # writes benchmarks/results/soft_contact.{md,json,png}

The same bodies, masses, inertias, gravity, start (at rest) and grasp law
(``benchmarks/peers/mujoco_paper3d.py``). MuJoCo runs with its defaults (1 ms steps,
``implicitfast``, sliding friction 1) and again with its no-slip solver (10 iterations). Measured
over 5 s:

- **creep**: how fast the held object's centre still moves over the last 2 s (µm/s);
- **contact violation**: the largest distance between the surfaces at a contact, where rigid
  contact has 0 (grasping_sym: the constraint residual; MuJoCo: ``|contact.dist|``);
- **wall time** per simulated second (MuJoCo: the law in Python before each step, as a user
  would write it).
"""
from __future__ import annotations

import json
import time
from pathlib import Path

import numpy as np

import grasping_sym as gs
from benchmarks.machine import machine_info
from benchmarks.peers.mujoco_paper3d import FRICTION, TORSION, MujocoGrasp

RESULTS = Path(__file__).resolve().parent / "results"
T_FINAL = 5.0
CREEP_WINDOW = 2.0


def _creep(t: np.ndarray, pos: np.ndarray) -> float:
    """µm/s: the centre's displacement over the last ``CREEP_WINDOW`` s, per second."""
    i = int(np.searchsorted(t, t[-1] - CREEP_WINDOW))
    return float(np.linalg.norm(pos[-1] - pos[i]) / (t[-1] - t[i]) * 1e6)


def pinch_scene():
    """The planar pinch: paper3d with finger 2's out-of-plane joint at 0 and the ellipsoid
    unturned, both fingertips on its X axis, from rest."""
    import dataclasses

    from grasping_sym.model import chains
    base = gs.scenes.paper3d()
    f2 = dataclasses.replace(base.fingers[1], q0=chains.FINGER2_Q_OPPOSED)
    return gs.scenes.paper3d(name="pinch_planar", fingers=(base.fingers[0], f2),
                             rotation=((1.0, 0.0, 0.0), (0.0, 1.0, 0.0), (0.0, 0.0, 1.0)),
                             dq0=(0.0,) * 5)


def ours(scene, model) -> dict:
    t = np.linspace(0, T_FINAL, 501)
    model.simulate(T_FINAL, t_eval=t)
    walls = []
    for _ in range(3):
        start = time.perf_counter()
        res = model.simulate(T_FINAL, t_eval=t)
        walls.append(time.perf_counter() - start)
    pos = np.column_stack([res["x"], res["y"], res["z"]])
    stray = max(float(np.max(np.abs(res[k]))) for k in ("z", "q21", "qx", "qy"))
    method = model.manifest["defaults"]["method"]  # what simulate() runs without arguments
    return {"out_of_plane": stray, "label": f"grasping_sym ({method}, default tolerances)", "t": t, "pos": pos,
            "held": True, "creep_um_s": _creep(t, pos),
            "violation_m": float(np.max(res["constraint_residual"])),
            "wall_per_s": min(walls) / T_FINAL}


def mujoco_run(scene, model, noslip: int) -> dict:
    mj = MujocoGrasp(scene, model, timestep=1e-3, noslip=noslip)
    out = mj.run(T_FINAL, every=0.01)
    held = bool(out["ncon"] >= 2 and abs(out["pos"][-1, 1] - out["pos"][0, 1]) < 0.02)
    label = "MuJoCo, defaults" + (f" + no-slip solver ({noslip} iterations)" if noslip else "")
    return {"label": label, "t": out["t"], "pos": out["pos"], "held": held,
            "creep_um_s": _creep(out["t"], out["pos"]) if held else float("nan"),
            "violation_m": out["depth"], "wall_per_s": out["wall"] / T_FINAL}


def figure(grasps: dict, path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, rows = plt.subplots(len(grasps), 2, figsize=(11, 4.0 * len(grasps)),
                             constrained_layout=True, squeeze=False)
    for (title, runs), axes in zip(grasps.items(), rows):
        _panels(axes, runs, title)
    fig.suptitle("rigid rolling contact (grasping_sym) against soft contact (MuJoCo)")
    fig.savefig(path, dpi=110)
    plt.close(fig)


def _panels(axes, runs, title: str) -> None:
    for r, colour in zip(runs, ("tab:blue", "tab:orange", "tab:green")):
        y = (r["pos"][:, 1] - r["pos"][0, 1]) * 1e3
        axes[0].plot(r["t"], np.clip(y, -12, None), color=colour, label=r["label"])
        if r["held"]:
            i = int(np.searchsorted(r["t"], 1.0))
            axes[1].plot(r["t"][i:], (r["pos"][i:, 1] - r["pos"][i, 1]) * 1e6, color=colour,
                         label=r["label"])
    axes[0].set_ylim(-12, 1)
    axes[0].set_xlabel("time [s]")
    axes[0].set_ylabel("centre height from the start [mm]")
    axes[0].set_title(f"{title}: held, or dropped (clipped at -12 mm)")
    axes[1].set_xlabel("time [s]")
    axes[1].set_ylabel("height from t = 1 s [µm]")
    axes[1].set_title(f"{title}: creep of the held object")
    for ax in axes:
        ax.grid(True, linewidth=0.3)
        ax.legend(fontsize=8)


def compare(scene) -> list[dict]:
    """grasping_sym, MuJoCo with its defaults and MuJoCo with its no-slip solver on ``scene``."""
    model = gs.build(scene)
    runs = [ours(scene, model), mujoco_run(scene, model, 0), mujoco_run(scene, model, 10)]
    for r in runs:
        print(f"{scene.name}: {r['label']}: held {r['held']}, creep {r['creep_um_s']:.3g} um/s, "
              f"violation {r['violation_m']:.3g} m, wall {r['wall_per_s'] * 1e3:.2f} ms per "
              "simulated s")
    return runs


def _row(r) -> str:
    creep = f"{r['creep_um_s']:.3g}" if r["held"] else "–"
    held = "yes" if r["held"] else "**no**: it slips out"
    return (f"| {r['label']} | {held} | {creep} | {r['violation_m']:.2g} m | "
            f"{r['wall_per_s'] * 1e3:.2f} ms |")


def main() -> None:
    import mujoco

    t0 = time.time()
    grasps = {"paper3d": compare(gs.scenes.paper3d(name="paper3d_rest", dq0=(0.0,) * 5)),
              "planar pinch": compare(pinch_scene())}
    RESULTS.mkdir(exist_ok=True)
    figure(grasps, RESULTS / "soft_contact.png")
    info = machine_info()
    table = {g: [{k: v for k, v in r.items() if k not in ("t", "pos")} for r in runs]
             for g, runs in grasps.items()}
    (RESULTS / "soft_contact.json").write_text(json.dumps(
        {"grasps": table, "mujoco": mujoco.__version__, "friction": [FRICTION, TORSION],
         "machine": info}, indent=1, default=float))
    sections = []
    stray = grasps["planar pinch"][0]["out_of_plane"]
    for g, runs in grasps.items():
        note = ([f"grasping_sym's out-of-plane states (z, q21, qx, qy) stay within {stray:.1e} "
                 "over the run: the motion is planar.", ""] if g == "planar pinch" else [])
        sections += [f"## {g}", "", *note,
                     "| run | object held | creep µm/s | contact violation | wall per simulated s |",
                     "|---|---|---|---|---|", *[_row(r) for r in runs], ""]
    md = "\n".join([
        "# Rigid rolling contact against soft contact",
        "",
        f"Generated by `python -m benchmarks.soft_contact` on "
        f"{time.strftime('%Y-%m-%d %H:%M:%S UTC', time.gmtime())} (total {time.time() - t0:.0f} s). "
        "Do not edit by hand.",
        "",
        "Two grasps from rest, 5 s each, the same bodies, gravity, start and grasp law in both "
        "codes: paper3d (finger 2 tilted out of the plane), and the planar pinch (the same "
        "fingers and ellipsoid with every joint and the object in the xy plane, gravity in it: "
        "a 2D pinch; `pinch_scene`). MuJoCo "
        f"{mujoco.__version__} with 1 ms steps, `implicitfast`, `condim=4`, friction "
        f"{FRICTION} (sliding) and {TORSION} m (torsional; grasping_sym's is viscous, 2e-5 N m s), "
        "contacts detected within 1 mm (`margin` = `gap` = 1 mm). Creep: the object centre's "
        f"speed over the last {CREEP_WINDOW:g} s. Violation: the largest distance between the "
        "surfaces at a contact over the run, where rigid contact has none.",
        "",
        *sections,
        "grasping_sym's creep is the grasp still settling (the centre spring's sag approaching "
        "rest), not a slip: the contacts roll without slipping by construction. MuJoCo's wall "
        "time includes the law, evaluated in Python before every step.",
        "",
        "![soft contact](soft_contact.png)",
        "",
        f"Machine: {info.get('cpu')}; commit {info.get('git_commit')}.",
        "",
    ])
    (RESULTS / "soft_contact.md").write_text(md)
    print(md)


if __name__ == "__main__":
    main()
