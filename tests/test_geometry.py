"""Planar contour geometry: curvature against closed forms, and validation of bad curves.

Every expected value here is an analytic formula written independently of
``grasping_sym.geometry`` (no call back into the package computes an expected value).
"""
from __future__ import annotations

import math
import re

import numpy as np
import pytest
import sympy as sp

from grasping_sym.errors import InvalidCurveError
from grasping_sym.geometry import library
from grasping_sym.geometry.curves import PlanarCurve, T

#: Vertex offset of the paper's object catenary (paper eqs 39-40), m.
S_OBJ = 3.363e-3


# ------------------------------------------------------------------ circles
@pytest.mark.parametrize("clockwise", [False, True], ids=["ccw", "cw"])
@pytest.mark.parametrize("by", ["angle", "arclength"])
def test_circle_curvature_is_inverse_radius_with_sign_of_direction(by, clockwise):
    radius, cx, cy = 0.017, 0.003, -0.002
    c = library.circle(radius, (cx, cy), by=by, start=0.4, span=2.5, clockwise=clockwise)
    t = np.linspace(*c.domain, 57)
    v = c.evaluate(t)
    sign = -1.0 if clockwise else 1.0
    np.testing.assert_allclose(v["curvature"], sign / radius, rtol=1e-12, atol=0)
    # the points are on the circle, at polar angle start +- t (angle) or +- t/r (arclength)
    phi = 0.4 + sign * (t if by == "angle" else t / radius)
    np.testing.assert_allclose(v["x"], cx + radius * np.cos(phi), rtol=0, atol=1e-15)
    np.testing.assert_allclose(v["y"], cy + radius * np.sin(phi), rtol=0, atol=1e-15)
    expected_speed = radius if by == "angle" else 1.0
    np.testing.assert_allclose(np.hypot(v["dx"], v["dy"]), expected_speed, rtol=1e-12)
    np.testing.assert_allclose(v["speed"], expected_speed, rtol=1e-12)
    assert c.unit_speed is (by == "arclength")


def test_circle_domain_is_span_in_radians_of_arc():
    r = 0.02
    assert library.circle(r, by="angle", span=0.7).domain == pytest.approx((-0.7, 0.7), abs=0)
    assert library.circle(r, by="arclength", span=0.7).domain == pytest.approx(
        (-0.7 * r, 0.7 * r), rel=1e-15)


# ------------------------------------------------------------------ ellipse, parabola
@pytest.mark.parametrize("clockwise", [False, True], ids=["ccw", "cw"])
def test_ellipse_curvature_matches_closed_form(clockwise):
    a, b = 0.031, 0.012
    e = library.ellipse(a, b, (0.001, 0.002), start=0.3, span=3.0, clockwise=clockwise)
    t = np.linspace(*e.domain, 201)
    v = e.evaluate(t)
    expected = a * b / (a**2 * np.sin(t) ** 2 + b**2 * np.cos(t) ** 2) ** 1.5
    sign = -1.0 if clockwise else 1.0
    np.testing.assert_allclose(v["curvature"], sign * expected, rtol=1e-12, atol=0)
    np.testing.assert_allclose(
        v["speed"], np.sqrt(a**2 * np.sin(t) ** 2 + b**2 * np.cos(t) ** 2), rtol=1e-13)
    assert not e.unit_speed


def test_parabola_curvature_and_unit_tangent():
    # (t, t^2): kappa = 2 / (1 + 4 t^2)^(3/2), tangent (1, 2t)/sqrt(1 + 4t^2)
    c = PlanarCurve(T, T**2, T, (-2.0, 2.0), "parabola")
    t = np.linspace(-2, 2, 81)
    v = c.evaluate(t)
    np.testing.assert_allclose(v["curvature"], 2 / (1 + 4 * t**2) ** 1.5, rtol=1e-13)
    tx, ty = (sp.lambdify(T, e, "numpy")(t) for e in c.tangent)
    np.testing.assert_allclose(np.broadcast_to(tx, t.shape), 1 / np.sqrt(1 + 4 * t**2), rtol=1e-14)
    np.testing.assert_allclose(ty, 2 * t / np.sqrt(1 + 4 * t**2), rtol=1e-14, atol=1e-16)


