"""Control inputs, controllers of one's own, and the model as CasADi Functions (issue 14)."""
from __future__ import annotations

import casadi as ca
import numpy as np
import pytest
import sympy as sp

import grasping_sym as gs
from grasping_sym.assemble.controller import controller_function
from grasping_sym.errors import ControllerError, ExpressionError, InputScheduleError, InvalidSceneError

RADAU = {"method": "radau", "rtol": 1e-9, "atol": 1e-12}


@pytest.fixture(scope="module")
def torque_model():
    return gs.build(gs.scenes.paper2d(inputs="torques"))


@pytest.fixture(scope="module")
def closed_loop():
    return gs.build(gs.scenes.paper2d())


def _states_on_the_motion(model, n=4):
    res = model.simulate(0.5, method="radau", rtol=1e-8, atol=1e-12, t_eval=np.linspace(0, 0.5, n + 1))
    return res.x[1:]


def test_torque_inputs_are_named_and_zero_by_default(torque_model, closed_loop):
    assert torque_model.input_names == ("u1", "u2")
    assert closed_loop.input_names == ()
    # the same structure: the controller is a layer apart (nothing re-derived)
    assert torque_model.manifest["structure"] == closed_loop.manifest["structure"]
    assert closed_loop.manifest["controller"] == {"law": "paper", "uses_object": False,
                                                  "reads_time": False}
    a = torque_model.simulate(1.0, **RADAU)
    b = closed_loop.simulate(1.0, **RADAU)
    np.testing.assert_array_equal(a.x, b.x)


def test_a_model_with_inputs_loads_from_its_cache(torque_model):
    """A model with inputs has two run-time parameters per input in its driver (``u = a + b
    t``): its manifest is valid, a second build loads it from the cache instead of deriving
    and compiling it again, and ``gs.load`` reads it (both refused it as an invalid manifest)."""
    from grasping_sym.store.manifest_schema import manifest_problems

    assert manifest_problems(torque_model.manifest) == []
    again = gs.build(gs.scenes.paper2d(inputs="torques"))
    assert again.build_info["source"] == "cache" and "rebuilt_because" not in again.build_info
    loaded = gs.load(torque_model.path)
    u = [2e-3, -1e-3]
    np.testing.assert_array_equal(loaded.simulate(0.2, u=u, **RADAU).x, torque_model.simulate(0.2, u=u, **RADAU).x)


def test_the_rhs_is_affine_in_the_inputs(torque_model):
    for x in _states_on_the_motion(torque_model):
        f0 = torque_model.rhs(x)
        fu = torque_model.rhs(x, [2e-3, -1e-3])
        f2 = torque_model.rhs(x, [4e-3, -2e-3])
        assert np.abs(fu - f0).max() > 1.0  # the inputs act (rad/s^2)
        np.testing.assert_allclose(f2 - f0, 2 * (fu - f0), rtol=1e-9, atol=1e-9)


def test_tables_restart_at_their_knots_and_agree_across_integrators(torque_model):
    tab = gs.inputs.piecewise_linear([0.0, 0.5, 1.0], [[0, 0], [2e-3, -1e-3], [0, 0]])
    r = torque_model.simulate(1.0, u=tab, **RADAU)
    c = torque_model.simulate(1.0, u=tab, method="cvodes", rtol=1e-10, atol=1e-12)
    assert r.stats["segments"] == 2
    assert len(r.t) == len(c.t) == 1001
    np.testing.assert_allclose(r.x[-1], c.x[-1], rtol=0, atol=1e-7)
    # a table that is constant is the constant input, bit for bit
    const = torque_model.simulate(1.0, u=[2e-3, -1e-3], **RADAU)
    held = torque_model.simulate(1.0, u=gs.inputs.zero_order_hold([0.0], [[2e-3, -1e-3]]), **RADAU)
    np.testing.assert_array_equal(const.x, held.x)
    # and the input moves the object
    assert abs(const["theta"][-1] - torque_model.simulate(1.0, **RADAU)["theta"][-1]) > 1e-3


