"""Bad input is refused with a real exception whose message names every problem."""
from __future__ import annotations

import math
import subprocess
import sys
import textwrap

import numpy as np
import pytest

import grasping_sym as gs
from grasping_sym.errors import ContactLeftContourError, InvalidSceneError
from grasping_sym.geometry import library
from grasping_sym.geometry.curves import PlanarCurve, T


# ------------------------------------------------------------------ scenes
def test_nan_and_negative_parameters_are_named_together():
    with pytest.raises(InvalidSceneError) as info:
        gs.scenes.paper2d(l11=-0.065, fd=float("nan"))
    err = info.value
    assert len(err.problems) == 2
    msg = str(err)
    assert "l11 = -0.065" in msg and "fd = nan" in msg


@pytest.mark.parametrize("bad", [0.0, -1.0, math.inf, np.nan, "0.5", None])
def test_every_parameter_value_is_checked(bad):
    with pytest.raises(InvalidSceneError) as info:
        gs.scenes.paper2d(I=bad)
    assert "I = " in str(info.value)


def test_unknown_parameter_is_named():
    with pytest.raises(InvalidSceneError) as info:
        gs.scenes.paper2d(fdd=0.5)
    assert "'fdd'" in str(info.value) and "unknown parameters" in str(info.value)


def test_unknown_output_is_named():
    with pytest.raises(InvalidSceneError) as info:
        gs.scenes.paper2d(outputs=("Q", "energy"))
    assert "'energy'" in str(info.value) and "kinetic_energy" in str(info.value)


def test_geometric_parameter_cannot_be_runtime():
    with pytest.raises(InvalidSceneError) as info:
        gs.scenes.paper2d(runtime=("fd", "l11"))
    err = info.value
    assert len(err.problems) == 1 and "'l11'" in str(err)


def test_scene_problems_are_reported_together():
    with pytest.raises(InvalidSceneError) as info:
        gs.scenes.paper2d(runtime=("l12",), outputs=("bogus",), m11=-1.0, q1_0=math.nan)
    msg = str(info.value)
    assert len(info.value.problems) == 4
    for word in ("'l12'", "'bogus'", "m11 = -1.0", "q1_0 = nan"):
        assert word in msg


@pytest.mark.parametrize("s0", [0.05, -0.0300001])
def test_initial_contact_outside_domain(s0):
    with pytest.raises(InvalidSceneError) as info:
        gs.scenes.paper2d(u0_0=s0, u1_0=s0)
    msg = str(info.value)
    assert "fingertip" in msg and "object" in msg and "(-0.03, 0.03)" in msg


def test_initial_contact_outside_object_domain_only():
    with pytest.raises(InvalidSceneError) as info:
        gs.scenes.planar_finger(library.circle(0.015, by="angle"), library.paper_object(),
                                u1_0=0.04)
    assert len(info.value.problems) == 1 and "object (0.04)" in str(info.value)


def test_invalid_contour_is_reported_by_the_scene():
    """Contours are sampled lazily (not at construction) but before anything is derived."""
    cusp = PlanarCurve(0.01 + T**2, T**3, T, (-0.02, 0.02), "cusp tip")
    scene = gs.scenes.planar_finger(cusp, library.paper_object(), name="cusp_tip")
    with pytest.raises(InvalidSceneError) as info:
        gs.build(scene)
    assert "fingertip contour" in str(info.value) and "not regular" in str(info.value)


def test_concave_contact_is_refused():
    # the object traversed counterclockwise: kappa1 = -100 at its vertex, sum < 0
    scene = gs.scenes.planar_finger(library.paper_fingertip(),
                                    library.circle(0.01, start=math.pi, clockwise=False),
                                    name="concave")
    with pytest.raises(InvalidSceneError) as info:
        gs.build(scene)
    assert "kappa0 + kappa1" in str(info.value)


# ------------------------------------------------------------------ leaving the contour
@pytest.fixture(scope="module")
def short_model():
    """Circular fingertip of arc +-6 mm on the paper object: the contact leaves it at ~0.3 s."""
    scene = gs.scenes.planar_finger(library.circle(0.015, span=0.4), library.paper_object(),
                                    name="short_contour", outputs=("Q",))
    return gs.build(scene)


def test_contact_leaving_domain_raises_with_time(short_model):
    lo, hi = short_model.lower[-1], short_model.upper[-1]
    assert (lo, hi) == pytest.approx((-0.006, 0.006), rel=1e-15)
    times = {}
    for method in ("cvodes", "idas", "rk4"):
        with pytest.raises(ContactLeftContourError) as info:
            short_model.simulate(1.0, method=method)
        err = info.value
        assert 0.0 < err.t < 1.0, method
        assert "domain" in str(err) or "left [" in str(err)
        assert err.x is not None and lo <= err.x[-1] <= hi  # last state still inside
        assert abs(err.x[-1] - lo) <= 1e-4  # ... and next to the end it left by
        times[method] = err.t
    # the adaptive runs interpolate on the 1 ms grid, rk4 reports the step before
    assert abs(times["cvodes"] - times["rk4"]) <= 1e-3
    assert abs(times["cvodes"] - times["idas"]) <= 1e-3


