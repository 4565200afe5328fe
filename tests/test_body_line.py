"""A free 2D body on a line of the world (``gs.scenes.body_on_line``, ``disk_on_incline``): the
2D contact modes and their switches against answers anyone can work out by hand (MODELS.md
section 5, uniform disk of radius r, I = m r^2 / 2):

- on an incline of angle b it rolls iff tan b <= 3 mu, with acceleration (2/3) g sin b,
  normal force m g cos b and friction m g sin b / 3; otherwise it slides with g (sin b -
  mu cos b) while its spin grows at 2 mu g cos b / r;
- thrown along a table with backspin it slides until the slip stops, at
  t* = (v0 - v_f) / (mu g), then rolls at v_f = (2 v0 + r theta'_0) / 3 (the angular momentum
  about the contact point is kept while it slides);
- dropped from a height h it hits the table at sqrt(2 g h) and leaves at e times that; no
  impact adds energy.
"""
from __future__ import annotations

import math

import numpy as np
import pytest

import grasping_sym as gs
from grasping_sym.errors import InvalidSceneError

G = 9.81
R, MASS = 0.05, 0.1


def _down(b: float) -> np.ndarray:
    return np.array([math.cos(b), -math.sin(b)])


@pytest.mark.parametrize("mu, rolls", [(0.2, True), (0.05, False), (0.1 + 1e-3, True), (0.1 - 1e-3, False)])
def test_a_disk_on_an_incline_rolls_iff_tan_b_is_at_most_3_mu(mu, rolls):
    b = math.atan(0.3)      # tan b = 0.3: the boundary is mu = 0.1
    model = gs.build(gs.scenes.disk_on_incline(R, MASS, b, friction=gs.contact.coulomb(mu)))
    T = 0.3
    res = model.simulate(T, t_eval=np.linspace(0.0, T, 31), rtol=1e-10, atol=1e-12)
    assert set(res.modes) == {"rolling" if rolls else "sliding"} and not res.events
    travelled = (res.x[:, 0:2] - res.x[0, 0:2]) @ _down(b)
    acc = 2 * travelled[-1] / T**2
    if rolls:
        assert acc == pytest.approx(2 / 3 * G * math.sin(b), rel=1e-9)
        assert res["Ft"][-1] == pytest.approx(MASS * G * math.sin(b) / 3, rel=1e-9)
        np.testing.assert_allclose(res["dtheta"] * R, acc * res.t, rtol=1e-8, atol=1e-12)  # v = r theta'
    else:
        assert acc == pytest.approx(G * (math.sin(b) - mu * math.cos(b)), rel=1e-9)
        spin = 2 * mu * G * math.cos(b) / R
        np.testing.assert_allclose(res["dtheta"], spin * res.t, rtol=1e-8, atol=1e-10)
        assert res["cone_ratio"][-1] == pytest.approx(mu, rel=1e-12)
    assert res["normal_force"][-1] == pytest.approx(MASS * G * math.cos(b), rel=1e-9)


def test_backspin_slides_then_rolls_at_the_located_time(tmp_path):
    mu, v0, spin0 = 0.3, 1.0, -20.0          # theta' < 0: spinning against the roll
    model = gs.build(gs.scenes.body_on_line(gs.curves.circle(R, by="angle", span=3 * math.pi,
                                                             clockwise=True), mass=MASS,
                                            inertia=MASS * R**2 / 2, theta=math.pi / 2,
                                            velocity=(v0, 0.0), dtheta=spin0, name="backspin",
                                            friction=gs.contact.coulomb(mu)))
    res = model.simulate(0.4, t_eval=np.linspace(0.0, 0.4, 41), rtol=1e-10, atol=1e-12)
    # drawn: the modes over time and an animation of the body on its line
    assert [p.name for p in gs.viz.write_figures(model.scene, res, tmp_path)] == ["backspin_modes.png"]
    assert gs.viz.animate(res, tmp_path / "backspin.gif", fps=5).stat().st_size > 1000
    v_f = (2 * v0 + R * spin0) / 3
    t_star = (v0 - v_f) / (mu * G)
    (event,) = res.events
    assert (event["from"], event["to"], event["witness"]) == ("sliding", "rolling", "slip")
    assert event["t"] == pytest.approx(t_star, rel=1e-9)
    assert res["dx"][-1] == pytest.approx(v_f, rel=1e-9)
    assert res["dtheta"][-1] * R == pytest.approx(v_f, rel=1e-9)
    assert res.modes[0] == "sliding" and res.modes[-1] == "rolling"


