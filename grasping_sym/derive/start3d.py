"""A consistent start for a 3D grasping scene: every contact condition holds at ``t = 0``.

Configuration. The unknowns are the joint angles, the object's position (free object), a
small rotation of the object and the four surface coordinates of each contact; the equations,
per contact, are ``p_f = p_o`` (3) and opposite normals, ``(n_f + n_o) . x_o = (n_f + n_o) . y_o
= 0`` (2). There are fewer equations than unknowns, so Gauss-Newton takes the weighted
least-norm step: the start moves as little as possible from the scene's guess (the object's
surface coordinates are weighted to move least: the user chose the points to touch). The
scene is refused when the residual stays above ``TOL`` m.

Speeds. ``scene.dq0`` (joint speeds wished at the start) becomes the admissible motion
closest to it in kinetic energy: ``V0 = N (N^T M N)^-1 N^T M Vd`` with ``N`` a basis of the
speeds with ``A V = 0`` (the contact constraints' velocity rows).

The paper formulation also needs the initial frames ``Psi0 = (n0, b0, e0)``, ``Psi1 = (n1, b1,
e1)``: ``b`` is the direction of the contact's motion on the object, from the regular
formulation's rates, so the paper formulation cannot start at rest (it is 0/0 there).
"""
from __future__ import annotations

import dataclasses
import math

import casadi as ca
import numpy as np
import sympy as sp

from grasping_sym import rotations
from grasping_sym.derive.bodies3d import finger_sx, surface_sx
from grasping_sym.derive.grasp3d import derive_grasp3d
from grasping_sym.errors import InvalidSceneError, MovingFrameSingularityError
from grasping_sym.geometry.surfaces import U, V
from grasping_sym.model.grasp3d import GraspScene3D, start_inside, start_note

#: m, largest contact residual accepted at the start.
TOL = 1e-12
MAX_ITER = 60
#: Weights of the least-norm step: how freely each kind of unknown moves.
WEIGHTS = {"q": 1.0, "pos": 1.0, "rot": 1.0, "tip": 1.0, "obj": 0.05}


def _skew(w):
    return ca.vertcat(ca.horzcat(0, -w[2], w[1]), ca.horzcat(w[2], 0, -w[0]), ca.horzcat(-w[1], w[0], 0))


def _residual_function(scene: GraspScene3D):

    nQ = sum(f.chain.n for f in scene.fingers)
    N = scene.n_contacts
    nw = nQ + (3 if scene.free else 0) + 3 + 4 * N
    w = ca.SX.sym("w", nw)
    R0 = ca.SX.sym("R0", 3, 3)
    q = w[:nQ]
    k = nQ
    pos = w[k:k + 3] if scene.free else ca.DM(scene.position)
    k += 3 if scene.free else 0
    R = R0 @ (ca.DM.eye(3) + _skew(w[k:k + 3]))
    k += 3
    res, weights = [], [WEIGHTS["q"]] * nQ + ([WEIGHTS["pos"]] * 3 if scene.free else []) + [WEIGHTS["rot"]] * 3
    off = 0
    frames = []
    for i, f in enumerate(scene.fingers):
        n = f.chain.n
        # same symbolic finger as the dynamics (cached): gravity only adds terms not used here
        fin = finger_sx(f.chain, scene.gravity, q[off:off + n], ca.SX.zeros(n))
        off += n
        uv = w[k + 4 * i:k + 4 * i + 4]
        sf = surface_sx(f.tip, uv[0], uv[1])
        so = surface_sx(scene.object_surface, uv[2], uv[3])
        pf = fin["r"] + fin["Pi"] @ sf["S"]
        po = pos + R @ so["S"]
        nf, no = fin["Pi"] @ sf["n"], R @ so["n"]
        xo, yo = R @ so["x"], R @ so["y"]
        res += [pf - po, ca.dot(nf + no, xo), ca.dot(nf + no, yo)]
        weights += [WEIGHTS["tip"]] * 2 + [WEIGHTS["obj"]] * 2
        frames.append(ca.horzcat(fin["Pi"] @ sf["x"], fin["Pi"] @ sf["y"], xo))
    F = ca.vertcat(*res)
    fun = ca.Function("start_residual", [w, R0], [F, ca.jacobian(F, w), *frames])
    return fun, np.asarray(weights), nQ


