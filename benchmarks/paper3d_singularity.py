"""Figure: the paper's moving-frame formulation as the ``paper3d`` grasp comes to rest.

Builds ``paper3d`` in both formulations (compiled), runs the paper's with the checks on (it
raises ``MovingFrameSingularityError`` where ``|D_i| = |omega0.e0 + omega1.e1|`` falls to
1e-6 of its start) and again with the checks off (to show what happens past that point), and
plots ``|D_1|``, ``|D_2|`` against time with the regular formulation's contact speeds on the
object (m/s, from its trajectory) over the whole 5 s.

    python -m benchmarks.paper3d_singularity   ->  benchmarks/results/paper3d_rest_singularity.png
"""
from __future__ import annotations

from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

import grasping_sym as gs  # noqa: E402
from grasping_sym.errors import IntegratorError, MovingFrameSingularityError  # noqa: E402

OUT = Path(__file__).parent / "results" / "paper3d_rest_singularity.png"
T_FINAL = 5.0
RUN = {"method": "radau", "rtol": 1e-7, "atol": 1e-10}


def contact_speed(scene, res, i: int) -> np.ndarray:
    """m/s, speed of contact ``i`` on the object's surface (central differences of the trace)."""
    u = res.x[:, res.state_names.index(f"u_o{i}")]
    v = res.x[:, res.state_names.index(f"v_o{i}")]
    pts = scene.object_surface.evaluate(u, v)["point"]
    return np.linalg.norm(np.gradient(pts, res.t, axis=0), axis=1)


def run() -> dict:
    regular_scene = gs.scenes.paper3d()
    regular = gs.build(regular_scene).simulate(T_FINAL, **RUN)
    paper = gs.build(gs.scenes.paper3d(formulation="paper"))
    err = None
    try:
        paper.simulate(T_FINAL, **RUN)
    except MovingFrameSingularityError as e:
        err = e
    unchecked, failure = None, None
    try:
        unchecked = paper.simulate(T_FINAL, checks=False, **RUN)
    except IntegratorError as e:   # past the singularity the run may also fail outright
        failure = e
        t, X = getattr(e, "trajectory", (None, None))
        if t is not None and len(t):
            outs = paper.outputs_batch(X)
            unchecked = type("R", (), {"t": np.asarray(t), "outputs": outs})()
    agree = None
    if unchecked is not None and failure is None:
        agree = float(np.max(np.abs(unchecked.x[:, :23] - regular.x[:, :23])))
    return {"regular": regular, "scene": regular_scene, "unchecked": unchecked, "err": err,
            "failure": failure, "agree": agree}


def main() -> Path:
    r = run()
    fig, ax = plt.subplots(figsize=(8, 4.6))
    u = r["unchecked"]
    if u is not None:
        for i, c in ((1, "C0"), (2, "C1")):
            ax.semilogy(u.t, np.abs(u.outputs[f"frame_denominator{i}"]), c, lw=1,
                        label=f"paper: |omega0.e0 + omega1.e1| at contact {i} (rad/s)")
    for i, c in ((1, "C0"), (2, "C1")):
        ax.semilogy(r["regular"].t, contact_speed(r["scene"], r["regular"], i), c + "--", lw=1,
                    label=f"regular: contact {i}'s speed on the object (m/s)")
    e = r["err"]
    if e is not None:
        ax.axvline(e.t, color="r", lw=0.8)
        ax.axhline(e.threshold, color="r", lw=0.8, ls=":")
        ax.annotate(f"MovingFrameSingularityError ({e.contact})\nt = {e.t:.3f} s, "
                    f"|D| = {abs(e.denominator):.2e} rad/s", (e.t, e.threshold),
                    xytext=(0.45, 0.85), textcoords="axes fraction",
                    arrowprops={"arrowstyle": "->"}, fontsize=8)
    if r["failure"] is not None:
        ax.axvline(r["failure"].t, color="k", lw=0.8, ls="-.")
        ax.annotate(f"unchecked run fails: t = {r['failure'].t:.3f} s", (r["failure"].t, 1e-8),
                    fontsize=7, rotation=90, va="bottom")
    if r["agree"] is not None:
        ax.text(0.45, 0.62, f"unchecked (checks=False), the paper formulation reaches {T_FINAL:g} s;\n"
                f"its body states differ from the regular one's by at most {r['agree']:.1e}",
                transform=ax.transAxes, fontsize=7)
    ax.set_xlabel("t (s)")
    ax.set_title("paper3d: the moving-frame formulation as the grasp comes to rest")
    ax.legend(fontsize=7, loc="lower left")
    fig.tight_layout()
    OUT.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(OUT, dpi=120)
    print(f"wrote {OUT}; named error at t = {e.t if e else None} s "
          f"({e.contact if e else ''}, |D| = {abs(e.denominator) if e else None:.3g}); unchecked run "
          f"{'failed at t = %.4g s' % r['failure'].t if r['failure'] else 'reached %g s' % T_FINAL}; "
          f"body states vs regular: {r['agree']}")
    return OUT


if __name__ == "__main__":
    main()
