"""Contact modes of a 3D grasp over a table (model.grasp3d_modes, derive.grasp3d_modes,
runtime.modes; docs/conventions.md section 9): checked against the rolling model, the rolling
model's own cone event, Coulomb's law, the energy balance of a slide, a free fall's exact
motion once both fingers let go, and the ellipsoid's exact distance to the table; one finger
pressing a free ball onto a table against the statics at rest, and onto a turntable against
the table's material velocity."""
from __future__ import annotations

import threading

import casadi as ca
import numpy as np
import pytest
from scipy.integrate import simpson

import grasping_sym as gs
from grasping_sym.assemble import kinds
from grasping_sym.errors import FrictionConeError, InvalidSceneError
from grasping_sym.geometry import surface_library
from grasping_sym.model.grasp3d_modes import MODES_GAIN
from grasping_sym.runtime import modes
from grasping_sym.runtime.modes import rotation
from tests.scenes import BALL_M, BALL_R, pressed_ball

TOL = {"rtol": 1e-9, "atol": 1e-11}
SEMI_AXES = (0.020, 0.025, 0.030)
#: a table 1 cm below the pivot's height (gravity is -y); the object's chart covers its bottom
TABLE = ((0.0, -0.01, 0.0), (0.0, 1.0, 0.0))
#: Coulomb friction at the two fingers, then at the table
LAW = gs.contact.coulomb((0.08, 0.08, 0.5))


@pytest.fixture(scope="module")
def base():
    return gs.scenes.paper3d(object_surface=surface_library.ellipsoid(*SEMI_AXES, lon=(-2.5, 4.0),
                                                                      name="object ellipsoid"))


@pytest.fixture(scope="module")
def model(base):
    table = gs.scenes.world_plane(*TABLE, support=(-1.5708, 0.0))
    return gs.build(gs.scenes.with_modes(base, planes=[table]))


@pytest.fixture(scope="module")
def rolling(model):
    """The base's rolling model as the modes hold it: paper3d's gain 0 (its runs project)
    made ``MODES_GAIN`` (the modes' runs do not)."""
    assert model.scene.base.gain == MODES_GAIN
    return gs.build(model.scene.base)


def test_rolling_modes_are_the_rolling_model(model, rolling):
    """Both fingers rolling, the table apart, is paper3d's model: the same right-hand side at
    states near the start, to round-off (1e-11 of its largest entry; 4e-12 measured: the
    modes' 9 x 9 solve rounds differently from paper3d's layers) and, with no friction limit, a run with no switch.
    In these modes the compiled rhs takes its branch with them folded in (``rhs_branches``;
    about half the general rhs's instructions): the compiled general rhs's numbers, to
    round-off (2e-17 of the largest entry measured; CasADi's folding adds or multiplies by
    exact 0s and 1s)."""
    rng = np.random.default_rng(5)
    x0 = model.initial_state()
    n = len(rolling.state_names)
    p = model.default_params.copy()
    p[model.p_names.index("mode3")] = 2
    assert model.manifest["folded_modes"] == [0, 0, 2]
    counts = model.manifest["op_counts"]
    assert counts["rhs_modes_002_sx_instructions"] < 0.6 * counts["rhs_sx_instructions"]
    general = ca.external(f"{model.name}_rhs_any", str(model.library_path))
    for _ in range(5):
        x = x0 + np.concatenate([rng.normal(scale=1e-3, size=n), [0.0, 0.0]])
        a, b = rolling.rhs(x[:n]), model.rhs(x, p)[:n]
        assert np.max(np.abs(a - b)) < 1e-11 * np.max(np.abs(a))  # normwise
        c = np.ravel(general(0.0, x, [], p, [])[0])
        assert np.max(np.abs(model.rhs(x, p) - c)) < 1e-15 * np.max(np.abs(c))  # normwise
    r = model.simulate(0.05, t_eval=np.linspace(0.0, 0.05, 11), **TOL)
    r0 = rolling.simulate(0.05, t_eval=np.linspace(0.0, 0.05, 11), method="radau", **TOL)
    assert r.events == [] and (r.modes[:, :2] == "rolling").all() and (r.modes[:, 2] == "separated").all()
    assert np.max(np.abs(r.x[:, :n] - r0.x)) < 1e-8


