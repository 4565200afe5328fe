"""Optimal control through rolling contact (2D): turn the paper's object to 0.3 rad, at rest,
in 1 s, with the least effort, the contact kept closed.

paper2d with no controller and joint torques ``u`` as inputs: direct collocation (Legendre,
degree 3) in CasADi's ``Opti`` with IPOPT and exact Hessians of the exact closed loop
(``model.casadi_function``), ``min ∫ |u|² dt`` with the normal force ``f >= 0.1 N`` along the
way. The optimal ``u`` (piecewise constant) is then re-simulated by the compiled model.

Run: ``python examples/ocp_paper2d.py [out.png]``.

STATUS (work in progress, issue 14): IPOPT does not converge on this problem yet (3000
iterations, the dual infeasibility grows to 1e12 with 20 intervals; each exact Hessian of the
Lagrangian takes 11 ms in CasADi's virtual machine). Not run by the tests.
"""
from __future__ import annotations

import sys
import time

import casadi as ca
import numpy as np

import grasping_sym as gs

THETA_TARGET = 0.3   # rad
T_FINAL = 1.0        # s
F_MIN = 0.1          # N, least normal force
N_INTERVALS = 40
DEGREE = 3


def scene():
    """paper2d, open loop: no law, joint torques as inputs; no constraint stabilisation (the
    collocation keeps the constraints through the start's consistency and C'' = 0)."""
    return gs.scenes.paper2d(controller=None, inputs="torques", gf=0.0, gl=0.0, wf=0.0, wl=0.0,
                             outputs=("f", "lam", "constraint_residual"))


def squeeze(model, x0: np.ndarray) -> np.ndarray:
    """The joint torques of the paper's pull toward the pivot at ``x0`` (a first guess)."""
    p = gs.scenes.PAPER2D_PARAMS
    q1, q2 = x0[1], x0[2]
    l1, l2 = p["l11"], p["l12"]
    tip = np.array([l1 * np.sin(q1) + l2 * np.sin(q1 + q2), l1 * np.cos(q1) + l2 * np.cos(q1 + q2)])
    J = np.array([[l1 * np.cos(q1) + l2 * np.cos(q1 + q2), l2 * np.cos(q1 + q2)],
                  [-l1 * np.sin(q1) - l2 * np.sin(q1 + q2), -l2 * np.sin(q1 + q2)]])
    pivot = np.array([model.start_params["xm"], model.start_params["ym"]])
    return -J.T @ ((p["fd"] / p["r"]) * (tip - pivot))


