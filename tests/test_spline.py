"""The quintic spline contour (``geometry.spline``): interpolation, smoothness, accuracy,
the generated expressions, a compiled scene, and the named errors for bad points."""
from __future__ import annotations

import math

import casadi as ca
import numpy as np
import pytest

import grasping_sym as gs
from grasping_sym.errors import InvalidCurveError, InvalidSceneError
from grasping_sym.geometry.curves import T
from grasping_sym.geometry.spline import SplineCurve, spline
from grasping_sym.symbolic.contour_functions import OBJECT, leaf_expressions
from grasping_sym.symbolic.translate import SympyToCasadi

R = 0.02


def circle_points(n: int, radius: float = R) -> np.ndarray:
    th = 2 * math.pi * np.arange(n) / n
    return np.c_[radius * np.cos(th), radius * np.sin(th)]


def ellipse_points(n: int, a=0.020, b=0.015, start=math.pi + 0.3) -> np.ndarray:
    """Clockwise from the eccentric angle ``start``, as ``library.ellipse(clockwise=True)``."""
    t = start + 2 * math.pi * np.arange(n) / n
    return np.c_[a * np.cos(-t), b * np.sin(-t)]


def leaves_function(curve) -> ca.Function:
    """The eight leaves of ``compose`` for ``curve``, as one CasADi function of ``t``."""
    u = ca.SX.sym("u")
    tr = SympyToCasadi({T: u})
    conc = leaf_expressions(OBJECT, curve)
    return ca.Function("leaves", [u], [ca.vertcat(*[tr(conc[c]) for c in OBJECT.leaves()])],
                       {"cse": True})


@pytest.mark.parametrize("closed", [False, True])
@pytest.mark.parametrize("parametrization", ["arclength", "chord"])
def test_interpolates_its_points(closed, parametrization):
    pts = ellipse_points(17) if closed else ellipse_points(17)[:12]
    c = spline(pts, closed=closed, parametrization=parametrization)
    assert isinstance(c, SplineCurve) and isinstance(c, gs.PlanarCurve)
    d = c.spline_data
    ev = c.evaluate(d.params[:len(pts)])
    assert np.max(np.abs(np.c_[ev["x"], ev["y"]] - pts)) < 1e-15
    L = d.length
    assert c.domain == ((-L, 2 * L) if closed else (0.0, L))
    if closed:  # the parameter wraps around: one turn later is the same point
        ts = np.linspace(-0.9 * L, 0.9 * L, 7)
        a, b = c.evaluate(ts), c.evaluate(ts + L)
        assert np.max(np.abs(a["x"] - b["x"])) < 1e-15 and np.max(np.abs(a["curvature"] - b["curvature"])) < 1e-9


def test_closed_may_repeat_its_first_point():
    pts = circle_points(12)
    a = spline(pts, closed=True)
    b = spline(np.vstack([pts, pts[:1]]), closed=True)
    assert a.key() == b.key()
    assert a.key() != spline(circle_points(13), closed=True).key()


@pytest.mark.parametrize("closed", [False, True])
def test_c4_across_the_breaks(closed):
    """Derivatives 0..4 of neighbouring pieces agree at every break (the 5th jumps)."""
    d = spline(ellipse_points(20) if closed else ellipse_points(20)[:14], closed=closed).spline_data
    h = np.diff(d.breaks)
    for c in (d.cx, d.cy):
        for k in range(5):
            left = sum(c[j, :-1] * math.factorial(j) / math.factorial(j - k) * h[:-1] ** (j - k)
                       for j in range(k, 6))
            right = c[k, 1:] * math.factorial(k)
            scale = np.max(np.abs(c[k] * math.factorial(k))) + 1e-300
            assert np.max(np.abs(left - right)) < 1e-9 * scale, k


def test_curvature_converges_on_a_circle():
    """|kappa R + 1| <= 2e-3 (h/R)^4 with h = 2 pi R / n: fourth order in the spacing."""
    errors = []
    for n in (12, 24, 48, 96):
        c = spline(circle_points(n)[::-1], closed=True)  # clockwise: kappa = -1/R
        ts = np.linspace(0, c.spline_data.length, 4001)
        ev = c.evaluate(ts)
        err = float(np.max(np.abs(ev["curvature"] * R + 1)))
        assert err <= 2e-3 * (2 * math.pi / n) ** 4, (n, err)
        assert np.max(np.abs(ev["speed"] - 1)) < 1e-5            # arclength parameter
        assert abs(c.spline_data.length / (2 * math.pi * R) - 1) < 1e-6
        errors.append(err)
    assert all(e1 / e2 > 12 for e1, e2 in zip(errors, errors[1:]))  # ~16 per halving