@pytest.fixture(scope="module")
def slide(model):
    """mu = 0.08 at the fingers: contact 2 leaves its cone, then contact 1; both slide, lose
    their force and open; the object falls onto the table (0.5) and stays on it."""
    return model.simulate(0.2, mu=LAW, t_eval=np.linspace(0.0, 0.2, 2001), **TOL)


def test_slip_starts_where_the_rolling_model_leaves_its_cone(rolling, slide):
    """The first switch is where the rolling model's cone check stops it (FrictionConeError,
    located on its own lam, eta and f), at the same contact."""
    with pytest.raises(FrictionConeError) as err:
        rolling.simulate(0.06, mu=0.08, t_eval=np.linspace(0.0, 0.06, 61), method="radau", **TOL)
    first = slide.events[0]
    assert (first["from"], first["to"], first["witness"]) == ("rolling", "sliding", "cone")
    assert first["contact"] == err.value.contact
    assert abs(first["t"] - err.value.t) < 1e-8


def test_the_default_tolerances_slide_as_the_tight_ones_do(model, slide):
    """At the default rtol 1e-6 (atol 1e-9) the fingers leave their cones and slide as at
    1e-10: the same switches, within 1e-5 s. A slide that starts at the cone's edge gains slip
    speed as the square of the time: its direction there was followed into noise (the slip's
    acceleration 8e-8 m/s^2 of ~50), and its slip witness armed at 1e-10 m/s, below the loose
    run's noise; the fingers chattered between rolling and sliding (ChatteringError at
    0.0288 s). Now it starts against the rolling force (``modes.EDGE``) and its witness arms
    above the run's noise (``modes.SLIP_NOISE``)."""
    loose = model.simulate(0.2, mu=LAW, t_eval=slide.t)
    assert [(e["contact"], e["from"], e["to"], e["witness"]) for e in loose.events] == \
        [(e["contact"], e["from"], e["to"], e["witness"]) for e in slide.events]
    assert max(abs(a["t"] - b["t"]) for a, b in zip(loose.events, slide.events)) < 1e-5



@pytest.mark.parametrize("mu", [0.03, 0.05])
def test_a_slide_from_the_noise_of_a_loose_run_is_the_tight_runs(model, mu):
    """With mu = 0.03 (contact 1 slides from the start) and 0.05 (each contact leaves its cone)
    at the default tolerances: the fingers chattered between rolling and sliding
    (ChatteringError at 1e-5 s and 0.0115 s): held along ``slip`` while the slip was below
    the blend of ``derive.grasp3d_modes`` (1e-7 m/s, within the loose run's noise), the slip
    grew against ``slip`` (the contact's inverse effective mass is anisotropic; the consistent
    direction turns as the slip grows). The slide's onset (``derive.slip_onset``) turns with
    it: the same seven switches as at rtol 1e-9, within 1e-5 s. An explicit method keeps the
    blend (the onset's stiffness would bound its step: dop853 at rtol 1e-10 stopped as stiff):
    the same switches, within 1e-8 s; and radau at rtol 1e-8, within 1e-7 s (no spurious stop
    at a slide's start: with the onset's witness armed at a tenth of its width, paper3d's
    grasp took eight there at mu 0.04)."""
    law = gs.contact.coulomb((mu, mu, 0.5))
    t = np.linspace(0.0, 0.2, 201)
    loose, tight = model.simulate(0.2, mu=law, t_eval=t), model.simulate(0.2, mu=law, t_eval=t, **TOL)
    explicit = model.simulate(0.2, mu=law, t_eval=t, method="dop853", rtol=1e-10, atol=1e-12)
    middle = model.simulate(0.2, mu=law, t_eval=t, rtol=1e-8, atol=1e-10)
    for other, dt in ((loose, 1e-5), (middle, 1e-7), (explicit, 1e-8)):
        assert [(e["contact"], e["from"], e["to"]) for e in other.events] == \
            [(e["contact"], e["from"], e["to"]) for e in tight.events] and len(tight.events) == 7
        assert max(abs(a["t"] - b["t"]) for a, b in zip(other.events, tight.events)) < dt
    # friction takes energy from every slip (the force on the system is -A^T lam: its power
    # on the slip -(lam vt_x + eta vt_y)), the onset's too
    for j in (1, 2):
        sliding = loose.modes[:, j - 1] == "sliding"
        assert sliding.sum() > 10
        assert (loose[f"lam{j}"] * loose[f"vt_x{j}"] + loose[f"eta{j}"] * loose[f"vt_y{j}"])[sliding].min() >= 0

