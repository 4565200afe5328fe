"""Tests of the compiled runtime: driver.c + toolchain/library.py + runtime/compiled.py and c_loops.py."""
from __future__ import annotations

from pathlib import Path

import casadi as ca
import numpy as np
import pytest
from scipy.integrate import solve_ivp

from grasping_sym.errors import CompileError, IntegratorError
from grasping_sym.runtime.compiled import CompiledLibrary
from grasping_sym.store import platform as platform_
from grasping_sym.toolchain import compiler
from grasping_sym.toolchain.compiler import COMPILER_FLAGS, compile_shared
from grasping_sym.toolchain.library import build_library, driver_defines


def _dae_rhs(name: str, x: ca.SX, p: ca.SX, ode: ca.SX) -> ca.Function:
    t = ca.SX.sym("t")
    empty = ca.SX(0, 1)
    return ca.Function(
        name,
        [t, x, ca.SX.sym("z", 0), p, ca.SX.sym("u", 0)],
        [ode, empty, empty, empty],
        ["t", "x", "z", "p", "u"],
        ["ode", "alg", "quad", "zero"],
    )


def _generate(directory: Path, prefix: str, fns: list[ca.Function]) -> Path:
    cg = ca.CodeGenerator(f"{prefix}.c", {"with_header": True})  # a bare name, not a path
    for f in fns:
        cg.add(f)
    cg.generate(f"{directory}/")  # the directory goes in as the prefix
    return directory / f"{prefix}.c"


@pytest.fixture(scope="module")
def pendulum(tmp_path_factory):
    """Damped pendulum, x = (theta, omega), p = (damping,), with outputs."""
    d = tmp_path_factory.mktemp("pendulum")
    x = ca.SX.sym("x", 2)
    p = ca.SX.sym("p", 1)
    rhs = _dae_rhs("pend_rhs", x, p, ca.vertcat(x[1], -ca.sin(x[0]) - p[0] * x[1]))
    out = ca.Function(
        "pend_outputs", [x, p], [ca.vertcat(ca.cos(x[0]), 0.5 * x[1] ** 2 + 1 - ca.cos(x[0]), p[0] * x[1])],
        ["x", "p"], ["y"],
    )
    c_file = _generate(d, "pend", [rhs, rhs.jacobian(), out])
    so = build_library(c_file, d / "pend.so", rhs, out)
    return rhs, out, so


@pytest.fixture(params=[True, False], ids=["fast", "ctypes"])
def lib(request, pendulum):
    return CompiledLibrary(pendulum[2], state_names=["theta", "omega"], use_fast=request.param)


@pytest.fixture(scope="module")
def blowup(tmp_path_factory):
    """x' = x^2 (blows up at t = 1/x0), no parameters, no outputs."""
    d = tmp_path_factory.mktemp("blowup")
    x = ca.SX.sym("x", 1)
    rhs = _dae_rhs("blow_rhs", x, ca.SX.sym("p", 0), x**2)
    c_file = _generate(d, "blow", [rhs])
    return CompiledLibrary(build_library(c_file, d / "blow.so", rhs))


P = np.array([0.3])


def test_info_and_fast_path(pendulum, lib):
    assert (lib.nx, lib.np, lib.ny, lib.has_outputs) == (2, 1, 3, True)
    assert CompiledLibrary(pendulum[2]).fast  # built with pyfast.c -> extension used


def test_rhs_matches_casadi(pendulum, lib):
    rhs, out, _ = pendulum
    rng = np.random.default_rng(0)
    for x in rng.normal(size=(20, 2)) * 3:
        ref = np.array(rhs(0.0, x, [], P, [])[0]).ravel()
        np.testing.assert_allclose(lib.rhs(x, P), ref, rtol=1e-14, atol=1e-14)
        y_ref = np.array(out(x, P)).ravel()
        np.testing.assert_allclose(lib.outputs(x, P), y_ref, rtol=1e-14, atol=1e-14)