def solve_configuration(scene: GraspScene3D) -> dict:
    """Joint angles, object pose and contact coordinates satisfying every contact condition.

    Returns ``{"q", "pos", "R", "eta" (N x 5: u_f, v_f, u_o, v_o, psi), "residual",
    "iterations"}``. Raises ``InvalidSceneError`` naming the residual when it does not converge.
    """
    fun, weights, nQ = _residual_function(scene)
    N = scene.n_contacts
    w = np.concatenate([np.concatenate([f.q0 for f in scene.fingers]),
                        np.asarray(scene.position, float) if scene.free else [],
                        np.zeros(3),
                        np.concatenate([[*f.tip_contact, *f.object_contact] for f in scene.fingers])])
    R = np.asarray(scene.rotation, float)
    sw = np.sqrt(weights)
    kr = nQ + (3 if scene.free else 0)
    res = np.inf
    it = 0
    for it in range(MAX_ITER):  # noqa: B007 - the count is reported
        F, J = (np.asarray(a, float) for a in fun(w, R)[:2])
        F = F.ravel()
        res = float(np.max(np.abs(F)))
        if res <= 0.01 * TOL:
            break
        y, *_ = np.linalg.lstsq(J * sw, -F, rcond=None)
        step = sw * y
        w = w + step
        R = R @ rotations.from_rotvec(w[kr:kr + 3])
        w[kr:kr + 3] = 0.0
        if not np.all(np.isfinite(w)):
            break
    F = np.asarray(fun(w, R)[0], float).ravel()
    res = float(np.max(np.abs(F))) if np.all(np.isfinite(F)) else float("inf")
    if not res <= TOL:
        raise InvalidSceneError([
            f"no consistent start near the scene's guess: the contact residual stays at {res:.3g} "
            f"(m or unit normals) > {TOL:g} after {MAX_ITER} Gauss-Newton steps; move the guesses "
            "(finger q0, object position/rotation, tip_contact) closer to touching"])
    problems = []
    for i, f in enumerate(scene.fingers):
        uv = w[kr + 3 + 4 * i:kr + 7 + 4 * i]
        if not start_inside(f.tip, uv[:2]):
            problems.append(f"finger {i + 1}: the fingertip contact solved to (u, v) = {tuple(map(float, uv[:2]))}, "
                            f"outside the fingertip's domain {f.tip.domain}{start_note(f.tip)}; "
                            "move tip_contact or q0")
        if not start_inside(scene.object_surface, uv[2:]):
            problems.append(f"finger {i + 1}: the object contact solved to (u, v) = {tuple(map(float, uv[2:]))}, "
                            f"outside the object's domain {scene.object_surface.domain}"
                            f"{start_note(scene.object_surface)}")
    if problems:
        raise InvalidSceneError(problems)
    frames = [np.asarray(a, float) for a in fun(w, R)[2:]]
    eta = np.zeros((N, 5))
    for i, Fr in enumerate(frames):
        xf, yf, xo = Fr[:, 0], Fr[:, 1], Fr[:, 2]
        eta[i, :4] = w[kr + 3 + 4 * i:kr + 7 + 4 * i]
        eta[i, 4] = np.arctan2(-xo @ yf, xo @ xf)
    return {"q": w[:nQ].copy(), "pos": w[nQ:nQ + 3].copy() if scene.free else np.asarray(scene.position, float),
            "R": R, "eta": eta, "residual": res, "iterations": it}


def regular_state(scene: GraspScene3D, conf: dict) -> np.ndarray:
    """The regular formulation's state at rest from a solved configuration."""
    nQ = len(conf["q"])
    parts = [conf["q"], conf["pos"] if scene.free else [], rotations.quaternion(conf["R"]),
             np.zeros(nQ + (6 if scene.free else 3)), conf["eta"].ravel()]
    return np.concatenate([np.asarray(p, float) for p in parts])