def test_a_batch_runs_its_runs_side_by_side_as_one_by_one(model, monkeypatch):
    """``simulate_many`` of a model with modes runs each run by ``simulate``'s code, on its
    ``threads`` (``runtime.pool``: the C loops release the GIL, each thread its own watch):
    on two threads, every run's states, outputs, switches, modes and errors are those of one
    thread, bit for bit; the one whose fingers slide (mu = 0.08) switches."""
    mu = np.array([[0.08, 0.08, 0.5], [1.0, 1.0, 0.5], [0.3, 0.08, 0.5], [1.0, 0.5, 0.5]])
    kw = dict(mu=mu, t_eval=np.linspace(0.0, 0.05, 51), outputs=True, **TOL)
    one = model.simulate_many(0.05, threads=1, **kw)
    seen, plain = set(), modes.run

    def run(*args, **kwargs):
        seen.add(threading.get_ident())
        return plain(*args, **kwargs)

    monkeypatch.setattr(modes, "run", run)
    two = model.simulate_many(0.05, threads=2, **kw)
    assert len(seen) == 2  # the runs went to two threads
    assert np.array_equal(one.x, two.x) and one.events == two.events and one.events[0]
    assert list(one.errors) == list(two.errors) and one.status.tolist() == two.status.tolist()
    assert all(np.array_equal(one.outputs[k], two.outputs[k]) for k in one.outputs)
    assert all(np.array_equal(a, b) for a, b in zip(one.modes, two.modes))


def test_points_left_unwatched_change_no_switch(model, slide, monkeypatch):
    """The witnesses' points left unwatched while their margins are far from 0 at their rates
    (``c/watch.c``): the same seven switches at the same times (1e-12 s) and the same samples
    (1e-9) as a run watching every point; and with nearly every point left (a safety of 1e-9),
    where both fingers' normal forces fire in one step left unwatched (0.2 ms apart): each is
    located, in their order."""
    assert slide.stats["left_unwatched"] > slide.stats["watched"]
    monkeypatch.setattr(modes, "WATCH_SAFETY", 0.0)
    every = model.simulate(0.2, mu=LAW, t_eval=slide.t, **TOL)
    monkeypatch.setattr(modes, "WATCH_SAFETY", 1e-9)
    most = model.simulate(0.2, mu=LAW, t_eval=slide.t, **TOL)
    assert every.stats["left_unwatched"] == 0 and len(every.events) == len(slide.events) == 7
    # the default: the same numbers (0 measured); nearly every point left: restarts from
    # other steps' starts, within the tolerances (1.9e-12 s and 1.2e-9 measured)
    for other, dt, dx in ((slide, 1e-12, 1e-9), (most, 1e-11, 1e-8)):
        assert [(e["contact"], e["to"]) for e in every.events] == [(e["contact"], e["to"]) for e in other.events]
        assert max(abs(a["t"] - b["t"]) for a, b in zip(every.events, other.events)) < dt
        assert np.max(np.abs(every.x - other.x)) < dx


