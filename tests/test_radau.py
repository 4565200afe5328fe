"""Tests of the adaptive Radau IIA integrator in C (gs_radau5, CompiledLibrary.radau5,
Model.simulate(method='radau'))."""
from __future__ import annotations

from pathlib import Path

import casadi as ca
import numpy as np
import pytest

import grasping_sym as gs
from grasping_sym.errors import ContactLeftContourError, IntegratorError
from grasping_sym.runtime.compiled import CompiledLibrary
from grasping_sym.toolchain.library import build_library, driver_defines

T_FINAL = 3.0


@pytest.fixture(scope="module")
def reference(paper2d_model):
    """CVODES at tight tolerances: final state and states at a few output times."""
    t_eval = np.array([0.0, 0.05, 0.2, 0.7, 1.5, 2.25, T_FINAL])
    res = paper2d_model.simulate(T_FINAL, rtol=1e-12, atol=1e-14, t_eval=t_eval, outputs=False)
    return t_eval, res.x


def _err(x, ref):
    return float(np.max(np.abs(x - ref)))


def test_jacobian_is_compiled_in(paper2d_model):
    d = paper2d_model.manifest["driver_defines"]
    assert d["GS_HAS_JAC"] == 1 and d["GS_JAC"] == f"jac_{paper2d_model.name}_rhs"
    assert d["GS_JAC_BLOCK"] == 1


def test_tight_tolerance_matches_cvodes(paper2d_model, reference):
    t_eval, ref = reference
    res = paper2d_model.simulate(T_FINAL, method="radau", rtol=1e-10, atol=1e-10,
                                 t_eval=[0.0, T_FINAL], outputs=False)
    assert res.method == "radau"
    assert _err(res.x[-1], ref[-1]) <= 1e-9
    assert res.stats["n_jac"] >= 1 and res.stats["n_steps"] > 10


def test_error_decreases_with_rtol(paper2d_model, reference):
    ref = reference[1][-1]
    errors = []
    for rtol in (1e-4, 1e-6, 1e-8):
        res = paper2d_model.simulate(T_FINAL, method="radau", rtol=rtol, atol=rtol * 1e-3,
                                     t_eval=[0.0, T_FINAL], outputs=False)
        errors.append(_err(res.x[-1], ref))
    assert errors[0] > errors[1] > errors[2]
    assert errors[0] < 1e-7 and errors[2] < 1e-11


def test_intermediate_outputs_match_cvodes(paper2d_model, reference):
    t_eval, ref = reference
    res = paper2d_model.simulate(T_FINAL, method="radau", rtol=1e-8, atol=1e-10, t_eval=t_eval)
    np.testing.assert_array_equal(res.t, t_eval)
    np.testing.assert_array_equal(res.x[0], paper2d_model.initial_state())
    assert _err(res.x, ref) <= 1e-8
    # outputs are evaluated along the trajectory like for the other methods
    assert set(res.outputs) == set(paper2d_model.output_names)


def test_dense_output_between_steps(paper2d_model, reference):
    """Many output times inside single steps come from the collocation polynomial."""
    t_eval = np.linspace(0.0, T_FINAL, 3001)
    res = paper2d_model.simulate(T_FINAL, method="radau", rtol=1e-8, atol=1e-10,
                                 t_eval=t_eval, outputs=False)
    cv = paper2d_model.simulate(T_FINAL, rtol=1e-12, atol=1e-14, t_eval=t_eval, outputs=False)
    assert res.stats["n_steps"] < len(t_eval) - 1
    assert _err(res.x, cv.x) <= 1e-7


def test_library_stats_and_direct_call(paper2d_model):
    lib = paper2d_model.library
    t, X, st = lib.radau5(paper2d_model.initial_state(), [0.0, 1.0, 2.0], rtol=1e-6, atol=1e-9)
    assert X.shape == (3, lib.nx) and t.tolist() == [0.0, 1.0, 2.0]
    for k in ("n_steps", "n_rejected", "n_rhs", "n_jac", "n_lu", "n_newton"):
        assert isinstance(st[k], int) and st[k] >= 0
    assert st["n_rhs"] >= 3 * st["n_newton"] and st["n_lu"] >= 2
    # a given first step gives the same answer to tolerance
    _, X2, _ = lib.radau5(paper2d_model.initial_state(), [0.0, 1.0, 2.0], rtol=1e-6, atol=1e-9,
                          h0=1e-5)
    assert _err(X2, X) < 1e-7


