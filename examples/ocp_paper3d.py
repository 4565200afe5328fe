"""Optimal control through rolling contact (3D): turn paper3d's held ellipsoid by 0.2 rad
about the horizontal axis across the grasp in 1 s, coming to rest, with the least added
effort, both contacts kept closed.

paper3d with joint torques ``u`` (five) added to the grasp law, which holds the object against
gravity: direct collocation (Legendre) in CasADi's ``Opti`` with IPOPT on the exact closed loop
(``model.casadi_function``), ``min ∫ |u|² dt``, the normal forces ``>= 1 N`` at the collocation
points. The optimal ``u`` is re-simulated by the compiled model. ``solve(..., squeeze=mu)``
also keeps the grasp able to squeeze the object under ``mu`` at the collocation points
(``model.casadi_function("squeeze")``).

The closed loop is called once per collocation point (not through ``Function.map``): CasADi
then differentiates each call as the model's functions ask (``casadi_api.DERIVATIVE_OPTIONS``):
the constraint Jacobian through the function's symbolic Jacobian, the Hessian of the
Lagrangian through the symbolic Jacobian of its reverse derivative. Through a map it takes
every direction one by one, four times the work (42 s instead of 11 s on a 2-core machine).
The normal forces are the outputs function cut to them (``outputs=``), so that the derivatives
of the 13 outputs the problem does not constrain are never made.

Run: ``python examples/ocp_paper3d.py [out.png]``.
"""
from __future__ import annotations

import sys
import time

import casadi as ca
import numpy as np

import grasping_sym as gs

ANGLE = 0.2          # rad, about z (the grasp line runs along x)
T_FINAL = 1.0        # s
F_MIN = 1.0          # N
N_INTERVALS = 8
DEGREE = 3
COST_SCALE = 1e4     # the objective in (10 mN m)^2 s: of order 1 for IPOPT
HESSIAN = "exact"


def scene():
    # collocation does not project onto the constraints as the simulations do: the dynamics it
    # discretises hold them by the stabilisation gain (paper3d's own is 0, its runs projecting)
    return gs.scenes.paper3d(inputs="torques", gain=300.0)


def _quat_matrix(q):
    w, x, y, z = q[0], q[1], q[2], q[3]
    n2 = w * w + x * x + y * y + z * z
    return ca.vertcat(
        ca.horzcat(w * w + x * x - y * y - z * z, 2 * (x * y - w * z), 2 * (x * z + w * y)),
        ca.horzcat(2 * (x * y + w * z), w * w - x * x + y * y - z * z, 2 * (y * z - w * x)),
        ca.horzcat(2 * (x * z - w * y), 2 * (y * z + w * x), w * w - x * x - y * y + z * z)) / n2


