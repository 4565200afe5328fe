"""The soft-contact comparison's planar pinch (``benchmarks/soft_contact.py``) and its MuJoCo
peer (``benchmarks/peers/mujoco_paper3d.py``): the pinch stays in its plane and is held
without creep in grasping_sym, and MuJoCo, built from the same scene, holds it with its
no-slip solver at the same sag while its default solver lets it slip out."""
from __future__ import annotations

import numpy as np
import pytest

import grasping_sym as gs

pytest.importorskip("mujoco", reason="mujoco is in the test extra: pip install -e .[test]")

from benchmarks.peers.mujoco_paper3d import MujocoGrasp  # noqa: E402
from benchmarks.soft_contact import pinch_scene  # noqa: E402

T = 3.0


@pytest.fixture(scope="module")
def pinch():
    scene = pinch_scene()
    model = gs.build(scene)
    res = model.simulate(T, t_eval=np.linspace(0.0, T, 301))
    return scene, model, res


def test_the_pinch_stays_in_its_plane_and_is_held(pinch):
    _, _, res = pinch
    for k in ("z", "q21", "qx", "qy", "vz", "omegaX", "omegaY"):
        assert np.max(np.abs(res[k])) < 1e-12, k
    assert np.max(res["constraint_residual"]) < 1e-9
    sag = res["y"][-1] - res["y"][0]
    assert -4e-3 < sag < -1e-3  # the centre spring carries the weight: a few mm
    assert abs(res["vy"][-1]) < 1e-7  # at rest: no creep


def test_mujoco_holds_the_same_pinch_only_with_its_no_slip_solver(pinch):
    scene, model, res = pinch
    sag = res["y"][-1] - res["y"][0]
    held = MujocoGrasp(scene, model, timestep=1e-3, noslip=10).run(T, every=0.01)
    assert held["ncon"] == 2
    mj_sag = held["pos"][-1, 1] - held["pos"][0, 1]
    assert abs(mj_sag - sag) < 0.1 * abs(sag), (mj_sag, sag)
    # soft contact: the surfaces overlap or part by a fraction of a millimetre
    assert 1e-5 < held["depth"] < 2e-3
    dropped = MujocoGrasp(scene, model, timestep=1e-3, noslip=0).run(T, every=0.01)
    assert dropped["pos"][-1, 1] - dropped["pos"][0, 1] < -0.02
