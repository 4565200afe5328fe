"""A start solved at run time stays on the branch of the scene's start: neighbouring starting
angles give neighbouring finger postures and contact points (issue 25: theta0 = -1.138 and
-1.077 used to land on the two elbows), what was chosen is reported, and a start that the
branch does not reach is refused by name unless ``branch="any"`` is asked."""
from __future__ import annotations

import re

import numpy as np
import pytest

import grasping_sym as gs
from grasping_sym.errors import ProblemsError, StartBranchError, UnreachableStartError
from grasping_sym.runtime.start import START_TOL, _conditions_function
from grasping_sym.sweeps import START

# the issue's angles (-1.138, -1.077; 0.89, 0.95) with neighbours, few to stay cheap
GRIDS = (np.linspace(-1.2, -1.0, 9), np.linspace(0.8, 1.05, 11))


def _consistent(model, x) -> float:
    """max|G| of every start condition (contact Q, R and tangency) and of Cdot."""
    G = _conditions_function(model)(x)[0]
    return max(float(np.max(np.abs(G))), float(np.max(np.abs(model.library.constraints(x)[2]))))


@pytest.mark.parametrize("thetas", GRIDS, ids=["negative", "positive"])
def test_neighbouring_starting_angles_give_neighbouring_poses(paper2d_model, thetas):
    m = paper2d_model
    i = [m.state_names.index(k) for k in ("q1", "q2", "s")]
    sols = [m.solve_start(theta=float(t)) for t in thetas]
    X = np.array([s.x for s in sols])
    assert np.all(X[:, 0] == thetas)
    assert max(_consistent(m, x) for x in X) <= START_TOL
    # the scene's start has its elbow bent one way (q2 = 0.72 > 0): so do all of these
    assert m.initial_state()[2] > 0 and np.all(X[:, 2] > 0)
    # continuous: per rad of theta, the joints turn by less than 1 rad and the contact
    # point moves by less than 5 cm (the jumps were 0.8 rad and 5 mm in 0.06 rad)
    rate = np.abs(np.diff(X[:, i], axis=0)) / np.diff(thetas)[:, None]
    assert np.all(rate[:, :2] < 1.0) and np.all(rate[:, 2] < 0.05), rate
    # smooth, not only bounded: second differences are small
    assert np.max(np.abs(np.diff(X[:, i], 2, axis=0))) < 1e-3
    for s in sols:
        assert s.on_start_branch and s.branch == s.start_branch == -1
        assert s.solved == ("q1", "q2", "s") and s.contact == {"s": s.x[6]}
    assert m.initial_state(theta=float(thetas[3])).tolist() == sols[3].x.tolist()


def test_the_issue_angles_are_on_the_scene_start_elbow(paper2d_model):
    """theta0 = -1.138 used to give q1 = 1.420, q2 = -0.638, s = 4.9 mm (the other elbow);
    the start's branch has q2 = 0.84, s = 10.6 mm there, a neighbour of theta0 = -1.077's."""
    a, b = (paper2d_model.initial_state(theta=t) for t in (-1.138, -1.077))
    assert a[2] == pytest.approx(0.8429, abs=1e-3) and a[6] == pytest.approx(0.01069, abs=1e-4)
    assert abs(a[1] - b[1]) < 0.02 and abs(a[2] - b[2]) < 0.01 and abs(a[6] - b[6]) < 1e-3
    # independent check: the scene itself, started there, puts the pivot where the model has it
    scene = gs.scenes.paper2d(q1_0=float(a[1]), theta_0=-1.138, u0_0=float(a[6]), u1_0=float(a[6]))
    assert scene.q2_0 == pytest.approx(a[2], abs=1e-12)
    np.testing.assert_allclose(scene.pivot, list(paper2d_model.start_params.values()), rtol=0,
                               atol=1e-13)


def test_a_start_the_branch_does_not_reach_is_refused_by_name(paper2d_model):
    """Holding q1, the start's branch turns back at q1 = 0.783 (theta = 1.29); q1 = 0.9 has a
    consistent pose only with the object turned the other way (theta = -1.99)."""
    with pytest.raises(StartBranchError) as info:
        paper2d_model.initial_state(q1=0.9)
    err = info.value
    assert isinstance(err, UnreachableStartError)
    msg = str(err)
    for part in ("q1 = 0.9 is not reached on the branch of the scene's start",
                 "det dG/d(theta, q2, s) > 0", "turns back", "(det dG/d(theta, q2, s) < 0)",
                 "branch='any'"):
        assert part in msg, part
    assert re.search(r"turns back \(a fold\) or becomes singular at q1 = 0\.78\d* \(theta = 1\.2", msg)
    assert err.found[0] == pytest.approx(-1.9887, abs=1e-3) and err.reached[1] == pytest.approx(0.783, abs=1e-3)


def test_branch_any_accepts_the_other_branch_and_says_so(paper2d_model):
    m = paper2d_model
    other = m.solve_start(q1=0.9, branch="any")
    assert not other.on_start_branch and other.branch == -other.start_branch
    assert other.x[1] == 0.9 and _consistent(m, other.x) <= START_TOL
    assert np.all(other.x[3:6] == 0.0) and other.contact["s"] == pytest.approx(0.02296, abs=1e-4)
    # where the start's branch does reach, "any" is the same start
    assert m.initial_state(q1=0.7, branch="any").tolist() == m.initial_state(q1=0.7).tolist()
    with pytest.raises(ProblemsError, match=r"branch = 'bogus' must be 'start'"):
        m.initial_state(theta=0.1, branch="bogus")


def test_with_start_records_the_branch_and_contact_point(paper2d_model):
    moved = paper2d_model.with_start(theta=-1.1)
    info = moved.start["info"]["branch"]
    x = moved.initial_state()
    assert info["on_start_branch"] and info["branch"] == info["start_branch"] == -1
    assert info["contact"] == {"s": x[6]} and info["given"] == {"theta": -1.1}
    assert paper2d_model.solve_start().contact == {"s": 0.0}


def test_a_sweep_records_a_refused_start_as_a_failed_point(paper2d_model, tmp_path):
    ds = gs.sweep(paper2d_model, gs.sweep.points({"q1_0": [0.6, 0.9]}), 0.01,
                  store=tmp_path / "b.zarr", progress=False, method="radau")
    assert ds["status"].values.tolist() == [0, START]
    assert "StartBranchError" in ds["error"].values[1] and "branch='any'" in ds["error"].values[1]
    assert np.isnan(ds["theta"].values[1]) and ds["error"].values[0] == ""
