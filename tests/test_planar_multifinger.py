"""2D scenes with several fingers on one pivoted object (``ExtraFinger``).

Exact checks: a mirror-symmetric pair of fingers on an ellipse touched off its axes moves
(each finger alone would turn the object) but leaves the object still and the two fingers
mirrored; three fingers balance energy (d/dt kinetic = controller power) and keep every
contact on its constraints. An extra finger that cannot reach its contact is refused by name.
"""
from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.integrate import cumulative_simpson, simpson

import grasping_sym as gs
from grasping_sym.errors import FrictionConeError, InvalidSceneError
from grasping_sym.geometry import library as L
from grasping_sym.model.planar import ExtraFinger
from grasping_sym.viz.kinds import write_figures

U1 = math.pi + 0.3       # finger 1 touches the ellipse 0.3 rad below its -x vertex
TOL = {"rtol": 1e-10, "atol": 1e-12}


def _tip(name: str):
    return L.circle(0.01, name=name)


def _object():
    return L.ellipse(0.025, 0.018, span=6.2, clockwise=True, name="ellipse")


def _pivot() -> tuple[float, float]:
    return gs.scenes.planar_finger(_tip("tip"), _object(), name="one", u1_0=-U1).pivot


def _scene(name: str, extra, outputs, **params) -> object:
    return gs.scenes.planar_finger(_tip("tip"), _object(), name=name, u1_0=-U1, extra_fingers=extra,
                                   outputs=outputs, **params)


def test_mirror_symmetric_pair_holds_what_one_finger_turns():
    """Touched 0.3 rad off the ellipse's axis, one finger turns the object; a mirrored second
    finger cancels its torque exactly: the pair is in equilibrium and nothing moves."""
    xm, ym = _pivot()
    single = gs.build(_scene("single", (), ("constraint_residual", "f", "kinetic_energy")))
    turned = single.simulate(0.5, method="radau", rtol=1e-9, atol=1e-12)
    assert abs(turned["theta"][-1]) > 0.05

    mirror = ExtraFinger(_tip("tip2"), base=(2 * xm, 0.0), u1_0=U1 - math.pi)
    model = gs.build(_scene("mirror2", (mirror,), ("constraint_residual", "f1", "f2", "kinetic_energy")))
    x0 = model.initial_state()
    names = model.state_names
    assert names[:5] == ("theta", "q11", "q12", "q21", "q22")
    assert x0[names.index("q21")] == pytest.approx(-x0[names.index("q11")], abs=1e-12)
    assert x0[names.index("q22")] == pytest.approx(-x0[names.index("q12")], abs=1e-12)
    res = model.simulate(0.5, method="radau", rtol=1e-9, atol=1e-12)
    assert np.max(np.abs(res.x - x0)) <= 1e-12
    o = res.outputs
    assert np.max(np.abs(o["f1"] - o["f2"])) <= 1e-9 * np.max(np.abs(o["f1"]))
    assert o["f1"].min() > 0.5


def test_two_finger_scenes_have_default_outputs_and_plot(tmp_path):
    """Default outputs: each per-contact output once per finger; the figures draw both fingers
    and plot each finger's curves."""
    from grasping_sym.viz import plots

    xm, _ = _pivot()
    pair = ExtraFinger(_tip("tip2"), base=(2 * xm, 0.0), u1_0=U1 - math.pi + 0.2)
    scene = gs.scenes.planar_finger(_tip("tip"), _object(), name="pair2", u1_0=-U1,
                                    extra_fingers=(pair,))
    assert scene.outputs[:4] == ("Q1", "Q2", "R1", "R2")
    assert "N1_2" in scene.outputs and "kappa_sum2" in scene.outputs
    assert "constraint_residual" in scene.outputs
    # the figures need no build: a short made-up trajectory at the scene's start
    x0 = np.array(scene.initial_state(), dtype=float)
    t = np.linspace(0, 0.1, 5)
    outs = {k: np.linspace(0.1, 0.2, 5) for k in scene.outputs}
    res = gs.SimulationResult(t=t, x=np.tile(x0, (5, 1)), state_names=scene.state_names,
                              outputs=outs, method="made-up")
    every = plots.poses(scene, x0)
    assert len(every) == 2 and np.allclose(every[1].joint1, (2 * xm, 0.0))
    # both fingertips touch the object at the start: contact points coincide
    for p in every:
        assert np.linalg.norm(p.contact_finger - p.contact_object) < 1e-9
    paths = write_figures(scene, res, tmp_path)
    assert len(paths) == 12 and all(p.stat().st_size > 10_000 for p in paths)
    assert any(p.name == "constraints_log.png" for p in paths)
    curves = plots.TIME_PLOTS[0].curves(scene, res)
    assert [c[0] for c in curves] == [r"$\Delta f$, finger 1", r"$\Delta f$, finger 2"]


def _pair():
    """Two fingers on the ellipse, the stabilisation's gains 0 (shared by the tests below: one
    build)."""
    xm, _ = _pivot()
    return _scene("pair", (ExtraFinger(_tip("tip2"), base=(2 * xm, 0.0), u1_0=0.35),), ("f1", "f2", "lam2"),
                  gf=0.0, gl=0.0, wf=0.0, wl=0.0)