def test_parameter_symbol_is_replaced():
    u = sp.Symbol("u")
    c = PlanarCurve(sp.cos(u), sp.sin(u), u, (-1, 1), "unit circle in u")
    assert c.x.free_symbols == {T}
    assert float(c.evaluate(0.5)["curvature"]) == pytest.approx(1.0, rel=1e-14)


# ------------------------------------------------------------------ the paper's catenaries
@pytest.mark.parametrize("which", ["fingertip", "object"])
def test_paper_contours_are_unit_speed(which):
    c = library.paper_fingertip() if which == "fingertip" else library.paper_object()
    s = np.linspace(*c.domain, 301)
    v = c.evaluate(s)
    # measured from x', y' (``speed`` itself is the symbol 1 once unit speed is detected)
    np.testing.assert_allclose(np.hypot(v["dx"], v["dy"]), 1.0, rtol=0, atol=1e-12)
    assert c.unit_speed
    assert c.speed == 1


def test_paper_contour_curvatures_match_catenary_formula():
    ft, ob = library.paper_fingertip(), library.paper_object()
    s = np.linspace(-0.03, 0.03, 301)
    # catenary y = cosh(kx)/k-type contour of vertex curvature 2k: kappa(s) = 2k/(1 + (2k s)^2)
    kappa0 = 40.0 / (1 + (40.0 * s) ** 2)
    kappa1 = 100.0 / (1 + (100.0 * (s - S_OBJ)) ** 2)
    np.testing.assert_allclose(ft.evaluate(s)["curvature"], kappa0, rtol=1e-12)
    # the object contour turns clockwise about its interior: kappa1 = -(signed curvature)
    np.testing.assert_allclose(-ob.evaluate(s)["curvature"], kappa1, rtol=1e-12)


def test_paper_curvatures_at_start_sum_to_check_value():
    k0 = float(library.paper_fingertip().evaluate(0.0)["curvature"])
    k1 = -float(library.paper_object().evaluate(0.0)["curvature"])
    assert k0 == pytest.approx(40.0, rel=1e-13)
    assert k1 == pytest.approx(89.84, abs=5e-3)
    assert k0 + k1 == pytest.approx(129.84, abs=5e-3)  # docs/conventions.md check value


def test_paper_contours_match_models_md_formulas():
    s = np.linspace(-0.03, 0.03, 101)
    f, o = library.paper_fingertip().evaluate(s), library.paper_object().evaluate(s)
    np.testing.assert_allclose(f["x"], 0.035 - np.sqrt(1 + 4 * 20**2 * s**2) / 40, atol=1e-16)
    np.testing.assert_allclose(f["y"], np.arcsinh(40 * s) / 40, atol=1e-16)
    u = s - S_OBJ
    np.testing.assert_allclose(o["x"], -0.03 + np.sqrt(1 + 4 * 50**2 * u**2) / 100, atol=1e-16)
    np.testing.assert_allclose(o["y"], np.arcsinh(100 * u) / 100, atol=1e-16)


# ------------------------------------------------------------------ superellipse
@pytest.mark.parametrize("n", [2, 4, 6])
def test_superellipse_is_regular_convex_and_on_its_curve(n):
    a, b = 0.02, 0.012
    c = library.superellipse(a, b, n, span=math.pi)
    c.check()  # regular and finite over the whole closed curve
    t = np.linspace(-math.pi, math.pi, 721)
    v = c.evaluate(t)
    np.testing.assert_allclose(np.abs(v["x"] / a) ** n + np.abs(v["y"] / b) ** n, 1.0, rtol=1e-12)
    # |c'| >= r(t) >= min(a, b): regular with a margin, not just nonzero at samples
    assert np.all(v["speed"] >= min(a, b) * (1 - 1e-12))
    assert np.all(np.isfinite(v["curvature"]))
    assert np.all(v["curvature"] >= -1e-9)  # convex (zero curvature at the flat vertices)


def test_superellipse_n2_is_the_ellipse():
    a, b = 0.02, 0.012
    c = library.superellipse(a, b, 2, span=math.pi)
    # an ellipse has curvature a/b^2 at (a, 0) and b/a^2 at (0, b)
    assert float(c.evaluate(0.0)["curvature"]) == pytest.approx(a / b**2, rel=1e-12)
    assert float(c.evaluate(math.pi / 2)["curvature"]) == pytest.approx(b / a**2, rel=1e-12)