def test_curvature_converges_on_an_open_ellipse_arc():
    """Open arc, not-a-knot ends: relative curvature error at the points (ends included)."""
    a, b = 0.020, 0.015
    previous = None
    for n, tol in ((24, 2e-3), (48, 5e-5), (96, 3e-6)):
        th = np.linspace(-1.2, 1.2, n)
        c = spline(np.c_[a * np.cos(th), b * np.sin(th)])
        exact = a * b / (a**2 * np.sin(th) ** 2 + b**2 * np.cos(th) ** 2) ** 1.5
        err = float(np.max(np.abs(c.evaluate(c.spline_data.params)["curvature"] / exact - 1)))
        assert err < tol, (n, err)
        assert previous is None or previous / err > 16
        previous = err


@pytest.mark.parametrize("closed", [False, True])
def test_generated_expressions_match_the_fit(closed):
    """The SymPy expressions (as CasADi evaluates them) equal the numeric spline, and their
    derivatives (written out by the spline, not by SymPy) match finite differences."""
    c = spline(ellipse_points(30) if closed else ellipse_points(30)[:20], closed=closed)
    f = leaves_function(c)
    lo, hi = c.domain
    for t in np.linspace(lo, hi, 23)[1:-1]:
        v = np.array(f(t)).ravel()
        e = c.evaluate(t)
        ref = [e["x"], e["y"], e["dx"] / e["speed"], e["dy"] / e["speed"], e["speed"], e["curvature"]]
        np.testing.assert_allclose(v[:6], ref, rtol=1e-12, atol=1e-15)
        h = 1e-6
        ep, em = c.evaluate(t + h), c.evaluate(t - h)
        assert abs(v[6] - (ep["speed"] - em["speed"]) / (2 * h)) < 1e-6
        assert abs(v[7] - (ep["curvature"] - em["curvature"]) / (2 * h)) < 1e-4 * (1 + abs(v[7]))


def test_cost_does_not_grow_with_the_pieces():
    """One lookup call node picks the piece: the SX instruction count is the same for 40 and
    160 pieces (~35), and the lookup is called once, not once per coefficient."""
    counts = []
    for n in (40, 160):
        f = leaves_function(spline(circle_points(n), closed=True))
        counts.append(f.n_instructions())
        assert sum(f.instruction_id(k) == ca.OP_CALL for k in range(f.n_instructions())) == 1
    assert counts[0] == counts[1] < 200, counts


def test_spline_scene_builds_and_agrees_with_the_exact_ellipse():
    """100 points on the README's ellipse: the compiled spline scene follows the exact-ellipse
    scene over 0.5 s to 1e-7 rad / 1e-6 rad/s and 1e-9 m in the contact point (measured:
    theta 1.8e-8, dtheta 4.2e-7, contact 2.4e-10)."""
    a, b, u1 = 0.020, 0.015, math.pi + 0.3
    tip = gs.curves.paper_fingertip()
    ell = gs.curves.ellipse(a, b, start=math.pi, span=math.pi, clockwise=True, name="ellipse")
    obj = spline(ellipse_points(100, a, b, u1), closed=True, name="spline ellipse")
    exact = gs.build(gs.scenes.planar_finger(tip, ell, name="spline_ref_ellipse", u1_0=u1))
    model = gs.build(gs.scenes.planar_finger(tip, obj, name="spline_ellipse", u1_0=0.0))
    assert model.state_names == exact.state_names
    assert model.manifest["op_counts"]["rhs_sx_instructions"] < 2000   # a lookup, not 100 pieces
    r_ex = exact.simulate(0.5, method="cvodes")           # rtol 1e-10: the geometry is compared
    r_sp = model.simulate(0.5, method="cvodes", t_eval=r_ex.t)
    assert np.ptp(r_ex["theta"]) > 0.3                                    # it does roll
    assert np.max(np.abs(r_sp["theta"] - r_ex["theta"])) < 1e-7
    assert np.max(np.abs(r_sp["dtheta"] - r_ex["dtheta"])) < 1e-6
    for k in ("q1", "q2", "u0"):
        assert np.max(np.abs(r_sp[k] - r_ex[k])) < 1e-7, k
    pe, ps = ell.evaluate(r_ex["u1"]), obj.evaluate(r_sp["u1"])
    assert np.max(np.hypot(pe["x"] - ps["x"], pe["y"] - ps["y"])) < 1e-9
    assert np.max(np.abs(r_sp["Q"])) < 1e-9 and np.max(np.abs(r_sp["R"])) < 1e-9


