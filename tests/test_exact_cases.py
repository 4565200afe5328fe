"""Cases with exact answers (docs/conventions.md section 3) for circular contours.

The circles are placed off the body origins (fingertip centre O01, object pivot Om) so that
the controller's pull of O01 toward Om has a lever arm and the contact rolls a long way.
Contact points are recomputed here from the circle formulas, not from the package's curves.
"""
from __future__ import annotations

import math

import numpy as np
import pytest

import grasping_sym as gs
from grasping_sym.geometry import library

A, A_CENTRE = 0.015, (-0.005, 0.0)   # fingertip circle: radius (m), centre in O01-X0Y0
B, B_CENTRE = 0.010, (-0.010, 0.004)  # object circle: radius (m), centre in Om-XY
L11 = L12 = 0.065
OUTS = ("Q", "R", "kappa_sum", "tangency_defect")
TOL = dict(rtol=1e-12, atol=1e-14)


def _rot(a, v):
    c, s = np.cos(a), np.sin(a)
    return np.stack([c * v[0] - s * v[1], s * v[0] + c * v[1]])


def _o01(q1, q2):
    return np.stack([L11 * np.sin(q1) + L12 * np.sin(q1 + q2),
                     L11 * np.cos(q1) + L12 * np.cos(q1 + q2)])


def _finger_point(r, phi0, centre, radius):
    """Inertial contact point on the fingertip circle at polar angle ``phi0`` (local)."""
    c0 = np.stack([centre[0] + radius * np.cos(phi0), centre[1] + radius * np.sin(phi0)])
    return _o01(r["q1"], r["q2"]) + _rot(math.pi / 2 - r["q1"] - r["q2"], c0)


def _object_point(r, phi1, pivot):
    c1 = np.stack([B_CENTRE[0] + B * np.cos(phi1), B_CENTRE[1] + B * np.sin(phi1)])
    return np.asarray(pivot)[:, None] + _rot(-r["theta"], c1)


def _disks(by):
    return gs.scenes.planar_finger(
        library.circle(A, A_CENTRE, by=by, span=3.0),
        library.circle(B, B_CENTRE, by=by, start=math.pi, span=3.0, clockwise=True),
        name=f"disks_by_{by}", outputs=OUTS)


@pytest.fixture(scope="module")
def disks():
    """Disk on disk, by arclength (one state s) and by angle (u0, u1), over 3 s."""
    out = {}
    for by in ("arclength", "angle"):
        scene = _disks(by)
        out[by] = (scene, gs.build(scene).simulate(3.0, **TOL))
    return out


# ------------------------------------------------------------------ (a) parameterisation
@pytest.fixture(scope="module")
def circle_on_catenary():
    runs = {}
    for by in ("arclength", "angle"):
        scene = gs.scenes.planar_finger(library.circle(A, by=by), library.paper_object(),
                                        name=f"circle_{by}_on_catenary", outputs=OUTS)
        runs[by] = (scene, gs.build(scene).simulate(1.0, **TOL))
    return runs


def test_parameterisation_does_not_change_the_motion(circle_on_catenary):
    sc_s, rs = circle_on_catenary["arclength"]
    sc_a, ra = circle_on_catenary["angle"]
    assert sc_s.state_names[-1] == "s" and sc_a.state_names[-2:] == ("u0", "u1")
    assert np.ptp(rs["theta"]) > 0.5  # a large motion, not a rest state
    for name in ("theta", "q1", "q2"):
        np.testing.assert_allclose(ra[name], rs[name], rtol=0, atol=1e-9, err_msg=name)
    # equal path lengths: angle * radius on the fingertip, and the same s on the object
    np.testing.assert_allclose(A * ra["u0"], rs["s"], rtol=0, atol=1e-11)
    np.testing.assert_allclose(ra["u1"], rs["s"], rtol=0, atol=1e-11)
    p_s = _finger_point(rs, rs["s"] / A, (0.0, 0.0), A)
    p_a = _finger_point(ra, ra["u0"], (0.0, 0.0), A)
    assert np.max(np.hypot(*(p_s - p_a))) <= 1e-10


# ------------------------------------------------------------------ (b) disk on disk
@pytest.mark.parametrize("by", ["arclength", "angle"])
def test_disk_on_disk_rolling_relation(disks, by):
    """(kappa0 + kappa1) ds/dt = d/dt (q1 + q2 - theta), with kappa0 + kappa1 = 1/a + 1/b.

    Integrated along the run: the arclength rolled times (1/a + 1/b) equals the change of
    q1 + q2 - theta; by angle, the arclengths are a * du0 and b * du1.
    """
    scene, r = disks[by]
    rel = r["q1"] + r["q2"] - r["theta"]
    rel = rel - rel[0]
    if by == "arclength":
        rolled = [r["s"] - r["s"][0]]
    else:
        rolled = [A * (r["u0"] - r["u0"][0]), B * (r["u1"] - r["u1"][0])]
    assert np.ptp(rolled[0]) > 5e-3  # the contact rolls over a third of the small disk
    for arc in rolled:
        np.testing.assert_allclose(arc * (1 / A + 1 / B), rel, rtol=0, atol=1e-9)
    np.testing.assert_allclose(r["kappa_sum"], 1 / A + 1 / B, rtol=1e-12)


@pytest.mark.parametrize("by", ["arclength", "angle"])
def test_disk_on_disk_contact_points_coincide(disks, by):
    """The contact point seen from the finger and from the object is one point."""
    scene, r = disks[by]
    if by == "arclength":
        phi0, phi1 = r["s"] / A, math.pi - r["s"] / B
    else:
        phi0, phi1 = r["u0"], math.pi - r["u1"]
    p_finger = _finger_point(r, phi0, A_CENTRE, A)
    p_object = _object_point(r, phi1, scene.pivot)
    assert np.max(np.hypot(*(p_finger - p_object))) <= 1e-10
    # tangency: the outward normals are opposite, i.e. the centres and the contact align
    c_finger = _o01(r["q1"], r["q2"]) + _rot(math.pi / 2 - r["q1"] - r["q2"],
                                             np.array(A_CENTRE)[:, None] * np.ones_like(r["q1"]))
    c_object = np.asarray(scene.pivot)[:, None] + _rot(
        -r["theta"], np.array(B_CENTRE)[:, None] * np.ones_like(r["theta"]))
    np.testing.assert_allclose(np.hypot(*(c_finger - c_object)), A + B, rtol=0, atol=1e-10)
    assert np.max(np.abs(r["Q"])) <= 1e-10 and np.max(np.abs(r["R"])) <= 1e-10


def test_disk_on_disk_parameterisations_agree(disks):
    _, rs = disks["arclength"]
    _, ra = disks["angle"]
    for name in ("theta", "q1", "q2"):
        np.testing.assert_allclose(ra[name], rs[name], rtol=0, atol=1e-9, err_msg=name)