def test_coulomb_law_while_sliding(slide):
    """While a contact slides: |F_t| = mu f, and F_t along the slip velocity (friction takes
    power F_t . v_t >= 0 out of the system)."""
    j = slide.events[0]["contact"]
    rows = (slide.modes[:, j - 1] == "sliding") & (slide[f"slip_speed{j}"] > 1e-6)
    assert rows.sum() > 50
    f, ft = slide[f"normal_force{j}"][rows], slide[f"tangential_force{j}"][rows]
    assert np.max(np.abs(ft - 0.08 * f)) < 1e-12 * np.max(f)
    Ft = np.column_stack([slide[f"lam{j}"][rows], slide[f"eta{j}"][rows]])
    vt = np.column_stack([slide[f"vt_x{j}"][rows], slide[f"vt_y{j}"][rows]])
    cos = np.sum(Ft * vt, axis=1) / (np.linalg.norm(Ft, axis=1) * np.linalg.norm(vt, axis=1))
    assert np.min(cos) > 1 - 1e-9


def test_a_slide_loses_what_friction_dissipates(slide):
    """d(K + V)/dt = the joints' power and the spin friction's (``power``) minus what Coulomb
    friction takes, sum_i F_t,i . v_t,i, integrated by Simpson's rule along the slide."""

    opened = min(e["t"] for e in slide.events if e["to"] == "separated")
    rows = (slide.t > slide.events[0]["t"]) & (slide.t < opened)
    t = slide.t[rows]
    E = slide["kinetic_energy"][rows] + slide["potential_energy"][rows]
    friction = sum(slide[f"lam{i}"][rows] * slide[f"vt_x{i}"][rows] + slide[f"eta{i}"][rows] * slide[f"vt_y{i}"][rows]
                   for i in (1, 2))
    dissipated = simpson(friction, x=t)
    assert dissipated > 1e-7
    assert abs((E[-1] - E[0]) - simpson(slide["power"][rows] - friction, x=t)) < 1e-5 * dissipated


def test_released_object_falls_freely_then_lands_on_the_table(base, slide):
    """Both fingers open (f reaches 0); between their opening and the table's impact the
    object falls with g (position to 1e-9 m) with constant angular momentum ``R H omega``;
    its gap to the table is the ellipsoid's exact distance to the plane,
    ``n . (c - w0) - |D R^T n|`` (D the semi-axes), which the located impact zeroes; the plastic
    impact sticks and the object then stays on the table."""
    ev = [(e["contact"], e["from"], e["to"], e["witness"]) for e in slide.events]
    assert ev[:2] == [(2, "rolling", "sliding", "cone"), (1, "rolling", "sliding", "cone")]
    assert sorted(ev[2:4]) == [(1, "sliding", "separated", "normal_force"),
                               (2, "sliding", "separated", "normal_force")]
    assert ev[4] == (3, "separated", "rolling", "gap")
    t_open, t_land = slide.events[3]["t"], slide.events[4]["t"]
    rows = np.flatnonzero((slide.t > t_open) & (slide.t < t_land))
    assert len(rows) > 50
    names = base.state_names
    pick = lambda keys: slide.x[rows][:, [names.index(k) for k in keys]]  # noqa: E731
    pos, vel = pick(("x", "y", "z")), pick(("vx", "vy", "vz"))
    quat, om = pick(("qw", "qx", "qy", "qz")), pick(("omegaX", "omegaY", "omegaZ"))
    t = slide.t[rows] - slide.t[rows[0]]
    expected = pos[0] + np.outer(t, vel[0]) + 0.5 * np.outer(t**2, np.array(base.gravity))
    assert np.max(np.abs(pos - expected)) < 1e-9
    H = np.asarray(base.inertia)
    L = np.array([rotation(q) @ (H @ w) for q, w in zip(quat, om)])
    assert np.max(np.abs(L - L[0])) < 1e-9 * np.max(np.abs(L))
    n, w0, D = np.array(TABLE[1]), np.array(TABLE[0]), np.diag(SEMI_AXES)
    exact = np.array([n @ (c - w0) - np.linalg.norm(D @ rotation(q).T @ n) for c, q in zip(pos, quat)])
    assert np.max(np.abs(exact - slide["gap3"][rows])) < 1e-12 and exact.min() > 0
    after = slide.t > t_land
    assert (slide.modes[after, 2] == "rolling").all()
    assert np.max(np.abs(slide["gap3"][after])) < 1e-9 and np.all(slide["normal_force3"][after] > 0)