def _problems(exc: InvalidCurveError) -> str:
    return "\n".join(exc.problems)


@pytest.mark.parametrize("points, closed, words", [
    (circle_points(5), False, ["5 usable point(s)", "at least 6", "sample the contour more densely"]),
    (np.vstack([circle_points(5), circle_points(5)[:1]]), True, ["5 usable point(s)", "repeated first point"]),
    (np.r_[circle_points(12)[:4], [[np.nan, 0.0]], circle_points(12)[4:]], True,
     ["non-finite coordinates (indices 4)", "give finite values"]),
    (np.r_[circle_points(12)[:4], circle_points(12)[3:]], True,
     ["repeated point(s)", "points 3-4 coincide", "remove the duplicates"]),
    (0.01 * np.c_[[0, 1, 2, 3, 2.5, 1.5, 0.5], [0, 0, 0, 0, 0.05, 0.05, 0.05]], False,
     ["turn back sharply", "point(s) 3 (174 deg)", "round the corner"]),
    (np.c_[np.cos(np.linspace(0, 2 * np.pi, 40, endpoint=False)),
           np.sin(np.linspace(0, 4 * np.pi, 40, endpoint=False)) / 2] * 0.02, True,
     ["crosses itself", "between points 10 and 11", "between points 30 and 31", "reorder the points"]),
    (np.zeros((8, 3)), False, ["shape (8, 3)", "(n, 2)"]),
    ([[0, 0], [1, "a"]], False, ["cannot be read as numbers"]),
])
def test_bad_points_are_named(points, closed, words):
    with pytest.raises(InvalidCurveError) as err:
        spline(points, closed=closed, name="bad")
    text = str(err.value)
    assert "contour 'bad' is invalid" in text
    for w in words:
        assert w in text, (w, text)


def test_every_problem_is_listed_at_once():
    pts = np.r_[circle_points(12)[:4], [[np.inf, 0.0]], circle_points(12)[4:7], circle_points(12)[6:]]
    with pytest.raises(InvalidCurveError) as err:
        spline(pts, closed=True, parametrization="uniform")
    text = _problems(err.value)
    assert len(err.value.problems) == 3
    for w in ("non-finite coordinates (indices 4)", "points 7-8 coincide", "parametrization = 'uniform'"):
        assert w in text, (w, text)


def test_scene_validation_sees_a_spline_like_any_contour():
    """A counterclockwise object contour is refused by the scene (its direction, and here the
    relative curvature too), as for the library's contours: the spline is an ordinary
    PlanarCurve to the rest of the package."""
    obj = spline(ellipse_points(40)[::-1], closed=True)
    scene = gs.scenes.planar_finger(gs.curves.paper_fingertip(), obj, name="ccw", u1_0=0.0)
    with pytest.raises(InvalidSceneError) as err:
        scene.validate()
    assert "runs counterclockwise about the object" in str(err.value)
    assert "relative curvature" in str(err.value)


@pytest.mark.parametrize("closed", [True, False], ids=["closed", "open"])
def test_spline_object_listed_counterclockwise_is_named(closed):
    """Issue 25: points of an ellipse less curved than the fingertip (31 1/m < 40 1/m),
    listed counterclockwise. The relative curvature at the start is positive, so the scene
    used to be accepted with the fingertip inside the object, failing later with advice
    about the fingertip's curvature. Now the direction is named with the fix, and the same
    points reversed are accepted."""
    a, b = 0.05, 0.04
    th = np.linspace(0.0, 2 * math.pi, 48, endpoint=False)
    pts = np.c_[a * np.cos(th), b * np.sin(th)]               # counterclockwise from (a, 0)
    if not closed:
        pts = pts[:36]                                        # three quarters of it
    obj = spline(pts, closed=closed, name="sampled")
    scene = gs.scenes.planar_finger(gs.curves.paper_fingertip(), obj, name="ccw_spline", u1_0=0.0)
    with pytest.raises(InvalidSceneError) as err:
        scene.validate()
    msg = str(err.value)
    assert "object contour 'sampled' runs counterclockwise about the object" in msg
    assert ("the area it encloses is +" if closed else "its tangent turns by +") in msg
    assert "gs.curves.spline(points[::-1], ...)" in msg
    assert "relative curvature kappa0 + kappa1 =" not in msg  # kappa0 + kappa1 > 0 here
    gs.scenes.planar_finger(gs.curves.paper_fingertip(), spline(pts[::-1], closed=closed),
                            name="cw_spline", u1_0=0.0).validate()
