"""Grasp quality along a run of a grasp of a free object (``BuiltModel.grasp_quality``): at
every output time, the exact contact points and normals, from the object's pose and each
contact's coordinates on the object (3D: ``u_o{i}, v_o{i}`` on its surface; 2D: ``u1_{i}``
on its contour), and ``gs.quality``'s epsilon and force closure of them; from the run's
contact forces (its outputs), the smallest cone margin ``mu f - |F_t|`` over the contacts
and the internal (squeezing) force, N. Conventions: ``docs/conventions.md``, "Grasp quality".
"""
from __future__ import annotations

import numpy as np

from grasping_sym import quality
from grasping_sym.rotations import matrices

__all__ = ["contact_forces", "contacts_along", "grasp_quality"]


_POSE = ("x", "y", "z", "qw", "qx", "qy", "qz")


def _grasp3d(model, result) -> bool:
    """Whether ``result`` is a run of a 3D grasp of a free object (else a free 2D object's, or
    refused by name)."""
    scene = model.scene
    if getattr(scene, "kind", None) in ("planar", "planar_modes") and scene.free:
        return False
    if scene is None or getattr(scene, "kind", None) != "grasp3d" or not set(_POSE) <= set(result.state_names):
        raise ValueError("grasp_quality reads a grasp of a free object (a model of "
                         "gs.scenes.paper3d, a GraspScene3D whose state has x, y, z, qw, qx, qy, "
                         "qz, or a 2D scene with support='free') made by gs.build; this model is "
                         "not one")
    return True


def _local_frames(model, result) -> dict[str, np.ndarray]:
    """Per contact and row of a 3D grasp's ``result``, its ``point`` on the object and the
    frame ``normal`` (outward), ``x``, ``y`` there, in the object's frame (``(k, n, 3)``
    each): every contact's rows in one evaluation of the surface."""
    scene, names = model.scene, list(result.state_names)
    X = np.asarray(result.x, dtype=float)
    k, n = len(scene.fingers), len(X)
    charts = [getattr(result, "charts", {}).get(f"chart_o{i}") for i in range(1, k + 1)]
    geo = scene.object_surface.evaluate_frame(
        np.concatenate([X[:, names.index(f"u_o{i}")] for i in range(1, k + 1)]),
        np.concatenate([X[:, names.index(f"v_o{i}")] for i in range(1, k + 1)]),
        chart=None if all(ch is None for ch in charts) else
        np.concatenate([np.zeros(n, dtype=int) if ch is None else ch for ch in charts]))
    return {key: geo[key].reshape(k, n, 3) for key in _FRAME}


#: A contact's point and frame, in this order.
_FRAME = ("point", "normal", "x", "y")


def _frames(model, result, local=None, rows=None) -> tuple[np.ndarray, list[dict[str, np.ndarray]]]:
    """``(centres, frames)``: the object's centre ``(n, 3)`` at every row of ``result`` (or at
    ``rows``) and, per contact, its surface point and its frame ``normal`` (outward), ``x``,
    ``y`` carried to the world (``(n, 3)`` each); ``local``: ``_local_frames``' (made here
    when not given)."""
    names = list(result.state_names)
    X = np.asarray(result.x, dtype=float)
    if not _grasp3d(model, result):
        return _frames_planar(model.scene, names, X if rows is None else X[rows])
    local = _local_frames(model, result) if local is None else local
    if rows is not None:
        X, local = X[rows], {key: v[:, rows] for key, v in local.items()}
    c = X[:, [names.index(k) for k in _POSE[:3]]]
    rot = matrices(X[:, [names.index(k) for k in _POSE[3:]]])
    frames = []
    for i in range(len(local["point"])):
        # the four vectors of every row turned at once: (n, 3, 3) @ (n, 3, 4)
        world = rot @ np.stack([local[key][i] for key in _FRAME], axis=-1)
        frames.append({"point": c + world[..., 0], "normal": world[..., 1], "x": world[..., 2],
                       "y": world[..., 3]})
    return c, frames


