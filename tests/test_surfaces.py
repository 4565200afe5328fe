"""Surface geometry: curvatures and Montana's contact forms against closed forms, and validation.

Expected values are analytic formulas written here, or finite differences of the surface
point computed here; none comes from calling back into the quantity under test.
"""
from __future__ import annotations

import math

import numpy as np
import pytest
import sympy as sp

from grasping_sym.errors import InvalidSurfaceError
from grasping_sym.geometry import library
from grasping_sym.geometry import surface_library as sl
from grasping_sym.geometry.surfaces import ParametricSurface, U, V

RNG = np.random.default_rng(20240611)


def rot(axis: np.ndarray, angle: float) -> np.ndarray:
    """Rodrigues' rotation matrix."""
    k = np.asarray(axis, float) / np.linalg.norm(axis)
    Kx = np.array([[0, -k[2], k[1]], [k[2], 0, -k[0]], [-k[1], k[0], 0]])
    return np.eye(3) + math.sin(angle) * Kx + (1 - math.cos(angle)) * Kx @ Kx


R0 = rot([0.3, -1.0, 0.5], 0.7)


def grid(surface: ParametricSurface, n: int = 9, inset: float = 0.02):
    (u0, u1), (v0, v1) = surface.domain
    du, dv = inset * (u1 - u0), inset * (v1 - v0)
    return np.meshgrid(np.linspace(u0 + du, u1 - du, n), np.linspace(v0 + dv, v1 - dv, n), indexing="ij")


# ------------------------------------------------------------------ closed-form curvatures
@pytest.mark.parametrize("placed", [False, True], ids=["local", "rotated"])
def test_sphere_curvatures_normal_and_montana_forms(placed):
    r, c = 0.021, np.array([0.01, -0.02, 0.005])
    s = sl.sphere(r, c, R0, lat=(-1.4, 1.2)) if placed else sl.sphere(r, lat=(-1.4, 1.2))
    s.check()
    u, v = grid(s)
    val = s.evaluate(u, v)
    np.testing.assert_allclose(val["K"], 1 / r**2, rtol=1e-10)
    np.testing.assert_allclose(val["H"], -1 / r, rtol=1e-10)  # outward normal: H < 0
    np.testing.assert_allclose(val["k1"], -1 / r, rtol=1e-6)
    np.testing.assert_allclose(val["k2"], -1 / r, rtol=1e-6)
    centre = c if placed else np.zeros(3)
    np.testing.assert_allclose(val["normal"], (val["point"] - centre) / r, atol=1e-12)
    np.testing.assert_allclose(val["K_p"], np.broadcast_to(np.eye(2) / r, u.shape + (2, 2)), rtol=1e-10, atol=1e-9)
    np.testing.assert_allclose(val["M_p"][..., 0, 0], r * np.cos(v), rtol=1e-12)
    np.testing.assert_allclose(val["M_p"][..., 1, 1], r, rtol=1e-12)
    np.testing.assert_allclose(val["M_p"][..., 0, 1], 0, atol=1e-15)
    np.testing.assert_allclose(val["T_p"][..., 0], np.tan(v) / r, rtol=1e-10, atol=1e-9)
    np.testing.assert_allclose(val["T_p"][..., 1], 0, atol=1e-9)


def test_ellipsoid_gauss_curvature_and_outward_normal():
    a, b, c = 0.03, 0.02, 0.012
    s = sl.ellipsoid(a, b, c)
    s.check()
    val = s.evaluate(*grid(s, 11))
    x, y, z = np.moveaxis(val["point"], -1, 0)
    q = x**2 / a**4 + y**2 / b**4 + z**2 / c**4
    np.testing.assert_allclose(val["K"], 1 / (a**2 * b**2 * c**2 * q**2), rtol=1e-10)
    grad = np.stack([x / a**2, y / b**2, z / c**2], axis=-1)
    np.testing.assert_allclose(val["normal"], grad / np.linalg.norm(grad, axis=-1, keepdims=True), atol=1e-12)
    assert (val["k2"] < 0).all()  # convex, outward normal


def test_torus_curvatures():
    R, r = 0.05, 0.012
    s = sl.torus(R, r)
    s.check()
    u, v = grid(s, 13, inset=0.0)
    val = s.evaluate(u, v)
    np.testing.assert_allclose(val["K"], np.cos(v) / (r * (R + r * np.cos(v))), rtol=1e-9, atol=1e-6)
    np.testing.assert_allclose(val["H"], -(R + 2 * r * np.cos(v)) / (2 * r * (R + r * np.cos(v))), rtol=1e-10)
    expect_n = np.stack([np.cos(v) * np.cos(u), np.cos(v) * np.sin(u), np.sin(v)], axis=-1)
    np.testing.assert_allclose(val["normal"], expect_n, atol=1e-12)