def test_batch_equals_single(lib):
    X = np.random.default_rng(1).normal(size=(50, 2))
    XD = lib.rhs_batch(X, P)
    Y = lib.outputs_batch(X, P)
    assert XD.shape == (50, 2) and Y.shape == (50, 3)
    np.testing.assert_array_equal(XD, np.array([lib.rhs(x, P) for x in X]))
    np.testing.assert_array_equal(Y, np.array([lib.outputs(x, P) for x in X]))
    assert lib.rhs_batch(np.empty((0, 2)), P).shape == (0, 2)


def test_returns_fresh_arrays_and_converts_input(lib):
    a = lib.rhs([0.1, 0.2], P)
    b = lib.rhs([0.1, 0.2], P)
    assert a is not b and a.flags.owndata
    a[:] = 99.0
    assert b[0] != 99.0
    strided = np.array([0.1, 7.0, 0.2, 7.0])[::2]  # non-contiguous
    np.testing.assert_array_equal(lib.rhs(strided, P), b)
    np.testing.assert_array_equal(lib.rhs(np.array([0, 1]), p=[0]), lib.rhs([0.0, 1.0], [0.0]))
    np.testing.assert_array_equal(lib.rhs_batch(np.asfortranarray(np.ones((3, 2))), P)[0], lib.rhs([1, 1], P))


def test_wrong_shapes_raise_value_error(lib):
    with pytest.raises(ValueError, match=r"\(2,\)"):
        lib.rhs(np.zeros(3), P)
    with pytest.raises(ValueError, match=r"\(2,\)"):
        lib.rhs(np.zeros((1, 2)), P)
    with pytest.raises(ValueError, match=r"\(n, 2\)"):
        lib.rhs_batch(np.zeros(2), P)
    with pytest.raises(ValueError, match=r"\(1,\)"):
        lib.rhs(np.zeros(2), np.zeros(2))
    with pytest.raises(ValueError, match="np = 1"):
        lib.rhs(np.zeros(2))
    with pytest.raises(ValueError, match=r"\(2,\)"):
        lib.rk4(np.zeros(3), 0.0, 1.0, 0.1, p=P)


def _reference(x0, t_final):
    sol = solve_ivp(
        lambda t, x: [x[1], -np.sin(x[0]) - P[0] * x[1]], (0.0, t_final), x0,
        method="DOP853", rtol=1e-13, atol=1e-13,
    )
    return sol.y[:, -1]


def test_rk4_fourth_order(lib):
    x0 = np.array([1.0, 0.0])
    ref = _reference(x0, 2.0)
    errs = []
    for h in (0.2, 0.1, 0.05):
        t, X = lib.rk4(x0, 0.0, 2.0, h, p=P)
        assert t[0] == 0.0 and t[-1] == 2.0 and X.shape == (len(t), 2)
        np.testing.assert_array_equal(X[0], x0)
        errs.append(np.linalg.norm(X[-1] - ref))
    for coarse, fine in zip(errs, errs[1:]):
        assert 13.0 < coarse / fine < 19.0, errs


def test_rk4_stride(lib):
    x0 = np.array([0.5, 0.1])
    t1, X1 = lib.rk4(x0, 0.0, 1.0, 0.01, stride=1, p=P)
    t5, X5 = lib.rk4(x0, 0.0, 1.0, 0.01, stride=5, p=P)
    assert len(t1) == 101 and len(t5) == 21
    np.testing.assert_allclose(t5, t1[::5], atol=1e-15)
    np.testing.assert_array_equal(X5, X1[::5])


def test_rk4_nonfinite_raises_with_time(blowup):
    with pytest.raises(IntegratorError, match="non-finite") as info:
        blowup.rk4([1.0], 0.0, 2.0, 0.01)
    err = info.value
    assert 0.95 < err.t < 1.2  # exact solution 1/(1 - t) blows up at t = 1
    assert np.all(np.isfinite(err.x)) and err.x[0] > 10
    assert not np.all(np.isfinite(err.x_rejected))
    assert f"{err.t:.6g}" in str(err)
    t_stored, X_stored = err.trajectory
    assert t_stored[-1] <= err.t and np.all(np.isfinite(X_stored))