def initial_state(scene: GraspScene3D) -> tuple[np.ndarray, dict]:
    """``(x0, info)``: the scene's consistent start in its formulation's state order.

    ``info``: ``r_bar0`` (m, mean fingertip centre), ``residual``, ``iterations``, ``V0``.
    """

    conf = solve_configuration(scene)
    regular = (dataclasses.replace(scene, formulation="regular", outputs=()) if scene.formulation != "regular"
               else scene)
    x = regular_state(regular, conf)
    system = derive_grasp3d(regular)
    fn = system.function("start_pieces", "pieces")
    geo = system.function("start_geometry", "geometry")
    centre = ca.Function("start_values", [system.x, system.p], [system.start_values])
    # the centre spring's rest point is what this solve finds: zero here (it does not enter
    # the geometry, nor A or M)
    p = np.array([regular.params[k] for k in regular.runtime]
                 + [0.0] * (len(regular.p_names) - len(regular.runtime)))
    info = {"residual": conf["residual"], "iterations": conf["iterations"],
            "r_bar0": np.asarray(centre(x, p), float).ravel()}
    nQ = len(conf["q"])
    nz = nQ + (7 if scene.free else 4)
    nV = nQ + (6 if scene.free else 3)
    V0 = np.zeros(nV)
    if scene.dq0 is not None and np.any(np.asarray(scene.dq0) != 0):
        pc = fn(x=x, p=p)
        A, M = np.asarray(pc["A"], float), np.asarray(pc["M"], float)
        _, sv, Vt = np.linalg.svd(A)
        Nb = Vt[int(np.sum(sv > 1e-12 * sv[0])):].T
        Vd = np.zeros(nV)
        Vd[:nQ] = scene.dq0
        V0 = Nb @ np.linalg.solve(Nb.T @ M @ Nb, Nb.T @ M @ Vd)
        x[nz:nz + nV] = V0
    info["V0"] = V0
    if scene.formulation == "regular":
        return x, info
    # paper formulation: frames with b along the contact's motion on the object
    pc = fn(x=x, p=p)
    sigma = np.asarray(pc["sigma"], float).ravel()
    g = geo(x=x, p=p)
    R = conf["R"]
    contact = []
    for i, f in enumerate(scene.fingers):
        uf, vf, uo, vo, _ = conf["eta"][i]
        so = scene.object_surface.evaluate(uo, vo)
        st = f.tip.evaluate(uf, vf)
        d = _tangent(scene.object_surface, uo, vo) @ sigma[5 * i + 2:5 * i + 4]
        if not np.linalg.norm(d) > 0:
            raise _contact_at_rest(i + 1, float(np.linalg.norm(d)), x, regular.state_names)
        b_w = R @ d / np.linalg.norm(R @ d)
        Pi = np.asarray(g[f"Pi{i + 1}"], float)
        no_w, nf_w = R @ so["normal"], Pi @ st["normal"]
        F0 = np.column_stack([no_w, b_w, np.cross(no_w, b_w)])
        F1 = np.column_stack([nf_w, b_w, np.cross(nf_w, b_w)])
        contact += [conf["eta"][i, :4], [0.0], (R.T @ F0).ravel(order="F"), (Pi.T @ F1).ravel(order="F")]
    xp = np.concatenate([x[:nz + nV], *[np.asarray(c, float) for c in contact]])
    return xp, info


def _contact_at_rest(k: int, speed: float, x: np.ndarray, state_names) -> MovingFrameSingularityError:
    """The paper formulation's start refused: contact ``k`` does not move (``speed`` = ``|s'|``, m/s)."""
    name = f"frame_denominator{k}"
    denominator = 0.0 if speed == 0 else math.nan      # -(kn0 + kn1) s'
    return MovingFrameSingularityError(
        0.0, x,
        f"the paper formulation cannot start at rest: contact {k} does not move at t = 0 (the speed "
        f"of its contact point over the object surface is |s'| = {speed:.3e} m/s), so {name} = "
        f"omega0.e0 + omega1.e1 = -(kn0 + kn1) s' = {denominator:.3e} rad/s, and the moving frames "
        f"need |{name}| > 0 at the start: their trace direction b is the direction of the contact's "
        "motion and the geodesic curvatures (31)-(32) divide by it (simulate() then stops where it "
        "falls to a small fraction of its start value, runtime.checks.FRAME_DENOMINATOR_RELATIVE). "
        "Give the scene initial joint speeds dq0 that move every contact (paper3d's default dq0 "
        "does), or use formulation='regular', which is regular at rest",
        state_names, denominator=denominator, threshold=0.0, contact=name)


def _tangent(surface, u, v) -> np.ndarray:
    """3 x 2 ``[S_u S_v]`` at ``(u, v)`` (surface frame)."""


    f = sp.lambdify((U, V), [surface.S_u, surface.S_v], "numpy")
    Su, Sv = f(u, v)
    return np.column_stack([np.asarray(Su, float).ravel(), np.asarray(Sv, float).ravel()])