def test_plane_is_flat_with_rotated_normal():
    s = sl.plane(0.1, 0.04, (0.0, 0.01, 0.0), R0)
    s.check()
    assert s.domain == ((-0.05, 0.05), (-0.02, 0.02))
    val = s.evaluate(*grid(s, 5))
    for k in ("K", "H", "L", "M", "N", "K_p", "T_p"):
        np.testing.assert_allclose(val[k], 0.0, atol=1e-14)
    np.testing.assert_allclose(val["normal"], np.broadcast_to(R0[:, 2], val["normal"].shape), atol=1e-14)


def test_superquadric_lies_on_its_implicit_surface_and_n2_is_the_ellipsoid():
    a, b, c = 0.03, 0.02, 0.015
    q = sl.superquadric(a, b, c, 4)
    q.check()
    val = q.evaluate(*grid(q, 9))
    x, y, z = np.moveaxis(val["point"], -1, 0)
    np.testing.assert_allclose((x / a) ** 4 + (y / b) ** 4 + (z / c) ** 4, 1.0, rtol=1e-12)
    grad = np.stack([x**3 / a**4, y**3 / b**4, z**3 / c**4], axis=-1)
    np.testing.assert_allclose(val["normal"], grad / np.linalg.norm(grad, axis=-1, keepdims=True), atol=1e-10)
    e2 = sl.superquadric(a, b, c, 2).evaluate(*grid(q, 9))  # another chart of the ellipsoid
    x, y, z = np.moveaxis(e2["point"], -1, 0)
    qq = x**2 / a**4 + y**2 / b**4 + z**2 / c**4
    np.testing.assert_allclose(e2["K"], 1 / (a**2 * b**2 * c**2 * qq**2), rtol=1e-9)


# ------------------------------------------------------------------ normal curvature, shape operator
@pytest.mark.parametrize("make", [lambda: sl.ellipsoid(0.03, 0.02, 0.012), lambda: sl.superquadric(0.03, 0.02, 0.02)],
                         ids=["ellipsoid", "superquadric"])
def test_normal_curvature_and_shape_operator(make):
    s = make()
    du, dv = sp.symbols("du dv", real=True)
    kn = sp.lambdify((U, V, du, dv), s.normal_curvature(du, dv), "numpy")
    # independent: curvature of the surface curve t -> S(u0 + t du, v0 + t dv), projected on n
    t = sp.Symbol("t")
    u0, v0 = sp.symbols("u0 v0")
    curve = s.S.xreplace({U: u0 + t * du, V: v0 + t * dv})
    c1, c2 = curve.diff(t).subs(t, 0), curve.diff(t, 2).subs(t, 0)
    n_expr = s.normal.xreplace({U: u0, V: v0})
    kn_ref = sp.lambdify((u0, v0, du, dv), c2.dot(n_expr) / c1.dot(c1), "numpy")
    for _ in range(12):
        u, v = RNG.uniform(-3.0, 3.0), RNG.uniform(-1.2, 1.2)
        val = s.evaluate(u, v)
        W = val["shape_operator"]
        np.testing.assert_allclose(np.sort(np.linalg.eigvals(W).real), [val["k1"], val["k2"]], rtol=1e-8)
        np.testing.assert_allclose(np.sort(-np.linalg.eigvalsh(val["K_p"])), [val["k1"], val["k2"]], rtol=1e-8)
        np.testing.assert_allclose(val["K_p"], np.swapaxes(val["K_p"], -1, -2), rtol=1e-12)
        for _ in range(5):
            d = RNG.normal(size=2)
            k = kn(u, v, *d)
            assert k == pytest.approx(kn_ref(u, v, *d), rel=1e-10)
            assert val["k1"] * (1 + 1e-10) <= k <= val["k2"] * (1 - 1e-10)


