"""Optimal control through rolling contact (2D): turn the paper's object to 0.3 rad, at rest,
in 1 s, with the least effort, the contact kept closed and inside a friction cone of mu = 0.3.

paper2d with no controller and joint torques ``u`` as inputs: direct collocation (Legendre,
degree 3) in CasADi's ``Opti`` with IPOPT and exact Hessians of the exact closed loop
(``model.casadi_function``, evaluated by compiled C), ``min ∫ |u|² dt`` with the normal force ``f >= 0.1 N`` along the
way, and the friction cone ``|lam| <= mu f`` with ``mu = 0.3`` at every collocation point
(``model.casadi_function("cone")``: ``mu^2 f^2 - lam^2 >= 0``, imposed with 0.95 mu at the
collocation points so that it also holds between them; without it the optimum needs
``|lam|/f = 0.54``). The optimal ``u`` (piecewise constant) is then re-simulated by the compiled
model with ``mu = 0.3``: a force leaving the cone anywhere between the collocation points
would stop it with ``FrictionConeError``, so a run that finishes found no slip.

Run: ``python examples/ocp_paper2d.py [out.png]``.
What made IPOPT converge (measured, benchmarks/results/control.md): the start as the first
guess of every state (a guess off the contact, e.g. theta ramped alone, starts 17 N of
constraint violation away and diverges); only theta and its rate fixed at the end (the joint
speeds follow through the contact; fixing them too repeats constraints, and IPOPT's dual
infeasibility grows to 1e12); a box around the motion; the objective scaled to order 1.

The optimal torques are re-simulated twice: by the rolling model with the cone checked, and by
the same scene with contact modes (``gs.scenes.with_modes``), where the contact could slide or
open: it rolls all along (no switch), on the rolling run's path to 4e-11 rad.
"""
from __future__ import annotations

import math
import sys
import time

import casadi as ca
import numpy as np

import grasping_sym as gs

THETA_TARGET = 0.3   # rad
T_FINAL = 1.0        # s
F_MIN = 0.1          # N, least normal force
MU = 0.3             # Coulomb friction coefficient at the contact
MU_BACKOFF = 0.95    # the cone imposed at the collocation points: 0.95 mu (between them the
                     # polynomial's force may cross an active constraint; at 1.0 it does, by 1e-6)
N_INTERVALS = 20
DEGREE = 4
COST_SCALE = 1e6     # the objective in (mN m)^2 s: of order 1 for IPOPT


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


def solve(model, *, n: int = N_INTERVALS, degree: int = DEGREE, compiled: bool = True,
          verbose: bool = False, mu: float | None = MU) -> dict:
    """The optimal control problem; returns the solution and IPOPT's figures. ``compiled``:
    the closed loop and its derivatives evaluated by compiled C (built once and kept with the
    model), else by CasADi's virtual machine on the SX expanded into the problem. ``mu``: the
    friction cone kept at every collocation point (None: unlimited friction)."""
    f = model.casadi_function("ode", compiled=compiled)
    y = model.casadi_function("outputs", compiled=compiled)
    cone = model.casadi_function("cone", compiled=compiled)
    i_f = model.output_names.index("f")
    x0 = model.initial_state()
    nx, nu = x0.size, len(model.input_names)
    i_theta, i_dtheta = model.state_names.index("theta"), model.state_names.index("dtheta")
    # Lagrange basis on [0, 1] through 0 and the Legendre points: its derivatives at the
    # collocation points (C) and its end values (D)
    C, D, _ = (np.array(m) for m in ca.collocation_coeff(ca.collocation_points(degree, "legendre")))
    D = D.ravel()
    h = T_FINAL / n
    opti = ca.Opti()
    u_guess = squeeze(model, x0)
    X = opti.variable(nx, n + 1)           # the states at the mesh points
    Xc = opti.variable(nx, n * degree)     # ... and at the collocation points, interval by interval
    U = opti.variable(nu, n)               # the torques, constant on each interval
    p = ca.DM.zeros(0, 1)
    # the closed loop and the normal force at every collocation point in one call each
    # (Function.map: CasADi differentiates f once, not once per point)
    Urep = ca.repmat(U, degree, 1).reshape((nu, n * degree))
    F = f.map(n * degree)(Xc, Urep, p)
    Y = y.map(n * degree)(Xc, Urep, p)
    opti.subject_to(X[:, 0] == x0)
    cost = 0
    for k in range(n):
        cols = slice(k * degree, (k + 1) * degree)
        xs = ca.horzcat(X[:, k], Xc[:, cols])
        # collocation: the polynomial's slope at each point is the closed loop's rate there
        opti.subject_to(h * F[:, cols] == xs @ C)
        opti.subject_to(X[:, k + 1] == xs @ D)
        cost = cost + h * ca.sumsqr(U[:, k])
    opti.subject_to(Y[i_f, :] >= F_MIN)
    if mu is not None:  # inside the cone: mu^2 f^2 - lam^2 >= 0 (f >= F_MIN > 0 above)
        _, margin = cone.map(n * degree)(Xc, Urep, p, MU_BACKOFF * mu)
        opti.subject_to(margin >= 0)
    opti.set_initial(U, np.repeat(u_guess[:, None], n, 1))
    opti.set_initial(X, np.repeat(x0[:, None], n + 1, 1))   # the start everywhere (on the contact)
    opti.set_initial(Xc, np.repeat(x0[:, None], n * degree, 1))
    # a box around the motion (the contact parameters inside their contours' domains, angles
    # within 1 rad of the start, speeds below 20 rad/s): IPOPT's iterates stay inside it, where
    # the closed loop is what it models
    lo, hi = model.lower, model.upper
    box_lo = np.where(np.isfinite(lo), lo, x0 - 1.0)
    box_hi = np.where(np.isfinite(hi), hi, x0 + 1.0)
    n_q = (nx - 1) // 2
    box_lo[n_q:2 * n_q], box_hi[n_q:2 * n_q] = -20.0, 20.0
    opti.subject_to(opti.bounded(np.repeat(box_lo[:, None], n + 1, 1), X,
                                 np.repeat(box_hi[:, None], n + 1, 1)))
    opti.subject_to(opti.bounded(np.repeat(box_lo[:, None], n * degree, 1), Xc,
                                 np.repeat(box_hi[:, None], n * degree, 1)))
    # at rest at the target: theta and its rate (the rolling contact leaves one degree of
    # freedom, so the joint speeds follow; asking them to vanish too would repeat constraints)
    opti.subject_to(X[i_theta, n] == THETA_TARGET)
    opti.subject_to(X[i_dtheta, n] == 0)
    opti.minimize(COST_SCALE * cost)
    opti.solver("ipopt", {"expand": not compiled, "print_time": verbose},
                {"print_level": 5 if verbose else 0, "hessian_approximation": "exact"})
    t0 = time.perf_counter()
    sol = opti.solve()
    wall = time.perf_counter() - t0
    stats = sol.stats()
    return {"U": np.atleast_2d(sol.value(U)).reshape(nu, n), "X": sol.value(X), "wall_time": wall,
            "iterations": int(stats["iter_count"]), "status": stats["return_status"],
            "cost": float(sol.value(cost)), "h": h, "f_points": np.ravel(sol.value(Y[i_f, :]))}