def test_laws_add_up_and_a_new_law_compiles_only_its_layer(closed_loop):
    c = gs.scenes.PAPER2D_PARAMS["c"]
    summed = gs.build(gs.scenes.paper2d(controller=gs.controllers.paper2d() + gs.controllers.damping(0.004)))
    direct = gs.build(gs.scenes.paper2d(c=c + 0.004))
    assert summed.manifest["structure"] == closed_loop.manifest["structure"]
    for x in _states_on_the_motion(direct):
        np.testing.assert_allclose(summed.rhs(x), direct.rhs(x), rtol=1e-11, atol=1e-9)


def test_feedforward_expressions_of_time_are_evaluated_in_c(torque_model):
    t = sp.Symbol("t")
    ff = gs.build(gs.scenes.paper2d(controller=gs.controllers.paper2d()
                                    + gs.controllers.feedforward([2e-3 * (1 - t), sp.Integer(0)])))
    assert ff.manifest["outputs_time"] is True
    assert ff.manifest["controller"]["reads_time"] is True
    tab = gs.inputs.piecewise_linear([0.0, 1.0], [[2e-3, 0.0], [0.0, 0.0]])
    a = ff.simulate(1.0, **RADAU)
    b = torque_model.simulate(1.0, u=tab, **RADAU)
    np.testing.assert_allclose(a.x, b.x, rtol=0, atol=1e-9)
    np.testing.assert_allclose(a["f"], b["f"], rtol=0, atol=1e-7)


def test_a_user_law_reads_named_quantities(closed_loop):
    @gs.controllers.law
    def pull(m):
        fd, r, c = m.param("fd"), m.param("r"), m.param("c")
        return [-c * m.dq[0] - m.J[0].T @ ((fd / r) * (m.tip[0] - m.pivot))]

    mine = gs.build(gs.scenes.paper2d(controller=pull))
    for x in _states_on_the_motion(closed_loop):
        np.testing.assert_allclose(mine.rhs(x), closed_loop.rhs(x), rtol=1e-12, atol=1e-10)


def test_outputs_picked_by_name_are_rows_of_the_whole_function(torque_model):
    """casadi_function("outputs", outputs=...): the rows named, in that order, with the whole
    function's values and derivatives; names the model lacks, or rows of another function,
    are refused by name."""
    names = torque_model.output_names
    pick = ("lam", "f")
    rows = [names.index(k) for k in pick]
    whole = torque_model.casadi_function("outputs")
    part = torque_model.casadi_function("outputs", outputs=pick)
    u = np.array([2e-3, -1e-3])
    for x in _states_on_the_motion(torque_model, n=2):
        np.testing.assert_array_equal(np.ravel(part(x, u, [])), np.ravel(whole(x, u, []))[rows])
        # the two Jacobians are two expressions (evaluated in another order): rounding apart
        np.testing.assert_allclose(np.array(part.jacobian()(x, u, [], 0)[0]),
                                   np.array(whole.jacobian()(x, u, [], 0)[0])[rows], rtol=1e-11,
                                   atol=1e-12)
    with pytest.raises(ValueError, match=r"outputs = \['nope'\]: give one or more"):
        torque_model.casadi_function("outputs", outputs=["nope"])
    with pytest.raises(ValueError, match="picks rows of the 'outputs' function"):
        torque_model.casadi_function("ode", outputs=["f"])