def test_rk4_bounds_raise(lib):
    # theta rises from 0 with omega = 1 and crosses 0.5 near t = 0.53
    with pytest.raises(IntegratorError, match=r"= \S+ left \[-inf, 0.5\]") as info:
        lib.rk4([0.0, 1.0], 0.0, 2.0, 0.01, p=P, hi=[0.5, np.inf])
    err = info.value
    assert 0.45 < err.t < 0.6 and err.x[0] <= 0.5 < err.x_rejected[0]
    assert "theta=" in str(err)  # state names appear in the message
    with pytest.raises(IntegratorError, match="initial state"):
        lib.rk4([0.0, 1.0], 0.0, 1.0, 0.01, p=P, lo=[0.1, -np.inf])


def test_outputs_absent(blowup):
    assert not blowup.has_outputs and blowup.ny == -1
    with pytest.raises(AttributeError):
        blowup.outputs([1.0])
    np.testing.assert_array_equal(blowup.rhs([3.0]), [9.0])  # np == 0: p may be omitted


def test_models_carry_no_timing_loop(lib):
    """The benchmark's C loop lives in benchmarks/ (``benchmarks/rhs_loop.py``), not in the
    model libraries."""
    assert not hasattr(lib._lib, "gs_rhs_loop_ns")


def test_compile_error_has_stderr(tmp_path):
    bad = tmp_path / "bad.c"
    bad.write_text("int f(void) { return 1 }\n")
    with pytest.raises(CompileError) as info:
        compile_shared([bad], tmp_path / "bad.so", {"FOO": 1})
    msg = str(info.value)
    assert "expected" in msg and "bad.c" in msg  # gcc's diagnostic
    assert "-DFOO=1" in msg and "-O2" in msg  # the full command
    assert not (tmp_path / "bad.so").exists()
    assert [p.name for p in tmp_path.iterdir()] == ["bad.c"]  # no temporary files left


V3_FLAGS = "fpu sse2 cx16 lahf_lm popcnt sse4_1 sse4_2 ssse3 avx avx2 bmi1 bmi2 f16c fma abm movbe xsave"


@pytest.mark.parametrize(("machine", "flags", "env", "level"), [
    ("x86_64", V3_FLAGS, None, "x86-64-v3"),
    ("x86_64", V3_FLAGS, "auto", "x86-64-v3"),
    ("x86_64", V3_FLAGS, "baseline", "baseline"),
    ("x86_64", V3_FLAGS.replace(" fma", ""), None, "baseline"),  # an AVX CPU without FMA
    ("x86_64", "", None, "baseline"),  # no /proc/cpuinfo
    ("aarch64", V3_FLAGS, None, "baseline"),
])
def test_isa_level(monkeypatch, machine, flags, env, level):
    monkeypatch.setattr(platform_.platform, "machine", lambda: machine)
    monkeypatch.setattr(platform_, "_cpu_flags", lambda: frozenset(flags.split()))
    if env is None:
        monkeypatch.delenv("GRASPING_SYM_ISA", raising=False)
    else:
        monkeypatch.setenv("GRASPING_SYM_ISA", env)
    assert compiler.isa_level() == level
    assert bool(compiler.isa_flags()) == (level != "baseline")
    from grasping_sym.store.platform import library_tag  # noqa: PLC0415
    mvec = "-mvec" if compiler.vector_libm() else ""  # glibc's vector libm (test_vecmath)
    assert mvec == "" or level == "x86-64-v3"
    opt = {"full": "", "quick": "-quick", "none": "-O0"}[platform_.optimization()]  # conftest's
    assert library_tag().endswith("-" + level + mvec + opt)  # the level is part of the name


