"""Planar contour geometry: curvature against closed forms, and validation of bad curves.

Every expected value here is an analytic formula written independently of
``grasping_sym.geometry`` (no call back into the package computes an expected value).
"""
from __future__ import annotations

import math

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