def test_sphere_christoffel_symbols_closed_form():
    s = sl.sphere(0.02)
    G = [[[sp.lambdify((U, V), s.christoffel[k][i][j], "numpy") for j in range(2)] for i in range(2)]
         for k in range(2)]
    for u, v in RNG.uniform([-3.0, -1.2], [3.0, 1.2], size=(10, 2)):
        # u longitude, v latitude: E = r^2 cos^2 v, F = 0, G = r^2
        expect = {(0, 0, 0): 0, (0, 0, 1): -math.tan(v), (0, 1, 0): -math.tan(v), (0, 1, 1): 0,
                  (1, 0, 0): math.sin(v) * math.cos(v), (1, 0, 1): 0, (1, 1, 0): 0, (1, 1, 1): 0}
        for (k, i, j), e in expect.items():
            assert float(G[k][i][j](u, v)) == pytest.approx(e, abs=1e-12)


# ------------------------------------------------------------------ Montana's forms, any chart
def _fd_frame_derivatives(s: ParametricSurface, u: float, v: float, h: float = 1e-5):
    """[x y]^T [n_u n_v] and y^T [x_u x_v] by central differences of the frame."""
    def frame(uu, vv):
        val = s.evaluate(uu, vv)
        return val["x"], val["y"], val["normal"]
    x, y, n = frame(u, v)
    (xu_p, _, nu_p), (xu_m, _, nu_m) = frame(u + h, v), frame(u - h, v)
    (xv_p, _, nv_p), (xv_m, _, nv_m) = frame(u, v + h), frame(u, v - h)
    n_u, n_v = (nu_p - nu_m) / (2 * h), (nv_p - nv_m) / (2 * h)
    x_u, x_v = (xu_p - xu_m) / (2 * h), (xv_p - xv_m) / (2 * h)
    dn = np.array([[x @ n_u, x @ n_v], [y @ n_u, y @ n_v]])
    dx = np.array([y @ x_u, y @ x_v])
    return dn, dx


@pytest.mark.parametrize("name", ["ellipsoid", "sheared sphere", "torus", "superquadric"])
def test_montana_forms_against_finite_differences(name):
    r = 0.02
    s = {
        "ellipsoid": lambda: sl.ellipsoid(0.03, 0.02, 0.012, rotation=R0),
        # a non-orthogonal chart of a sphere: K_p must still be I/r
        "sheared sphere": lambda: ParametricSurface(
            [r * sp.cos(V) * sp.cos(U + sp.Rational(1, 2) * V), r * sp.cos(V) * sp.sin(U + sp.Rational(1, 2) * V),
             r * sp.sin(V)], (U, V), ((-3, 3), (-1.2, 1.2)), "sheared"),
        "torus": lambda: sl.torus(0.05, 0.012),
        "superquadric": lambda: sl.superquadric(0.03, 0.02, 0.02),
    }[name]()
    for u, v in RNG.uniform([-2.5, -1.1], [2.5, 1.1], size=(6, 2)):
        val = s.evaluate(u, v)
        M = val["M_p"]
        S_u = (s.evaluate(u + 1e-6, v)["point"] - s.evaluate(u - 1e-6, v)["point"]) / 2e-6
        S_v = (s.evaluate(u, v + 1e-6)["point"] - s.evaluate(u, v - 1e-6)["point"]) / 2e-6
        frame = np.stack([val["x"], val["y"]])
        np.testing.assert_allclose(frame @ np.stack([S_u, S_v], axis=1), M, rtol=1e-6, atol=1e-9)
        np.testing.assert_allclose(np.cross(val["normal"], val["x"]), val["y"], atol=1e-12)
        dn, dx = _fd_frame_derivatives(s, u, v)
        scale = np.abs(dn).max()
        np.testing.assert_allclose(val["K_p"] @ M, dn, atol=1e-7 * scale)
        np.testing.assert_allclose(val["T_p"] @ M, dx, atol=1e-7 * max(np.abs(dx).max(), 1.0))
        if name == "sheared sphere":
            assert abs(val["F"]) > 1e-6  # really non-orthogonal
            np.testing.assert_allclose(val["K_p"], np.eye(2) / r, rtol=1e-9, atol=1e-8)


# ------------------------------------------------------------------ surfaces of revolution
def test_revolved_circle_is_the_sphere_and_the_torus():
    r, R = 0.02, 0.05
    rev = sl.surface_of_revolution(library.circle(r, by="angle", span=1.3))
    sph = sl.sphere(r)
    assert rev.domain == sph.domain
    uv = grid(sph, 7)
    a, b = rev.evaluate(*uv), sph.evaluate(*uv)
    for k in ("point", "normal", "K", "H", "K_p", "T_p"):
        np.testing.assert_allclose(a[k], b[k], rtol=1e-12, atol=1e-12)
    tor = sl.surface_of_revolution(library.circle(r, (R, 0.0), by="angle", span=math.pi))
    u, v = grid(tor, 9, inset=0.0)
    t = tor.evaluate(u, v)
    np.testing.assert_allclose(t["K"], np.cos(v) / (r * (R + r * np.cos(v))), rtol=1e-9, atol=1e-6)
    np.testing.assert_allclose(t["point"], sl.torus(R, r).evaluate(u, v)["point"], atol=1e-15)