def test_the_optimisation_level_is_in_the_flags_and_the_name(monkeypatch):
    """``GRASPING_SYM_OPT``: ``full`` (unset) compiles at -O2, ``quick`` at -Og, ``none`` at
    -O0 (the last -O of every command, a file named quick too), each library under its own
    name; anything else is refused by name."""
    from grasping_sym.store.platform import library_tag  # noqa: PLC0415

    names, ids = {}, set()
    for level, flag, quick in (("full", "-O2", "-Og"), ("quick", "-Og", "-Og"),
                               ("none", "-O0", "-O0")):
        monkeypatch.setenv("GRASPING_SYM_OPT", level)
        flags = compiler._common_flags({}, [], [])
        assert [f for f in flags if f.startswith("-O")][-1] == flag
        seen: list = []
        monkeypatch.setattr(compiler, "_run_all", lambda jobs, at_once, seen=seen: seen.extend(jobs))
        compiler.compile_objects([__file__], "/nonexistent", quick=[__file__])
        assert [f for f in seen[0][0] if f.startswith("-O")][-1] == quick
        names[level] = library_tag()
        ids.add(compiler.toolchain_id())
    for level, tag in (("quick", "-quick"), ("none", "-O0")):
        assert tag in names[level] and names[level].replace(tag, "") == names["full"]
    assert len(ids) == 1  # the manifest's compiled_with: a model keeps a library of each level
    monkeypatch.setenv("GRASPING_SYM_OPT", "O3")
    with pytest.raises(ValueError, match="GRASPING_SYM_OPT='O3'.*'full'.*'quick'.*'none'"):
        library_tag()


def test_every_level_computes_what_a_full_build_does(tmp_path, monkeypatch, paper3d_model):
    """The quick level (-Og) and none (-O0, the test suite's: conftest, its paper3d) compute
    the numbers of the full one (-O2), bit for bit: paper3d's compiled rhs (vector libm and
    shared reciprocals included) at random states, and a run of its default method,
    projection and outputs."""
    import grasping_sym as gs  # noqa: PLC0415
    from grasping_sym.store import paths  # noqa: PLC0415

    models = {"none": paper3d_model}
    assert "-O0" in paper3d_model.library_path.name
    for level, tag in (("full", None), ("quick", "-quick")):
        monkeypatch.setenv("GRASPING_SYM_OPT", level)
        with paths.root_override(tmp_path / level):
            models[level] = gs.build(gs.scenes.paper3d())
        assert tag is None or tag in models[level].library_path.name
    full = models["full"]
    x0 = np.asarray(full.initial_state())
    X = x0 + np.random.default_rng(3).normal(scale=1e-2, size=(50, x0.size))
    a = full.simulate(0.5)
    for level in ("quick", "none"):
        other = models[level]
        assert np.array_equal(np.array([full.rhs(x) for x in X]), np.array([other.rhs(x) for x in X]))
        b = other.simulate(0.5)
        assert np.array_equal(a.x, b.x) and a.outputs.keys() == b.outputs.keys()
        assert all(np.array_equal(a.outputs[k], b.outputs[k]) for k in a.outputs)


def test_isa_setting_unknown(monkeypatch):
    monkeypatch.setenv("GRASPING_SYM_ISA", "avx512")
    with pytest.raises(ValueError, match="GRASPING_SYM_ISA='avx512'.*'auto'.*'baseline'"):
        compiler.isa_level()


def test_isa_flags_old_compiler(monkeypatch):
    """A compiler that rejects -march=x86-64-v3 (gcc < 11) builds for the baseline."""
    monkeypatch.setattr(platform_.platform, "machine", lambda: "x86_64")
    monkeypatch.setattr(platform_, "_cpu_flags", lambda: frozenset(V3_FLAGS.split()))
    monkeypatch.setattr(compiler, "_compiler_accepts", lambda cc, flag: False)
    monkeypatch.delenv("GRASPING_SYM_ISA", raising=False)
    assert compiler.isa_level() == "x86-64-v3" and compiler.isa_flags() == ()