def test_two_fingers_compiled_equal_the_symbolic_reference():
    """The template/compose path for several contacts against SymPy lambdify of the same
    derivation (in doubles, and in 40 digits as the exact value), at states along a run (on
    the constraint manifold). Stabilisation gains 0:
    with the paper's (~1e7 1/s^2) the one-ulp rounding of Q and R alone makes the two
    evaluations differ by ~1e-9 (see tests/test_compiled_vs_symbolic.py)."""
    from tests.oracles.reference import ReferenceModel

    xm, ym = _pivot()
    scene = _pair()
    model = gs.build(scene)
    res = model.simulate(0.3, method="radau", rtol=1e-9, atol=1e-12, t_eval=np.linspace(0, 0.3, 9))
    ref = ReferenceModel(scene)
    err_compiled, err_reference = [], []
    for x in res.x:
        a, b, exact = model.rhs(x), ref.rhs(x), ref.rhs_exact(x)
        err_compiled.append(np.max(np.abs(a - exact) / (1 + np.abs(exact))))
        err_reference.append(np.max(np.abs(b - exact) / (1 + np.abs(exact))))
        ya, yb = model.outputs(x), ref.outputs(x)
        assert abs(ya["f2"] - yb["f2"]) <= 1e-12 * (1 + abs(yb["f2"]))
    # as accurate as NumPy's evaluation of the derivation, against the same in 40 digits:
    # both err by up to ~1e-12 (roundings amplified by the closed loop's solves), the
    # largest of 61 states measured 1.2e-12 and 8.7e-13 (8.1e-13 for the compiled code
    # before its shared reciprocals, codegen.reciprocals); 9 of them are checked (the
    # suite's time budget: each exact evaluation takes ~0.5 s)
    assert max(err_reference) <= 2e-12
    assert max(err_compiled) <= 2 * max(err_reference)


def test_three_fingers_balance_energy_and_keep_contact():
    xm, ym = _pivot()
    extra = (ExtraFinger(_tip("tip2"), base=(2 * xm, 0.0), u1_0=0.35),
             ExtraFinger(_tip("tip3"), base=(xm - 0.0325, ym + 0.149), u1_0=-math.pi / 2 + 0.1))
    scene = _scene("three", extra, ("constraint_residual", "f1", "f2", "f3", "kinetic_energy", "power"))
    model = gs.build(scene)
    assert len(model.state_names) == 1 + 6 + 1 + 6 + 6
    t = np.linspace(0.0, 1.0, 4001)
    res = model.simulate(1.0, rtol=1e-11, atol=1e-13, t_eval=t)
    o = res.outputs
    work = cumulative_simpson(o["power"], x=res.t, initial=0.0)
    drift = np.max(np.abs(o["kinetic_energy"] - o["kinetic_energy"][0] - work))
    # measured ~2e-12 J whatever the tolerance: the stabilisation's corrections do work at that
    # level (with the gains at 0 it is 2e-13 J); an error in the derivation would show at the
    # scale of the kinetic energy itself, 8e-7 J here
    assert o["kinetic_energy"].max() > 1e-7
    assert drift <= 2e-11, drift
    assert o["constraint_residual"].max() <= 1e-10
    for i in (1, 2, 3):
        assert o[f"f{i}"].min() > 0.5                       # every finger keeps pressing


def test_an_unreachable_extra_finger_is_refused():
    far = ExtraFinger(_tip("tip2"), base=(1.0, 0.0), u1_0=0.3)
    scene = _scene("far", (far,), ("constraint_residual",))
    with pytest.raises(InvalidSceneError, match="cannot touch the object"):
        scene.initial_state()


def test_extra_finger_problems_are_listed():
    bad = ExtraFinger(_tip("tip2"), base=(math.nan, 0.0), u1_0=99.0, lengths=(0.065, -1.0))
    with pytest.raises(InvalidSceneError) as info:
        _scene("bad", (bad,), ("f3",))
    msg = str(info.value)
    assert "finite numbers" in msg and "outside the object's domain" in msg and "'f3'" in msg