def test_casadi_function_matches_the_compiled_model_and_finite_differences(torque_model):
    f = torque_model.casadi_function()
    assert (f.name_in(), f.name_out()) == (["x", "u", "p"], ["xdot"])
    u = np.array([2e-3, -1e-3])
    jac = f.jacobian()
    rng = np.random.default_rng(7)
    for x in _states_on_the_motion(torque_model):
        # one piece of SX against the compiled layers: equal to 1e-10 of the largest rate
        # (the agreement tests/test_layers.py shows for the layers)
        ref = torque_model.rhs(x, u)
        np.testing.assert_allclose(np.ravel(f(x, u, [])), ref, rtol=1e-10, atol=1e-10 * np.abs(ref).max())
        J = np.array(jac(x, u, [], 0)[0])          # d xdot / d x
        Ju = np.array(jac(x, u, [], 0)[1])         # d xdot / d u
        for i in range(x.size):
            e = np.zeros(x.size)
            e[i] = 1e-6 * max(1.0, abs(x[i]))
            fd = (np.ravel(f(x + e, u, [])) - np.ravel(f(x - e, u, []))) / (2 * e[i])
            np.testing.assert_allclose(J[:, i], fd, rtol=1e-6, atol=1e-6 * np.abs(J).max())
        for i in range(u.size):
            e = np.zeros(u.size)
            e[i] = 1e-6
            fd = (np.ravel(f(x, u + e, [])) - np.ravel(f(x, u - e, []))) / 2e-6
            np.testing.assert_allclose(Ju[:, i], fd, rtol=1e-6, atol=1e-6 * np.abs(Ju).max())
        # second derivatives: the Hessian of a weighted sum against differences of its gradient
        w = rng.normal(size=x.size)
        xs = ca.SX.sym("x", x.size)
        g = ca.Function("g", [xs], [ca.gradient(ca.dot(w, f(xs, u, [])), xs)])
        H = np.array(ca.Function("H", [xs], [ca.jacobian(g(xs), xs)])(x))
        k = torque_model.state_names.index("q1")
        e = np.zeros(x.size)
        e[k] = 1e-6
        fd = (np.ravel(g(x + e)) - np.ravel(g(x - e))) / 2e-6
        np.testing.assert_allclose(H[:, k], fd, rtol=1e-6, atol=1e-6 * np.abs(H).max())


def test_casadi_function_in_an_integrator_with_sensitivities(torque_model):
    f = torque_model.casadi_function()
    x, u = ca.SX.sym("x", 7), ca.SX.sym("u", 2)
    integ = ca.integrator("I", "cvodes", {"x": x, "u": u, "ode": f(x, u, [])}, 0.0, 0.2,
                          {"abstol": 1e-12, "reltol": 1e-10})
    x0 = torque_model.initial_state()
    U = ca.MX.sym("U", 2)
    xf = integ(x0=x0, u=U)["xf"]
    sens = ca.Function("s", [U], [ca.jacobian(xf, U)])
    u0 = np.array([1e-3, 0.0])
    S = np.array(sens(u0))
    fd = (np.array(integ(x0=x0, u=u0 + [1e-5, 0])["xf"]) - np.array(integ(x0=x0, u=u0 - [1e-5, 0])["xf"])) / 2e-5
    np.testing.assert_allclose(S[:, 0], np.ravel(fd), rtol=1e-4, atol=1e-6 * np.abs(S).max())


def test_bad_control_input_is_refused_by_name(torque_model, closed_loop):
    with pytest.raises(ValueError, match="no inputs"):
        closed_loop.simulate(0.1, u=[1e-3, 0.0])
    with pytest.raises(ValueError, match="2 \\(one joint torque"):
        torque_model.simulate(0.1, u=[1e-3])
    with pytest.raises(TypeError, match="controller"):
        torque_model.simulate(0.1, u=lambda t: [0, 0])
    with pytest.raises(TypeError, match="feedforward"):
        torque_model.simulate(0.1, u=[sp.Symbol("t") * 1e-3, 0])
    with pytest.raises(ValueError, match="non-finite"):
        torque_model.simulate(0.1, u=[np.nan, 0.0])
    with pytest.raises(ValueError, match="rk4"):
        torque_model.simulate(1.0, u=gs.inputs.piecewise_linear([0.0, 0.5], [[0, 0], [1e-3, 0]]),
                              method="rk4")
    with pytest.raises(ValueError, match="strictly increasing"):
        gs.inputs.piecewise_linear([0.0, 0.0], [[0, 0], [1, 1]])
    with pytest.raises(InvalidSceneError, match="controller"):
        gs.scenes.paper2d(controller="pid")
    with pytest.raises(InvalidSceneError, match="inputs"):
        gs.scenes.paper2d(inputs="forces")
    with pytest.raises(ValueError, match="3 torques"):
        gs.build(gs.scenes.paper2d(controller=gs.controllers.law(lambda m: ca.SX.zeros(3))))


