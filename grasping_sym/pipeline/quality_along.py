"""Grasp quality along a run of a 3D grasp (``BuiltModel.grasp_quality``): at every output
time, the exact contact points and normals, from the object's pose and each contact's
surface coordinates (``u_o{i}, v_o{i}``) on the object's surface, and ``gs.quality``'s
epsilon and force closure of them; with a friction coefficient, the smallest cone margin
``mu f - |F_t|`` over the contacts (N). Conventions: ``docs/conventions.md``, "Grasp quality".
"""
from __future__ import annotations

import numpy as np

from grasping_sym import quality

__all__ = ["contacts_along", "grasp_quality"]


def _rotations(qs: np.ndarray) -> np.ndarray:
    """Body-to-world rotation matrices of the quaternions ``(w, x, y, z)`` (rows)."""
    q = qs / np.linalg.norm(qs, axis=1, keepdims=True)
    w, x, y, z = q.T
    return np.stack([
        np.stack([1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)], axis=-1),
        np.stack([2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)], axis=-1),
        np.stack([2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)], axis=-1),
    ], axis=1)


def contacts_along(model, result) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``(centres, points, normals)`` at every row of ``result``: the object's centre
    ``(n, 3)``, the contacts' points ``(n, k, 3)`` and their unit normals into the object
    ``(n, k, 3)`` (the surface's outward normal, turned around), world frame, m."""
    scene = model.scene
    names = list(result.state_names)
    pose = ("x", "y", "z", "qw", "qx", "qy", "qz")
    if scene is None or getattr(scene, "kind", None) != "grasp3d" or not set(pose) <= set(names):
        raise ValueError("grasp_quality reads a 3D grasp of a free object (a model of "
                         "gs.scenes.paper3d or a GraspScene3D whose state has x, y, z, qw, qx, qy, "
                         "qz) made by gs.build; this model is not one")
    X = np.asarray(result.x, dtype=float)
    c = X[:, [names.index(k) for k in pose[:3]]]
    rot = _rotations(X[:, [names.index(k) for k in pose[3:]]])
    k = len(scene.fingers)
    points, normals = [], []
    for i in range(1, k + 1):
        u, v = X[:, names.index(f"u_o{i}")], X[:, names.index(f"v_o{i}")]
        geo = scene.object_surface.evaluate(u, v)
        points.append(c + np.einsum("nij,nj->ni", rot, geo["point"]))
        out = np.einsum("nij,nj->ni", rot, geo["normal"])
        normals.append(-out / np.linalg.norm(out, axis=1, keepdims=True))
    return c, np.stack(points, axis=1), np.stack(normals, axis=1)


def grasp_quality(model, result, mu=None, *, length: float | None = None,
                  edges: int = quality.EDGES) -> dict[str, np.ndarray]:
    """``{"t", "epsilon_lower", "epsilon_upper", "force_closure", "cone_margin_min"}`` along
    ``result`` (module docstring): ``force_closure`` 1 (closed), 0 (not) or NaN (the bounds
    straddle 0); ``mu``: one coefficient or one per contact (default the model's friction
    law); ``length``: the torque scale (default the largest distance of a contact from the
    centre at the start). ``cone_margin_min`` needs the run's outputs (``f{i}``, ``lam{i}``,
    ``eta{i}``)."""
    if mu is None:
        law = getattr(model, "friction", None)
        if law is None:
            raise ValueError("grasp_quality needs a friction coefficient: give mu (one, or one "
                             "per contact), or build the scene with friction=gs.contact.coulomb(mu)")
        mu = law.mu
    centres, points, normals = contacts_along(model, result)
    k = points.shape[1]
    mus = np.broadcast_to(np.asarray(mu, dtype=float), (k,))
    if length is None:
        length = float(np.max(np.linalg.norm(points[0] - centres[0], axis=1)))
    lower, upper, closed = [], [], []
    for c, p, n in zip(centres, points, normals):
        q = quality.epsilon(p, n, mus, centre=c, length=length, edges=edges)
        lower.append(q.lower)
        upper.append(q.upper)
        fc = q.force_closure
        closed.append(np.nan if fc is None else float(fc))
    out = {"t": np.asarray(result.t, dtype=float).copy(), "epsilon_lower": np.array(lower),
           "epsilon_upper": np.array(upper), "force_closure": np.array(closed)}
    names = [(f"f{i}", f"lam{i}", f"eta{i}") for i in range(1, k + 1)]
    if all(all(n in result.outputs for n in row) for row in names):
        margins = [mus[i] * result[f] - np.hypot(result[lam], result[eta])
                   for i, (f, lam, eta) in enumerate(names)]
        out["cone_margin_min"] = np.min(np.stack(margins, axis=1), axis=1)
    return out