def test_a_dropped_disk_bounces_by_e_and_no_impact_adds_energy():
    h, e = 0.1, 0.5
    model = gs.build(gs.scenes.body_on_line(gs.curves.circle(R, by="angle", span=3 * math.pi,
                                                             clockwise=True), mass=MASS,
                                            inertia=MASS * R**2 / 2, theta=math.pi / 2,
                                            position=(0.0, R + h), start="as given", name="drop",
                                            dtheta=3.0, friction=gs.contact.coulomb(0.4, e=e)))
    res = model.simulate(0.5, t_eval=np.linspace(0.0, 0.5, 501), rtol=1e-10, atol=1e-12)
    hits = [ev for ev in res.events if ev["from"] == "separated"]
    assert hits and hits[0]["t"] == pytest.approx(math.sqrt(2 * h / G), rel=1e-9)
    # the first rebound: the centre leaves at e sqrt(2 g h) upward
    first = hits[0]["t"]
    after = res.t > first + 1e-9
    k = int(np.argmax(after))
    vy_after = res["dy"][k] + G * (res.t[k] - first)     # back to the impact's instant
    assert vy_after == pytest.approx(e * math.sqrt(2 * G * h), rel=1e-8)
    energy = res["energy"]
    assert np.all(np.diff(energy) <= 1e-12 * abs(energy[0]))   # never gains energy
    assert energy[-1] < energy[0] - 0.5 * MASS * G * h          # the impacts took a part


def test_a_body_on_a_line_is_checked_by_name():
    with pytest.raises(InvalidSceneError, match="runs counterclockwise"):
        gs.scenes.body_on_line(gs.curves.circle(R, by="angle", span=math.pi), mass=1.0, inertia=1.0)
    with pytest.raises(InvalidSceneError, match="line_normal .* must be a unit vector"):
        gs.scenes.disk_on_incline(line_normal=(0.0, 2.0))
    with pytest.raises(InvalidSceneError, match="inertia = -1"):
        gs.scenes.body_on_line(gs.curves.circle(R, clockwise=True, span=3.0), mass=1.0, inertia=-1)


def test_a_disk_at_rest_on_a_rising_conveyor_slides_then_rolls_at_a_third_of_its_speed():
    """A belt moving along x at V and rising with acceleration a (``line_motion``): the disk at
    rest slips on it; friction mu m (g + a) speeds its centre at mu (g + a) and its contact
    point at 3 mu (g + a), so the slip stops at t* = V / (3 mu (g + a)) and it rolls on at V / 3
    (no force needed on a belt at constant speed), its normal force m (g + a) throughout."""
    mu, V, a = 0.4, 0.6, 2.0
    disk = gs.scenes.body_on_line(gs.curves.circle(R, by="angle", span=3 * math.pi, clockwise=True),
                                  mass=MASS, inertia=MASS * R**2 / 2, theta=math.pi / 2, name="belt",
                                  line_motion=(f"{V} * t", f"{a} / 2 * t**2"),
                                  friction=gs.contact.coulomb(mu))
    res = gs.build(disk).simulate(0.2, t_eval=np.linspace(0.0, 0.2, 21), rtol=1e-10, atol=1e-12)
    (event,) = res.events
    assert (event["from"], event["to"]) == ("sliding", "rolling")
    assert event["t"] == pytest.approx(V / (3 * mu * (G + a)), rel=1e-9)
    assert res["dx"][-1] == pytest.approx(V / 3, rel=1e-9)
    np.testing.assert_allclose(res["normal_force"], MASS * (G + a), rtol=1e-9)
    assert res["dy"][-1] == pytest.approx(a * 0.2, rel=1e-9)          # it rides the belt up
    with pytest.raises(InvalidSceneError, match="line_motion .* give two expressions of t"):
        gs.scenes.body_on_line(disk.contour, mass=1.0, inertia=1.0, line_motion=("t", "t", "t"))
    with pytest.raises(InvalidSceneError, match="is not 0 at t = 0"):
        gs.scenes.body_on_line(disk.contour, mass=1.0, inertia=1.0, line_motion=("1 + t", "0"))