# ------------------------------------------------------------------ validation
def test_cusp_on_a_sample_is_reported_as_not_regular_with_its_t():
    c = PlanarCurve((T - 0.25) ** 2, (T - 0.25) ** 3, T, (-1.0, 1.0), "cusp")
    with pytest.raises(InvalidCurveError) as info:
        c.check()
    msg = str(info.value)
    assert "not regular" in msg
    assert "t = 0.25" in msg
    assert "'cusp'" in msg


def test_zero_speed_circle_is_not_regular():
    # a "circle" whose parameter stops: (r cos t^3, r sin t^3) has zero speed at t = 0
    r = 0.01
    c = PlanarCurve(r * sp.cos(T**3), r * sp.sin(T**3), T, (-1.0, 1.0), "stalled circle")
    with pytest.raises(InvalidCurveError) as info:
        c.check()
    assert "not regular" in str(info.value)
    assert "t = 0" in str(info.value)


@pytest.mark.parametrize(
    "x, y, what",
    [((T - 0.2123) ** 2, (T - 0.2123) ** 3, "not regular"),
     (T, 1 / (T - 0.2123), "not finite")],
    ids=["cusp", "pole"],
)
def test_singularity_between_samples_is_found(x, y, what):
    """A cusp or a pole at t = 0.2123 (not on the 401-point sampling grid of [-1, 1]).

    The curve is not regular (or not finite) on its domain whatever the sampling, so
    ``check`` must refuse it; sampling alone only sees speeds of ~5e-3 / values of ~400.
    """
    c = PlanarCurve(x, y, T, (-1.0, 1.0), "off-grid singularity")
    with pytest.raises(InvalidCurveError) as info:
        c.check()
    assert what in str(info.value)


def test_non_finite_curve_is_refused_with_t():
    c = PlanarCurve(1 / T, T, T, (-1.0, 1.0), "hyperbola through the pole")
    with pytest.raises(InvalidCurveError) as info:
        c.check()
    msg = str(info.value)
    assert "not finite" in msg and "t = 0" in msg


def test_free_symbols_are_refused_at_construction():
    a = sp.Symbol("a_len")
    with pytest.raises(InvalidCurveError) as info:
        PlanarCurve(a * sp.cos(T), sp.sin(T), T, (-1, 1), "free")
    assert "a_len" in str(info.value) and "free symbols" in str(info.value)


@pytest.mark.parametrize("kink", [sp.Abs(T), sp.sign(T) * T**2], ids=["Abs", "sign"])
def test_kinks_are_refused_at_construction(kink):
    with pytest.raises(InvalidCurveError) as info:
        PlanarCurve(kink, T, T, (-1, 1), "kinked")
    assert "smooth" in str(info.value)


@pytest.mark.parametrize("domain", [(1.0, -1.0), (0.0, 0.0), (0.0, math.inf), (math.nan, 1.0)])
def test_bad_domain_is_refused(domain):
    with pytest.raises(InvalidCurveError) as info:
        PlanarCurve(T, T**2, T, domain, "bad domain")
    assert "domain" in str(info.value)


def test_construction_problems_are_reported_together():
    b = sp.Symbol("b_len")
    with pytest.raises(InvalidCurveError) as info:
        PlanarCurve(sp.Abs(T), b * T, T, (-1, 1), "two problems")
    err = info.value
    assert len(err.problems) == 2
    assert "smooth" in str(err) and "b_len" in str(err)


def test_check_problems_are_reported_together():
    # cusp at t = 0 and a pole at t = 0.5, both on the sampling grid of [-1, 1]
    c = PlanarCurve(T**2 + T**3 / (T - sp.Rational(1, 2)), T**3, T, (-1.0, 1.0), "cusp and pole")
    with pytest.raises(InvalidCurveError) as info:
        c.check()
    msg = str(info.value)
    assert "not regular" in msg and "t = 0 " in msg
    assert "not finite" in msg and "t = 0.5" in msg


@pytest.mark.parametrize("bad", [0.0, -0.01, math.nan, math.inf])
def test_library_refuses_non_positive_sizes(bad):
    with pytest.raises(InvalidCurveError) as info:
        library.circle(bad)
    assert "radius" in str(info.value)
    with pytest.raises(InvalidCurveError) as info:
        library.ellipse(0.02, bad)
    assert "b =" in str(info.value)


