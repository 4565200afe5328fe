"""Grasp quality (``gs.quality``) against cases worked by hand: Ferrari and Canny's epsilon of
contacts on a disk and on a sphere, with the torque measured per radius (``length = R``)."""
from __future__ import annotations

import math

import numpy as np
import pytest

from grasping_sym import quality

R = 0.03


def _ring(n: int, dim: int) -> np.ndarray:
    th = 2 * np.pi * np.arange(n) / n
    e = np.column_stack([np.cos(th), np.sin(th)])
    return e if dim == 2 else np.column_stack([e, np.zeros(n)])


@pytest.mark.parametrize("mu", [0.1, 0.2, 0.5])
def test_three_contacts_at_120_degrees_on_a_disk(mu):
    """2D, inward normals ``-e_i``: a unit normal force with tangential part ``s t_i`` makes
    the torque ``R s`` about the centre, so the edges' wrenches are ``(-e_i +- mu t_i, +-mu)``:
    the two triangles at torque ``+-mu`` are facets of their hull, both at distance ``mu`` from
    the origin, and the side facets lie farther for these ``mu``: epsilon = mu."""
    e = _ring(3, 2)
    q = quality.epsilon(R * e, -e, mu, length=R)
    assert q.lower == q.upper and abs(q.lower - mu) < 1e-12
    assert q.force_closure is True


def test_frictionless_contacts_cannot_resist_a_torque():
    e = _ring(3, 2)
    assert quality.epsilon(R * e, -e, 0.0, length=R).upper == 0.0
    assert quality.epsilon(R * e, -e, 0.0, length=R).force_closure is False
    e3 = _ring(3, 3)
    assert quality.epsilon(R * e3, -e3, 0.0, length=R).force_closure is False


def test_contacts_that_all_push_one_way_hold_nothing_by_the_origins_distance():
    """2D, three contacts on a line all pushing +y (mu 0.2) about the middle one: every edge
    wrench has unit y force, so ``W`` lies in the plane ``f_y = 1`` and holds ``(0, 1, 0)``
    (the middle contact's normal force): the origin is at distance 1 outside, epsilon = -1.
    The same contacts moved by 3 m, the centre with them, give the same."""
    points = np.array([[-1.0, 0.0], [0.0, 0.0], [1.0, 0.0]])
    normals = np.tile([0.0, 1.0], (3, 1))
    for shift in (0.0, 3.0):
        q = quality.epsilon(points + shift, normals, 0.2, centre=[shift, shift])
        assert abs(q.lower + 1.0) < 1e-9 and q.force_closure is False


@pytest.mark.parametrize("mu", [0.3, 1.0])
def test_two_antipodal_contacts_on_a_disk(mu):
    """2D: the four edge wrenches ``(-1, mu, mu)``, ``(-1, -mu, -mu)``, ``(1, -mu, mu)``,
    ``(1, mu, -mu)`` sum to 0; each face of their tetrahedron lies on a plane like
    ``mu x + y + z = mu``: epsilon = mu / sqrt(2 + mu^2) (Nguyen: two antipodal contacts with
    friction close a planar grasp)."""
    e = np.array([[1.0, 0.0], [-1.0, 0.0]])
    q = quality.epsilon(R * e, -e, mu, length=R)
    assert abs(q.lower - mu / math.sqrt(2 + mu * mu)) < 1e-12 and q.force_closure


@pytest.mark.parametrize("mu", [0.3, 1.0])
def test_two_antipodal_point_contacts_on_a_sphere_leave_the_spin_free(mu):
    """3D: no contact force has a moment about the line through two antipodal points, so the
    spin about it is resisted by nothing whatever the friction: epsilon = 0."""
    e = np.array([[1.0, 0.0, 0.0], [-1.0, 0.0, 0.0]])
    q = quality.epsilon(R * e, -e, mu, length=R)
    assert q.lower == 0.0 and abs(q.upper) < 1e-12 and q.force_closure is False
    # the support function is 0 both ways along that spin
    spin = np.array([[0, 0, 0, 1.0, 0, 0], [0, 0, 0, -1.0, 0, 0]])
    np.testing.assert_allclose(quality.support(R * e, -e, mu, spin, length=R), 0.0, atol=1e-15)