def _frames_planar(scene, names: list[str], X: np.ndarray):
    """``_frames`` of a free 2D object (docs/conventions.md section 13): its contour point at
    each contact, ``Om + Rot(-theta) c1(u1)``, the unit tangent ``b1 = Rot(-theta) T1`` (its
    ``x``) and the outward normal ``-n1 = (-b1y, b1x)`` (the object contour runs clockwise)."""
    c = X[:, [names.index("x"), names.index("y")]]
    th = X[:, names.index("theta")]
    cos, sin = np.cos(th), np.sin(th)

    def turned(v):  # Rot(-theta) v, row by row
        return np.column_stack([cos * v[:, 0] + sin * v[:, 1], -sin * v[:, 0] + cos * v[:, 1]])

    one = scene.n_fingers == 1
    frames = []
    for i in range(1, scene.n_fingers + 1):
        key = ("s" if scene.shared_parameter else "u1") if one else f"u1_{i}"
        ev = scene.object.evaluate(X[:, names.index(key)])
        shape = th.shape
        point = np.column_stack([np.broadcast_to(ev["x"], shape), np.broadcast_to(ev["y"], shape)])
        tangent = np.column_stack([np.broadcast_to(ev["dx"], shape), np.broadcast_to(ev["dy"], shape)])
        b1 = turned(tangent / np.linalg.norm(tangent, axis=1, keepdims=True))
        frames.append({"point": c + turned(point), "normal": np.column_stack([-b1[:, 1], b1[:, 0]]),
                       "x": b1})
    return c, frames