def test_library_refuses_unknown_parameterisation():
    with pytest.raises(InvalidCurveError) as info:
        library.circle(0.01, by="degrees")
    assert "'degrees'" in str(info.value)


# ------------------------------------------------------------------ number types (issue 25)
@pytest.mark.parametrize("kind", [np.float32, np.float16, np.float64, np.int64, np.array],
                         ids=["float32", "float16", "float64", "int64", "0-d array"])
def test_library_accepts_any_real_number_type(kind):
    """A radius from a float32 array, an int64, a 0-d array: the same contour as the float."""
    def val(x):
        return kind(x)

    r = float(val(0.01)) if kind is not np.int64 else 1.0
    c = library.circle(val(0.01) if kind is not np.int64 else val(1), (val(0), val(0)),
                       start=val(0), span=val(1), clockwise=np.bool_(False))
    assert float(c.evaluate(0.0)["curvature"]) == pytest.approx(1 / r, rel=1e-12)
    e = library.ellipse(val(2), val(1), start=val(0), span=val(1), clockwise=True)
    assert float(e.evaluate(0.0)["x"]) == pytest.approx(2.0, rel=1e-12)
    s = library.superellipse(val(2), val(1), np.int64(4), span=val(1))
    assert float(s.evaluate(0.0)["x"]) == pytest.approx(2.0, rel=1e-12)
    k = library.catenary(val(20), val(0), sign=np.int64(-1), domain=(val(-0), val(1)))
    assert float(k.evaluate(0.0)["curvature"]) == pytest.approx(40.0, rel=1e-6)
    g = library.polynomial_graph([val(0), val(1)], (val(-1), val(1)), offset=val(1))
    assert float(g.evaluate(0.5)["x"]) == pytest.approx(1.5, rel=1e-6)
    p = PlanarCurve(val(1), "t", T, (val(0), val(1)), "numpy numbers")
    assert p.domain == (0.0, 1.0) and type(p.domain[0]) is float
    assert float(p.evaluate(0.5)["x"]) == pytest.approx(1.0, rel=1e-6)


def test_float32_radius_keeps_its_float_value_and_python_floats_keep_their_key():
    c = library.circle(np.float32(0.01))
    assert float(c.evaluate(0.0)["x"]) == pytest.approx(float(np.float32(0.01)), rel=1e-15, abs=0)
    assert library.circle(0.01).key() == library.circle(np.float64(0.01)).key()


@pytest.mark.parametrize("bad, shown", [(True, "True"), (1 + 2j, "(1+2j)"), ("0.01", "'0.01'"),
                                        (np.float32("nan"), "np.float32(nan)"), (np.inf, "inf"),
                                        (np.array([0.01]), "array([0.01])"), (None, "None")])
def test_library_names_what_is_not_a_real_number(bad, shown):
    with pytest.raises(InvalidCurveError) as info:
        library.circle(bad)
    assert f"radius = {shown}" in str(info.value) and "finite positive number" in str(info.value)


def test_library_names_every_bad_argument_at_once():
    with pytest.raises(InvalidCurveError) as info:
        library.ellipse(0.02, 0.01, center=("0", 0), start=1j, clockwise="false")
    problems = info.value.problems
    assert len(problems) == 3, problems
    text = "\n".join(problems)
    for w in ("center = ('0', 0) must be two finite real numbers", "start = 1j must be a finite real",
              "clockwise = 'false' must be True or False"):
        assert w in text, text
    with pytest.raises(InvalidCurveError, match=r"n = 3\.0 must be an even integer"):
        library.superellipse(0.02, 0.01, 3.0)
    with pytest.raises(InvalidCurveError, match=r"sign = True must be \+1 or -1"):
        library.catenary(20.0, 0.0, sign=True)


@pytest.mark.parametrize("domain", [("a", 1), (0.0,), "ab", 5, (0, 1, 2), (True, 1.0), (0, 1j)])
def test_domain_that_is_not_two_numbers_is_named(domain):
    """A string, a short tuple, a bool: InvalidCurveError naming the domain and the fix
    (never a raw ValueError or IndexError)."""
    with pytest.raises(InvalidCurveError) as info:
        PlanarCurve("t", "t**2", T, domain, "bad domain")
    msg = str(info.value)
    assert f"domain = {domain!r} is not two real numbers" in msg
    assert "give (t_min, t_max)" in msg and "'bad domain'" in msg