def test_revolution_about_y_of_an_ellipse():
    a, b = 0.02, 0.03  # spheroid with equatorial radius a, polar semi-axis b along y
    s = sl.surface_of_revolution(library.ellipse(a, b, span=1.2), axis="y")
    s.check()
    val = s.evaluate(*grid(s, 7))
    x, y, z = np.moveaxis(val["point"], -1, 0)
    np.testing.assert_allclose((x**2 + z**2) / a**2 + y**2 / b**2, 1.0, rtol=1e-12)
    q = (x**2 + z**2) / a**4 + y**2 / b**4
    np.testing.assert_allclose(val["K"], 1 / (a**4 * b**2 * q**2), rtol=1e-10)
    assert (np.einsum("...i,...i", val["normal"], val["point"]) > 0).all()  # outward


# ------------------------------------------------------------------ validation
def test_pole_is_reported_as_not_regular_with_its_point():
    r = 0.02
    s = ParametricSurface([r * sp.cos(V) * sp.cos(U), r * sp.cos(V) * sp.sin(U), r * sp.sin(V)],
                          (U, V), ((-math.pi, math.pi), (-1.0, math.pi / 2)), "through a pole")
    with pytest.raises(InvalidSurfaceError) as err:
        s.check()
    msg = str(err.value)
    assert "not regular" in msg and "1.5708" in msg and "pole" in msg
    sl.sphere(r).check()  # the library chart stops short of the poles


def test_non_smooth_free_symbols_and_bad_domain_all_reported():
    a, w = sp.symbols("a w")
    with pytest.raises(InvalidSurfaceError) as err:
        ParametricSurface([sp.Abs(U), a * V, sp.Piecewise((U, U > 0), (0, True))], (U, V),
                          ((1.0, 0.0), (0.0, math.inf)), "bad")
    problems = err.value.problems
    assert len(problems) == 5, problems
    text = "\n".join(problems)
    for word in ("u-domain", "v-domain", "non-smooth", "free symbols a", "piecewise"):
        assert word in text
    with pytest.raises(InvalidSurfaceError, match="non-smooth"):
        ParametricSurface([U, V, sp.Max(U, V)])
    with pytest.raises(InvalidSurfaceError, match="free symbols w"):
        ParametricSurface([U, V, w * U * V])
    with pytest.raises(InvalidSurfaceError, match="exactly three"):
        ParametricSurface([U, V])


def test_library_numbers_are_validated_together():
    with pytest.raises(InvalidSurfaceError) as err:
        sl.sphere(-1.0, (0, 0, float("nan")), np.diag([1.0, 1.0, -1.0]), lat=(-1.0, 2.0))
    assert len(err.value.problems) == 4
    with pytest.raises(InvalidSurfaceError) as err:
        sl.superquadric(0.1, float("inf"), 0.1, n=3)
    assert len(err.value.problems) == 2
    with pytest.raises(InvalidSurfaceError, match="must exceed"):
        sl.torus(0.01, 0.02)
    with pytest.raises(InvalidSurfaceError, match="radius x"):
        sl.surface_of_revolution(library.circle(0.02, by="angle", span=2.0))
    with pytest.raises(InvalidSurfaceError, match="axis"):
        sl.surface_of_revolution(library.circle(0.02, by="angle"), axis="w")


def test_parameters_are_renamed_and_key_is_content_based():
    a, b = sp.symbols("a b")
    s1 = ParametricSurface([b, a, a * b], (b, a), ((0, 1), (0, 2)))  # note the swap
    assert s1.S[0] == U and s1.S[1] == V
    s2 = ParametricSurface([U, V, U * V], (U, V), ((0, 1), (0, 2)), "other name")
    assert s1.key() == s2.key()
    assert s1.key() != ParametricSurface([U, V, U * V], (U, V), ((0, 1), (0, 3))).key()
    assert sl.ellipsoid(0.03, 0.02, 0.01).key() != sl.ellipsoid(0.03, 0.02, 0.011).key()
    val = s2.evaluate(np.zeros((4, 3)), 0.5)
    assert val["point"].shape == (4, 3, 3) and val["K_p"].shape == (4, 3, 2, 2) and val["K"].shape == (4, 3)