def test_refusals(base):
    with pytest.raises(InvalidSceneError, match="regular"):
        gs.scenes.with_modes(gs.scenes.paper3d(formulation="paper"))
    with pytest.raises(InvalidSceneError, match="runtime"):
        gs.scenes.with_modes(gs.scenes.paper3d(runtime=("gain",)))
    with pytest.raises(InvalidSceneError, match="unit vector"):
        gs.scenes.world_plane((0, 0, 0), (0, 2, 0))
    cutting = gs.scenes.with_modes(base, planes=[gs.scenes.world_plane((0, 0.05, 0), (0, 1, 0),
                                                                       support=(-1.5708, 0.0))])
    with pytest.raises(InvalidSceneError, match="cuts the object"):
        kinds.kind(cutting).solve_start(cutting)


def test_a_sweep_over_mu_measures_slip_and_hold(model, slide, tmp_path):
    """gs.sweep over mu: ``first_slip:i`` is each finger's located slip (the run's own switch),
    ``held`` 0 once the fingers have let go, 1 where mu holds the grasp."""
    ds = gs.sweep(model, {"mu": [0.08, 0.5]}, t_final=0.12, measures=("held", "first_slip:1", "first_slip:2"),
                  store=tmp_path / "s.zarr", progress=False, **TOL)
    assert (ds["status"].values == 0).all()
    slips = {e["contact"]: e["t"] for e in slide.events[::-1] if e["to"] == "sliding"}
    assert abs(float(ds["first_slip_1"].sel(mu=0.08)) - slips[1]) < 1e-9  # two runs: other steps
    assert abs(float(ds["first_slip_2"].sel(mu=0.08)) - slips[2]) < 1e-9
    assert list(ds["held"].values) == [0.0, 1.0]
    assert np.isinf(ds["first_slip_1"].sel(mu=0.5)) and np.isinf(ds["first_slip_2"].sel(mu=0.5))