def test_domain_problem_is_listed_with_the_others():
    with pytest.raises(InvalidCurveError) as info:
        PlanarCurve(T, sp.Symbol("a_len") * T, T, ("0", "1"), "two problems")
    assert len(info.value.problems) == 2
    assert "free symbols a_len" in str(info.value) and "not two real numbers" in str(info.value)


# ------------------------------------------------------------------ self-crossing (issue 25)
LEMNISCATE = ("0.02*cos(t)/(1 + sin(t)**2)", "0.02*sin(t)*cos(t)/(1 + sin(t)**2)")


@pytest.mark.parametrize("domain", [(0.0, 2 * math.pi), (0.3, 0.3 + 2 * math.pi), (0.0, 4 * math.pi),
                                    (1.0, 5.0)], ids=["one period", "shifted", "twice", "part"])
def test_lemniscate_is_refused_where_it_crosses(domain):
    """The lemniscate of Bernoulli passes through its centre at t = pi/2 and t = 3 pi/2: the
    check names both parameter values (a sample falls exactly on the crossing in the first
    case, between samples in the others)."""
    c = PlanarCurve(*LEMNISCATE, T, domain, "lemniscate")
    with pytest.raises(InvalidCurveError) as info:
        c.check()
    msg = str(info.value)
    assert "crosses itself" in msg and "'lemniscate'" in msg
    assert "t = 1.5708 and at t = 4.71239" in msg, msg
    assert "shrink the domain" in msg


def test_one_lobe_of_the_lemniscate_is_accepted():
    PlanarCurve(*LEMNISCATE, T, (-1.5, 1.5), "lobe").check()


def test_a_loop_between_the_ends_is_refused():
    """A prolate cycloid's loop, (t - 2 sin t, 1 - 2 cos t): it crosses itself on the axis
    x = 0 at t = -+t_c with t_c = 2 sin t_c (1.895494...), between samples."""
    c = PlanarCurve(T - 2 * sp.sin(T), 1 - 2 * sp.cos(T), T, (-4.0, 4.0), "prolate cycloid")
    with pytest.raises(InvalidCurveError, match="crosses itself") as info:
        c.check()
    ta, tb = (float(v) for v in re.findall(r"t = (-?[\d.]+)", str(info.value))[:2])
    t_c = 1.895494267033981  # the root of t = 2 sin t
    assert ta == pytest.approx(-t_c, abs=1e-4) and tb == pytest.approx(t_c, abs=1e-4)


@pytest.mark.parametrize("make, period", [
    (lambda: library.ellipse(0.02, 0.015, start=math.pi, span=math.pi, clockwise=True), 2 * math.pi),
    (lambda: library.ellipse(0.025, 0.018, span=6.2, clockwise=True), 2 * math.pi),
    (lambda: library.circle(0.01, by="angle", span=20.0), 2 * math.pi),
    (lambda: library.circle(0.01, span=4.0), 2 * math.pi * 0.01),
    (lambda: library.circle(0.01, span=3.0), None),
    (lambda: library.paper_object(), None),
], ids=["ellipse once", "ellipse twice", "circle 3 turns", "circle by arclength", "arc", "catenary"])
def test_closed_contours_going_round_more_than_once_are_not_crossings(make, period):
    """A closed contour may be declared over more than one turn (the contact can go round):
    that is a repetition, found as ``period``, not a self-crossing; the end meeting the start
    is fine."""
    c = make()
    c.check()
    if period is None:
        assert c.period is None and not c.orientation.closed
    else:
        assert c.period == pytest.approx(period, rel=1e-9) and c.orientation.closed


def test_orientation_turning_and_area():
    """Closed: +-2 pi and the enclosed area pi a b with the sign of the direction; an open
    arc: its angle and the fan area from the origin."""
    a, b = 0.02, 0.015
    for clockwise, sgn in ((False, 1), (True, -1)):
        o = library.ellipse(a, b, start=math.pi, span=math.pi, clockwise=clockwise).orientation
        assert o.closed and o.turning == pytest.approx(sgn * 2 * math.pi, rel=1e-9)
        assert o.area == pytest.approx(sgn * math.pi * a * b, rel=1e-4)   # 401-gon
    o = library.circle(0.01, by="angle", span=1.0, clockwise=True).orientation
    assert not o.closed and o.turning == pytest.approx(-2.0, rel=1e-9)
    assert o.area == pytest.approx(-0.5 * 0.01**2 * 2.0, rel=1e-4)