@pytest.mark.parametrize("mu", [0.3, 1.0])
def test_two_contacts_on_a_sphere_squeeze_up_to_the_friction_angle(mu):
    """3D, two contacts on a sphere at ``R (+-cos a, sin a, 0)``, inward normals: the line
    between them runs along x and makes the angle ``a`` with each normal, so they squeeze
    (Nguyen) iff ``tan a <= mu``. Squeezing, the origin lies in ``W`` and the free spin makes
    epsilon exactly 0: the hulls of the inscribed and circumscribed polyhedral cones (computed
    as for any grasp) bound it on both sides. Past the angle of the circumscribed cones the
    origin lies outside both hulls: epsilon < 0, by the hulls as before."""
    limit = math.atan(mu)
    outer = math.atan(mu / math.cos(math.pi / quality.EDGES))
    for a, squeezes in ((0.0, True), (0.5 * limit, True), (limit - 1e-6, True),
                        (outer + 0.05, False), (1.2, False)):
        e = np.array([[math.cos(a), math.sin(a), 0.0], [-math.cos(a), math.sin(a), 0.0]])
        p, n = R * e, -e
        assert bool(quality.two_contacts_squeeze(p, n, mu)) is squeezes, a
        q = quality.epsilon(p, n, mu, length=R)
        inner = quality._inradius(quality.primitive_wrenches(p, n, mu, length=R))
        circ = quality._inradius(quality.primitive_wrenches(p, n, mu, length=R,
                                                            scale=1.0 / math.cos(math.pi / quality.EDGES)))
        if squeezes:
            assert (q.lower, q.upper) == (0.0, 0.0) and q.force_closure is False
            assert inner <= 0.0 <= circ + 1e-12
        else:
            assert q.lower == inner < 0 and q.upper == max(inner, circ) < 0
            assert q.force_closure is False


def test_three_contacts_on_a_sphere_are_bounded_and_the_bounds_close_in():
    """3D, three contacts at 120 degrees on the equator: a pure torque about the x axis pairs
    with the contacts' forces ``x x e_i``, along z, tangential: ``h = mu sqrt(3) / 2``
    exactly, so epsilon is at most that; the inscribed and circumscribed cones bound it, more
    tightly with more edges; and no direction's exact support value is below the lower bound."""
    mu = 0.5
    e = _ring(3, 3)
    torque_x = np.array([[0, 0, 0, 1.0, 0, 0]])
    assert abs(quality.support(R * e, -e, mu, torque_x, length=R)[0] - mu * math.sqrt(3) / 2) < 1e-15
    q8 = quality.epsilon(R * e, -e, mu, length=R, edges=8)
    q16 = quality.epsilon(R * e, -e, mu, length=R, edges=16)
    assert 0 < q8.lower <= q16.lower <= q16.upper <= q8.upper <= mu * math.sqrt(3) / 2
    assert q16.upper - q16.lower <= mu * (1 / math.cos(math.pi / 16) - 1) * 2
    u = np.random.default_rng(3).normal(size=(20000, 6))
    u /= np.linalg.norm(u, axis=1, keepdims=True)
    assert quality.support(R * e, -e, mu, u, length=R).min() >= q16.lower


def test_the_grasp_matrix_maps_contact_forces_to_the_wrench():
    """Its columns are the wrenches of the frame's unit forces: ``G f`` is the sum of the
    contacts' forces and of their moments (over ``length``) about the centre."""
    rng = np.random.default_rng(1)
    e = _ring(3, 3)
    c = np.array([0.01, -0.02, 0.005])
    G = quality.grasp_matrix(R * e + c, -e, centre=c, length=0.05)
    assert G.shape == (6, 9)
    f_local = rng.normal(size=9)
    n = -e
    forces = []
    for i in range(3):  # rebuild the world forces from the frame G uses: its columns
        frame = G[:3, 3 * i:3 * i + 3]
        assert np.allclose(frame.T @ frame, np.eye(3)) and np.allclose(frame[:, 0], n[i])
        forces.append(frame @ f_local[3 * i:3 * i + 3])
    force = sum(forces)
    moment = sum(np.cross(R * e[i], forces[i]) for i in range(3)) / 0.05
    np.testing.assert_allclose(G @ f_local, np.concatenate([force, moment]), atol=1e-14)