def test_short_run_within_domain_succeeds(short_model):
    r = short_model.simulate(0.2)
    assert np.all(r["s"] >= -0.006) and np.max(np.abs(r["Q"])) <= 1e-10


# ------------------------------------------------------------------ simulate arguments
def test_bad_method(paper2d_model):
    with pytest.raises(ValueError, match=r"'euler'.*cvodes.*idas.*rk4"):
        paper2d_model.simulate(1.0, method="euler")


@pytest.mark.parametrize("t_final", [0.0, -1.0, math.nan, math.inf, "1"])
def test_bad_t_final(paper2d_model, t_final):
    with pytest.raises(TypeError if isinstance(t_final, str) else ValueError, match="t_final"):
        paper2d_model.simulate(t_final)


@pytest.mark.parametrize("shape", [(6,), (8,), (1, 7)])
def test_x0_of_wrong_shape(paper2d_model, shape):
    with pytest.raises(ValueError, match=r"x0 has shape .*expected \(7,\).*theta"):
        paper2d_model.simulate(0.1, x0=np.zeros(shape))


@pytest.mark.parametrize("bad", [math.nan, math.inf])
def test_x0_non_finite(paper2d_model, bad):
    x0 = paper2d_model.initial_state()
    x0[4] = bad
    with pytest.raises(ValueError, match="non-finite"):
        paper2d_model.simulate(0.1, x0=x0)


def test_x0_outside_contour_domain(paper2d_model):
    x0 = paper2d_model.initial_state()
    x0[-1] = 0.031
    with pytest.raises(ContactLeftContourError):
        paper2d_model.simulate(0.1, x0=x0)


def test_params_of_a_folded_model(paper2d_model):
    with pytest.raises(ValueError, match="folded"):
        paper2d_model.simulate(0.1, params={"fd": 0.7})


def test_unknown_runtime_param():
    model = gs.build(gs.scenes.paper2d(runtime=("fd", "c")))
    with pytest.raises(ValueError, match="'l11' is not a run-time parameter"):
        model.simulate(0.1, params={"l11": 0.07})


@pytest.mark.parametrize("t_eval", [[0.0], [0.0, 0.1, 0.1], [0.0, 0.2, 0.1]])
def test_bad_t_eval(paper2d_model, t_eval):
    with pytest.raises(ValueError, match="t_eval"):
        paper2d_model.simulate(0.1, t_eval=np.array(t_eval))


def test_rk4_needs_a_uniform_grid(paper2d_model):
    with pytest.raises(ValueError, match="uniform"):
        paper2d_model.simulate(0.1, method="rk4", t_eval=np.array([0.0, 0.01, 0.03, 0.1]))


def test_t_eval_must_end_at_t_final(paper2d_model):
    """simulate(1.0, t_eval=...) must not silently integrate to another final time."""
    with pytest.raises(ValueError, match="t_eval"):
        paper2d_model.simulate(1.0, t_eval=np.linspace(0.0, 2.0, 201))


@pytest.mark.parametrize("h", [0.0, -1e-4, math.nan], ids=["zero", "negative", "nan"])
def test_bad_rk4_step(paper2d_model, h):
    with pytest.raises(ValueError, match=r"\bh\b"):
        paper2d_model.simulate(0.1, method="rk4", h=h)


@pytest.mark.parametrize("kw", [{"rtol": -1e-8}, {"atol": -1e-12}, {"rtol": math.nan}])
def test_bad_tolerances(paper2d_model, kw):
    with pytest.raises(ValueError, match=next(iter(kw))):
        paper2d_model.simulate(0.1, **kw)


def test_t_eval_with_nan_is_refused_not_hung(paper2d_model):
    """Run in a child process: a NaN output time must raise ValueError, not hang CVODES."""
    code = textwrap.dedent("""
        import numpy as np, grasping_sym as gs
        m = gs.build(gs.scenes.paper2d())
        try:
            m.simulate(1.0, t_eval=np.array([0.0, np.nan, 1.0]))
        except ValueError as exc:
            print("ValueError", exc)
        else:
            print("no error")
    """)
    try:
        out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                             timeout=20)
    except subprocess.TimeoutExpired:
        pytest.fail("simulate(t_eval=[0, nan, 1]) did not return within 20 s (CVODES hangs)")
    assert out.stdout.startswith("ValueError"), out.stdout + out.stderr