# ------------------------------------------------------------------ direction of travel (issue 25)
OBJECT_CONTOURS = {  # every library object contour, built as the guide says (clockwise)
    "circle": lambda cw: library.circle(0.02, start=math.pi, span=1.5, clockwise=cw),
    "circle by angle": lambda cw: library.circle(0.02, by="angle", start=math.pi, span=math.pi, clockwise=cw),
    "ellipse": lambda cw: library.ellipse(0.020, 0.015, start=math.pi, span=math.pi, clockwise=cw),
    "ellipse twice round": lambda cw: library.ellipse(0.025, 0.018, span=6.2, clockwise=cw),
    "superellipse": lambda cw: library.superellipse(0.02, 0.015, 4, start=math.pi, span=1.0, clockwise=cw),
    "off-centre circle": lambda cw: library.circle(0.1, center=(0.0, 0.02), clockwise=cw),
}


def _validate(fingertip, obj, **kw):
    import grasping_sym as gs

    gs.scenes.planar_finger(fingertip, obj, name="direction", **kw).validate()


@pytest.mark.parametrize("shape", sorted(OBJECT_CONTOURS))
def test_every_library_object_contour_is_accepted_clockwise_and_named_counterclockwise(shape):
    from grasping_sym.errors import InvalidSceneError

    make = OBJECT_CONTOURS[shape]
    u1 = make(True).domain[0] * 0.5 + make(True).domain[1] * 0.5
    _validate(library.paper_fingertip(), make(True), u1_0=u1)
    with pytest.raises(InvalidSceneError) as info:
        _validate(library.paper_fingertip(), make(False), u1_0=u1)
    msg = str(info.value)
    assert "object contour" in msg and "runs counterclockwise about the object" in msg, msg
    assert "clockwise=True" in msg and "points[::-1]" in msg


def test_paper_contours_and_the_hard_cases_keep_their_direction():
    """The paper's catenaries, an object with an inflection, the exact-case disks (the object
    circle's centre off its pivot, the pivot outside it), and a concave hollow whose frame's
    origin is on the material's side (an open arc bent the other way on purpose) pass."""
    _validate(library.paper_fingertip(), library.paper_object())
    _validate(library.paper_fingertip(),
              library.polynomial_graph([-0.02, 0.0, 50.0, -5000.0], (-0.012, 0.012)), u1_0=0.001)
    _validate(library.circle(0.015, (-0.005, 0.0), span=3.0),
              library.circle(0.010, (-0.010, 0.004), start=math.pi, span=3.0, clockwise=True))
    _validate(library.circle(0.015), library.circle(1.01 * 0.015, center=(-0.05, 0.003)))


def test_object_listed_counterclockwise_is_refused_before_the_run():
    """The reviewer's case: an object less curved than the fingertip, listed counterclockwise.
    The relative curvature at the start is positive (40 - 31.25 1/m), so nothing but the
    direction tells that the fingertip is placed inside the object."""
    from grasping_sym.errors import InvalidSceneError

    obj = library.ellipse(0.05, 0.04, span=math.pi, name="big ellipse")   # counterclockwise
    with pytest.raises(InvalidSceneError) as info:
        _validate(library.paper_fingertip(), obj, u1_0=0.0)
    msg = str(info.value)
    assert "object contour 'big ellipse' runs counterclockwise about the object" in msg
    assert "the area it encloses is +0.006283 m^2" in msg          # pi a b, counterclockwise
    assert "fingertip would be put inside the object" in msg and "relative curvature kappa0" not in msg
    _validate(library.paper_fingertip(), library.ellipse(0.05, 0.04, span=math.pi, clockwise=True), u1_0=0.0)


def test_fingertip_listed_clockwise_is_refused():
    from grasping_sym.errors import InvalidSceneError

    with pytest.raises(InvalidSceneError) as info:
        _validate(library.circle(0.01, span=2.0, clockwise=True, name="tip"), library.paper_object())
    msg = str(info.value)
    assert "fingertip contour 'tip' runs clockwise about the fingertip" in msg
    assert "its tangent turns by -4 rad" in msg and "clockwise=False" in msg
