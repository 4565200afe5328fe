"""Shared reciprocals (emit/reciprocals.py): the rewritten program computes what CasADi's
does, to within a rounding per division, with one division per shared denominator; the C
written from it (vecmath's bodies) agrees."""
from __future__ import annotations

import json
from collections import Counter
from pathlib import Path

import casadi as ca
import numpy as np

from grasping_sym.emit import algorithm
from grasping_sym.emit.reciprocals import share_reciprocals
from tests.oracles.program import run


def _divisions(program):
    return Counter(ins.op for ins in program)


def test_small_function_gets_one_inverse_per_shared_denominator():
    x = ca.SX.sym("x", 4)
    f = ca.Function("f", [x], [ca.vertcat(x[0] / x[3], x[1] / x[3], (x[2] + 1) / x[3],
                                          x[0] / x[1])], {"cse": True})
    program = algorithm.read(f)
    new = share_reciprocals(program)
    ops = _divisions(new)
    assert ops["INV"] == 1 and ops["DIV"] == 1           # x[0]/x[1] is the only lone division
    assert ops["MUL"] == _divisions(program)["MUL"] + 3
    args = [np.array([0.3, -1.7, 2.2, 0.9])]
    got = run(new, args, [4])[0]
    np.testing.assert_allclose(got, np.array(f(args[0])).ravel(), rtol=4e-16, atol=0)


def test_a_program_without_shared_denominators_is_returned_as_is():
    x = ca.SX.sym("x", 2)
    program = algorithm.read(ca.Function("g", [x], [x[0] / x[1] + ca.sin(x[0])]))
    assert share_reciprocals(program) is program


def test_large_closed_loop_agrees_with_casadi():
    """paper3d's closed loop at its committed start (work indices reused many times, hundreds
    of divisions by a few dozen values): the rewritten program, run by the interpreter above,
    is as close to the exact value (60 digits) as CasADi's own program is."""
    import grasping_sym as gs
    from grasping_sym.assemble.controller import controller_torques
    from grasping_sym.derive.grasp3d import derive_grasp3d

    start = json.loads((Path(__file__).resolve().parents[1] / "generated" / "paper3d"
                        / "start.json").read_text())
    system = derive_grasp3d(gs.scenes.paper3d(), torques=controller_torques)
    f = ca.Function("f", [system.x, system.p], [system.xdot], {"cse": True})
    program = algorithm.read(f)
    new = share_reciprocals(program)
    before, after = _divisions(program), _divisions(new)
    assert after["DIV"] + after["INV"] < before["DIV"] / 4
    assert after["DIV"] + after["MUL"] == before["DIV"] + before["MUL"]
    x0 = np.array(start["initial_state"])
    p = np.array([start["start_params"][k] for k in system.param_names])
    rng = np.random.default_rng(3)
    for scale in (0.0, 1e-3, 1e-2):  # the start, and states near it
        args = [x0 + scale * rng.standard_normal(x0.size), p]
        want = np.array(f(*args)).ravel()
        plain, = run(program, args, [f.nnz_out(0)])
        got, = run(new, args, [f.nnz_out(0)])
        exact, = run(program, args, [f.nnz_out(0)], exact=True)
        np.testing.assert_array_equal(plain, want)      # the interpreter runs CasADi's program
        err_casadi = np.max(np.abs(want - exact))
        err_shared = np.max(np.abs(got - exact))
        assert err_shared <= 4 * err_casadi + 1e-15 * np.max(np.abs(exact))