@pytest.mark.skipif(compiler.isa_level() == "baseline", reason="this CPU has no x86-64-v3")
def test_isa_build_is_bit_identical_to_baseline(tmp_path, pendulum, monkeypatch):
    """The x86-64-v3 build fuses no multiply-add: every result equals the baseline build's.
    (This C calls libm as CasADi wrote it, not grouped by codegen.vecmath: see test_vecmath
    for glibc's vector libm.)"""
    rhs, out, _ = pendulum
    c_file = _generate(tmp_path, "pend", [rhs, rhs.jacobian(), out])
    libs = {}
    for level in ("auto", "baseline"):
        monkeypatch.setenv("GRASPING_SYM_ISA", level)
        libs[level] = CompiledLibrary(build_library(c_file, tmp_path / level / "pend.so", rhs, out))
    X = np.random.default_rng(0).uniform(-3, 3, (200, 2))
    a, b = (libs[k].rhs_batch(X, P) for k in ("auto", "baseline"))
    assert np.array_equal(a, b)
    t, xa, _ = libs["auto"].radau5([0.3, 0.1], np.linspace(0, 2, 5), P, rtol=1e-8, atol=1e-10)
    _, xb, _ = libs["baseline"].radau5([0.3, 0.1], t, P, rtol=1e-8, atol=1e-10)
    assert np.array_equal(xa, xb)


def test_missing_compiler(tmp_path, monkeypatch):
    src = tmp_path / "ok.c"
    src.write_text("int f(void) { return 1; }\n")
    monkeypatch.setenv("CC", "no-such-compiler-xyz")
    with pytest.raises(CompileError, match="C compiler is required.*CC"):
        compile_shared([src], tmp_path / "ok.so", {})


def test_compile_clean_and_atomic(tmp_path, pendulum, caplog):
    rhs, out, _ = pendulum
    c_file = _generate(tmp_path, "pend", [rhs, rhs.jacobian(), out])
    so = tmp_path / "lib" / "pend.so"
    with caplog.at_level("WARNING"):
        build_library(c_file, so, rhs, out)
        build_library(c_file, so, rhs, out)  # rebuild replaces in place
    assert not caplog.records, [r.getMessage() for r in caplog.records]  # no compiler warnings
    assert [p.name for p in so.parent.iterdir()] == ["pend.so"]
    assert isinstance(COMPILER_FLAGS, tuple) and "-O2" in COMPILER_FLAGS
    d = driver_defines(rhs, out)
    assert d["GS_NX"] == 2 and d["GS_NP"] == 1 and d["GS_NY"] == 3 and d["GS_RHS"] == "pend_rhs"
    # the same .so also serves CasADi's external() (rhs + its Jacobian)
    ext = ca.external("pend_rhs", str(so))
    np.testing.assert_allclose(np.array(ext(0, [0.3, 0.1], [], P, [])[0]).ravel(),
                               CompiledLibrary(so).rhs([0.3, 0.1], P), rtol=1e-15)


