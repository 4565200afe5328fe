"""The paper's moving-frame formulation (``tests/oracles/reference3d_paper.py``) against reference3d.

(1) While the contact moves, both formulations agree on the bodies and the contact points;
(2) the moving frames stay orthonormal and matched (n1 = -n0, b1 = b0); (3) toward rest the
paper's formulation stops with ``MovingFrameSingularityError`` where |s'| is small, never a
NaN; (4) the regular formulation runs through the same rest.
"""
from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.integrate import solve_ivp

from grasping_sym.errors import GraspingSymError, MovingFrameSingularityError
from tests.oracles.reference3d import Reference3D, Scene3D
from tests.oracles.reference3d_paper import SL_UV, PaperReference3D, rolling_start

TOL = {"method": "LSODA", "rtol": 1e-10, "atol": 1e-12}


@pytest.fixture(scope="module")
def ellipsoid() -> PaperReference3D:
    return PaperReference3D()


@pytest.fixture(scope="module")
def sphere() -> PaperReference3D:
    return PaperReference3D(Scene3D(semi_axes=(0.025, 0.025, 0.025)))


def _contact_points(m: PaperReference3D, x_ref: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    o = m.outputs(np.r_[x_ref[:15], np.zeros(19)])    # points depend only on body + (u, v)
    return o["p_f"], o["p_o"]


@pytest.fixture(scope="module")
def moving_run(ellipsoid):
    m = ellipsoid
    ref = m.ref
    x0 = ref.initial_state()
    xr = ref.initial_state(ref.admissible_speeds(x0) @ np.array([1.0, 0.5]))
    xp = m.initial_state(xr)
    T = 0.1
    ts = np.linspace(0.0, T, 21)
    sr = solve_ivp(ref, (0.0, T), xr, t_eval=ts, **TOL)
    sp_ = solve_ivp(m, (0.0, T), xp, t_eval=ts, **TOL)
    assert sr.status == 0 and sp_.status == 0
    return m, sr, sp_


def test_formulations_agree_while_contact_moves(moving_run, record_property):
    m, sr, sp_ = moving_run
    body_err = point_err = 0.0
    for k in range(sr.t.size):
        xr, xp = sr.y[:, k], sp_.y[:, k]
        body_err = max(body_err, np.max(np.abs(xr[:11] - xp[:11])))
        pf_r, po_r = _contact_points(m, xr)
        o = m.outputs(xp)
        point_err = max(point_err, np.max(np.abs(pf_r - o["p_f"])), np.max(np.abs(po_r - o["p_o"])))
        assert abs(o["s_dot"]) > 1e-3                       # the contact really moves
    moved = np.linalg.norm(sr.y[13:15, -1] - sr.y[13:15, 0])
    print(f"\nbody state max diff {body_err:.2e}, contact point max diff {point_err:.2e} m, "
          f"object (u, v) moved {moved:.3f}, s(T) = {sp_.y[15, -1]:.4e} m")
    record_property("body_err", float(body_err))
    record_property("point_err", float(point_err))
    assert moved > 1e-2
    assert body_err <= 1e-8 and point_err <= 1e-8
    # the surface coordinates and psi agree too
    assert np.max(np.abs(m.reference_state(sp_.y[:, -1])[11:] - sr.y[11:, -1])) <= 1e-8
    assert sp_.y[15, -1] > 0                                 # s, the arclength, grew


def test_frames_stay_orthonormal(moving_run, record_property):
    m, _, sp_ = moving_run
    outs = [m.outputs(sp_.y[:, k]) for k in range(sp_.t.size)]
    ortho = max(o["frame_orthonormality"] for o in outs)
    match = max(o["frame_match"] for o in outs)
    normal = max(o["normal_drift"] for o in outs)
    print(f"\nframes: orthonormality {ortho:.2e}, R Psi0 D - Pi Psi1 {match:.2e}, "
          f"n - surface normal {normal:.2e}")
    record_property("frame_orthonormality", float(ortho))
    assert ortho <= 1e-9 and match <= 1e-9 and normal <= 1e-9


@pytest.fixture(scope="module")
def rest_run(sphere):
    m = sphere
    xp = m.initial_state(rolling_start(m.ref))
    log = []

    def f(t, x):
        log.append((t, *m.denominator(x)))
        return m.rhs(x, t)

    with pytest.raises(MovingFrameSingularityError) as info:
        solve_ivp(f, (0.0, 3.0), xp, **TOL)
    return m, info.value, np.array(log)


def test_paper_formulation_stops_at_rest(rest_run, record_property):
    m, err, log = rest_run
    assert isinstance(err, GraspingSymError)
    assert np.all(np.isfinite(log))
    print(f"\nMovingFrameSingularityError at t = {err.t:.4f} s: D = {err.denominator:.3e} rad/s "
          f"(threshold {err.threshold:.3e}), s' = {err.s_dot:.3e} m/s; peak |s'| {np.abs(log[:, 3]).max():.3e}")
    record_property("t_singular", float(err.t))
    record_property("denominator", float(err.denominator))
    assert err.t is not None and 0.1 < err.t < 3.0
    assert math.isfinite(err.denominator) and abs(err.denominator) < err.threshold
    assert abs(err.s_dot) <= 1e-5 and abs(err.s_dot) <= 1e-3 * np.abs(log[:, 3]).max()
    # |D| = (kn0 + kn1) |s'|
    assert abs(abs(err.denominator) - abs(err.s_dot) * (1 / 0.025 + 1 / 0.010)) <= 1e-9


def test_regular_formulation_runs_through_rest(rest_run):
    m, err, _ = rest_run
    ref: Reference3D = m.ref
    x0 = rolling_start(ref)
    T = 3.0
    sol = solve_ivp(ref, (0.0, T), x0, dense_output=True, **TOL)
    assert sol.status == 0 and np.all(np.isfinite(sol.y))
    for t in np.linspace(err.t, T, 9):
        xdot = ref.rhs(sol.sol(t))
        assert np.all(np.isfinite(xdot))
    rate_end = np.linalg.norm(ref.rhs(sol.y[:, -1])[SL_UV.start:SL_UV.stop])
    rate_0 = np.linalg.norm(ref.rhs(x0)[SL_UV.start:SL_UV.stop])
    assert rate_end <= 1e-5 * rate_0


def test_paper_efs_without_geodesic_torsion_drifts(moving_run):
    """The paper's (Efs) as printed has no geodesic-torsion term: exact only along lines of
    curvature. On the ellipsoid the frames leave the surface normal and the bodies diverge."""
    m0, sr, _ = moving_run
    m = PaperReference3D(reference=m0.ref, geodesic_torsion=False)
    T = float(sr.t[-1])
    sp_ = solve_ivp(m, (0.0, T), m.initial_state(sr.y[:, 0]), **TOL)
    body_err = np.max(np.abs(sr.y[:11, -1] - sp_.y[:11, -1]))
    drift = m.outputs(sp_.y[:, -1])["normal_drift"]
    print(f"\nwithout tg: body diff {body_err:.2e}, normal drift {drift:.2e}")
    assert body_err > 1e-4 and drift > 1e-3