def test_paper3d_with_torque_inputs():
    scene = gs.scenes.paper3d(inputs="torques")
    model = gs.build(scene)
    assert model.input_names == ("u1", "u2", "u3", "u4", "u5")
    base = gs.build(gs.scenes.paper3d())
    assert model.manifest["structure"] == base.manifest["structure"]
    x = base.initial_state()
    np.testing.assert_array_equal(model.rhs(x), base.rhs(x))
    assert np.abs(model.rhs(x, [1e-3, 0, 0, 0, 0]) - base.rhs(x)).max() > 1e-3


def test_paper3d_casadi_function_has_exact_derivatives():
    """3D too: the one-piece SX of the closed loop against the compiled layers, and its first
    and second directional derivatives against central differences."""
    model = gs.build(gs.scenes.paper3d(inputs="torques"))
    f = model.casadi_function()
    x = model.simulate(0.3, method="radau", rtol=1e-6, atol=1e-9, t_eval=[0, 0.3]).x[-1]
    u = np.array([1e-3, -2e-3, 0.0, 1e-3, 0.0])
    ref = model.rhs(x, u)
    np.testing.assert_allclose(np.ravel(f(x, u, [])), ref, rtol=1e-10, atol=1e-10 * np.abs(ref).max())
    rng = np.random.default_rng(2)
    v, w = rng.normal(size=x.size), rng.normal(size=x.size)
    xs = ca.SX.sym("x", x.size)
    d1 = ca.jtimes(f(xs, u, []), xs, ca.DM(v))
    d2 = ca.jtimes(d1, xs, ca.DM(w))
    fn = ca.Function("d", [xs], [d1, d2])
    a1, a2 = (np.ravel(r) for r in fn(x))
    e = 1e-6
    fd1 = (np.ravel(f(x + e * v, u, [])) - np.ravel(f(x - e * v, u, []))) / (2 * e)
    fd2 = (np.ravel(fn(x + e * w)[0]) - np.ravel(fn(x - e * w)[0])) / (2 * e)
    np.testing.assert_allclose(a1, fd1, rtol=1e-6, atol=1e-6 * np.abs(a1).max())
    np.testing.assert_allclose(a2, fd2, rtol=1e-6, atol=1e-6 * np.abs(a2).max())


def test_constraint_and_output_functions_have_exact_derivatives(torque_model):
    """The contact constraints and the outputs as CasADi Functions: zero on the motion, equal
    to the compiled outputs, and their Jacobians equal to central differences."""
    con = torque_model.casadi_function("constraints")
    out = torque_model.casadi_function("outputs")
    u = np.array([2e-3, -1e-3])
    jc, jo = con.jacobian(), out.jacobian()
    for x in _states_on_the_motion(torque_model):
        assert np.abs(np.ravel(con(x, []))).max() < 1e-9
        compiled = torque_model.outputs(x, torque_model.with_inputs(None, u))
        np.testing.assert_allclose(np.ravel(out(x, u, [])), list(compiled.values()), rtol=1e-9,
                                   atol=1e-9)
        Jc = np.array(jc(x, [], 0)[0])
        Jo = np.array(jo(x, u, [], 0)[0])
        for i in range(x.size):
            e = np.zeros(x.size)
            e[i] = 1e-6 * max(1.0, abs(x[i]))
            fdc = (np.ravel(con(x + e, [])) - np.ravel(con(x - e, []))) / (2 * e[i])
            fdo = (np.ravel(out(x + e, u, [])) - np.ravel(out(x - e, u, []))) / (2 * e[i])
            np.testing.assert_allclose(Jc[:, i], fdc, rtol=1e-6, atol=1e-6 * max(1.0, np.abs(Jc).max()))
            # the outputs include max(|Q|, |R|), whose derivative jumps where they cross: compare
            # the smooth ones
            smooth = [k for k, name in enumerate(torque_model.output_names) if name != "constraint_residual"]
            np.testing.assert_allclose(Jo[smooth, i], fdo[smooth], rtol=1e-6,
                                       atol=1e-6 * np.abs(Jo[smooth]).max())