def test_bad_arguments(paper2d_model):
    lib = paper2d_model.library
    x0 = paper2d_model.initial_state()
    with pytest.raises(ValueError, match="strictly increasing"):
        lib.radau5(x0, [0.0, 1.0, 1.0])
    with pytest.raises(ValueError, match="rtol"):
        lib.radau5(x0, [0.0, 1.0], rtol=0.0)
    with pytest.raises(ValueError, match="shape"):
        lib.radau5(x0[:3], [0.0, 1.0])


@pytest.mark.parametrize("name", ["radau5", "dopri5"])
def test_initial_state_refused_in_c(paper2d_model, name):
    """The C integrators check x0 themselves (finite, inside the bounds) before any step
    or output row; the wrapper names the state."""
    lib = paper2d_model.library
    lo, hi = paper2d_model.lower, paper2d_model.upper
    i = int(np.flatnonzero(np.isfinite(hi))[0])
    x0 = paper2d_model.initial_state()
    outside = x0.copy()
    outside[i] = hi[i] + 1e-3
    with pytest.raises(IntegratorError, match=rf"initial state: {paper2d_model.state_names[i]} = \S+ left"):
        getattr(lib, name)(outside, [0.0, 0.5], lo=lo, hi=hi)
    nan = x0.copy()
    nan[1] = np.nan
    with pytest.raises(IntegratorError, match=rf"initial state: {paper2d_model.state_names[1]} are non-finite"):
        getattr(lib, name)(nan, [0.0, 0.5])
    # the return code itself, on the CPython fast path (rows with t_out <= t0 not written)
    out, stats = np.full((3, lib.nx), 7.0), np.zeros(16)
    rc, t_fail = lib._call_adaptive(name[:-1] if name == "radau5" else name,
                                    np.array([0.0, 0.5]), outside, lib.default_p, 1e-6, 1e-9, 0.0,
                                    1000, 0, lo, hi, None, 0.0, out, stats)
    assert rc == -2 and t_fail == 0.0 and stats[0] == stats[2] == 0
    np.testing.assert_array_equal(out[0], outside)
    np.testing.assert_array_equal(out[1], outside)


def test_fast_path_matches_ctypes_path(paper2d_model):
    """radau5 / dopri5 through the CPython fast path give the ctypes path's results, bit for
    bit, and the same failure (the same C function runs behind both)."""
    fast = paper2d_model.library
    assert fast.fast
    slow = CompiledLibrary(fast.path, state_names=fast.state_names, use_fast=False,
                           default_p=fast.default_p)
    x0 = paper2d_model.initial_state()
    t_out = [0.0, 0.5, 1.0]
    for name, kw in (("radau5", dict(rtol=1e-6, atol=1e-9)),
                     ("dopri5", dict(rtol=1e-10, atol=1e-12))):
        runs = [getattr(lib, name)(x0, t_out, lo=paper2d_model.lower, hi=paper2d_model.upper, **kw)
                for lib in (fast, slow)]
        np.testing.assert_array_equal(runs[0][1], runs[1][1])
        assert {k: v for k, v in runs[0][2].items() if k != "wall_time"} == \
            {k: v for k, v in runs[1][2].items() if k != "wall_time"}
    messages = []
    for lib in (fast, slow):
        with pytest.raises(IntegratorError, match=r"too many steps \(3\)") as info:
            lib.radau5(x0, t_out, max_steps=3)
        messages.append(str(info.value))
    assert messages[0] == messages[1]


def test_fast_path_rejects_bad_low_level_arguments(paper2d_model):
    ext = paper2d_model.library._ext
    nx = paper2d_model.library.nx
    t, x0 = np.array([0.0, 1.0]), paper2d_model.initial_state()
    out, stats = np.empty((3, nx)), np.zeros(16)
    p = paper2d_model.default_params  # the pivot: a run-time input fixed by the start
    args = [0, t, x0, p, 1e-6, 1e-9, 0.0, 100_000, 0, None, None, None, 0.0, out, stats]
    assert ext.adaptive(*args)[0] == 2
    for i, bad, match in ((1, t.astype(np.float32), "t_out must be a C-contiguous"),
                          (2, x0[:3].copy(), "x0 must have shape"),
                          (13, np.empty((2, nx)), "out must have shape"),
                          (14, np.zeros(16)[::2], "stats must be a C-contiguous"),
                          (0, 7, "method must be 0")):
        bad_args = list(args)
        bad_args[i] = bad
        with pytest.raises((TypeError, ValueError), match=match):
            ext.adaptive(*bad_args)
    read_only = np.zeros(16)
    read_only.flags.writeable = False
    with pytest.raises(TypeError, match="writeable"):
        ext.adaptive(*args[:14], read_only)


