"""``grasping_sym.rotations`` against SciPy's ``Rotation`` (the oracle): quaternions to
matrices, matrices to quaternions (each of Shepperd's four branches, and ``w >= 0``), rotation
vectors to matrices (large, small and tiny angles, half a turn)."""
from __future__ import annotations

import math

import numpy as np
from scipy.spatial.transform import Rotation

from grasping_sym import rotations


def _turns(n: int, seed: int) -> Rotation:
    return Rotation.random(n, random_state=seed)


def test_quaternions_give_scipys_matrices():
    r = _turns(200, 1)
    x, y, z, w = r.as_quat().T
    scale = np.random.default_rng(2).uniform(0.5, 2.0, 200)[:, None]   # normalised first
    got = rotations.matrices(np.column_stack([w, x, y, z]) * scale)
    assert np.abs(got - r.as_matrix()).max() < 2e-15
    assert np.abs(rotations.matrices([1.0, 0.0, 0.0, 0.0])[0] - np.eye(3)).max() == 0.0


def test_matrices_give_scipys_quaternions_with_w_nonnegative():
    R = _turns(300, 3).as_matrix()
    # each branch: the trace largest, and each diagonal entry largest (half-turns about x, y, z)
    R = np.concatenate([R, [np.diag([1.0, -1.0, -1.0]), np.diag([-1.0, 1.0, -1.0]),
                            np.diag([-1.0, -1.0, 1.0])]])
    for M in R:
        q = rotations.quaternion(M)
        x, y, z, w = Rotation.from_matrix(M).as_quat()
        want = np.array([w, x, y, z]) * (1.0 if w >= 0 else -1.0)
        assert q[0] >= 0 and abs(np.linalg.norm(q) - 1.0) < 1e-15
        assert np.abs(q - want).max() < 2e-15 or (abs(want[0]) < 1e-15 and np.abs(q + want).max() < 2e-15)
        assert np.abs(rotations.matrices(q)[0] - M).max() < 3e-15


def test_rotation_vectors_give_scipys_matrices():
    rng = np.random.default_rng(4)
    axes = rng.normal(size=(60, 3))
    axes /= np.linalg.norm(axes, axis=1, keepdims=True)
    for angle in (3.0, math.pi, 1.0, 1e-3, 1.01e-4, 0.99e-4, 1e-7, 0.0):
        for a in axes:
            w = angle * a
            err = np.abs(rotations.from_rotvec(w) - Rotation.from_rotvec(w).as_matrix()).max()
            assert err < 1e-15, (angle, err)
