"""Where a finger chain's fingertip is, in NumPy: for choosing a scene's start guesses
(``model.chains``' conventions; the derivation's ``r`` and ``Pi``, ``derive.spatial``)."""
from __future__ import annotations

import math

import numpy as np

from grasping_sym.model.chains import FingerChain


def _rotation(axis, angle: float) -> np.ndarray:
    """Rodrigues' rotation by ``angle`` (rad) about ``axis`` (normalised)."""
    a = np.asarray(axis, dtype=float) / np.linalg.norm(axis)
    k = np.array([[0.0, -a[2], a[1]], [a[2], 0.0, -a[0]], [-a[1], a[0], 0.0]])
    return np.eye(3) + math.sin(angle) * k + (1.0 - math.cos(angle)) * k @ k


def tip_pose(chain: FingerChain, q) -> tuple[np.ndarray, np.ndarray]:
    """m, 3x3: the fingertip centre ``r`` and frame ``Pi`` of ``chain`` at the joint angles
    ``q`` (rad): ``R_k = R_(k-1) F_k Rot(a_k, q_k)``, ``p_(k+1) = p_k + R_k vector_k``."""
    q = np.asarray(q, dtype=float)
    if q.shape != (chain.n,):
        raise ValueError(f"q = {q.tolist()} must have {chain.n} angles (rad), one per joint of "
                         f"finger {chain.name} ({', '.join(chain.joint_names)})")
    R, p = np.eye(3), np.array(chain.base, dtype=float)
    for joint, angle in zip(chain.joints, q):
        if joint.frame is not None:
            R = R @ np.array(joint.frame)
        R = R @ _rotation(joint.axis, float(angle))
        p = p + R @ np.array(joint.vector)
    return p + R @ np.array(chain.tip_offset), R @ np.array(chain.tip_rotation)


def facing(direction) -> tuple[float, float]:
    """rad: the longitude and latitude ``(u, v) = (atan2(y, x), asin(z))`` of the unit
    ``direction``: the point of a sphere's chart (``surface_library.sphere``) and of a
    superquadric's (a radial chart) that faces it; a start guess for an ellipsoid's."""
    d = np.asarray(direction, dtype=float)
    d = d / np.linalg.norm(d)
    return math.atan2(d[1], d[0]), math.asin(max(-1.0, min(1.0, float(d[2]))))