def solve(model, *, n: int = N_INTERVALS, degree: int = DEGREE, verbose: bool = False) -> dict:
    """The optimal control problem; returns the solution and IPOPT's figures."""
    f = model.casadi_function("ode")
    y = model.casadi_function("outputs")
    i_f = model.output_names.index("f")
    x0 = model.initial_state()
    nx, nu = x0.size, len(model.input_names)
    i_theta, i_dtheta = model.state_names.index("theta"), model.state_names.index("dtheta")
    tau = np.append(0.0, ca.collocation_points(degree, "legendre"))
    C, D, B = np.zeros((degree + 1, degree + 1)), np.zeros(degree + 1), np.zeros(degree + 1)
    for j in range(degree + 1):  # Lagrange basis: derivative matrix, end weights, quadrature
        coeff = np.poly1d([1.0])
        for r in range(degree + 1):
            if r != j:
                coeff *= np.poly1d([1.0, -tau[r]]) / (tau[j] - tau[r])
        D[j] = coeff(1.0)
        dcoeff = np.polyder(coeff)
        for r in range(degree + 1):
            C[j, r] = dcoeff(tau[r])
        B[j] = np.polyint(coeff)(1.0)
    h = T_FINAL / n
    opti = ca.Opti()
    u_guess = squeeze(model, x0)
    X = opti.variable(nx, n + 1)
    Xc = [opti.variable(nx, degree) for _ in range(n)]
    U = opti.variable(nu, n)
    p = ca.DM.zeros(0, 1)
    opti.subject_to(X[:, 0] == x0)
    cost = 0
    lo, hi = model.lower, model.upper
    for k in range(n):
        xs = [X[:, k]] + [Xc[k][:, j] for j in range(degree)]
        x_end = D[0] * xs[0]
        for j in range(1, degree + 1):
            xp = sum(C[r, j] * xs[r] for r in range(degree + 1))
            opti.subject_to(h * f(xs[j], U[:, k], p) == xp)
            opti.subject_to(y(xs[j], U[:, k], p)[i_f] >= F_MIN)
            x_end = x_end + D[j] * xs[j]
        cost = cost + B[1:] @ np.ones(degree) * h * ca.sumsqr(U[:, k])
        opti.subject_to(X[:, k + 1] == x_end)
        opti.set_initial(U[:, k], u_guess)  # states: the start everywhere (on the contact)
        opti.set_initial(Xc[k], np.repeat(x0[:, None], degree, axis=1))
        opti.set_initial(X[:, k + 1], x0)
    for i in np.flatnonzero(np.isfinite(lo)):
        opti.subject_to(opti.bounded(lo[i], X[i, :], hi[i]))
    opti.subject_to(X[i_theta, n] == THETA_TARGET)
    opti.subject_to(X[i_dtheta, n] == 0)
    n_q = (nx - 1) // 2  # rest: every speed zero at the end
    opti.subject_to(X[n_q:2 * n_q, n] == 0)
    opti.minimize(cost)
    opti.solver("ipopt", {"expand": True}, {"print_level": 5 if verbose else 0, "tol": 1e-10,
                                             "hessian_approximation": "exact"})
    t0 = time.perf_counter()
    sol = opti.solve()
    wall = time.perf_counter() - t0
    stats = sol.stats()
    return {"U": np.atleast_2d(sol.value(U)).reshape(nu, n), "X": sol.value(X), "wall_time": wall,
            "iterations": int(stats["iter_count"]), "status": stats["return_status"],
            "cost": float(sol.value(cost)), "h": h}


def resimulate(model, result: dict):
    """The compiled model under the optimal (zero-order hold) torques."""
    n = result["U"].shape[1]
    knots = np.arange(n) * result["h"]
    u = gs.inputs.zero_order_hold(knots, result["U"].T)
    return model.simulate(T_FINAL, u=u, method="radau", rtol=1e-10, atol=1e-12)


def main(out: str | None = None) -> dict:
    model = gs.build(scene())
    result = solve(model)
    res = resimulate(model, result)
    theta_end = float(res["theta"][-1])
    print(f"IPOPT: {result['status']}, {result['iterations']} iterations, "
          f"{result['wall_time']:.2f} s; cost {result['cost']:.4g} N^2 m^2 s")
    print(f"re-simulated: theta(1 s) = {theta_end:.6f} rad (target {THETA_TARGET}), "
          f"min f = {res['f'].min():.4f} N")
    if out:
        import matplotlib  # noqa: PLC0415

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt  # noqa: PLC0415

        fig, ax = plt.subplots(3, 1, figsize=(7, 7), sharex=True)
        ax[0].plot(res.t, res["theta"])
        ax[0].axhline(THETA_TARGET, ls=":", c="k")
        ax[0].set_ylabel("θ (rad)")
        tk = np.arange(result["U"].shape[1] + 1) * result["h"]
        for i in range(result["U"].shape[0]):
            ax[1].step(tk, np.append(result["U"][i], result["U"][i, -1]), where="post", label=f"u{i + 1}")
        ax[1].set_ylabel("torque (N m)")
        ax[1].legend(loc="upper right")
        ax[2].plot(res.t, res["f"])
        ax[2].axhline(F_MIN, ls=":", c="k")
        ax[2].set_ylabel("normal force f (N)")
        ax[2].set_xlabel("t (s)")
        fig.suptitle("paper2d: minimum-effort turn to 0.3 rad by rolling (IPOPT, exact Hessians)")
        fig.tight_layout()
        fig.savefig(out, dpi=110)
    return {**result, "theta_end": theta_end, "f_min": float(res["f"].min())}


if __name__ == "__main__":
    main(sys.argv[1] if len(sys.argv) > 1 else None)
