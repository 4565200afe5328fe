"""Contact kinematics of two surfaces (Montana 1988) against exact answers and the contact constraints.

The finger is fixed; the object's pose (position and unit quaternion) is integrated from the
prescribed relative motion together with the contact coordinates, and the two are compared:
exactly known rotations for a sphere on a plane (docs/conventions.md section 3), and the constraints
"points coincide, normals opposite, frames differ by psi" for arbitrary surfaces.
"""
from __future__ import annotations

import math

import numpy as np
import pytest
import sympy as sp
from scipy.integrate import solve_ivp

from grasping_sym.derive import contact3d as c3
from grasping_sym.geometry import surface_library as sl
from grasping_sym.geometry.surfaces import ParametricSurface, U, V
from tests.oracles import contact3d_numeric as c3n

RNG = np.random.default_rng(3)
TOL = {"rtol": 1e-12, "atol": 1e-14, "method": "DOP853"}
MAX_RHS_CALLS = 40_000


def rot(axis, angle: float) -> np.ndarray:
    """Rodrigues' rotation matrix: right-handed turn by ``angle`` about ``axis``."""
    k = np.asarray(axis, float) / np.linalg.norm(axis)
    Kx = np.array([[0, -k[2], k[1]], [k[2], 0, -k[0]], [-k[1], k[0], 0]])
    return np.eye(3) + math.sin(angle) * Kx + (1 - math.cos(angle)) * Kx @ Kx


def quat_of(R: np.ndarray) -> np.ndarray:
    """Unit quaternion ``(w, x, y, z)`` of a rotation matrix (Shepperd: pivot on the largest)."""
    t = np.array([np.trace(R), R[0, 0], R[1, 1], R[2, 2]])
    i = int(np.argmax(t))
    if i == 0:
        w = math.sqrt(1 + t[0]) / 2
        return np.array([w, R[2, 1] - R[1, 2], R[0, 2] - R[2, 0], R[1, 0] - R[0, 1]]) / np.array([1, *[4 * w] * 3])
    j, k = i % 3, (i + 1) % 3                      # the other two axes (0-based), cyclic
    a = math.sqrt(max(1 + 2 * R[i - 1, i - 1] - t[0], 0.0)) / 2
    q = np.zeros(4)
    q[i] = a
    q[0] = (R[k, j] - R[j, k]) / (4 * a)
    q[1 + j] = (R[j, i - 1] + R[i - 1, j]) / (4 * a)
    q[1 + k] = (R[k, i - 1] + R[i - 1, k]) / (4 * a)
    return q


