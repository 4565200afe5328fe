"""Figure: the paper's moving-frame formulation approaching rest (one finger, spherical object).

Runs ``PaperReference3D`` (``derive/reference3d_paper.py``) from ``rolling_start`` until it
raises ``MovingFrameSingularityError`` and plots ``|D| = |omega0.e0 + omega1.e1|`` and
``|s'|`` against time, with the regular formulation's contact rate (the object's contact
speed ``|R S_o,uv (u_o, v_o)'|``, m/s) over the same run and beyond.

    python -m benchmarks.paper3d_singularity   ->  benchmarks/results/paper3d_rest_singularity.png
"""
from __future__ import annotations

from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
from scipy.integrate import solve_ivp  # noqa: E402

from grasping_sym.derive.reference3d import Scene3D  # noqa: E402
from grasping_sym.derive.reference3d_paper import (  # noqa: E402
    MovingFrameSingularityError,
    PaperReference3D,
    rolling_start,
)

OUT = Path(__file__).parent / "results" / "paper3d_rest_singularity.png"
TOL = {"method": "LSODA", "rtol": 1e-10, "atol": 1e-12}


def run(T: float = 2.0) -> dict:
    m = PaperReference3D(Scene3D(semi_axes=(0.025, 0.025, 0.025)))
    ref = m.ref
    x0 = rolling_start(ref)
    log = []

    def f(t, x):
        log.append((t, *m.denominator(x)))
        return m.rhs(x, t)

    err = None
    try:
        solve_ivp(f, (0.0, T), m.initial_state(x0), **TOL)
    except MovingFrameSingularityError as e:
        err = e
    L = np.array(log)
    L = L[np.argsort(L[:, 0], kind="stable")]
    sol = solve_ivp(ref, (0.0, T), x0, dense_output=True, **TOL)
    ts = np.linspace(0.0, T, 400)
    speed = []
    for t in ts:
        x = sol.sol(t)
        rates = ref.rhs(x)[13:15]
        To = np.asarray(m._geom(np.r_[x[:15], np.zeros(19)])[11].full(), float)
        speed.append(np.linalg.norm(To @ rates))   # object-frame contact speed = |s'| (m/s)
    return {"t": L[:, 0], "D": L[:, 1], "sdot": L[:, 3], "err": err, "t_ref": ts, "speed_ref": np.array(speed)}


def main() -> Path:
    r = run()
    fig, ax = plt.subplots(figsize=(7, 4.2))
    ax.semilogy(r["t"], np.abs(r["D"]), label="paper: |omega0.e0 + omega1.e1| (rad/s)")
    ax.semilogy(r["t"], np.abs(r["sdot"]), label="paper: |s'| (m/s)")
    ax.semilogy(r["t_ref"], r["speed_ref"], "k--", lw=1, label="regular: contact speed (m/s)")
    e = r["err"]
    if e is not None:
        ax.axvline(e.t, color="r", lw=0.8)
        ax.axhline(e.threshold, color="r", lw=0.8, ls=":")
        ax.annotate(f"MovingFrameSingularityError\nt = {e.t:.4f} s, D = {e.denominator:.2e} rad/s",
                    (e.t, abs(e.denominator)), xytext=(0.55, 0.8), textcoords="axes fraction",
                    arrowprops={"arrowstyle": "->"}, fontsize=8)
    ax.set_xlabel("t (s)")
    ax.set_title("One finger, spherical object: the moving-frame formulation at rest")
    ax.legend(fontsize=8, loc="lower left")
    fig.tight_layout()
    OUT.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(OUT, dpi=120)
    print(f"wrote {OUT}; error at t = {e.t if e else None}, D = {e.denominator if e else None}")
    return OUT


if __name__ == "__main__":
    main()