def test_max_steps_failure_names_time(paper2d_model):
    with pytest.raises(IntegratorError, match=r"too many steps \(5\)") as info:
        paper2d_model.simulate(T_FINAL, method="radau", rtol=1e-8, atol=1e-10, max_steps=5,
                               t_eval=[0.0, 1.0, T_FINAL])
    err = info.value
    assert not isinstance(err, ContactLeftContourError)
    assert 0.0 < err.t < 1.0 and f"t = {err.t:.6g} s" in str(err)
    assert err.code == -6 and err.stats["n_steps"] == 5
    np.testing.assert_array_equal(err.trajectory[0], [0.0])
    assert np.all(np.isfinite(err.x))


@pytest.fixture(scope="module")
def short_domain_model():
    """Fingertip contour whose domain ends at s = -0.001: s drifts to about -4.8e-3."""
    scene = gs.scenes.paper2d(fingertip=gs.curves.catenary(20.0, 0.035, sign=-1,
                                                           domain=(-0.001, 0.03)))
    return gs.build(scene)


def test_contact_leaving_domain(short_domain_model):
    m = short_domain_model
    assert m.lower[-1] == pytest.approx(-0.001)
    with pytest.raises(ContactLeftContourError, match="left") as info:
        m.simulate(T_FINAL, method="radau", rtol=1e-6, atol=1e-9)
    err = info.value
    assert 0.0 < err.t < T_FINAL
    assert err.x[-1] >= -0.001  # the last accepted state is inside the domain
    assert err.x_rejected[-1] < -0.001
    # the crossing time agrees with the dense CVODES trajectory of the unbounded model
    cv = gs.build(gs.scenes.paper2d()).simulate(T_FINAL, rtol=1e-10, atol=1e-12, outputs=False)
    t_cross = cv.t[np.argmax(cv.x[:, -1] < -0.001)]
    assert abs(err.t - t_cross) < 0.05


# --------------------------------------------------------------- toy stiff problem
LAMBDA = 1000.0


def _prothero_robinson(directory: Path, with_jac: bool) -> CompiledLibrary:
    """y' = -L (y - cos t) - sin t, y(0) = 1: exact solution y = cos t."""
    t = ca.SX.sym("t")
    x = ca.SX.sym("x", 1)
    empty = ca.SX(0, 1)
    rhs = ca.Function("pr_rhs", [t, x, ca.SX.sym("z", 0), ca.SX.sym("p", 0), ca.SX.sym("u", 0)],
                      [-LAMBDA * (x - ca.cos(t)) - ca.sin(t), empty, empty, empty],
                      ["t", "x", "z", "p", "u"], ["ode", "alg", "quad", "zero"])
    jac = rhs.jacobian()
    cg = ca.CodeGenerator("pr.c", {"with_header": True})
    for f in (rhs, jac):
        cg.add(f)
    cg.generate(f"{directory}/")
    so = build_library(directory / "pr.c", directory / "pr.so", rhs,
                       jac_fn=jac if with_jac else None)
    defines = driver_defines(rhs, jac_fn=jac if with_jac else None)
    assert defines["GS_HAS_JAC"] == int(with_jac)
    return CompiledLibrary(so)


@pytest.mark.parametrize("with_jac", [True, False], ids=["jacobian", "finite-differences"])
def test_prothero_robinson_converges(tmp_path, with_jac):
    lib = _prothero_robinson(tmp_path, with_jac)
    t_out = np.linspace(0.0, 10.0, 21)
    errors = []
    for rtol in (1e-4, 1e-6, 1e-8, 1e-10):
        t, X, st = lib.radau5([1.0], t_out, rtol=rtol, atol=rtol)
        errors.append(float(np.max(np.abs(X[:, 0] - np.cos(t)))))
        assert st["n_steps"] < 2000  # stiff: the step is not limited by 1/LAMBDA
        assert (st["n_jac"] > 0) == with_jac or not with_jac
    assert errors[-1] < 1e-9
    assert all(a > b for a, b in zip(errors, errors[1:]))