def test_bad_contacts_are_refused_by_name():
    e = _ring(3, 3)
    with pytest.raises(ValueError, match="unit vectors"):
        quality.epsilon(R * e, -2 * e, 0.5)
    with pytest.raises(ValueError, match=r"give k contacts"):
        quality.epsilon(R * e, -e[:, :2], 0.5)
    with pytest.raises(ValueError, match="mu = -0.1"):
        quality.epsilon(R * e, -e, -0.1)
    with pytest.raises(ValueError, match="edges = 2"):
        quality.epsilon(R * e, -e, 0.5, edges=2)
    two = np.array([[1.0, 0.0, 0.0], [-1.0, 0.0, 0.0]])
    for args, match in (((R * two[:, :2], -two[:, :2], 0.5), "two 3D contacts"),
                        ((R * np.tile(two, (2, 1)), -np.tile(two, (2, 1)), 0.5), "two 3D contacts"),
                        ((R * two, -2 * two, 0.5), "unit vectors"),
                        ((R * two, -two, np.nan), "mu = nan"),
                        ((R * two, -two, [0.5, 0.5, 0.5]), "one per contact"),
                        ((np.full((2, 3), np.inf), -two, 0.5), "finite")):
        with pytest.raises(ValueError, match=match):
            quality.two_contacts_squeeze(*args)
    # a pair that squeezes builds no hull: its length and edges are refused all the same
    for kw, match in ((dict(length=-1.0), "length = -1.0"), (dict(length=math.nan), "length = nan"),
                      (dict(edges=2), "edges = 2")):
        with pytest.raises(ValueError, match=match):
            quality.epsilon(R * two, -two, 0.5, **kw)


def test_along_a_paper3d_run_the_contacts_lie_on_the_turning_ellipsoid(paper3d_model):
    """``BuiltModel.grasp_quality``: the contact points, carried to the object's frame, satisfy
    the ellipsoid's equation (semi-axes 20, 25, 30 mm) and the normals are its implicit
    gradient's, turned inward; two point contacts leave the spin about the line through them
    free: epsilon = 0 and no force closure at every output time; the smallest cone margin is
    that of the run's own forces."""
    from grasping_sym.pipeline.quality_along import contacts_along

    model = paper3d_model
    res = model.simulate(0.5, t_eval=np.linspace(0.0, 0.5, 6))
    c, p, n = contacts_along(model, res)
    rot = res.object_rotations()
    axes = np.array([0.020, 0.025, 0.030])
    for i in range(2):
        body = np.einsum("nji,nj->ni", rot, p[:, i] - c)  # R^T (p - c)
        np.testing.assert_allclose(np.sum((body / axes) ** 2, axis=1), 1.0, atol=1e-12)
        grad = np.einsum("nij,nj->ni", rot, body / axes ** 2)
        np.testing.assert_allclose(n[:, i], -grad / np.linalg.norm(grad, axis=1, keepdims=True),
                                   atol=1e-12)
    q = model.grasp_quality(res, mu=0.5)
    assert np.all(q["epsilon_lower"] == 0.0) and np.all(np.abs(q["epsilon_upper"]) < 1e-12)
    assert np.all(q["force_closure"] == 0.0)
    # every row at once (the squeeze test on all rows) as row by row, where the contacts squeeze
    # (mu 0.5) and, at mu 0.01, at rows of both kinds (the hulls, epsilon < 0, where they do not)
    length = float(np.max(np.linalg.norm(p[0] - c[0], axis=1)))
    for kw, match in ((dict(length=-1.0), "length = -1.0"), (dict(edges=2), "edges = 2")):
        with pytest.raises(ValueError, match=match):  # every row squeezes: checked all the same
            model.grasp_quality(res, mu=0.5, **kw)
    for mu in (0.5, 0.01):
        qm = model.grasp_quality(res, mu=mu)
        rows = [quality.epsilon(p[k], n[k], mu, centre=c[k], length=length) for k in range(len(res.t))]
        np.testing.assert_array_equal(qm["epsilon_lower"], [r.lower for r in rows])
        np.testing.assert_array_equal(qm["epsilon_upper"], [r.upper for r in rows])
    assert (qm["epsilon_upper"] < 0).any() and (qm["epsilon_upper"] == 0.0).any()
    margin = np.minimum(0.5 * res["f1"] - np.hypot(res["lam1"], res["eta1"]),
                        0.5 * res["f2"] - np.hypot(res["lam2"], res["eta2"]))
    np.testing.assert_allclose(q["cone_margin_min"], margin, rtol=0, atol=1e-12)
    with pytest.raises(ValueError, match="give mu"):
        model.grasp_quality(res)