def test_one_finger_presses_a_free_ball_onto_a_table():
    """One finger and a table hold a free ball (issue 27 part 5). The finger, 4 mm beside the
    ball's top, presses it toward the ball's given centre ``a`` (controllers.paper3d with one
    finger on a free object); the ball falls 0.5 mm, lands, rolls under the finger and comes to
    rest. The statics at rest are solved here from the joint angles and the ball's centre alone:
    the unknown finger force ``F`` (on the finger, at the contact point ``p``) and the table's
    friction ``T`` and normal force ``N`` satisfy the finger's joints,
    ``J^T F - ((p - r_tip) x F)_z (1, 1) = J^T (fd / r_ctrl)(r_tip - a)`` (its weight held, the
    axes -z), and the ball's forces and moment: 5 equations for 4 unknowns, consistent to
    round-off, and equal to the model's multipliers. The landing is found wherever the outputs
    are asked (a sparse t_eval once let the ball fall through the table)."""
    R, r, link, m, g, fd, r_ctrl = BALL_R, 0.010, 0.065, BALL_M, 9.81, 0.5, 0.010
    a, scene = pressed_ball("press", 0.004)
    with pytest.raises(InvalidSceneError, match="needs a surface of the world"):
        gs.build(scene)
    table = gs.scenes.world_plane((0.0, 0.0, 0.0), (0.0, 1.0, 0.0), support=(-np.pi / 2, 0.0))
    model = gs.build(gs.scenes.with_modes(scene, planes=[table]))
    res = model.simulate(1.0, mu=0.8, t_eval=np.linspace(0.0, 1.0, 21), **TOL)
    sparse = model.simulate(1.0, mu=0.8, t_eval=np.linspace(0.0, 1.0, 3), **TOL)
    assert [(e["contact"], e["from"], e["to"]) for e in res.events] == [(2, "separated", "rolling")]
    assert len(sparse.events) == len(res.events) and abs(sparse.events[0]["t"] - res.events[0]["t"]) < 1e-12
    assert np.max(np.abs(sparse.x[-1] - res.x[-1])) < 1e-9
    y = {k: v[-1] for k, v in res.outputs.items()}
    assert y["object_speed"] < 1e-6 and y["object_angular_speed"] < 1e-4  # at rest
    q1, q12 = res["q11"][-1], res["q11"][-1] + res["q12"][-1]
    tip = np.array([-0.1275 + link * (np.sin(q1) + np.sin(q12)), link * (np.cos(q1) + np.cos(q12))])
    J = link * np.array([[np.cos(q1) + np.cos(q12), np.cos(q12)], [-np.sin(q1) - np.sin(q12), -np.sin(q12)]])
    c = np.array([res["x"][-1], res["y"][-1]])
    lever = r * (c - tip) / np.linalg.norm(c - tip)      # p - r_tip
    pull = fd / r_ctrl * (tip - a[:2])
    # unknowns (F_x, F_y, T, N): finger joints (2), ball forces (2), ball moment about c (1)
    A = np.array([[J[0, 0] + lever[1], J[1, 0] - lever[0], 0, 0],
                  [J[0, 1] + lever[1], J[1, 1] - lever[0], 0, 0],
                  [-1, 0, 1, 0], [0, -1, 0, 1],
                  [(tip + lever - c)[1], -(tip + lever - c)[0], R, 0]])
    b = np.array([*(J.T @ pull), 0.0, m * g, 0.0])
    sol, *_ = np.linalg.lstsq(A, b, rcond=None)
    assert np.linalg.norm(A @ sol - b) < 1e-7 * np.linalg.norm(b)
    F, T, N = sol[:2], sol[2], sol[3]
    assert abs(T) > 0.03  # the ball rolled to a rest where friction works
    assert y["f2"] == pytest.approx(N, rel=1e-7)
    assert y["tangential_force2"] == pytest.approx(abs(T), rel=1e-6)
    assert np.hypot(y["f1"], y["tangential_force1"]) == pytest.approx(np.linalg.norm(F), rel=1e-7)
    assert res["y"][-1] == pytest.approx(R, abs=1e-10) and abs(y["gap2"]) < 1e-10


