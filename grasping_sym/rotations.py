"""Rotations in 3D on NumPy alone: unit quaternions ``(w, x, y, z)``, rotation matrices and
rotation vectors. SciPy's ``Rotation`` computes the same, but importing it costs every build's
process 0.3 s (SciPy's linear algebra and spatial modules), which no other step of a build
needs; ``tests/test_rotations.py`` checks these against it."""
from __future__ import annotations

import math

import numpy as np


def matrices(quaternions) -> np.ndarray:
    """``(n, 3, 3)`` body-to-world rotation matrices of the quaternions ``(w, x, y, z)``
    (rows ``(n, 4)``, or one ``(4,)``; each normalised first)."""
    q = np.atleast_2d(np.asarray(quaternions, dtype=float))
    q = q / np.linalg.norm(q, axis=1, keepdims=True)
    w, x, y, z = q.T
    xx, yy, zz, xy, xz, yz, wx, wy, wz = x * x, y * y, z * z, x * y, x * z, y * z, w * x, w * y, w * z
    R = np.empty((len(q), 3, 3))  # written in place: half the time of stacking rows of columns
    R[:, 0, 0], R[:, 0, 1], R[:, 0, 2] = 1 - 2 * (yy + zz), 2 * (xy - wz), 2 * (xz + wy)
    R[:, 1, 0], R[:, 1, 1], R[:, 1, 2] = 2 * (xy + wz), 1 - 2 * (xx + zz), 2 * (yz - wx)
    R[:, 2, 0], R[:, 2, 1], R[:, 2, 2] = 2 * (xz - wy), 2 * (yz + wx), 1 - 2 * (xx + yy)
    return R


def quaternion(R) -> np.ndarray:
    """The unit quaternion ``(w, x, y, z)``, ``w >= 0``, of the rotation matrix ``R`` (3x3):
    from the largest of ``1 + trace`` and ``1 + 2 R_ii - trace`` (Shepperd's choice: no
    component is found by dividing by a small one)."""
    R = np.asarray(R, dtype=float)
    trace = R[0, 0] + R[1, 1] + R[2, 2]
    i = int(np.argmax([R[0, 0], R[1, 1], R[2, 2], trace]))
    if i == 3:
        q = np.array([1.0 + trace, R[2, 1] - R[1, 2], R[0, 2] - R[2, 0], R[1, 0] - R[0, 1]])
    else:
        j, k = (i + 1) % 3, (i + 2) % 3
        q = np.empty(4)
        q[0] = R[k, j] - R[j, k]
        q[1 + i] = 1.0 - trace + 2.0 * R[i, i]
        q[1 + j] = R[j, i] + R[i, j]
        q[1 + k] = R[k, i] + R[i, k]
    q /= np.linalg.norm(q)
    return q if q[0] >= 0 else -q


def from_rotvec(w) -> np.ndarray:
    """The rotation matrix of the rotation vector ``w`` (axis times angle, rad): Rodrigues'
    ``I + a [w] + b [w]^2`` with ``a = sin t / t``, ``b = (1 - cos t) / t^2``, ``t = |w|``
    (their series below ``t = 1e-4``, where the closed forms lose digits)."""
    w = np.asarray(w, dtype=float)
    t2 = float(w @ w)
    t = math.sqrt(t2)
    if t < 1e-4:
        a, b = 1.0 - t2 / 6.0 + t2 * t2 / 120.0, 0.5 - t2 / 24.0 + t2 * t2 / 720.0
    else:
        a, b = math.sin(t) / t, (1.0 - math.cos(t)) / t2
    K = np.array([[0.0, -w[2], w[1]], [w[2], 0.0, -w[0]], [-w[1], w[0], 0.0]])
    return np.eye(3) + a * K + b * (K @ K)