def test_the_manifest_says_when_a_law_reads_the_object():
    model = gs.build(gs.scenes.paper2d(controller=gs.controllers.orientation2d(0.3, 50.0, 0.3)))
    assert model.manifest["controller"] == {"law": "paper2d + orientation2d(0.3)",
                                            "uses_object": True, "reads_time": False}


def test_bad_controller_arguments_are_refused_by_name():
    with pytest.raises(ValueError, match="max_force"):
        gs.controllers.orientation2d(0.3, 50.0, max_force=0.0)
    with pytest.raises(ValueError, match="axis"):
        gs.controllers.turn3d(0.2, 1.0, axis=(0.0, 0.0, 0.0))
    with pytest.raises(ValueError, match="rotation matrix"):
        gs.controllers.turn3d(0.2, 1.0, reference=np.ones((3, 3)))
    with pytest.raises(ValueError, match="max_torque"):
        gs.controllers.turn3d(0.2, 1.0, max_torque=-1.0)
    with pytest.raises(ValueError, match="besides the time"):
        gs.controllers.feedforward([sp.Symbol("t") * sp.Symbol("k"), 0])
    with pytest.raises(TypeError, match="function of the model's quantities"):
        gs.controllers.law(0.5)
    with pytest.raises(ControllerError, match="parameter 'nope'"):
        gs.build(gs.scenes.paper2d(controller=gs.controllers.law(lambda m: [m.param("nope") * m.dq[0]])))
    for bad, why in ((np.nan, "finite"), (np.inf, "finite"), (-0.1, ">= 0"), ("a", "give a number")):
        with pytest.raises(ControllerError, match=f"damping c = .*{why}"):
            gs.controllers.damping(bad)
    with pytest.raises(ControllerError, match="orientation2d gain = nan"):
        gs.controllers.orientation2d(0.3, np.nan)
    with pytest.raises(ControllerError, match="turn3d angle = inf"):
        gs.controllers.turn3d(np.inf, 1.0)
    with pytest.raises(ExpressionError, match="beyond a double's range"):  # at once, not computed
        gs.controllers.feedforward(["9**9**9**9", "0"])


def _layer(controller, scene=gs.scenes.paper2d):
    """The controller layer of a scene with ``controller`` (what a build makes first)."""
    return controller_function(scene(controller=controller), "t")


def _law_error(fn, scene=gs.scenes.paper2d) -> str:
    with pytest.raises(ControllerError) as exc:
        _layer(gs.controllers.law(fn), scene)
    return str(exc.value)


def test_laws_that_do_not_give_torques_are_refused_by_name():
    assert "returned NoneType" in _law_error(lambda m: None)
    assert "returned str" in _law_error(lambda m: "torques")
    assert "returned an MX expression" in _law_error(lambda m: [ca.MX.sym("a", 2)])
    assert "returned a SymPy expression" in _law_error(lambda m: [sp.Symbol("k"), 0])
    assert "non-finite torque" in _law_error(lambda m: [np.nan, 0.0])
    assert "gave 3 torques; this model has 2 joints" in _law_error(lambda m: ca.SX.zeros(3))
    assert "raised ZeroDivisionError" in _law_error(lambda m: 1 / 0)

    def branching(m):
        if m.dq[0][0] > 0:  # a Python if on SX
            return [m.dq[0]]
        return [-m.dq[0]]
    assert "ca.if_else" in _law_error(branching)
    k = ca.SX.sym("k")
    assert "uses symbols ['k'] that are not the model's quantities" in _law_error(lambda m: [k * m.dq[0]])
    # before any derivation: the build hashes the law's expressions first
    with pytest.raises(ControllerError, match="returned NoneType"):
        gs.build(gs.scenes.paper2d(controller=gs.controllers.law(lambda m: None)))