def resimulate(model, result: dict, mu: float | None = MU):
    """The compiled model under the optimal (zero-order hold) torques, the friction cone
    checked with ``mu`` (``FrictionConeError`` if a force leaves it; None: not checked)."""
    n = result["U"].shape[1]
    knots = np.arange(n) * result["h"]
    u = gs.inputs.zero_order_hold(knots, result["U"].T)
    return model.simulate(T_FINAL, u=u, method="radau", rtol=1e-10, atol=1e-12,
                          mu=math.inf if mu is None else mu)


def resimulate_with_modes(result: dict, mu: float = MU, t_final: float = T_FINAL):
    """The optimal torques on the same scene with contact modes (``gs.scenes.with_modes``): the
    contact may slide or open there, and every switch would be recorded in ``res.events``."""
    n = result["U"].shape[1]
    u = gs.inputs.zero_order_hold(np.arange(n) * result["h"], result["U"].T)
    model = gs.build(gs.scenes.with_modes(scene()))
    return model.simulate(t_final, u=u, mu=mu, rtol=1e-10, atol=1e-12,
                          t_eval=np.linspace(0.0, t_final, int(round(100 * t_final)) + 1))


def main(out: str | None = None) -> dict:
    model = gs.build(scene())
    result = solve(model)
    res = resimulate(model, result)
    with_modes = resimulate_with_modes(result)
    print(f"re-simulated with contact modes (mu = {MU}): {len(with_modes.events)} switches, "
          f"modes {sorted(set(with_modes.modes))}")
    theta_end = float(res["theta"][-1])
    print(f"IPOPT: {result['status']}, {result['iterations']} iterations, "
          f"{result['wall_time']:.2f} s; cost {result['cost']:.4g} N^2 m^2 s")
    ratio = float(np.max(np.abs(res["lam"]) / res["f"]))
    print(f"re-simulated: theta(1 s) = {theta_end:.7f} rad (target {THETA_TARGET}), "
          f"min f = {res['f'].min():.4f} N (at the collocation points {result['f_points'].min():.4f} N), "
          f"max |lam|/f = {ratio:.4f} (mu = {MU}): no slip")
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
    names = list(res.state_names)
    rolling_at = np.array([res.x[np.argmin(np.abs(res.t - t)), [names.index(k) for k in ("theta", "q1", "q2")]]
                           for t in with_modes.t])
    return {**result, "theta_end": theta_end, "f_min": float(res["f"].min()), "cone_ratio_max": ratio,
            "modes_events": with_modes.events, "modes": with_modes.modes,
            "modes_vs_rolling": float(np.max(np.abs(with_modes.x[:, :3] - rolling_at)))}


if __name__ == "__main__":
    main(sys.argv[1] if len(sys.argv) > 1 else None)