def test_two_contacts_read_in_the_objects_frame_give_the_worlds_internal_force(paper3d_model):
    """Along a run of two 3D contacts the internal force is taken in the object's frame from
    each force's components along its contact's frame (``quality_along._squeezing``): at every
    row it is the general computation's in the world (``_internal_norms`` of the world
    forces, ``quality.internal_forces`` where the points coincide) to 1e-12 N, a row whose
    two points were made to coincide included."""
    from grasping_sym.pipeline import quality_along as qa

    model = paper3d_model
    res = model.simulate(0.3, t_eval=np.linspace(0.0, 0.3, 31))
    local = qa._local_frames(model, res)
    local["point"][1][7] = local["point"][0][7]                    # one row: the points coincide
    cols = qa._force_columns(model, res)
    got = qa._squeezing(model, res, local, cols)
    c, frames = qa._frames(model, res, local)
    points = np.stack([f["point"] for f in frames], axis=1)
    want = qa._internal_norms(c, points, qa.contact_forces(model, res, (c, frames)))
    np.testing.assert_allclose(got, want, rtol=0, atol=1e-12)
    assert got[7] != got[6] and want[7] > 0


def test_the_contact_forces_move_the_object_as_newton_says_and_squeeze_it(paper3d_model):
    """The world contact forces read from the run's outputs (``contact_forces``: ``f`` along
    the normal into the object, ``(lam, eta)`` along the fingertip's tangents from the frame
    angle ``psi``) and gravity give the object's acceleration of the compiled model:
    ``m v' = F1 + F2 + m g``, to rounding. Their internal part is, for two contacts, the
    squeeze along the line between them, ``+-((F1 - F2) . e) e / 2``."""
    from grasping_sym.pipeline.quality_along import contact_forces, contacts_along

    model = paper3d_model
    # at rtol 1e-9 (measured 1.3e-13); at the default 1e-7 the frames carry the integration's
    # error, 3e-11 N (the gaps C alone are projected)
    res = model.simulate(0.5, t_eval=np.linspace(0.0, 0.5, 6), rtol=1e-9, atol=1e-11)
    forces = contact_forces(model, res)
    names = list(model.state_names)
    iv = [names.index(k) for k in ("vx", "vy", "vz")]
    m, g = model.scene.mass, np.array(model.scene.gravity)
    for row, x in enumerate(res.x):
        accel = model.rhs(x)[iv]
        np.testing.assert_allclose(m * accel, forces[row].sum(axis=0) + m * g, rtol=0, atol=1e-12)
    _, points, _ = contacts_along(model, res)
    q = model.grasp_quality(res, mu=0.5)
    for row in range(len(res.t)):
        e = points[row, 1] - points[row, 0]
        e /= np.linalg.norm(e)
        half = 0.5 * (forces[row, 0] - forces[row, 1]) @ e * e
        np.testing.assert_allclose(quality.internal_forces(points[row], forces[row]),
                                   [half, -half], rtol=0, atol=1e-12)
        assert abs(q["internal_force"][row] - math.sqrt(2) * np.linalg.norm(half)) < 1e-12
    assert q["internal_force"].min() > 1.0  # the grasp law squeezes: about 3 N along the line


