"""The optimal-control example (examples/ocp_paper2d.py) solves, and its optimum holds when the
compiled model re-simulates it."""
from __future__ import annotations

import importlib.util
from pathlib import Path

import numpy as np
import pytest

import grasping_sym as gs
from grasping_sym.errors import FrictionConeError

EXAMPLES = Path(__file__).resolve().parents[1] / "examples"


def _example(name: str):
    spec = importlib.util.spec_from_file_location(name, EXAMPLES / f"{name}.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def test_ocp_paper2d_reaches_the_target_with_the_contact_closed(tmp_path):
    ocp = _example("ocp_paper2d")
    out = ocp.main(str(tmp_path / "ocp.png"))  # the compiled functions (compiled=True)
    assert out["status"] == "Solve_Succeeded"
    # the compiled model under the optimal torques: theta(1 s) within 1e-4 rad of the target
    assert abs(out["theta_end"] - ocp.THETA_TARGET) < 1e-4
    # the path constraint holds where it is imposed, and the contact never opens in between
    assert out["f_points"].min() >= ocp.F_MIN - 1e-6
    assert out["f_min"] > 0.9 * ocp.F_MIN
    # inside the friction cone: re-simulated with mu (a slip would have raised
    # FrictionConeError), and the cone constraint was active (the optimum without it needs 0.54)
    assert 0.9 * ocp.MU < out["cone_ratio_max"] <= ocp.MU
    assert np.all(np.isfinite(out["U"])) and (tmp_path / "ocp.png").stat().st_size > 10_000
    # re-simulated with contact modes on (gs.scenes.with_modes): never a switch, it rolls all
    # along, on the rolling re-simulation's path (theta, q1, q2 at common output times)
    assert out["modes_events"] == [] and set(out["modes"]) == {"rolling"}
    assert out["modes_vs_rolling"] < 1e-8
    # with less friction than the optimum needs (|lam|/f = 0.287 at the start), the rolling
    # run's cone check stops it at t = 0, and with modes the same torques slide from the start
    # until the slip stops
    with pytest.raises(FrictionConeError) as err:
        ocp.resimulate(gs.build(ocp.scene()), out, mu=0.25)
    assert err.value.t == 0.0
    slipped = ocp.resimulate_with_modes(out, mu=0.25, t_final=0.1)
    assert slipped.modes[0] == "sliding" and slipped.events[0]["to"] == "rolling"


def test_orientation2d_turns_the_object_and_holds_it(tmp_path):
    ex = _example("orientation2d")
    out = ex.main(str(tmp_path / "orientation.png"))
    # each command reached to within the proportional law's offset (about 1/gain of the
    # torque of law (32) there), with the contact firmly closed
    assert all(abs(e) < 5e-3 for e in out["errors"]), out["errors"]
    assert out["f_min"] > 0.5
    for t, theta, _, _ in out["pieces"]:
        settled = theta[t >= t[0] + 0.5]
        assert np.ptp(settled) < 1e-4  # held, not drifting


def test_turn3d_turns_the_held_ellipsoid(tmp_path):
    ex = _example("turn3d")
    out = ex.main(str(tmp_path / "turn3d.png"))
    # turned to within the proportional law's offset against the grasp law's pull, and held
    assert abs(out["phi_end"] - ex.ANGLE) < 5e-3
    settled = out["phi"][out["t"] >= 1.0]
    assert np.ptp(settled) < 1e-4
    assert out["f_min"] > 2.0 and out["drift"].max() < 5e-3  # held: firm contacts, centre within 5 mm


def test_trifinger_turns_the_rounded_cube_in_force_closure(tmp_path):
    """The URDF hand turns its cube to within 5 mrad of 0.3 rad in 2 s, every contact
    pushing, no joint at a limit, and the grasp in force closure with epsilon between its
    bounds all along (a positive lower bound: the grasp resists every wrench)."""
    ex = _example("trifinger_turn")
    out = ex.main(str(tmp_path / "trifinger_turn.png"))
    assert abs(out["phi_end"] - ex.ANGLE) < 5e-3
    assert out["f_min"] > 1.0 and out["joint_room"] > 0.05 and out["closure"]
    assert np.all(out["eps_lower"] > 0.1) and np.all(out["eps_lower"] <= out["eps_upper"])
    assert (tmp_path / "trifinger_turn.png").stat().st_size > 10_000


def test_ocp_paper3d_turns_the_held_ellipsoid_on_a_coarse_mesh():
    """The 3D example's problem on a coarse mesh (3 intervals of degree 2: the example's own,
    8 of degree 3, takes 40 s): IPOPT solves it, and the compiled model re-simulating the
    torques turns the object near the target with both contacts closed; and again with the
    grasp kept able to squeeze the object under mu = 0.05 (``squeeze=``)."""
    ocp = _example("ocp_paper3d")
    import grasping_sym as gs

    model = gs.build(ocp.scene())
    result = ocp.solve(model, n=3, degree=2)
    assert result["status"] == "Solve_Succeeded"
    assert result["f_points"].min() >= ocp.F_MIN - 1e-6
    res = ocp.resimulate(model, result)
    phi = ocp.turn(model, res, result["R0"])
    assert abs(phi[-1] - ocp.ANGLE) < 0.02
    assert min(res["f1"].min(), res["f2"].min()) > ocp.F_MIN
    # the squeeze as a path constraint (casadi_function("squeeze")): without it the optimum's
    # contact line leans out of mu = 0.05 cones (tan 0.071 measured); with it, IPOPT keeps the
    # margins >= 0 at the collocation points and the re-simulated run squeezes at every row
    from grasping_sym.pipeline.quality_along import contacts_along

    def squeezes(run):
        _, p, n = contacts_along(model, run)
        return gs.quality.two_contacts_squeeze(p, n, 0.05)

    assert not squeezes(res).all()
    held = ocp.solve(model, n=3, degree=2, squeeze=0.05)
    assert held["status"] == "Solve_Succeeded" and held["squeeze_points"].min() >= -1e-7
    again = ocp.resimulate(model, held)
    assert squeezes(again).all() and min(again["f1"].min(), again["f2"].min()) > ocp.F_MIN


def test_compiled_casadi_functions_equal_the_sx_ones_and_their_derivatives():
    """model.casadi_function(compiled=True): the C of the SX function and of its Jacobian,
    forward, reverse and forward-over-reverse derivatives, loaded through casadi.external,
    gives the SX function's values and derivatives."""
    import casadi as ca

    import grasping_sym as gs

    ocp = _example("ocp_paper2d")
    model = gs.build(ocp.scene())
    f, fc = model.casadi_function(), model.casadi_function(compiled=True)
    assert fc.class_name() == "External"
    x = model.simulate(0.2, u=[5e-3, 1e-3], method="radau", rtol=1e-8, atol=1e-12,
                       t_eval=[0, 0.2]).x[-1]
    u = np.array([5e-3, 1e-3])
    np.testing.assert_allclose(np.ravel(fc(x, u, [])), np.ravel(f(x, u, [])), rtol=1e-12, atol=1e-12)
    w = np.random.default_rng(0).normal(size=x.size)
    X, U = ca.MX.sym("x", x.size), ca.MX.sym("u", u.size)
    for g in (f, fc):  # the gradient of w.f and its Hessian along a direction, through MX
        lag = ca.dot(ca.DM(w), g(X, U, ca.DM.zeros(0, 1)))
        grad = ca.gradient(lag, X)
        hv = ca.jtimes(grad, X, ca.DM(w))
        out = ca.Function("o", [X, U], [grad, hv, ca.jacobian(g(X, U, ca.DM.zeros(0, 1)), X)])
        vals = [np.array(v) for v in out(x, u)]
        if g is f:
            ref = vals
        else:
            for a, b in zip(vals, ref):
                np.testing.assert_allclose(a, b, rtol=1e-10, atol=1e-10 * np.abs(b).max())


def test_a_damaged_compiled_functions_library_is_rebuilt_not_loaded():
    """A flipped byte in the compiled functions' library and an unreadable checksum record:
    the next process rebuilds the library (the same bytes) instead of loading it."""
    import json
    import os
    import subprocess
    import sys

    from grasping_sym.store import files as stored

    script = (
        "import sys, json, numpy as np; sys.path.insert(0, sys.argv[1]); import ocp_paper2d as o; "
        "import grasping_sym as gs; m = gs.build(o.scene()); "
        "c = m.casadi_function('constraints', compiled=True); "
        "print(json.dumps({'dir': str(m.directory), "
        "'residual': float(np.abs(np.ravel(c(m.initial_state(), []))).max())}))")

    def run() -> dict:
        out = subprocess.run([sys.executable, "-c", script, str(EXAMPLES)], check=True,
                             capture_output=True, text=True).stdout
        return json.loads(out.strip().splitlines()[-1])

    import grasping_sym as gs

    model = gs.build(_example("ocp_paper2d").scene())
    model.casadi_function("constraints", compiled=True)  # compiled (or found) here
    lib = next((model.directory / "casadi_api").glob("api-constraints-*.so"))
    record = lib.with_suffix(".json")
    good = stored.read_json(record)["sha256"]
    data = bytearray(lib.read_bytes())
    data[len(data) // 2] ^= 0xFF
    damaged = lib.parent / "damaged.tmp"
    damaged.write_bytes(bytes(data))
    os.replace(damaged, lib)  # a new file: nothing that has the library loaded is touched
    record.write_text("{not json")
    again = run()
    assert stored.read_json(record)["sha256"] == good  # rebuilt, the same bytes
    assert again["residual"] < 1e-9