def test_a_spinning_disk_dropped_on_a_table_slides_off_the_impact_on_its_cone():
    """A disk spinning at 50 rad/s (clockwise) falls 10 cm onto a table (e = 0, mu = 0.4): its
    contact point slips backwards at 2.5 m/s, more than the impact's friction can stop, so the
    impulse lies on the cone's edge, P_t = mu P_n with P_n = m sqrt(2 g h) (Moreau): just after,
    the centre moves at mu sqrt(2 g h) and the spin has dropped by r P_t / I. It then slides
    until the slip stops and rolls at (2 v + r theta') / 3, its momentum about the contact
    point kept from the impact on."""
    h, mu, spin = 0.1, 0.4, 50.0
    model = gs.build(gs.scenes.body_on_line(gs.curves.circle(R, by="angle", span=20 * math.pi,
                                                             clockwise=True), mass=MASS,
                                            inertia=MASS * R**2 / 2, theta=math.pi / 2,
                                            position=(0.0, R + h), start="as given", dtheta=spin,
                                            name="spin_drop", friction=gs.contact.coulomb(mu)))
    res = model.simulate(0.4, t_eval=np.linspace(0.0, 0.4, 41), rtol=1e-10, atol=1e-12)
    hit, stop = res.events
    assert (hit["from"], hit["to"], stop["from"], stop["to"]) == ("separated", "sliding", "sliding", "rolling")
    v = math.sqrt(2 * G * h)
    late = hit["t"] * (1 + 1e-12)
    after = model.simulate(late, t_eval=[0.0, late], rtol=1e-10, atol=1e-12)
    s = dict(zip(model.state_names, after.x[-1]))
    Pt = mu * MASS * v
    assert s["dx"] == pytest.approx(Pt / MASS, rel=1e-9) and abs(s["dy"]) < 1e-9
    assert s["dtheta"] == pytest.approx(spin - R * Pt / (MASS * R**2 / 2), rel=1e-9)
    assert res["dx"][-1] == pytest.approx((2 * s["dx"] + R * s["dtheta"]) / 3, rel=1e-9)


def test_a_belt_speeding_up_makes_the_rolling_disk_slide_where_its_cone_ends():
    """A disk at rest rolls on a belt whose speed grows as k t^2 / 2 (acceleration k t): rolling
    needs friction m k t / 3, so it slides at t* = 3 mu g / k, located at the step, and then its
    centre speeds up at mu g."""
    mu, k = 0.3, 10.0
    disk = gs.scenes.body_on_line(gs.curves.circle(R, by="angle", span=20 * math.pi, clockwise=True),
                                  mass=MASS, inertia=MASS * R**2 / 2, theta=math.pi / 2, name="belt_k",
                                  line_motion=(f"{k} / 6 * t**3", "0"), friction=gs.contact.coulomb(mu))
    res = gs.build(disk).simulate(1.2, t_eval=np.linspace(0.0, 1.2, 13), rtol=1e-10, atol=1e-12)
    (event,) = res.events
    assert (event["from"], event["to"], event["witness"]) == ("rolling", "sliding", "cone")
    assert event["t"] == pytest.approx(3 * mu * G / k, rel=1e-9)
    after = res.t > event["t"]
    v_star = k * event["t"]**2 / 6        # the centre's speed at the switch: a third of the belt's
    np.testing.assert_allclose(res["dx"][after], v_star + mu * G * (res.t[after] - event["t"]), rtol=1e-9)


def test_a_new_start_of_a_model_with_modes_is_given_whole():
    """A model with contact modes has no compiled start conditions: ``initial_state(theta=...)``
    says so by name, with the way to give a start (the state whole, ``simulate(x0=...)``)."""
    model = gs.build(gs.scenes.disk_on_incline())
    with pytest.raises(NotImplementedError, match="a model with contact modes .* simulate\\(x0=x0\\)"):
        model.initial_state(theta=0.1)