def rot_of(q: np.ndarray) -> np.ndarray:
    w, x, y, z = q / np.linalg.norm(q)
    return np.array([[1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
                     [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
                     [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)]])


def quat_rate(omega: np.ndarray, q: np.ndarray) -> np.ndarray:
    """``q' = (0, omega) * q / 2`` for a world (spatial) angular velocity: ``R' = [omega]x R``."""
    w, x, y, z = q
    ox, oy, oz = omega
    return 0.5 * np.array([-ox * x - oy * y - oz * z, ox * w + oy * z - oz * y,
                           oy * w + oz * x - ox * z, oz * w + ox * y - oy * x])


def integrate(surf_f, pose_f, surf_o, eta0, t_span, w_of_t, v_of_t=None, t_eval=None):
    """Integrate ``eta`` with :func:`contact_rates` and the object pose from its twist, jointly.

    The twist is ``omega_o = C_f w``, ``p_o' = C_f v - omega_o x (c - p_o)`` (finger fixed);
    state ``(eta, p_o, q_o)``. Returns the solution and ``pose(y)``.
    """
    R0, p0 = c3n.object_pose_from_contact(surf_f, pose_f, surf_o, eta0)
    y0 = np.concatenate([eta0, p0, quat_of(R0)])

    calls = [0]

    def rhs(t, y):
        calls[0] += 1
        if calls[0] > MAX_RHS_CALLS:  # fail, not hang, if wrong rates make the integration stiff
            raise RuntimeError(f"more than {MAX_RHS_CALLS} right-hand-side calls by t = {t:.6g}")
        w = w_of_t(t)
        v = np.zeros(3) if v_of_t is None else v_of_t(t)
        cf = c3n.contact_frame_world(surf_f, *pose_f, y[0], y[1])
        omega, p_dot = c3n.object_twist(cf.frame, cf.point, y[5:8], w, v)
        return np.concatenate([c3n.contact_rates(surf_f, surf_o, y[:5], w, v[:2]), p_dot, quat_rate(omega, y[8:])])

    sol = solve_ivp(rhs, t_span, y0, t_eval=t_eval, **TOL)
    assert sol.success, sol.message
    return sol, R0, p0


def residual_max(surf_f, pose_f, surf_o, sol) -> float:
    return max(c3n.contact_residuals(surf_f, pose_f, surf_o, (rot_of(y[8:]), y[5:8]), y[:5])["max"]
               for y in sol.y.T)


# ------------------------------------------------------------------ signs, symbolic = numeric
def test_sphere_on_plane_signs():
    """Object sphere rolling about +y on the plane z = 0 moves the contact along +x at r w_y.

    The sphere's centre is above the plane (the plane's normal, +z, points into the sphere), so
    the rolling sphere's centre moves with ``omega x (centre - contact) = (r w_y, 0, 0)``; the
    contact follows it. Without spin ``psi`` changes only as the ball's chart frame turns along
    the path (``T_o``; the plane's ``T_f = 0``), and ``w_z`` turns the
    object counterclockwise about ``n_f``, which decreases ``psi`` (the angle from x_o to x_f).
    """
    r, plane, ball = 0.05, sl.plane(1, 1), sl.sphere(0.05)
    eta = [0.1, -0.2, 0.4, 0.3, 0.7]
    g = ball.evaluate(0.4, 0.3)
    d = c3n.contact_rates(plane, ball, eta, [0.0, 2.0, 0.0])
    assert d[0] == pytest.approx(r * 2.0) and abs(d[1]) < 1e-15
    assert d[4] == pytest.approx(g["T_p"] @ g["M_p"] @ d[2:4], abs=1e-14)  # only the chart frame turns
    d = c3n.contact_rates(plane, ball, eta, [-2.0, 0.0, 0.0])
    assert d[1] == pytest.approx(r * 2.0) and abs(d[0]) < 1e-15
    d = c3n.contact_rates(plane, ball, eta, [0.0, 0.0, 1.5])
    assert np.allclose(d, [0, 0, 0, 0, -1.5], atol=1e-15)
    # pure translation of the ball along +x: the contact follows it on the plane, stays on the ball
    d = c3n.contact_rates(plane, ball, eta, [0, 0, 0], [0.3, 0.0])
    assert np.allclose(d[:2], [0.3, 0.0], atol=1e-15) and np.allclose(d[2:], 0, atol=1e-15)
    # a plane (object) sliding by +x over a fixed ball (finger): the contact stays on the ball and
    # moves by -v over the plane, in the plane's frame: R_psi M_o alpha_o' = -v
    d = c3n.contact_rates(ball, plane, [0.4, 0.3, 0.1, -0.2, 0.7], [0, 0, 0], [0.3, 0.0])
    assert np.allclose(d[:2], 0, atol=1e-15)
    assert np.allclose(c3.r_psi(0.7) @ d[2:4], [-0.3, 0.0], atol=1e-14)


def test_symbolic_equals_numeric():
    """Generic symbolic forms and the surfaces' own forms give the numeric evaluator's rates."""
    ff, fo = c3.MontanaForms.generic("f"), c3.MontanaForms.generic("o")
    psi, wx, wy, wz, vx, vy = sp.symbols("psi w_x w_y w_z v_x v_y", real=True)
    rates = c3.contact_rates_symbolic(ff, fo, psi, (wx, wy, wz), (vx, vy))
    fn = sp.lambdify([*ff.entries(), *fo.entries(), psi, wx, wy, wz, vx, vy], list(rates.vector), "math")
    fin = sl.ellipsoid(0.04, 0.025, 0.03, rotation=rot([1, 2, 0.5], 0.4))
    obj = sl.ellipsoid(0.05, 0.035, 0.02)
    for _ in range(5):
        eta = [*RNG.uniform(-1, 1, 4), RNG.uniform(-3, 3)]
        w, v = RNG.normal(size=3), RNG.normal(size=2) * 0.02
        vals = [*c3n.forms_from_evaluation(fin.evaluate(*eta[:2])).entries(),
                *c3n.forms_from_evaluation(obj.evaluate(*eta[2:4])).entries()]
        sym = np.array(fn(*vals, eta[4], *w, *v))
        assert np.allclose(sym, c3n.contact_rates(fin, obj, eta, w, v), rtol=1e-11, atol=1e-12)
    # the surface-specific equations (a sphere on a torus: small expressions)
    tor, ball = sl.torus(0.06, 0.02), sl.sphere(0.03)
    eq = c3.contact_equations(tor, ball, sliding=True)
    f2 = sp.lambdify([*eq.coords, *eq.w, *eq.v], list(eq.rates.vector), "math")
    eta, w, v = [0.3, 0.2, -0.5, 0.4, 1.1], [0.3, -0.7, 0.2], [0.01, -0.02]
    assert np.allclose(f2(*eta, *w, *v), c3n.contact_rates(tor, ball, eta, w, v), rtol=1e-11, atol=1e-12)


def test_relative_motion_round_trip():
    """:func:`relative_motion` inverts :func:`object_twist` (fixed finger) and is frame-consistent."""
    C = rot(RNG.normal(size=3), 1.1)
    c, p_o = RNG.normal(size=3), RNG.normal(size=3)
    w, v = RNG.normal(size=3), np.array([*RNG.normal(size=2), 0.0])
    omega, p_dot = c3n.object_twist(C, c, p_o, w, v)
    v2, w2 = c3n.relative_motion(C, c, (np.zeros(3), np.zeros(3), np.zeros(3)), (omega, p_dot, p_o))
    assert np.allclose(v2, v, atol=1e-14) and np.allclose(w2, w, atol=1e-14)


# ------------------------------------------------------------------ docs/conventions.md section 3
def _circle_setup(r: float, Rc: float):
    """Sphere (object) of radius r on the plane z = 0 (finger, fixed at the identity).

    The contact on the plane starts at (Rc, 0) and runs counterclockwise (about +z) round the
    circle of radius Rc centred at the origin O at the angle ``phi = 2 pi t``. Rolling without
    spin about the contact: ``w = -(Rc phi'/r) (cos phi, sin phi, 0)`` in the plane's frame
    (horizontal, along the line from O to the contact). The sphere's chart is placed so that its
    pole axis (body z) points from the sphere's centre to O: contact at latitude
    ``atan(r/Rc)`` (polar angle ``beta`` with ``tan beta = Rc/r``), ``psi = pi/2``.
    """
    plane, ball = sl.plane(4 * Rc, 4 * Rc), sl.sphere(r)
    pose_f = (np.eye(3), np.zeros(3))
    phid = 2 * math.pi
    eta0 = np.array([Rc, 0.0, 0.0, math.atan2(r, Rc), math.pi / 2])

    def w_of_t(t):
        phi = phid * t
        return -(Rc * phid / r) * np.array([math.cos(phi), math.sin(phi), 0.0])

    return plane, pose_f, ball, eta0, w_of_t


def test_sphere_rolls_once_round_a_circle_without_spin():
    """docs/conventions.md section 3: one lap turns the sphere by 2 pi sqrt(1 + (R/r)^2) about C -> O.

    Measured: ``R_end R_start^T`` (world) against the rotation by ``2 pi sqrt(1 + (R/r)^2)``,
    right-handed about the unit vector from the sphere's centre C to the circle's centre O,
    for the counterclockwise lap (about the plane's normal) of ``_circle_setup``. The contact
    curve on the sphere is the circle of latitude ``v_o = atan(r/R)`` about that axis.
    """
    r, Rc = 0.03, 0.07
    plane, pose_f, ball, eta0, w_of_t = _circle_setup(r, Rc)
    sol, R0, p0 = integrate(plane, pose_f, ball, eta0, (0.0, 1.0), w_of_t, t_eval=np.linspace(0, 1, 41))
    L = math.hypot(Rc, r)
    a0 = np.array([-Rc, 0.0, -r]) / L                      # from C = (Rc, 0, r) to O = 0
    assert np.allclose(p0, [Rc, 0, r], atol=1e-15) and np.allclose(R0 @ [0, 0, 1], a0, atol=1e-15)
    uf, vf, uo, vo, psi = sol.y[:5]
    assert np.max(np.abs(np.hypot(uf, vf) - Rc)) < 1e-10                      # circle on the plane
    assert np.max(np.abs(vo - math.atan2(r, Rc))) < 1e-10                     # circle of latitude
    assert np.max(np.abs(np.arctan2(vf, uf)[1:-1] - 2 * math.pi * sol.t[1:-1]
                         + 2 * math.pi * (sol.t[1:-1] > 0.5))) < 1e-9           # at constant speed
    R1 = rot_of(sol.y[8:, -1])
    expected = rot(a0, 2 * math.pi * math.sqrt(1 + (Rc / r) ** 2))
    assert np.max(np.abs(R1 @ R0.T - expected)) < 1e-8
    # the same as an angle (mod 2 pi) about a0
    Rrel = R1 @ R0.T
    ang = math.atan2(0.5 * a0 @ np.array([Rrel[2, 1] - Rrel[1, 2], Rrel[0, 2] - Rrel[2, 0], Rrel[1, 0] - Rrel[0, 1]]),
                     0.5 * (np.trace(Rrel) - 1))
    assert abs(math.remainder(ang - 2 * math.pi * math.sqrt(1 + (Rc / r) ** 2), 2 * math.pi)) < 1e-8
    assert np.allclose(sol.y[5:8, -1], p0, atol=1e-10)
    assert residual_max(plane, pose_f, ball, sol) < 1e-10


def test_holonomy_of_a_circle_of_latitude():
    """A closed contact path on the sphere enclosing the cap of area A turns it by A/r^2 about n.

    Same rolling as the lap test, stopped when the contact on the sphere has gone once round
    its circle of latitude (after ``phi = 2 pi cos(beta)`` on the plane; ``u_o`` falls by 2 pi):
    the contact is back at the same material point of the sphere. The path turns left on the
    plane about the plane's normal +z, hence *right* on the sphere about its outward normal
    (the normals are opposite); the cap around the pole axis, ``A = 2 pi r^2 (1 - cos beta)``,
    lies on that side. Measured: the sphere's orientation change ``R_end R_start^T`` (world)
    is the rotation by ``-A/r^2`` about +z (clockwise seen from the sphere's side); equivalently
    ``psi`` has grown by ``A/r^2``, as ``R_end R_start^T = Rz(psi_start - psi_end)`` whenever
    both contacts are back at their starting material points on a plane finger.
    """
    r, Rc = 0.04, 0.03
    plane, pose_f, ball, eta0, w_of_t = _circle_setup(r, Rc)
    cb = r / math.hypot(Rc, r)
    sol, R0, _ = integrate(plane, pose_f, ball, eta0, (0.0, cb), w_of_t, t_eval=np.linspace(0, cb, 21))
    y1 = sol.y[:, -1]
    assert abs(y1[2] - eta0[2] + 2 * math.pi) < 1e-10 and abs(y1[3] - eta0[3]) < 1e-10
    A = 2 * math.pi * r**2 * (1 - cb)
    assert np.max(np.abs(rot_of(y1[8:]) @ R0.T - rot([0, 0, 1], -A / r**2))) < 1e-8
    assert abs(math.remainder(y1[4] - eta0[4] - A / r**2, 2 * math.pi)) < 1e-9
    assert residual_max(plane, pose_f, ball, sol) < 1e-10


def test_holonomy_of_a_geodesic_triangle():
    """Three quarter great circles, 90-degree corners: the octant, A = pi r^2 / 2, turns by pi/2.

    The plane path is three straight legs of length ``pi r/2``, each turned 90 degrees left
    (counterclockwise about +z) from the previous one; on the sphere they are the edges of an
    octant with vertices on the body's axes (``r e_x``, ``r e_y``, ``-r e_z``: right turns
    about the outward normal, the octant on that side, ``A = 4 pi r^2 / 8``). Rolling stops at
    each corner. The sphere's chart is rotated (pole along body (1, 1, 1)) so the path stays
    35 degrees or more from its poles. Measured: the contact ends at the starting material point
    ``r e_x`` and ``R_end R_start^T = Rz(-A/r^2) = Rz(-pi/2)``, as for the cap.
    """
    r = 0.025
    k = np.array([1.0, 1.0, 1.0]) / math.sqrt(3)
    Rb = rot(np.cross([0, 0, 1], k), math.acos(k[2]))   # shape z -> body (1, 1, 1)
    plane, ball = sl.plane(0.5, 0.5), sl.sphere(r, rotation=Rb)
    d = Rb.T @ [1.0, 0, 0]
    eta = np.array([0.01, -0.02, math.atan2(d[1], d[0]), math.asin(d[2]), 0.3])
    pose_f = (np.eye(3), np.zeros(3))
    R0, _ = c3n.object_pose_from_contact(plane, pose_f, ball, eta)
    # Without slip the contact moves in the same world direction over both surfaces, so the
    # first leg runs along the world image of body e_y (tangent at r e_x) to reach r e_y.
    d0 = R0 @ [0.0, 1.0, 0.0]
    assert abs(d0[2]) < 1e-15
    R, p = R0, None
    corners = []
    for leg in range(3):
        th = math.atan2(d0[1], d0[0]) + leg * math.pi / 2   # rolling direction on the plane
        w = np.array([-math.sin(th), math.cos(th), 0.0])      # speed r: w = n x d, |w| = 1 rad/s
        sol, Rs, ps = integrate(plane, pose_f, ball, eta, (0.0, math.pi / 2), lambda t, w=w: w)
        if p is not None:                                     # restart from the integrated pose
            assert np.allclose(Rs, R, atol=1e-10) and np.allclose(ps, p, atol=1e-12)
        eta, p, R = sol.y[:5, -1], sol.y[5:8, -1], rot_of(sol.y[8:, -1])
        assert residual_max(plane, pose_f, ball, sol) < 1e-10
        corners.append(ball.evaluate(eta[2], eta[3])["point"] / r)
    assert np.allclose(corners[0], [0, 1, 0], atol=1e-10)
    assert np.allclose(corners[1], [0, 0, -1], atol=1e-10)
    assert np.allclose(ball.evaluate(eta[2], eta[3])["point"], [r, 0, 0], atol=1e-11)
    assert np.max(np.abs(R @ R0.T - rot([0, 0, 1], -math.pi / 2))) < 1e-8


# ------------------------------------------------------------------ arbitrary surfaces
def _smooth_random(n: int, scale: float, seed: int):
    rng = np.random.default_rng(seed)
    amp, freq, phase = rng.normal(size=(3, n)) * scale, rng.uniform(0.5, 4.0, (3, n)), rng.uniform(0, 6.3, (3, n))
    return lambda t: np.sum(amp * np.sin(freq * t + phase), axis=1)


CASES = {
    "ellipsoid on ellipsoid, rolling": (
        lambda: sl.ellipsoid(0.04, 0.025, 0.03), lambda: sl.ellipsoid(0.05, 0.035, 0.02),
        [0.2, 0.1, -0.4, 0.3, 0.8], False),
    "ellipsoid on ellipsoid, sliding": (
        lambda: sl.ellipsoid(0.04, 0.025, 0.03), lambda: sl.ellipsoid(0.05, 0.035, 0.02),
        [0.2, 0.1, -0.4, 0.3, 0.8], True),
    "ellipsoid on torus patch, rolling": (
        lambda: sl.torus(0.06, 0.02, u=(-1.5, 1.5), v=(-1.2, 1.2)),
        lambda: sl.ellipsoid(0.03, 0.045, 0.02), [0.1, 0.2, 1.9, -0.2, -1.0], False),
}


@pytest.mark.parametrize("case", list(CASES))
def test_constraints_hold_along_arbitrary_motion(case):
    """Contact points coincide, normals are opposite and frames differ by psi to 1e-9 all along.

    The finger sits at a generic fixed pose; the object's pose is integrated from the prescribed
    relative motion (smooth random w, and v for sliding) and the contact coordinates from
    :func:`contact_rates`: two independent integrations of the same motion that agree only if
    every sign in the contact equations is right.
    """
    make_f, make_o, eta0, sliding = CASES[case]
    surf_f, surf_o = make_f(), make_o()
    pose_f = (rot([0.3, -1.0, 0.5], 0.7), np.array([0.01, -0.02, 0.03]))
    w_of_t = _smooth_random(3, 2.0, 11)
    v_of_t = None
    if sliding:
        vv = _smooth_random(3, 0.01, 12)
        v_of_t = lambda t: np.array([*vv(t)[:2], 0.0])  # noqa: E731
    sol, _, _ = integrate(surf_f, pose_f, surf_o, np.array(eta0), (0.0, 1.5), w_of_t, v_of_t,
                          t_eval=np.linspace(0, 1.5, 61))
    assert residual_max(surf_f, pose_f, surf_o, sol) < 1e-9
    moved = np.ptp(sol.y[:4], axis=1)
    assert np.all(moved > 0.15), f"the contact hardly moved: {moved}"
    assert np.all(np.abs(sol.y[[1, 3]]) < 1.25)               # kept away from the charts' poles
    for y in sol.y.T[::10]:
        rep = c3n.relative_curvature_report(surf_f.evaluate(*y[:2])["K_p"], surf_o.evaluate(*y[2:4])["K_p"], y[4])
        assert rep.name == "regular" and rep.min_eigenvalue > 0


# ------------------------------------------------------------------ singular relative curvature
def _concave(surface: ParametricSurface) -> ParametricSurface:
    """The same point set with the parameters swapped: the normal (and K_p) flip sign."""
    (a, b), (c, d) = surface.domain
    return ParametricSurface(surface.S, (V, U), ((c, d), (a, b)), f"concave {surface.name}")


def test_flat_on_flat_is_reported():
    plane = sl.plane(1, 1)
    rep = c3n.relative_curvature_report(plane.evaluate(0, 0)["K_p"], plane.evaluate(0.1, 0.2)["K_p"], 0.4)
    assert rep.singular and rep.name == "flat on flat" and rep.det == 0
    with pytest.raises(c3n.RelativeCurvatureSingularError, match="flat on flat") as exc:
        c3n.contact_rates(plane, plane, [0, 0, 0.1, 0.2, 0.4], [0.0, 1.0, 0.0])
    assert exc.value.report.name == "flat on flat" and exc.value.eta[4] == 0.4


def test_matched_concave_on_convex_is_reported():
    r = 0.03
    ball, cup = sl.sphere(r), _concave(sl.sphere(r))
    assert np.allclose(cup.evaluate(0.3, 0.2)["K_p"], -np.eye(2) / r)
    eta = [0.2, 0.1, 0.1, 0.3, 1.3]
    with pytest.raises(c3n.RelativeCurvatureSingularError, match="matched concave on convex"):
        c3n.contact_rates(ball, cup, eta, [0.5, 0.0, 0.0])
    # a larger cup is regular, a smaller one would interpenetrate
    big = _concave(sl.sphere(2 * r))
    rep = c3n.relative_curvature_report(ball.evaluate(0.2, 0.1)["K_p"], big.evaluate(0.1, 0.3)["K_p"], 1.3)
    assert rep.name == "regular" and np.allclose(rep.eigenvalues, 1 / (2 * r))
    small = _concave(sl.sphere(r / 2))
    rep = c3n.relative_curvature_report(ball.evaluate(0.2, 0.1)["K_p"], small.evaluate(0.1, 0.3)["K_p"], 1.3)
    assert rep.name == "interpenetrating" and not rep.singular
    # the symbolic relative curvature is identically singular too
    eq = c3.contact_equations(ball, cup)
    assert abs(float(eq.rates.det.subs(dict(zip(eq.coords, eta))))) < 1e-9


def test_cylinder_on_plane_is_a_line_contact():
    r = 0.02
    cyl = ParametricSurface((r * sp.cos(U), r * sp.sin(U), V), (U, V), ((-3, 3), (-0.1, 0.1)), "cylinder")
    rep = c3n.relative_curvature_report(sl.plane(1, 1).evaluate(0, 0)["K_p"], cyl.evaluate(0.2, 0.0)["K_p"], 0.0)
    assert rep.singular and rep.name == "line contact"


def test_constraints_hold_with_a_moving_finger():
    """Both bodies move: the equations take the relative motion, from :func:`relative_motion`.

    The finger's pose follows its own smooth random twist; the object's twist is the finger's
    plus the prescribed relative motion ``(v, w)`` at the contact. The rates are computed from
    ``(v, w)`` recovered by :func:`relative_motion` from the two world twists, as a dynamics
    model would, and the constraints must hold to 1e-9 along the run.
    """
    surf_f, surf_o = sl.superquadric(0.03, 0.04, 0.035, 4), sl.ellipsoid(0.05, 0.035, 0.02)
    eta0 = np.array([0.3, -0.2, -0.4, 0.3, 0.8])
    Rf0, pf0 = rot([1.0, 0.2, -0.4], 1.2), np.array([0.02, 0.01, -0.03])
    R0, p0 = c3n.object_pose_from_contact(surf_f, (Rf0, pf0), surf_o, eta0)
    w_of_t, vv, wf_of_t, vf_of_t = (_smooth_random(3, s, k) for s, k in ((1.0, 21), (0.01, 22), (1.0, 23), (0.05, 24)))

    def rhs(t, y):
        p_o, q_o, p_f, q_f = y[5:8], y[8:12], y[12:15], y[15:19]
        cf = c3n.contact_frame_world(surf_f, rot_of(q_f), p_f, y[0], y[1])
        omega_f, pdot_f = wf_of_t(t), vf_of_t(t)
        w, v = w_of_t(t), np.array([*vv(t)[:2], 0.0])
        omega_o = omega_f + cf.frame @ w
        pdot_o = pdot_f + np.cross(omega_f, cf.point - p_f) + cf.frame @ v - np.cross(omega_o, cf.point - p_o)
        v_rel, w_rel = c3n.relative_motion(cf.frame, cf.point, (omega_f, pdot_f, p_f), (omega_o, pdot_o, p_o))
        return np.concatenate([c3n.contact_rates(surf_f, surf_o, y[:5], w_rel, v_rel), pdot_o,
                               quat_rate(omega_o, q_o), pdot_f, quat_rate(omega_f, q_f)])

    y0 = np.concatenate([eta0, p0, quat_of(R0), pf0, quat_of(Rf0)])
    sol = solve_ivp(rhs, (0.0, 1.0), y0, t_eval=np.linspace(0, 1, 41), **TOL)
    assert sol.success, sol.message
    res = max(c3n.contact_residuals(surf_f, (rot_of(y[15:]), y[12:15]), surf_o, (rot_of(y[8:12]), y[5:8]), y[:5])["max"]
              for y in sol.y.T)
    assert res < 1e-9
    assert np.all(np.ptp(sol.y[:4], axis=1) > 0.1) and np.all(np.abs(sol.y[[1, 3]]) < 1.25)