def test_a_rising_table_meets_the_pressed_ellipsoid():
    """A driven plane (``world_plane(..., motion=(0, "0.1*t", 0))``): the table starts 0.5 mm
    under an ellipsoid (semi-axes 22, 20, 16 mm) that one finger presses from above, 4 mm off
    its top (``tests.scenes.pressed_ball``), and rises at 0.1 m/s; its gap is the exact distance of the
    turning ellipsoid to the moving plane, ``n . (c - w0 - d(t)) - |D R^T n|`` (the turn's
    share, measured 7e-7 m, far above the 1e-12 checked); the impact is located where that
    reaches 0, and afterwards the contact moves with the table (relative normal speed 0) as
    it lifts the ellipsoid and the finger."""
    R = BALL_R
    axes = (1.1 * R, R, 0.8 * R)
    _, scene = pressed_ball("press_rise", 0.004, axes)
    table = gs.scenes.world_plane((0.0, 0.0, 0.0), (0.0, 1.0, 0.0), support=(-np.pi / 2, 0.0),
                                  motion=(0, "0.1*t", 0))
    model = gs.build(gs.scenes.with_modes(scene, planes=[table]))
    law = gs.contact.coulomb((3.0, 0.5))
    r = model.simulate(0.03, mu=law, t_eval=np.linspace(0.0, 0.03, 61), **TOL)
    hit = [e for e in r.events if e["contact"] == 2 and e["witness"] == "gap"]
    assert len(hit) == 1 and hit[0]["from"] == "separated"
    names, D, n = scene.state_names, np.diag(axes), np.array([0.0, 1.0, 0.0])

    def exact(t, x):
        c, q = x[[names.index(k) for k in "xyz"]], x[[names.index(k) for k in ("qw", "qx", "qy", "qz")]]
        return n @ c - 0.1 * t - np.linalg.norm(D @ rotation(q).T @ n)

    before = np.flatnonzero(r.t < hit[0]["t"])
    assert len(before) > 3
    assert np.max(np.abs([exact(t, x) - g for t, x, g in zip(r.t[before], r.x[before], r["gap2"][before])])) < 1e-12
    at = model.simulate(hit[0]["t"], mu=law, t_eval=[0.0, hit[0]["t"]], **TOL)
    assert abs(exact(at.t[-1], at.x[-1])) < 1e-9
    after = r.t > hit[0]["t"]
    assert (r.modes[after, 1] != "separated").all() and np.max(np.abs(r["normal_speed2"][after])) < 1e-9
    assert r["y"][-1] > R + 0.001                                   # lifted past its start


def test_a_turntable_spinning_up_drags_the_pressed_ball():
    """The finger presses the ball onto a turntable whose rate grows as ``w(t) = 2 t`` rad/s
    about the vertical through ``w0``, 2 cm beside the ball (``world_plane(spin=...)``). The
    ball lands (the impact stops its slip on the table's moving material) and rolls on: its
    material point at the support moves exactly with the table's material there,
    ``v + R (omega x S) = w(t) n x (r_c - w0)``, computed here from the state and the sphere's
    formula (to 1e-12 m/s, at speeds up to 2 cm/s; an error in the rate of the table's velocity
    along the moving contact would show as an offset of about 1e-4 m/s)."""
    R = BALL_R
    _, scene = pressed_ball("press_turn", 0.0)
    w0 = np.array([-0.03, 0.0, 0.0])
    turntable = gs.scenes.world_plane(tuple(w0), (0.0, 1.0, 0.0), support=(-np.pi / 2, 0.0), spin="2*t")
    for bad in ("2*s", "1/t", "t**0.5", "log(t)", [1.0, 2.0], float("nan")):
        with pytest.raises(InvalidSceneError, match="plane spin"):
            gs.scenes.world_plane(tuple(w0), (0.0, 1.0, 0.0), spin=bad)
    model = gs.build(gs.scenes.with_modes(scene, planes=[turntable]))
    res = model.simulate(0.5, mu=(0.5, 1.0), t_eval=np.linspace(0.0, 0.5, 11), **TOL)
    assert [(e["contact"], e["from"], e["to"]) for e in res.events] == [(2, "separated", "rolling")]
    assert (res.modes[1:] == "rolling").all()
    names = model.state_names
    speeds = []
    for t, x in zip(res.t[1:], res.x[1:]):
        u, v = x[names.index("u_w1")], x[names.index("v_w1")]
        S = R * np.array([np.cos(v) * np.cos(u), np.cos(v) * np.sin(u), np.sin(v)])
        Rm = rotation(x[[names.index(k) for k in ("qw", "qx", "qy", "qz")]])
        r_c = x[[names.index(k) for k in "xyz"]] + Rm @ S
        v_c = x[[names.index(k) for k in ("vx", "vy", "vz")]] + Rm @ np.cross(
            x[[names.index(k) for k in ("omegaX", "omegaY", "omegaZ")]], S)
        v_table = 2 * t * np.cross((0.0, 1.0, 0.0), r_c - w0)
        assert np.max(np.abs(v_c - v_table)) < 1e-12
        speeds.append(np.linalg.norm(v_table))
    assert max(speeds) > 0.019  # the ball is carried