def test_the_squeeze_margin_for_optimal_control_is_the_squeeze_test_as_a_smooth_function(
        paper3d_model, paper2d_model):
    """``casadi_function("squeeze")`` ``(x, mu) -> margin``, per contact ``e . n_i -
    1/sqrt(1 + mu_i^2)``. Exactly: contacts at the ellipsoid's equator at ``u`` and ``u + pi``
    (through its centre; semi-axes a = 20, b = 25 mm), the object turned and moved, its
    quaternion not of unit length: each margin is ``1/(|p| |g|) - 1/sqrt(1 + mu_i^2)`` with
    ``p = (a cos u, b sin u)`` and ``g = (cos u / a, sin u / b)`` the ellipse's implicit
    gradient. Along a run: the margins of the contacts' points and normals computed here, to
    1e-12, both >= 0 exactly at the rows ``gs.quality.two_contacts_squeeze`` finds (rows of
    both kinds at mu = 0.01: the line's largest angle to a normal along the run has tangents
    0.001 to 0.019); its Jacobian is the central differences'. A 2D model has none."""
    import casadi as ca

    from grasping_sym.pipeline.quality_along import contacts_along

    model = paper3d_model
    fn = model.casadi_function("squeeze")
    names = list(model.state_names)
    a, b = 0.020, 0.025
    mu = np.array([0.3, 1.2])
    turn = np.array([0.9, 0.2, -0.3, 0.4]) * 1.1                      # |q| = 1.16
    for u in (0.4, 1.1, 2.5):
        x = model.initial_state().copy()
        for k, v in zip(("x", "y", "z", "qw", "qx", "qy", "qz", "u_o1", "v_o1", "u_o2", "v_o2"),
                        (0.01, -0.02, 0.03, *turn, u, 0.0, u + math.pi, 0.0)):
            x[names.index(k)] = v
        exact = 1.0 / (math.hypot(a * math.cos(u), b * math.sin(u)) * math.hypot(math.cos(u) / a, math.sin(u) / b))
        np.testing.assert_allclose(np.asarray(fn(x, mu)).ravel(), exact - 1.0 / np.sqrt(1.0 + mu ** 2),
                                   rtol=0, atol=1e-14)
    res = model.simulate(0.5, t_eval=np.linspace(0.0, 0.5, 26))
    _, p, n = contacts_along(model, res)
    e = (p[:, 1] - p[:, 0]) / np.linalg.norm(p[:, 1] - p[:, 0], axis=1, keepdims=True)
    for m in (0.5, 0.01):
        cos = 1.0 / math.sqrt(1.0 + m * m)
        here = np.column_stack([np.sum(e * n[:, 0], axis=1) - cos, -np.sum(e * n[:, 1], axis=1) - cos])
        got = np.array([np.asarray(fn(x, [m, m])).ravel() for x in res.x])
        np.testing.assert_allclose(got, here, rtol=0, atol=1e-12)
        assert np.min(np.abs(got)) > 1e-9                          # no row on a cone's surface
        squeeze = quality.two_contacts_squeeze(p, n, m)
        np.testing.assert_array_equal((got >= 0).all(axis=1), squeeze)
    assert squeeze.any() and not squeeze.all()                     # mu = 0.01: rows of both kinds
    jac = fn.jacobian()
    x, h = res.x[7], 1e-6
    J = np.asarray(jac(x, mu, fn(x, mu))[0])                       # d margin / d x
    for k in (names.index(s) for s in ("qx", "u_o1", "v_o2", "z")):
        step = np.zeros(len(names))
        step[k] = h
        fd = (np.asarray(fn(x + step, mu)) - np.asarray(fn(x - step, mu))).ravel() / (2 * h)
        np.testing.assert_allclose(J[:, k], fd, rtol=1e-6, atol=1e-8)
    assert isinstance(fn, ca.Function)
    with pytest.raises(ValueError, match="squeeze"):
        paper2d_model.casadi_function("squeeze")
