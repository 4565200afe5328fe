"""Contact modes of a 3D grasp (model.grasp3d_modes, derive.grasp3d_modes, runtime.modes;
docs/conventions.md section 9): checked against the rolling model, the rolling model's own
cone event, Coulomb's law, the energy balance of a slide, and a free fall's exact motion
once both fingers let go."""
from __future__ import annotations

import numpy as np
import pytest

import grasping_sym as gs
from grasping_sym.errors import FrictionConeError, InvalidSceneError

TOL = {"rtol": 1e-9, "atol": 1e-11}


@pytest.fixture(scope="module")
def base():
    return gs.scenes.paper3d()


@pytest.fixture(scope="module")
def model(base):
    return gs.build(gs.scenes.with_modes(base))


@pytest.fixture(scope="module")
def rolling(base):
    return gs.build(base)


def test_rolling_modes_are_the_rolling_model(model, rolling):
    """Both contacts rolling is paper3d's model: the same right-hand side at states near the
    start (to 1e-12 relative) and, with no friction limit, a run with no switch."""
    rng = np.random.default_rng(5)
    x0 = rolling.initial_state()
    for _ in range(5):
        x = x0 + rng.normal(scale=1e-3, size=len(x0))
        a, b = rolling.rhs(x), model.rhs(x)
        assert np.max(np.abs(a - b) / (np.abs(a) + 1e-9)) < 1e-12
    r = model.simulate(0.05, t_eval=np.linspace(0.0, 0.05, 11), **TOL)
    r0 = rolling.simulate(0.05, t_eval=np.linspace(0.0, 0.05, 11), method="radau", **TOL)
    assert r.events == [] and (r.modes == "rolling").all()
    assert np.max(np.abs(r.x - r0.x)) < 1e-8


@pytest.fixture(scope="module")
def slide(model):
    """mu = 0.08: contact 2 leaves its cone, slides."""
    return model.simulate(0.06, mu=0.08, t_eval=np.linspace(0.0, 0.06, 601), **TOL)


def test_slip_starts_where_the_rolling_model_leaves_its_cone(rolling, slide):
    """The first switch is where the rolling model's cone check stops it (FrictionConeError,
    located on its own lam, eta and f), at the same contact."""
    with pytest.raises(FrictionConeError) as err:
        rolling.simulate(0.06, mu=0.08, t_eval=np.linspace(0.0, 0.06, 61), method="radau", **TOL)
    first = slide.events[0]
    assert (first["from"], first["to"], first["witness"]) == ("rolling", "sliding", "cone")
    assert first["contact"] == err.value.contact
    assert abs(first["t"] - err.value.t) < 1e-8


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
    from scipy.integrate import simpson

    j = slide.events[0]["contact"]
    k = np.searchsorted(slide.t, slide.events[0]["t"]) + 1
    t = slide.t[k:]
    E = slide["kinetic_energy"][k:] + slide["potential_energy"][k:]
    friction = sum(slide[f"lam{i}"][k:] * slide[f"vt_x{i}"][k:] + slide[f"eta{i}"][k:] * slide[f"vt_y{i}"][k:]
                   for i in (1, 2))
    dissipated = simpson(friction, x=t)
    assert dissipated > 1e-7 and slide.modes[-1, j - 1] == "sliding"
    assert abs((E[-1] - E[0]) - simpson(slide["power"][k:] - friction, x=t)) < 1e-5 * dissipated


def test_dropped_grasp_falls_freely(base, model):
    """mu = 0.02: both contacts slide from the start, lose their normal force and open; the
    object then falls with g and spins with constant angular momentum (Euler's free rigid
    body: ``H omega`` turned to the world is constant)."""
    r = model.simulate(0.2, mu=0.02, t_eval=np.linspace(0.0, 0.2, 401), **TOL)
    assert [(e["from"], e["to"]) for e in r.events] == [("sliding", "separated")] * 2
    assert sorted(e["contact"] for e in r.events) == [1, 2]
    rows = np.flatnonzero((r.modes == "separated").all(axis=1))[2:]
    names = base.state_names
    pos = r.x[rows][:, [names.index(k) for k in ("x", "y", "z")]]
    vel = r.x[rows][:, [names.index(k) for k in ("vx", "vy", "vz")]]
    t = r.t[rows] - r.t[rows[0]]
    g = np.array(base.gravity)
    expected = pos[0] + np.outer(t, vel[0]) + 0.5 * np.outer(t**2, g)
    assert np.max(np.abs(pos - expected)) < 1e-9
    H = np.asarray(base.inertia)
    quat = r.x[rows][:, [names.index(k) for k in ("qw", "qx", "qy", "qz")]]
    om = r.x[rows][:, [names.index(k) for k in ("omegaX", "omegaY", "omegaZ")]]
    L = np.array([gs.runtime.modes.rotation(q) @ (H @ w) for q, w in zip(quat, om)])
    assert np.max(np.abs(L - L[0])) < 1e-9 * max(1.0, np.max(np.abs(L)))
    assert np.all(r["gap1"][rows] > 0) and np.all(r["gap2"][rows] > 0)


def test_refusals(base):
    with pytest.raises(InvalidSceneError, match="regular"):
        gs.scenes.with_modes(gs.scenes.paper3d(formulation="paper"))
    with pytest.raises(InvalidSceneError, match="runtime"):
        gs.scenes.with_modes(gs.scenes.paper3d(runtime=("gain",)))