@pytest.mark.parametrize("make, match", [
    (lambda: gs.scenes.planar_finger([1, 2], library.paper_object()), "fingertip is list"),
    (lambda: gs.scenes.planar_finger(None, library.paper_object()), "fingertip is NoneType"),
    (lambda: gs.scenes.planar_finger(library.paper_fingertip(), library.paper_object(),
                                     extra_fingers=("abc",)), "extra finger 2 is str"),
    (lambda: gs.scenes.PlanarFingerScene(name="x", fingertip=library.paper_fingertip(),
                                         object=library.paper_object(), params=[1, 2]),
     "params is list"),
    (lambda: gs.scenes.planar_finger(library.paper_fingertip(), library.paper_object(), fd=True),
     "fd = True"),
    (lambda: gs.scenes.paper3d(dq0=[math.nan] * 5), "dq0 = .* must hold finite numbers"),
    (lambda: gs.scenes.paper3d(position=(math.nan, 0.0, 0.0)), "position = .* finite numbers"),
])
def test_wrong_types_and_non_finite_values_are_named(make, match):
    with pytest.raises(InvalidSceneError, match=match):
        make()


# ------------------------------------------------------------------ output selections
def test_a_huge_or_repeated_output_selection_is_refused_at_once_in_a_short_message():
    """10**6 names (known or not) are refused by count, before any work, in a message of a few
    hundred characters; a repeated name is refused (a result holds one column per name)."""
    for outputs in (("Q",) * 10**6, tuple(f"bogus{i}" for i in range(10**6))):
        with pytest.raises(InvalidSceneError, match="lists 1000000 names, but the scene has only 13") as info:
            gs.scenes.paper2d(outputs=outputs)
        assert len(str(info.value)) < 1000
    with pytest.raises(InvalidSceneError, match="outputs names 'Q' more than once"):
        gs.scenes.paper2d(outputs=("Q", "Q", "f"))
    with pytest.raises(InvalidSceneError, match="outputs names 'f1' more than once"):
        gs.scenes.paper3d(outputs=("f1", "lam1", "f1"))
    with pytest.raises(InvalidSceneError, match=r"unknown outputs 'x0', .*'x9', \.\.\. and 2 more: choose"):
        gs.scenes.paper2d(outputs=tuple(f"x{i}" for i in range(12)))
    with pytest.raises(InvalidSceneError, match=r"outputs = 'Qf' is a string: give a tuple"):
        gs.scenes.paper2d(outputs="Qf")


def test_simulate_takes_outputs_as_a_switch_not_as_names(paper2d_model):
    from grasping_sym.errors import RunArgumentError

    with pytest.raises(RunArgumentError, match=r"outputs = \('Q',\) is tuple: give True or False: "
                                               r"the outputs themselves are chosen when the scene"):
        paper2d_model.simulate(0.01, outputs=("Q",))
    with pytest.raises(RunArgumentError, match="checks = 'yes' is str"):
        paper2d_model.simulate_many(0.01, checks="yes")


def test_tolerances_that_accept_any_step_and_empty_batches_are_refused(paper2d_model):
    """rtol or atol of 1 or more accepts any step: refused before the run, not blamed on the
    physics afterwards; simulate_many of no runs is named."""
    from grasping_sym.errors import RunArgumentError

    for kw in ({"rtol": 2.0}, {"rtol": 1.0, "method": "cvodes"}, {"atol": 1e300}):
        with pytest.raises(RunArgumentError, match=r"must be below 1 .* accepts any step"):
            paper2d_model.simulate(0.05, **kw)
    with pytest.raises(RunArgumentError, match=r"rtol = 5\.0 must be below 1"):
        paper2d_model.simulate_many(0.05, rtol=5.0)
    with pytest.raises(RunArgumentError, match=r"simulate_many: no runs \(x0 empty\)"):
        paper2d_model.simulate_many(0.05, x0=np.empty((0, len(paper2d_model.state_names))))
    # below 100 eps the C loops' error estimate is rounding: refused by name, every way in
    for method in ("radau", "dop853"):
        with pytest.raises(RunArgumentError, match=r"rtol = 1e-15 is below 2.22e-14 .* give rtol >= 2.22e-14"):
            paper2d_model.simulate(0.05, method=method, rtol=1e-15)
    with pytest.raises(RunArgumentError, match=r"rtol = 1e-15 is below 2.22e-14"):
        paper2d_model.simulate_many(0.05, rtol=1e-15)
    assert paper2d_model.simulate(0.05, rtol=2.3e-14, atol=1e-14).t[-1] == 0.05


def test_a_domain_exit_names_the_state(short_model):
    """The C loops name the state that left its contour's domain, not only its index."""
    for method in ("radau", "rk4"):
        with pytest.raises(ContactLeftContourError, match=r"s = -0\.006\d* left \[-0.006, 0.006\]"):
            short_model.simulate(1.0, method=method)