def contacts_along(model, result, frames=None) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``(centres, points, normals)`` at every row of ``result``: the object's centre
    ``(n, 3)``, the contacts' points ``(n, k, 3)`` and their unit normals into the object
    ``(n, k, 3)`` (the surface's outward normal, turned around), world frame, m. ``frames``:
    ``_frames``' (made here when not given)."""
    c, frames = _frames(model, result) if frames is None else frames
    return c, np.stack([f["point"] for f in frames], axis=1), _inward(np.stack([f["normal"] for f in frames], axis=1))


def _inward(normals: np.ndarray) -> np.ndarray:
    """Outward normals ``(n, k, 3)`` as unit normals into the object."""
    return normals / -np.sqrt(np.einsum("nki,nki->nk", normals, normals))[..., None]


def grasp_quality(model, result, mu=None, *, length: float | None = None,
                  edges: int = quality.EDGES) -> dict[str, np.ndarray]:
    """``{"t", "epsilon_lower", "epsilon_upper", "force_closure", "cone_margin_min",
    "internal_force"}`` along ``result`` (module docstring): ``force_closure`` 1 (closed), 0
    (not) or NaN (the bounds straddle 0); ``mu``: one coefficient or one per contact (default
    the model's friction law); ``length``: the torque scale (default the largest distance of a
    contact from the centre at the start). ``cone_margin_min`` (N) and ``internal_force`` (N:
    the norm of the contact forces' internal part, ``quality.internal_forces``; two fingers
    squeezing with ``F`` along the line between the contacts: ``sqrt(2) F``) need the run's
    outputs (``f{i}``, ``lam{i}``, ``eta{i}``)."""
    if mu is None:
        law = getattr(model, "friction", None)
        if law is None:
            raise ValueError("grasp_quality needs a friction coefficient: give mu (one, or one "
                             "per contact), or build the scene with friction=gs.contact.coulomb(mu)")
        mu = law.mu
    if _grasp3d(model, result) and len(model.scene.fingers) == 2:
        return _two_contacts(model, result, mu, length, edges)
    frames = _frames(model, result)
    centres, points, normals = contacts_along(model, result, frames)
    mus = quality.coefficients(mu, points.shape[1])
    if length is None:
        length = float(np.max(np.linalg.norm(points[0] - centres[0], axis=1)))
    quality.check_scales(length, edges)
    lower, upper, closed = _by_hulls(points, normals, mus, centres, length, edges,
                                     np.arange(len(points)), len(points))
    return _with_forces(model, result, mus, lower, upper, closed,
                        lambda cols: _internal_norms(centres, points, contact_forces(model, result, frames)))


def _by_hulls(points, normals, mus, centres, length: float, edges: int, rows, n: int):
    """``(lower, upper, closed)`` over ``n`` rows: epsilon's bounds and force closure by the
    hulls (``quality.epsilon``) at ``rows`` (``points``, ``normals``, ``centres``: theirs, in
    that order), exactly 0 and not closed at the others."""
    lower, upper, closed = np.zeros(n), np.zeros(n), np.zeros(n)
    for j, row in enumerate(rows):
        q = quality.epsilon(points[j], normals[j], mus, centre=centres[j], length=length, edges=edges)
        lower[row], upper[row] = q.lower, q.upper
        fc = q.force_closure
        closed[row] = np.nan if fc is None else float(fc)
    return lower, upper, closed


def _with_forces(model, result, mus, lower, upper, closed, internal) -> dict:
    """``grasp_quality``'s result: epsilon's bounds and force closure, and from the run's force
    outputs (where it has them: ``_force_columns``) the smallest cone margin and the internal
    force (``internal(columns)``)."""
    out = {"t": np.asarray(result.t, dtype=float).copy(), "epsilon_lower": lower,
           "epsilon_upper": upper, "force_closure": closed}
    cols = _force_columns(model, result)
    if cols is not None:
        out["cone_margin_min"] = _margins(result, cols, mus)
        out["internal_force"] = internal(cols)
    return out


def _two_contacts(model, result, mu, length: float | None, edges: int) -> dict:
    """``grasp_quality`` of a 3D grasp of two contacts. Whether they squeeze (epsilon exactly
    0: ``quality.two_contacts_squeeze``) and their internal force depend on the points and
    normals relative to each other alone, so every row is read in the object's own frame, no
    row turned to the world; the rows that do not squeeze are turned and take the hulls
    (whose polyhedral cones depend on the world's axes), as every row of another grasp, with
    the default torque scale from the first row in the world."""
    local = _local_frames(model, result)
    n = local["point"].shape[1]
    mus = quality.coefficients(mu, 2)
    quality.check_scales(length, edges)
    points = np.swapaxes(local["point"], 0, 1)                 # (n, 2, 3), from the centre
    normals = _inward(np.swapaxes(local["normal"], 0, 1))
    rows = np.flatnonzero(~quality.squeezes(points, normals, mus))
    lower, upper, closed = np.zeros(n), np.zeros(n), np.zeros(n)
    if len(rows):
        if length is None:
            c0, points0, _ = contacts_along(model, result, _frames(model, result, local, rows=[0]))
            length = float(np.max(np.linalg.norm(points0[0] - c0[0], axis=1)))
        c, p, nn = contacts_along(model, result, _frames(model, result, local, rows=rows))
        lower, upper, closed = _by_hulls(p, nn, mus, c, length, edges, rows, n)
    return _with_forces(model, result, mus, lower, upper, closed,
                        lambda cols: _squeezing(model, result, local, cols))


def _margins(result, cols, mus) -> np.ndarray:
    """The smallest cone margin ``mu f - |F_t|`` over the contacts at every row, ``|F_t|`` of
    the tangential components in the contact's orthonormal frame (exact)."""
    f_n = np.column_stack([result[c[0]] for c in cols])
    f_t = np.column_stack([np.abs(result[c[1]]) if len(c) == 2 else np.hypot(result[c[1]], result[c[2]])
                           for c in cols])
    return np.min(mus[None] * f_n - f_t, axis=1)


def _squeezing(model, result, local, cols) -> np.ndarray:
    """``_internal_norms`` of two 3D contacts, in the object's frame: ``|(F1 - F2) . e| /
    sqrt(2)`` with each ``F . e`` from its force's components along the contact's frame
    (``contact_forces``) dotted with ``e``, no force vector formed; coincident points (no
    ``e``) as ``_internal_norms`` takes them."""
    names = list(result.state_names)
    X = np.asarray(result.x, dtype=float)
    d = local["point"][1] - local["point"][0]
    dist = np.sqrt(np.einsum("ni,ni->n", d, d))
    apart = dist > 0
    e = d / np.where(apart, dist, 1.0)[:, None]
    along = []
    for i, (f, lam, eta) in enumerate(cols):
        on_x, on_y = _on_object_axes(result, X[:, names.index(f"psi{i + 1}")], lam, eta)
        along.append(-result[f] * np.einsum("ni,ni->n", local["normal"][i], e)
                     + on_x * np.einsum("ni,ni->n", local["x"][i], e)
                     + on_y * np.einsum("ni,ni->n", local["y"][i], e))
    out = np.abs(along[0] - along[1]) / np.sqrt(2.0)
    if not apart.all():
        frames = [{key: local[key][i] for key in _FRAME} for i in range(2)]
        rest = _internal_norms(np.zeros((len(X), 3)), np.swapaxes(local["point"], 0, 1),
                               contact_forces(model, result, (None, frames)))
        out[~apart] = rest[~apart]
    return out


def _internal_norms(centres, points, forces) -> np.ndarray:
    """The norm of the contact forces' internal part at every row (``quality.internal_forces``);
    for two contacts apart, every row at once: ``|(F1 - F2) . e| / sqrt(2)``, ``e`` the unit
    vector between them (the part ``+-((F1 - F2) . e) e / 2`` at each)."""
    out = np.full(len(points), np.nan)
    general = np.ones(len(points), dtype=bool)
    if points.shape[1] == 2:
        d = points[:, 1] - points[:, 0]
        dist = np.linalg.norm(d, axis=1)
        general = ~(dist > 0)
        e = d / np.where(general, 1.0, dist)[:, None]
        out[~general] = np.abs(np.einsum("ni,ni->n", forces[:, 0] - forces[:, 1], e))[~general] / np.sqrt(2.0)
    for row in np.flatnonzero(general):
        out[row] = np.linalg.norm(quality.internal_forces(points[row], forces[row], centres[row]))
    return out


def _force_columns(model, result) -> list[tuple[str, ...]] | None:
    """Per contact, the run's outputs of its force: ``(f{i}, lam{i}, eta{i})`` in 3D (the
    normal force and the tangential ones along the fingertip's ``x_f``, ``y_f``), ``(f, lam)``
    in 2D (with several fingers ``f{i}``, ``lam{i}``; with contact modes ``normal_force{i}``,
    ``lam{i}``); None when the run has no such outputs."""
    if getattr(model.scene, "kind", None) in ("planar", "planar_modes"):
        n = model.scene.n_fingers
        for f_name in ("f", "normal_force"):
            numbered = n > 1 or f"{f_name}1" in result.outputs
            cols = [(f"{f_name}{i}", f"lam{i}") for i in range(1, n + 1)] if numbered else [(f_name, "lam")]
            if all(all(c in result.outputs for c in row) for row in cols):
                return cols
        return None
    k = len(model.scene.fingers) if model.scene is not None else 0
    cols = [(f"f{i}", f"lam{i}", f"eta{i}") for i in range(1, k + 1)]
    return cols if all(all(n in result.outputs for n in row) for row in cols) else None


def contact_forces(model, result, frames=None) -> np.ndarray | None:
    """The contact forces on the object ``(n, k, 3)``, world frame, N, from the run's outputs:
    ``f{i} n + lam{i} x_f + eta{i} y_f`` (docs/conventions.md sections 6 and 10: ``n`` the
    fingertip's outward normal, into the object; ``x_f = cos(psi) x_o - sin(psi) y_o`` and
    ``y_f = -sin(psi) x_o - cos(psi) y_o`` the fingertip's tangents, from the object's
    ``x_o, y_o`` and the frame angle ``psi{i}``); in 2D ``(n, k, 2)``, ``f{i} n1 + lam{i} b1``
    (section 13). None when the run has no such outputs. ``frames``: ``_frames``' (made here
    when not given)."""
    cols = _force_columns(model, result)
    if cols is None:
        return None
    _, frames = _frames(model, result) if frames is None else frames
    if len(cols[0]) == 2:
        return np.stack([-result[f][:, None] * fr["normal"] + result[lam][:, None] * fr["x"]
                         for (f, lam), fr in zip(cols, frames)], axis=1)
    names = list(result.state_names)
    X = np.asarray(result.x, dtype=float)
    out = []
    for i, ((f, lam, eta), fr) in enumerate(zip(cols, frames), start=1):
        on_x, on_y = _on_object_axes(result, X[:, names.index(f"psi{i}")], lam, eta)
        out.append(-result[f][:, None] * fr["normal"] + on_x[:, None] * fr["x"] + on_y[:, None] * fr["y"])
    return np.stack(out, axis=1)


def _on_object_axes(result, psi: np.ndarray, lam: str, eta: str) -> tuple[np.ndarray, np.ndarray]:
    """``lam x_f + eta y_f`` (the outputs ``lam``, ``eta`` along the fingertip's tangents) on
    the object's ``x_o, y_o``: ``x_f = cos(psi) x_o - sin(psi) y_o``, ``y_f = -sin(psi) x_o -
    cos(psi) y_o`` give ``(lam cos - eta sin, -(lam sin + eta cos))``."""
    cos, sin = np.cos(psi), np.sin(psi)
    a, b = result[lam], result[eta]
    return a * cos - b * sin, -(a * sin + b * cos)