def test_a_list_of_one_torque_per_joint_is_the_column_of_every_joint():
    as_list = _layer(gs.controllers.law(lambda m: [-0.01 * m.dq[0][0], 2e-3 + m.q[0][1]]))
    as_column = _layer(gs.controllers.law(lambda m: ca.vertcat(-0.01 * m.dq[0][0], 2e-3 + m.q[0][1])))
    x = np.linspace(0.1, 0.7, 7)
    tau = as_list.function(0.0, x, [0.0, 0.0]).full().ravel()
    np.testing.assert_array_equal(tau, as_column.function(0.0, x, [0.0, 0.0]).full().ravel())
    assert tau[0] != 0.0


def test_a_law_of_the_other_dimension_is_refused_by_name():
    with pytest.raises(ControllerError, match="orientation2d.* laws of 2D scenes, .*; this scene is 3D") as exc:
        _layer(gs.controllers.orientation2d(0.3, 50.0), gs.scenes.pivot3d)
    assert "paper3d, turn3d" in str(exc.value)
    with pytest.raises(ControllerError, match="paper3d is a law of 3D scenes, .*; this scene is 2D"):
        _layer(gs.controllers.paper3d())
    with pytest.raises(ControllerError, match="turn3d"):
        _layer(gs.controllers.turn3d(0.2, 1.0) + gs.controllers.damping(0.01))


@pytest.mark.parametrize("knots, a, b, why", [
    ([1.0, 0.5], np.zeros((3, 2)), np.zeros((3, 2)), r"strictly increasing: knot 1 \(0.5 s\) follows knot 0"),
    ([0.5, 0.5], np.zeros((3, 2)), np.zeros((3, 2)), "strictly increasing"),
    ([0.5], np.zeros((1, 2)), np.zeros((1, 2)), r"a has shape \(1, 2\): give one row per segment \(2 for 1 knots"),
    ([0.5, np.nan], np.zeros((3, 2)), np.zeros((3, 2)), "not all finite"),
    ([0.5], [[0, 0], [np.inf, 0]], np.zeros((2, 2)), "a has non-finite entries"),
    ([0.5], np.zeros((2, 2)), np.zeros((2, 3)), r"b has shape \(2, 3\)"),
    ([0.5], [[0, 0], [1]], np.zeros((2, 2)), "a is not a table of numbers"),
    (["0.5"], np.zeros((2, 2)), np.zeros((2, 2)), "knots must be numbers"),
])
def test_a_schedule_is_checked_when_made(knots, a, b, why):
    with pytest.raises(InputScheduleError, match=why):
        gs.inputs.Schedule(knots, a, b)


def test_a_table_with_a_non_finite_time_names_the_times():
    with pytest.raises(InputScheduleError, match=r"times has non-finite entries: give finite knot times \(s\)"):
        gs.inputs.piecewise_linear([0.0, np.nan], [[0.0, 0.0], [1.0, 0.0]])
    with pytest.raises(InputScheduleError, match=r"values has non-finite entries: give finite input values"):
        gs.inputs.zero_order_hold([0.0, 1.0], [[0.0, 0.0], [np.inf, 0.0]])


def test_a_checked_schedule_runs_and_a_wrong_width_is_named(torque_model):
    sched = gs.inputs.Schedule([0.05], [[0.0, 0.0], [1e-3, 0.0]], np.zeros((2, 2)))
    np.testing.assert_array_equal(sched([0.0, 0.1]), [[0.0, 0.0], [1e-3, 0.0]])
    assert torque_model.simulate(0.1, u=sched, **RADAU).stats["segments"] == 2
    with pytest.raises(InputScheduleError, match="u has 3 inputs; the model has 2"):
        torque_model.simulate(0.1, u=gs.inputs.Schedule([], [[0.0, 0.0, 0.0]], [[0.0, 0.0, 0.0]]))
