"""Grasp quality from contact points, normals and friction: the grasp matrix, force closure and
Ferrari and Canny's epsilon (``gs.quality``). Conventions: ``docs/conventions.md``, "Grasp
quality".

A contact at ``p`` with unit normal ``n`` (pointing into the object: the direction a finger
pushes) and Coulomb coefficient ``mu`` transmits the forces ``f = s (n + t)``, ``s >= 0``,
``t`` perpendicular to ``n`` with ``|t| <= mu``. Its wrench on the object about the point
``c`` (the object's centre: give it; default the contacts' mean) is ``(f, (p - c) x f /
rho)``: the torque divided by a length ``rho`` (default the largest ``|p - c|``), so that
forces and torques are measured alike.

- ``W``: the convex hull of every contact's wrenches of unit normal force (``s = 1``), the
  wrenches the grasp exerts when the normal forces sum to at most 1 (Ferrari and Canny's
  L1 grasp, 1992).
- ``epsilon``: the signed radius of the largest ball about the origin inside ``W``,
  ``min over unit directions u of h_W(u)``, ``h_W`` the support function; positive: the
  grasp resists every wrench (force closure), and a wrench of size ``epsilon`` in the worst
  direction needs normal forces summing to 1; zero: some wrench is resisted by nothing;
  negative: the origin lies that far outside ``W`` (every contact pushing one way).

In 2D a friction cone has two edges: ``W`` is a polygon's hull and ``epsilon`` exact. In 3D
the circular cone is bounded by the polyhedral cones of ``edges`` edges inscribed in it and
circumscribed about it: ``epsilon`` is given as ``(lower, upper)``, apart by at most
``mu (1 / cos(pi / edges) - 1)`` times the largest ``|(u_f + u_t x (p - c) / rho)|``.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

__all__ = ["Quality", "check_scales", "epsilon", "grasp_matrix", "internal_forces", "primitive_wrenches",
           "support", "two_contacts_squeeze"]

#: The edges of the polyhedral cones bounding a 3D friction cone (``epsilon``): the bounds
#: are then at most 8 % of ``mu`` apart. The hulls of 6D points grow fast: 3 contacts of 8
#: edges take a few ms, of 16 edges 25 ms, of 32 edges 0.2 s.
EDGES = 8


@dataclass(frozen=True)
class Quality:
    """``lower <= epsilon <= upper`` (equal in 2D); ``force_closure``: True when
    ``lower > 0``, False when ``upper <= 0``, None when the bounds straddle 0 (give more
    ``edges``)."""
    lower: float
    upper: float

    @property
    def force_closure(self) -> bool | None:
        if self.lower > 0:
            return True
        if self.upper <= 0:
            return False
        return None


def _checked(points, normals, mu, centre):
    p = np.atleast_2d(np.asarray(points, dtype=float))
    n = np.atleast_2d(np.asarray(normals, dtype=float))
    if p.ndim != 2 or p.shape[1] not in (2, 3) or n.shape != p.shape:
        raise ValueError(f"points {p.shape} and normals {n.shape}: give k contacts as two (k, 2) or "
                         "(k, 3) arrays")
    if not (np.all(np.isfinite(p)) and np.all(np.isfinite(n))):
        raise ValueError("points and normals must be finite")
    norms = np.linalg.norm(n, axis=1)
    if np.any(np.abs(norms - 1.0) > 1e-9):
        raise ValueError(f"normals must be unit vectors (norms {norms.tolist()})")
    m = coefficients(mu, len(p))
    c = p.mean(axis=0) if centre is None else np.asarray(centre, dtype=float)
    if c.shape != (p.shape[1],) or not np.all(np.isfinite(c)):
        raise ValueError(f"centre = {centre!r}: give a finite point of the contacts' dimension")
    return p, n, m, c


def _tangents(n: np.ndarray) -> tuple[np.ndarray, np.ndarray | None]:
    """Unit tangents of each normal: 2D one (``n`` turned by +90 degrees), 3D two."""
    if n.shape[1] == 2:
        return np.column_stack([-n[:, 1], n[:, 0]]), None
    helper = np.where(np.abs(n[:, :1]) < 0.9, [[1.0, 0.0, 0.0]], [[0.0, 1.0, 0.0]])
    t1 = np.cross(n, helper)
    t1 /= np.linalg.norm(t1, axis=1, keepdims=True)
    return t1, np.cross(n, t1)


def _wrench(p: np.ndarray, f: np.ndarray, c: np.ndarray, rho: float) -> np.ndarray:
    r = p - c
    if p.shape[-1] == 2:
        tau = r[..., 0] * f[..., 1] - r[..., 1] * f[..., 0]
        return np.concatenate([f, tau[..., None] / rho], axis=-1)
    return np.concatenate([f, np.cross(r, f) / rho], axis=-1)


def grasp_matrix(points, normals, centre=None, length: float | None = None) -> np.ndarray:
    """The grasp matrix ``G`` (2D: 3 x 2k, 3D: 6 x 3k): column block ``i`` maps contact
    ``i``'s force, in its frame (normal, then tangents: 2D ``n`` turned by +90 degrees; 3D two
    orthonormal tangents), to its wrench on the object about ``centre`` (torque divided by
    ``length``, default the largest ``|p - c|``)."""
    p, n, _, c = _checked(points, normals, 0.0, centre)
    rho = _length(p, c, length)
    t1, t2 = _tangents(n)
    frames = [n, t1] if t2 is None else [n, t1, t2]
    blocks = [np.stack([_wrench(p[i], e[i], c, rho) for e in frames], axis=1) for i in range(len(p))]
    return np.concatenate(blocks, axis=1)


def internal_forces(points, forces, centre=None) -> np.ndarray:
    """The internal part of the contact forces ``forces`` (k, d) at ``points`` (k, d), world
    frame: their projection on the null space of the wrench map (the forces with no net force
    and no net moment about ``centre``: the grasp's squeeze), ``(k, d)``. For two contacts
    it is ``+-((F1 - F2) . e) e / 2``, ``e`` the unit vector from one contact to the other."""
    p = np.atleast_2d(np.asarray(points, dtype=float))
    f = np.atleast_2d(np.asarray(forces, dtype=float))
    if p.ndim != 2 or p.shape[1] not in (2, 3) or f.shape != p.shape:
        raise ValueError(f"points {p.shape} and forces {f.shape}: give k contacts as two (k, 2) "
                         "or (k, 3) arrays")
    c = p.mean(axis=0) if centre is None else np.asarray(centre, dtype=float)
    d = p.shape[1]
    eye = np.eye(d)
    # the wrench map on world force components (the moment unscaled: the null space is the same)
    cols = [_wrench(np.broadcast_to(p[i], (d, d)), eye, c, 1.0).T for i in range(len(p))]
    G = np.concatenate(cols, axis=1)
    stacked = f.reshape(-1)
    internal = stacked - np.linalg.pinv(G, rcond=1e-12) @ (G @ stacked)
    return internal.reshape(p.shape)


def coefficients(mu, k: int) -> np.ndarray:
    """``mu`` as ``k`` friction coefficients (one for all, or one per contact), refused by name
    unless finite and >= 0."""
    try:
        m = np.broadcast_to(np.asarray(mu, dtype=float), (k,)).copy()
    except (TypeError, ValueError):
        raise ValueError(f"mu = {mu!r}: give finite coefficients >= 0, one or one per contact ({k})") from None
    if np.any(~np.isfinite(m)) or np.any(m < 0):
        raise ValueError(f"mu = {mu!r}: give finite coefficients >= 0, one or one per contact")
    return m


def check_scales(length: float | None, edges: int) -> None:
    """Refuse, by name, a torque scale ``length`` that is not None or a finite number > 0 (m),
    and ``edges`` that is not an integer >= 3 (``epsilon``'s arguments, checked whether or not a
    hull is built)."""
    if not (isinstance(edges, int) and edges >= 3):
        raise ValueError(f"edges = {edges!r}: give an integer >= 3")
    if length is not None:
        _check_length(length)


def _check_length(length) -> None:
    try:
        ok = math.isfinite(length) and length > 0
    except TypeError:
        ok = False
    if not ok:
        raise ValueError(f"length = {length!r}: give a torque scale > 0 (m)")


def _length(p: np.ndarray, c: np.ndarray, length: float | None) -> float:
    if length is not None:
        _check_length(length)
        return float(length)
    rho = float(np.max(np.linalg.norm(p - c, axis=1)))
    return rho if rho > 0 else 1.0


def primitive_wrenches(points, normals, mu, centre=None, length: float | None = None,
                       edges: int = EDGES, scale: float = 1.0) -> np.ndarray:
    """The wrenches of unit normal force on the edges of each contact's friction cone (2D:
    its two edges; 3D: ``edges`` edges, the tangential part times ``scale``: 1 inscribed,
    ``1 / cos(pi / edges)`` circumscribed), one row each."""
    p, n, m, c = _checked(points, normals, mu, centre)
    rho = _length(p, c, length)
    t1, t2 = _tangents(n)
    rows = []
    for i in range(len(p)):
        if t2 is None:
            dirs = [n[i] + m[i] * t1[i], n[i] - m[i] * t1[i]]
        else:
            phi = 2 * np.pi * np.arange(edges) / edges
            dirs = n[i] + scale * m[i] * (np.cos(phi)[:, None] * t1[i] + np.sin(phi)[:, None] * t2[i])
        rows.append(_wrench(np.broadcast_to(p[i], np.shape(dirs)), np.asarray(dirs), c, rho))
    return np.concatenate(rows, axis=0)


def _distance(w: np.ndarray) -> float:
    """The distance from the origin to the hull of the rows of ``w``: the least ``|w^T l|``
    over weights ``l >= 0`` summing to 1 (non-negative least squares with the sum as one more,
    heavily weighted row; the weights then scaled to sum to 1 exactly)."""
    from scipy.optimize import nnls  # noqa: PLC0415 - only for an origin outside the hull

    scale = float(np.max(np.abs(w))) or 1.0
    heavy = 1e4 * scale
    a = np.vstack([w.T, np.full((1, len(w)), heavy)])
    b = np.concatenate([np.zeros(w.shape[1]), [heavy]])
    lam, _ = nnls(a, b, maxiter=50 * len(w))
    lam = lam / lam.sum()
    return float(np.linalg.norm(w.T @ lam))


def _inradius(w: np.ndarray) -> float:
    """``min over unit u of h(u)`` for the hull of the rows of ``w``: with the origin inside,
    the nearest facet's distance; outside, minus the origin's distance from the hull (to
    1e-8 of the wrenches' size); a hull of lower dimension than the space (some ``u`` has
    ``h(u) = h(-u) = 0``) holding the origin: 0."""
    from scipy.spatial import ConvexHull, QhullError  # noqa: PLC0415 - 0.2 s, only here

    outside = _distance(w)
    if outside > 1e-9 * (float(np.max(np.abs(w))) or 1.0):
        return -outside
    _, sv, _ = np.linalg.svd(w, full_matrices=False)
    if int(np.sum(sv > 1e-12 * max(sv[0], 1e-300))) < w.shape[1]:
        return 0.0
    try:
        hull = ConvexHull(w)
    except QhullError:  # flat within qhull's precision
        return 0.0
    return max(0.0, float(np.min(-hull.equations[:, -1])))  # unit normals: planes' distances


def support(points, normals, mu, directions, centre=None, length: float | None = None) -> np.ndarray:
    """``h_W(u)`` of the smooth friction cones for each row ``u`` of ``directions`` (exact:
    ``max over contacts of a.n + mu |a - (a.n) n|``, ``a`` the force that ``u`` pairs with a
    contact's force: ``u_f + (u_t x (p - c)) / rho`` in 3D, ``u_f + u_t (p - c)^perp / rho``
    in 2D)."""
    p, n, m, c = _checked(points, normals, mu, centre)
    rho = _length(p, c, length)
    u = np.atleast_2d(np.asarray(directions, dtype=float))
    d = p.shape[1]
    r = (p - c) / rho
    if d == 2:  # u_t (r x f) = f . (u_t * (-r_y, r_x))
        a = u[:, None, :2] + u[:, None, 2:3] * np.stack([-r[:, 1], r[:, 0]], axis=1)[None]
    else:  # u_t . (r x f) = f . (u_t x r)
        a = u[:, None, :3] + np.cross(u[:, None, 3:], r[None])
    an = np.einsum("ski,ki->sk", a, n)
    at = np.linalg.norm(a - an[..., None] * n[None], axis=-1)
    return np.max(an + m[None] * at, axis=1)


def two_contacts_squeeze(points, normals, mu) -> np.ndarray:
    """For two 3D point contacts, row by row (``points``, ``normals``: ``(..., 2, 3)``;
    ``mu``: one coefficient or one per contact): whether the line between them lies in both
    friction cones, one contact pushing along it and the other back (Nguyen's squeeze), i.e.
    whether the origin lies in ``W``. Two point contacts never close a 3D grasp: the pure
    spin about that line, with the force that makes it a spin about the centre, pairs with
    every contact force to 0 both ways (``h_W(u) = h_W(-u) = 0``), so epsilon <= 0 always;
    it is exactly 0 where they squeeze, and the origin's distance outside ``W`` (< 0)
    elsewhere. False for coincident points."""
    p = np.asarray(points, dtype=float)
    n = np.asarray(normals, dtype=float)
    if p.ndim < 2 or p.shape[-2:] != (2, 3) or n.shape != p.shape:
        raise ValueError(f"points {p.shape} and normals {n.shape}: give two 3D contacts as two "
                         "(2, 3) arrays, or (..., 2, 3) for many rows")
    if not (np.all(np.isfinite(p)) and np.all(np.isfinite(n))):
        raise ValueError("points and normals must be finite")
    if np.any(np.abs(np.sqrt(np.einsum("...i,...i->...", n, n)) - 1.0) > 1e-9):
        raise ValueError("normals must be unit vectors")
    m = np.asarray(mu, dtype=float)
    if m.shape not in ((), (1,), (2,)) or np.any(~np.isfinite(m)) or np.any(m < 0):
        raise ValueError(f"mu = {mu!r}: give a finite coefficient >= 0, or one per contact")
    return squeezes(p, n, np.broadcast_to(m, (2,)))


def squeezes(p: np.ndarray, n: np.ndarray, m: np.ndarray) -> np.ndarray:
    """``two_contacts_squeeze`` of arrays made as it requires (finite, the normals unit; ``m``:
    one coefficient per contact): its own checked arrays, and grasp quality along a run, whose
    contacts come from the surface's own frames."""
    d = p[..., 1, :] - p[..., 0, :]
    dd = np.einsum("...i,...i->...", d, d)
    # whether d, and -d, lies in each contact's cone (``v.n >= 0`` and ``|v - (v.n) n| <= mu
    # v.n``): for a unit n, ``|v - (v.n) n|^2 = |v|^2 - (v.n)^2``, so the cone holds the line
    # iff ``|d|^2 <= (1 + mu^2) (d.n)^2`` (no difference taken), d itself where ``d.n >= 0``
    # and -d where ``d.n <= 0``
    forward, backward = [], []
    for i in range(2):
        vn = np.einsum("...i,...i->...", d, n[..., i, :])
        inside = dd <= (1.0 + m[i] * m[i]) * (vn * vn)
        forward.append(inside & (vn >= 0))
        backward.append(inside & (vn <= 0))
    return (dd > 0) & ((forward[0] & backward[1]) | (backward[0] & forward[1]))


def epsilon(points, normals, mu, centre=None, length: float | None = None,
            edges: int = EDGES) -> Quality:
    """Ferrari and Canny's epsilon of the contacts (module docstring), as ``Quality(lower,
    upper)``: exact in 2D; in 3D the values of the polyhedral cones of ``edges`` edges
    inscribed in the friction cones (``lower``: their hull lies inside ``W``) and circumscribed
    about them (``upper``: their hull holds ``W``); exact (0, 0) for two 3D contacts that
    squeeze (``two_contacts_squeeze``)."""
    check_scales(length, edges)
    p, n, m, c = _checked(points, normals, mu, centre)
    if p.shape == (2, 3) and bool(squeezes(p, n, m)):
        return Quality(0.0, 0.0)
    inner = _inradius(primitive_wrenches(p, n, m, c, length, edges))
    if p.shape[1] == 2:
        return Quality(inner, inner)
    outer = _inradius(primitive_wrenches(p, n, m, c, length, edges,
                                         scale=1.0 / math.cos(math.pi / edges)))
    return Quality(inner, max(inner, outer))