def test_models_of_different_sizes_and_features_link_the_same_driver_objects(tmp_path, monkeypatch):
    """The driver's objects are compiled once per set of work sizes: a model of 3 states and
    one of 5 (each with 2 parameters, outputs of different lengths, a Jacobian) and one of 4
    with neither outputs nor a Jacobian link the very same object files; each library reads
    its own sizes and features at run time (``objects.links_c``): the one without a Jacobian
    integrates on differences to the same answer, the one without outputs has none to call, and a wrong shape is
    reported with the library's own size."""
    from grasping_sym.toolchain import objects

    monkeypatch.setenv("GRASPING_SYM_CACHE", str(tmp_path / "cache"))
    linked = []
    real = objects.driver_objects
    monkeypatch.setattr(objects, "driver_objects",
                        lambda *a, **k: linked.append(real(*a, **k)) or linked[-1])
    for nx, features in ((3, True), (5, True), (4, False)):
        x, p = ca.SX.sym("x", nx), ca.SX.sym("p", 2)
        ode = -p[0] * x + p[1] * ca.vertcat(x[1:], x[0]) ** 2  # a ring of decaying, coupled states
        rhs = _dae_rhs(f"ring{nx}_rhs", x, p, ode)
        out = ca.Function(f"ring{nx}_outputs", [x, p], [ca.vertcat(*[x[i] * x[i] for i in range(nx - 1)])])
        d = tmp_path / f"ring{nx}"
        d.mkdir()
        jac = rhs.jacobian() if features else None
        c_file = _generate(d, f"ring{nx}", [rhs, jac, out] if features else [rhs])
        lib = CompiledLibrary(build_library(c_file, d / f"ring{nx}.so", rhs,
                                            out if features else None, jac_fn=jac))
        x0, pv = np.linspace(0.1, 0.5, nx), np.array([0.7, 0.2])
        np.testing.assert_array_equal(lib.rhs(x0, pv), np.array(rhs(0, x0, [], pv, [])[0]).ravel())
        assert lib.has_outputs is features
        if features:
            np.testing.assert_array_equal(lib.outputs(x0, pv), np.array(out(x0, pv)).ravel())
            assert lib.outputs(x0, pv).shape == (nx - 1,)
        else:
            assert lib.ny == -1 and not hasattr(lib._ext, "outputs")
        with pytest.raises(ValueError, match=rf"\({nx},\)"):
            lib.rhs(np.zeros(nx + 1), pv)
        with pytest.raises(ValueError, match=r"np = 2"):
            lib.rhs(x0)
        _, X, stats = lib.radau5(x0, np.linspace(0.0, 1.0, 11), p=pv, rtol=1e-8, atol=1e-10)
        ref = solve_ivp(lambda t, y, f=rhs, pv=pv: np.array(f(t, y, [], pv, [])[0]).ravel(),
                        (0.0, 1.0), x0, t_eval=np.linspace(0.0, 1.0, 11), rtol=1e-11, atol=1e-13)
        np.testing.assert_allclose(X, ref.y.T, rtol=0, atol=1e-7)
    assert len(linked) == 3 and linked[0] == linked[1] == linked[2]
    assert len(list((tmp_path / "cache" / "objects").glob("driver-*"))) == 1


def test_radau_matrices_of_a_large_model_go_on_the_heap(tmp_path):
    """No size bound: gs_radau5 keeps its matrices on the stack up to GS_WORK_ON_STACK_MAX
    (256 KiB, n = 90) and on the heap above; a model of 120 states integrates like a small
    one (a chain of decaying states, exact solution known)."""
    nx = 120
    x, p = ca.SX.sym("x", nx), ca.SX.sym("p", 1)
    rhs = _dae_rhs("chain_rhs", x, p, -p[0] * x)
    c_file = _generate(tmp_path, "chain", [rhs, rhs.jacobian()])
    lib = CompiledLibrary(build_library(c_file, tmp_path / "chain.so", rhs, jac_fn=rhs.jacobian()))
    x0, t_out = np.linspace(1.0, 2.0, nx), np.linspace(0.0, 1.0, 5)
    _, X, stats = lib.radau5(x0, t_out, p=[1.5], rtol=1e-10, atol=1e-12)
    np.testing.assert_allclose(X, np.exp(-1.5 * t_out)[:, None] * x0, rtol=1e-8)
    assert stats["n_lu"] > 0


def test_the_link_file_refuses_a_feature_without_its_function():
    """The driver reads its features from the model's link file (``objects.links_c``): a
    feature flagged without its function's name, or a Jacobian whose inputs exceed the work
    sizes, is refused by name before anything is compiled (the driver's ``#error``s did it
    when the features were macros)."""
    from grasping_sym.toolchain import objects

    base = {"GS_RHS": "m_rhs", "GS_NX": 2, "GS_NP": 0, "GS_SZ_ARG": 8, "GS_SZ_RES": 8,
            "GS_SZ_IW": 1, "GS_SZ_W": 1}
    assert "int gs_model_outputs(" in objects.links_c(base)  # the stub, never called
    with pytest.raises(ValueError, match="GS_HAS_OUT"):
        objects.links_c({**base, "GS_HAS_OUT": 1})
    with pytest.raises(ValueError, match="GS_RHS"):
        objects.links_c({k: v for k, v in base.items() if k != "GS_RHS"})
    with pytest.raises(ValueError, match="GS_JAC_NIN"):
        objects.links_c({**base, "GS_HAS_JAC": 1, "GS_JAC": "jac_m_rhs", "GS_JAC_NIN": 99,
                         "GS_JAC_NOUT": 20, "GS_JAC_BLOCK": 1})