def solve(model, *, n: int = N_INTERVALS, degree: int = DEGREE, compiled: bool = False,
          verbose: bool = False, squeeze: float | None = None) -> dict:
    """The optimal control problem (``compiled``: see examples/ocp_paper2d.py). ``squeeze``: a
    friction coefficient under which the grasp must stay able to squeeze the object at every
    collocation point (``model.casadi_function("squeeze")``'s margins >= 0: the line between
    the contacts inside both friction cones, where the grasp's epsilon is 0)."""
    f = model.casadi_function("ode", compiled=compiled)
    forces = model.casadi_function("outputs", compiled=compiled, outputs=("f1", "f2"))
    x0 = model.initial_state()
    nx, nu = x0.size, len(model.input_names)
    names = model.state_names
    iq, iom, iv = names.index("qw"), names.index("omegaX"), names.index("vx")
    R0 = np.array(ca.evalf(_quat_matrix(ca.DM(x0[iq:iq + 4]))))
    # Lagrange basis on [0, 1] through 0 and the Legendre points: its derivatives at the
    # collocation points (C) and its end values (D)
    C, D, _ = (np.array(m) for m in ca.collocation_coeff(ca.collocation_points(degree, "legendre")))
    D = D.ravel()
    h = T_FINAL / n
    opti = ca.Opti()
    X = opti.variable(nx, n + 1)
    Xc = opti.variable(nx, n * degree)
    U = opti.variable(nu, n)
    p = ca.DM.zeros(0, 1)
    Urep = ca.repmat(U, degree, 1).reshape((nu, n * degree))
    points = range(n * degree)
    F = ca.horzcat(*[f(Xc[:, j], Urep[:, j], p) for j in points])
    Y = ca.horzcat(*[forces(Xc[:, j], Urep[:, j], p) for j in points])
    opti.subject_to(X[:, 0] == x0)
    cost = 0
    for k in range(n):
        cols = slice(k * degree, (k + 1) * degree)
        xs = ca.horzcat(X[:, k], Xc[:, cols])
        opti.subject_to(h * F[:, cols] == xs @ C)
        opti.subject_to(X[:, k + 1] == xs @ D)
        cost = cost + h * ca.sumsqr(U[:, k])
    opti.subject_to(ca.vec(Y) >= F_MIN)
    margins = None
    if squeeze is not None:
        fs = model.casadi_function("squeeze", compiled=compiled)
        margins = ca.horzcat(*[fs(Xc[:, j], [squeeze, squeeze]) for j in points])
        opti.subject_to(ca.vec(margins) >= 0)
    # the end: turned by ANGLE about z since the start, and at rest
    rel = _quat_matrix(X[iq:iq + 4, n]) @ R0.T
    opti.subject_to(ca.atan2(rel[1, 0], rel[0, 0]) == ANGLE)
    opti.subject_to(X[iom:iom + 3, n] == 0)
    opti.subject_to(X[iv:iv + 3, n] == 0)
    opti.set_initial(X, np.repeat(x0[:, None], n + 1, 1))
    opti.set_initial(Xc, np.repeat(x0[:, None], n * degree, 1))
    opti.minimize(COST_SCALE * cost)
    opti.solver("ipopt", {"print_time": verbose},
                {"print_level": 5 if verbose else 0, "hessian_approximation": HESSIAN})
    t0 = time.perf_counter()
    sol = opti.solve()
    wall = time.perf_counter() - t0
    stats = sol.stats()
    return {"U": np.atleast_2d(sol.value(U)).reshape(nu, n), "wall_time": wall,
            "iterations": int(stats["iter_count"]), "status": stats["return_status"],
            "cost": float(sol.value(cost)), "h": h, "R0": R0,
            "f_points": np.array(sol.value(Y)),
            "squeeze_points": None if margins is None else np.array(sol.value(margins))}


def resimulate(model, result: dict):
    n = result["U"].shape[1]
    u = gs.inputs.zero_order_hold(np.arange(n) * result["h"], result["U"].T)
    return model.simulate(T_FINAL, u=u, method="radau", rtol=1e-9, atol=1e-12)


def turn(model, res, R0) -> np.ndarray:
    iq = model.state_names.index("qw")
    out = []
    for q in res.x[:, iq:iq + 4]:
        rel = np.array(ca.evalf(_quat_matrix(ca.DM(q)))) @ R0.T
        out.append(np.arctan2(rel[1, 0], rel[0, 0]))
    return np.array(out)


def main(out: str | None = None) -> dict:
    model = gs.build(scene())
    result = solve(model)
    res = resimulate(model, result)
    phi = turn(model, res, result["R0"])
    omega = np.linalg.norm(res.x[-1, [model.state_names.index(k) for k in ("omegaX", "omegaY", "omegaZ")]])
    print(f"IPOPT: {result['status']}, {result['iterations']} iterations, {result['wall_time']:.2f} s")
    print(f"re-simulated: turn(1 s) = {phi[-1]:.6f} rad (target {ANGLE}), |omega| = {omega:.2e} rad/s, "
          f"min normal force {min(res['f1'].min(), res['f2'].min()):.3f} N")
    if out:
        import matplotlib  # noqa: PLC0415

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt  # noqa: PLC0415

        fig, ax = plt.subplots(2, 1, figsize=(7, 5.5), sharex=True)
        ax[0].plot(res.t, phi)
        ax[0].axhline(ANGLE, ls=":", c="k")
        ax[0].set_ylabel("turn about z (rad)")
        tk = np.arange(result["U"].shape[1] + 1) * result["h"]
        for i in range(result["U"].shape[0]):
            ax[1].step(tk, np.append(result["U"][i], result["U"][i, -1]), where="post", label=f"u{i + 1}")
        ax[1].set_ylabel("added torque (N m)")
        ax[1].set_xlabel("t (s)")
        ax[1].legend(loc="upper right", ncol=5, fontsize=8)
        fig.suptitle("paper3d: least-effort turn of the held ellipsoid by 0.2 rad (IPOPT)")
        fig.tight_layout()
        fig.savefig(out, dpi=110)
    return {**result, "phi_end": float(phi[-1]), "omega_end": float(omega),
            "f_min": float(min(res["f1"].min(), res["f2"].min()))}


if __name__ == "__main__":
    main(sys.argv[1] if len(sys.argv) > 1 else None)