# ------------------------------------------------------------------ number types (issue 25)
@pytest.mark.parametrize("kind", [np.float32, np.float16, np.int64, np.array],
                         ids=["float32", "float16", "int64", "0-d array"])
def test_library_surfaces_accept_any_real_number_type(kind):
    """Sizes, placements and chart ranges from NumPy arrays: the same surfaces as floats."""
    def val(x):
        return kind(x)

    s = sl.sphere(val(2), center=(val(0), val(1), val(0)), lon=(val(-1), val(1)), lat=(val(-1), val(1)))
    assert s.domain == ((-1.0, 1.0), (-1.0, 1.0))
    def point(surface, u, v):  # the chart's point only (no lambdify of the curvature forms)
        return np.array([float(c.subs({U: u, V: v})) for c in surface.S])

    np.testing.assert_allclose(point(s, 0.0, 0.0), [2.0, 1.0, 0.0], rtol=1e-12)
    e = sl.ellipsoid(val(3), val(2), val(1))
    np.testing.assert_allclose(point(e, math.pi / 2, 0.0), [0.0, 2.0, 0.0], atol=1e-12)
    q = sl.superquadric(val(2), val(2), val(1), n=np.int64(4))
    np.testing.assert_allclose(point(q, 0.0, 0.0), [2.0, 0.0, 0.0], atol=1e-12)
    t = sl.torus(val(3), val(1))
    np.testing.assert_allclose(point(t, 0.0, 0.0), [4.0, 0.0, 0.0], atol=1e-12)
    p = sl.plane(val(2), val(4), rotation=np.eye(3, dtype=np.float32))
    assert p.domain == ((-1.0, 1.0), (-2.0, 2.0))
    f = ParametricSurface([U, V, val(1)], (U, V), ((val(0), val(1)), (val(0), val(1))))
    assert f.domain == ((0.0, 1.0), (0.0, 1.0)) and point(f, 0.5, 0.5)[2] == 1.0


def test_float32_radius_is_its_float_value():
    s = sl.sphere(np.float32(0.01))
    r = float(sp.sqrt(sum(c**2 for c in s.S)).subs({U: 0.3, V: 0.2}))
    assert r == pytest.approx(float(np.float32(0.01)), rel=1e-15) and r != pytest.approx(0.01, rel=1e-12)


def test_library_surfaces_name_what_is_not_a_real_number():
    with pytest.raises(InvalidSurfaceError) as err:
        sl.sphere(True, center=("0", "0", "0"), lon=("a", 1))
    problems = "\n".join(err.value.problems)
    assert len(err.value.problems) == 3, problems
    for w in ("radius = True must be a finite positive number", "lon = ('a', 1) must be a pair of numbers",
              "center = ('0', '0', '0') must be three finite numbers"):
        assert w in problems, problems
    with pytest.raises(InvalidSurfaceError) as err:
        sl.torus(1j, "0.01")
    assert "R = 1j must be" in str(err.value) and "r = '0.01' must be" in str(err.value)
    with pytest.raises(InvalidSurfaceError, match=r"n = 4\.0 must be an even integer"):
        sl.superquadric(0.1, 0.1, 0.1, n=4.0)
    with pytest.raises(InvalidSurfaceError, match="must be a finite positive number"):
        sl.ellipsoid(np.float32("nan"), 0.1, 0.1)


@pytest.mark.parametrize("domain", [(("a", 1), (0, 1)), ("ab", (0, 1)), ((0, 1),), ((0, 1), (0, True)),
                                    5], ids=["string", "string pair", "one pair", "bool", "number"])
def test_surface_domain_that_is_not_numbers_is_named(domain):
    with pytest.raises(InvalidSurfaceError) as err:
        ParametricSurface([U, V, U * V], (U, V), domain, "bad domain")
    msg = str(err.value)
    assert f"domain = {domain!r} is not two pairs of real numbers" in msg
    assert "((u_min, u_max), (v_min, v_max))" in msg and "'bad domain'" in msg
    with pytest.raises(InvalidSurfaceError) as err:  # listed with the other problems
        ParametricSurface([U, V, sp.Symbol("w") * U], (U, V), domain, "bad domain")
    assert len(err.value.problems) == 2 and "free symbols w" in str(err.value)