def test_two_fingers_with_modes_roll_as_the_rolling_model_and_one_slips_at_its_cone():
    """Two fingers on the pivoted ellipse (``_pair``), each contact in its own mode
    (``with_modes``, ``docs/conventions.md`` section 8): all rolling, the right-hand side is
    the rolling two-finger model's; with finger 2's mu between its cone ratio at the start and
    its largest, contact 2 slides at the time the rolling model's own cone check stops it,
    with Coulomb's law, contact 1 still on its constraints, and the energy balance
    d(K + V)/dt = joints' power - lam2 v_t2; finger 2 started apart returns with a plastic
    impact that holds contact 1."""
    pair = _pair()
    rolling = gs.build(pair)
    model = gs.build(gs.scenes.with_modes(pair))
    assert model.p_names[:6] == ("mode1", "slip1", "mu1", "mode2", "slip2", "mu2")
    grid = dict(t_eval=np.linspace(0.0, 0.3, 301), **TOL)
    free = rolling.simulate(0.3, **grid)
    for x in free.x[::30]:
        a, b = model.rhs(x), rolling.rhs(x)
        assert np.max(np.abs(a - b) / (1 + np.abs(b))) < 2e-12
    ratio = np.abs(free["lam2"] / free["f2"])
    assert ratio.argmax() > 100  # contact 2's ratio grows: a mu between slips it mid-run
    mu2 = 0.5 * (ratio[0] + ratio.max())
    law = gs.contact.coulomb((0.5, mu2))
    with pytest.raises(FrictionConeError) as err:
        rolling.simulate(0.3, mu=law, **grid)
    res = model.simulate(0.3, mu=law, **grid)
    (slip,) = res.events
    assert (slip["contact"], slip["from"], slip["to"], slip["witness"]) == (2, "rolling", "sliding", "cone")
    assert err.value.contact == 2 and abs(slip["t"] - err.value.t) < 1e-8
    sliding = res.modes[:, 1] == "sliding"
    assert sliding.sum() > 100 and (res.modes[:, 0] == "rolling").all()
    f2, lam2, vt2 = (res[k][sliding] for k in ("normal_force2", "lam2", "vt2"))
    assert np.max(np.abs(np.abs(lam2) - mu2 * f2)) < 1e-12 * np.max(f2) and np.all(lam2 * vt2 >= 0)
    assert max(np.max(np.abs(res["Q1"])), np.max(np.abs(res["R1"])), np.max(np.abs(res["gap2"]))) < 1e-12
    rows = np.flatnonzero(sliding)[1:]
    t = res.t[rows]
    E = res["kinetic_energy"][rows] + res["potential_energy"][rows]
    dissipated = simpson(res["lam2"][rows] * res["vt2"][rows], x=t)
    assert dissipated > 1e-9
    assert abs((E[-1] - E[0]) - simpson(res["power"][rows] - res["lam2"][rows] * res["vt2"][rows], x=t)) \
        < 1e-6 * dissipated
    # runs that end at the switch or within ~3e-15 s of it (one of these, measured, locates the
    # event at its last output time exactly) report every output time
    for t_final in (*(slip["t"] + k * 1e-16 for k in range(0, 32, 2)), 0.18090392279547146):
        grid = np.linspace(0.0, t_final, 11)
        end = model.simulate(t_final, mu=law, t_eval=grid, **TOL)
        assert list(end.t) == list(grid) and np.all(np.isfinite(end.x))
    assert model.simulate_many(t_final, mu=law, t_eval=grid, x0=np.tile(end.x[0], (2, 1)), **TOL).x.shape \
        == (2, 11, len(model.state_names))
    # finger 2 pulled back starts apart (its contact parameters put on the common normal),
    # returns, and its plastic impact holds contact 1 (a joint impulse with contact 1's rows)
    x0 = model.initial_state()
    x0[model.state_names.index("q21")] += 0.002
    hold = gs.contact.coulomb((3.0, 0.5))
    back = model.simulate(0.05, x0=x0, mu=hold, t_eval=np.linspace(0.0, 0.05, 51), **TOL)
    (hit,) = back.events
    assert (hit["contact"], hit["from"], hit["to"], hit["witness"]) == (2, "separated", "rolling", "gap")
    assert hit["reset"] > 0.01 and back["gap2"][0] > 1e-5 and back["gap2"].min() > -1e-12
    after = back.t > hit["t"]
    assert np.abs(back["normal_speed2"][after]).max() < 1e-12 and (back.modes[:, 0] == "rolling").all()
    assert max(np.abs(back["Q1"]).max(), np.abs(back["R1"]).max()) < 1e-12
    # with mu1 = 0.5 the same impact would push contact 1 out of its cone: held it cannot be,
    # so the impulse starts it sliding (on its cone's edge, its slip where the impulse leaves
    # it: recorded as its own switch, witness "impulse"); friction stops that slip 29 us later
    # and it rolls on; the impact takes energy, and contact 1 stays on its constraints
    slid = model.simulate(0.05, x0=x0, mu=law, t_eval=np.linspace(0.0, 0.05, 51), **TOL)
    hit, started, stopped = slid.events[:3]
    assert (hit["contact"], hit["from"], hit["witness"]) == (2, "separated", "gap")
    assert (started["contact"], started["from"], started["to"], started["witness"], started["t"]) == \
        (1, "rolling", "sliding", "impulse", hit["t"])
    assert (stopped["contact"], stopped["from"], stopped["to"], stopped["witness"]) == (1, "sliding", "rolling", "slip")
    assert 0 < stopped["t"] - hit["t"] < 1e-3
    energy = slid["kinetic_energy"] + slid["potential_energy"]
    k = int(np.searchsorted(slid.t, hit["t"], side="right"))    # the first output after it
    assert energy[k] < energy[k - 1]
    assert max(np.abs(slid["Q1"]).max(), np.abs(slid["gap2"][k:]).max()) < 1e-12