def test_prothero_robinson_start_offset(tmp_path):
    """t_out[0] > t0 is allowed in C; from Python the start is t_out[0] (time-dependent rhs)."""
    lib = _prothero_robinson(tmp_path, True)
    t, X, _ = lib.radau5([np.cos(2.0)], [2.0, 3.0, 4.5], rtol=1e-9, atol=1e-9)
    np.testing.assert_allclose(X[:, 0], np.cos(t), atol=1e-8)


def _oscillators(directory: Path, name: str, speeds_first: bool) -> CompiledLibrary:
    """Two coupled damped oscillators, stiff (a spring of 1e4 1/s^2, damping 300 1/s) and
    nonlinear, as positions then speeds (the second-order rows radau5 reduces the Newton
    systems by) or speeds first (no such rows: the full systems)."""
    t = ca.SX.sym("t")
    x = ca.SX.sym("x", 4)
    q, v = (x[2:], x[:2]) if speeds_first else (x[:2], x[2:])
    a = ca.vertcat(-1e4 * (q[0] - q[1]) - 300 * v[0] + ca.sin(t),
                   -50 * q[1] * (1 + q[1] ** 2) + 1e4 * (q[0] - q[1]) - 0.5 * v[1])
    ode = ca.vertcat(a, v) if speeds_first else ca.vertcat(v, a)
    empty = ca.SX(0, 1)
    rhs = ca.Function(f"{name}_rhs", [t, x, ca.SX.sym("z", 0), ca.SX.sym("p", 0),
                                      ca.SX.sym("u", 0)], [ode, empty, empty, empty],
                      ["t", "x", "z", "p", "u"], ["ode", "alg", "quad", "zero"])
    jac = rhs.jacobian()
    cg = ca.CodeGenerator(f"{name}.c", {"with_header": True})
    for f in (rhs, jac):
        cg.add(f)
    cg.generate(f"{directory}/")
    return CompiledLibrary(build_library(directory / f"{name}.c", directory / f"{name}.so", rhs,
                                         jac_fn=jac))


def test_second_order_rows_reduce_the_newton_systems(tmp_path, paper2d_model):
    """With positions then speeds, radau5 solves its linear systems on the speeds' rows only
    (Hairer's M1 = M2, here 2 of 4); the same problem with the speeds first is solved in
    full. Both runs take the same steps and agree to rounding; paper2d's systems are reduced
    by its three positions."""
    reduced = _oscillators(tmp_path, "osc_qv", speeds_first=False)
    full = _oscillators(tmp_path, "osc_vq", speeds_first=True)
    t_out = np.linspace(0.0, 2.0, 41)
    x0 = np.array([0.1, -0.2, 0.0, 1.0])  # q, v
    for rtol in (1e-4, 1e-8):
        _, Xr, sr = reduced.radau5(x0, t_out, rtol=rtol, atol=rtol)
        _, Xf, sf = full.radau5(np.r_[x0[2:], x0[:2]], t_out, rtol=rtol, atol=rtol)
        assert sr["second_order_rows"] == 2 and sf["second_order_rows"] == 0
        assert sr["n_steps"] == sf["n_steps"] and sr["n_newton"] == sf["n_newton"]
        np.testing.assert_allclose(Xr, np.c_[Xf[:, 2:], Xf[:, :2]], rtol=0, atol=1e-12)
    res = paper2d_model.simulate(1.0, method="radau", t_eval=[0.0, 1.0], outputs=False)
    assert res.stats["second_order_rows"] == 3


def test_nonfinite_state_raises(tmp_path):
    """x' = x^2 from x = 1 blows up at t = 1."""
    x = ca.SX.sym("x", 1)
    empty = ca.SX(0, 1)
    rhs = ca.Function("bl_rhs", [ca.SX.sym("t"), x, ca.SX.sym("z", 0), ca.SX.sym("p", 0),
                                 ca.SX.sym("u", 0)], [x**2, empty, empty, empty],
                      ["t", "x", "z", "p", "u"], ["ode", "alg", "quad", "zero"])
    cg = ca.CodeGenerator("bl.c", {"with_header": True})
    cg.add(rhs)
    cg.add(rhs.jacobian())
    cg.generate(f"{tmp_path}/")
    lib = CompiledLibrary(build_library(tmp_path / "bl.c", tmp_path / "bl.so", rhs,
                                        jac_fn=rhs.jacobian()))
    with pytest.raises(IntegratorError, match="radau") as info:
        lib.radau5([1.0], [0.0, 2.0], rtol=1e-6, atol=1e-9)
    assert 0.9 < info.value.t < 1.001 and info.value.code in (-1, -5)
