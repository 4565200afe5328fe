"""The 4-lane right-hand side (emit/lanes.py): bit-identical to the scalar one, and
radau's results with it equal those without it, bit for bit."""
from __future__ import annotations

import ctypes
import json

import casadi as ca
import numpy as np
import pytest

from grasping_sym.assemble import structure_cache
from grasping_sym.assemble.kinds import casadi_functions
from grasping_sym.emit import lanes, vecmath
from grasping_sym.runtime import projection
from grasping_sym.runtime.compiled import CompiledLibrary
from grasping_sym.store.paths import generated_dir
from grasping_sym.toolchain.library import build_library, compile_model


def _dae(name: str, x: ca.SX, p: ca.SX, ode: ca.SX) -> ca.Function:
    t, empty = ca.SX.sym("t"), ca.SX(0, 1)
    return ca.Function(name, [t, x, ca.SX.sym("z", 0), p, ca.SX.sym("u", 0)],
                       [ode, empty, empty, empty], ["t", "x", "z", "p", "u"],
                       ["ode", "alg", "quad", "zero"], {"cse": True})


def _lanes_call(lib: CompiledLibrary, symbol: str, T, X, p) -> np.ndarray:
    """Call ``symbol`` (the 4-lane rhs) on the four rows of X."""
    fn = getattr(lib._lib, symbol)
    fn.restype = ctypes.c_int
    X = np.ascontiguousarray(X, dtype=float)
    Y = np.full_like(X, np.nan)
    dp = ctypes.POINTER(ctypes.c_double)
    xs = (dp * 4)(*[X[k].ctypes.data_as(dp) for k in range(4)])
    ys = (dp * 4)(*[Y[k].ctypes.data_as(dp) for k in range(4)])
    t = np.ascontiguousarray(T, dtype=float)
    pa = np.ascontiguousarray(p, dtype=float)
    assert fn(t.ctypes.data_as(dp), xs, pa.ctypes.data_as(dp), ys) == 0
    return Y


@pytest.mark.parametrize("vecmath_env", ["auto", "off"])
def test_every_supported_operation_is_bit_identical(tmp_path, monkeypatch, vecmath_env):
    """One rhs using every translated operation: the lanes equal four scalar calls exactly,
    with glibc's vector libm (both call it) and without (both call the scalar functions)."""
    monkeypatch.setenv("GRASPING_SYM_VECMATH", vecmath_env)
    x, p = ca.SX.sym("x", 3), ca.SX.sym("p", 2)
    a, b, c = x[0], x[1], x[2]
    terms = [ca.sin(a) * p[0], ca.cos(b), ca.tan(0.3 * c), ca.asin(0.5 * ca.tanh(a)),
             ca.acos(0.5 * ca.tanh(b)), ca.atan(c), ca.sinh(0.1 * a), ca.cosh(0.1 * b),
             ca.asinh(c), ca.acosh(2 + b ** 2), ca.atanh(0.5 * ca.tanh(c)), ca.exp(0.1 * a),
             ca.log(1 + a ** 2), ca.log1p(b ** 2), ca.expm1(0.1 * c), ca.sqrt(1 + c ** 2),
             ca.erf(a), ca.floor(b * 3), ca.ceil(c * 3), ca.fabs(a - b), ca.atan2(a, b),
             (2 + ca.sin(b)) ** (p[1] + c ** 2), ca.fmod(a * 7, 1.3), ca.fmin(a, b),
             ca.fmax(b, c), a / (1.5 + ca.cos(c)) - b * c]
    ode = ca.vertcat(sum(terms[0::3]), sum(terms[1::3]), sum(terms[2::3]))
    rhs = _dae("ops_rhs", x, p, ode)
    code = lanes.rhs_lanes_c(rhs)
    assert code is not None
    cg = ca.CodeGenerator("ops.c", {"with_header": True, "casadi_int": "long long int"})
    cg.add(rhs)
    cg.generate(str(tmp_path) + "/")
    c_file = tmp_path / "ops.c"
    c_file.write_text(vecmath.batch_libm_calls(c_file.read_text(), [rhs])[0] + code)  # as cwriter
    lib = CompiledLibrary(build_library(c_file, tmp_path / "ops.so", rhs,
                                        rhs_lanes=lanes.lanes_symbol(rhs)))
    rng = np.random.default_rng(7)
    P = np.array([0.7, 0.3])
    for _ in range(50):
        X = rng.uniform(-2, 2, (4, 3))
        Y = _lanes_call(lib, "ops_rhs_lanes", np.zeros(4), X, P)
        ref = np.array([lib.rhs(X[k], P) for k in range(4)])
        assert np.array_equal(Y, ref, equal_nan=True)
        assert np.isfinite(ref).all()


@pytest.mark.parametrize("expr", [
    lambda x: ca.if_else(x[0] > 0, x[1], -x[1]),  # a comparison and a ternary
    lambda x: ca.sign(x[0]) * x[1],  # casadi_sign: not translated
])
def test_unsupported_operations_give_no_lanes(expr):
    x, p = ca.SX.sym("x", 2), ca.SX.sym("p", 0)
    rhs = _dae("bad_rhs", x, p, ca.vertcat(x[1], expr(x)))
    assert lanes.rhs_lanes_c(rhs) is None


def test_paper2d_has_lanes_and_radau_is_unchanged(paper2d_model, tmp_path):
    """The committed paper2d C has the lanes; radau with them gives the same bits and stats as
    radau with three scalar calls per Newton iteration (the library compiled without)."""
    defines = paper2d_model.manifest["driver_defines"]
    assert defines["GS_HAS_RHS_LANES"] == 1 and defines["GS_RHS_LANES"] == "paper2d_rhs_lanes"
    directory = paper2d_model.library.path.parent
    c_files = [directory / f for f in paper2d_model.manifest["files"] if f.endswith(".c")]
    off = dict(defines, GS_HAS_RHS_LANES=0)
    off.pop("GS_RHS_LANES")
    structure = structure_cache.link_objects(*structure_cache.locate(paper2d_model.manifest["structure"]))
    without = CompiledLibrary(compile_model(c_files, tmp_path / "off.so", off, objects=structure),
                              paper2d_model.state_names)
    with_ = paper2d_model.library
    x0, p = paper2d_model.initial_state(), paper2d_model.params()
    t = np.linspace(0.0, 1.5, 7)
    for mask in (None, projection.mask(paper2d_model)):
        kw = {"rtol": 1e-6, "atol": 1e-9, "proj_mask": mask,
              "proj_tol": projection.PROJECT_TOL if mask is not None else 0.0}
        a, b = with_.radau5(x0, t, p, **kw), without.radau5(x0, t, p, **kw)
        assert np.array_equal(a[1], b[1])
        assert {k: v for k, v in a[2].items() if k != "wall_time"} == \
               {k: v for k, v in b[2].items() if k != "wall_time"}
    X = x0 + np.random.default_rng(1).normal(0, 0.01, (4, x0.size))
    Y = _lanes_call(with_, "paper2d_rhs_lanes", np.zeros(4), X, p if p is not None else [])
    assert np.array_equal(Y, np.array([with_.rhs(X[k], p) for k in range(4)]))
    assert json.loads((directory / "manifest.json").read_text())["driver_defines"] == defines


def test_rewrites_are_applied_to_every_builtin_scene():
    """Each built-in scene records what the rewrites did: the grouping reached every call of a
    libmvec function in every generated SX function (for paper2d, in layers: its contour
    functions and its structure's functions), and paper2d has its 4-lane rhs."""
    from grasping_sym.assemble import structure_cache, templates
    from grasping_sym.assemble.scene_functions import planar_structure
    from grasping_sym.assemble.structure import structure_functions
    from grasping_sym.emit import algorithm
    from grasping_sym.model.scenes import BUILTIN
    from grasping_sym.store import files as stored

    def libm_calls(f):
        return sum(1 for ins in algorithm.read(f)
                   if algorithm.LIBM_CALLS.get(ins.op) in vecmath.VECTOR_FUNCTIONS)

    for name, make in BUILTIN.items():
        manifest = stored.read_manifest(generated_dir() / name)
        rewrites = manifest["rewrites"]
        grouped = rewrites["vecmath_grouped_calls"]
        assert set(grouped) == set(manifest["c_symbols"]), name
        if "structure" not in manifest:
            assert grouped[f"{name}_rhs"] > 0, name
            continue
        scene = make()
        for f in casadi_functions(scene).model.helpers:  # the SX contour / jets functions
            assert grouped[f.name()] == libm_calls(f) > 0, f.name()
        meta = json.loads((generated_dir() / structure_cache.DIR / manifest["structure"]["name"]
                           / structure_cache.META).read_text())
        if name == "paper2d":
            assert rewrites["rhs_lanes"].startswith("applied (contours four at a time"), name
            assert meta["rewrites"]["rhs_lanes"] == "applied"
            spec, _ = planar_structure(scene)
            template, _ = templates.planar_template(spec.shared, spec.gravity, spec.n_fingers)
            sf = structure_functions(template, spec, meta["name"])
        else:  # 3D: no lanes (the rhs is too large), the structure's functions grouped
            from grasping_sym.assemble.structure3d import structure3d_functions
            sf = structure3d_functions(scene, meta["name"])
        counts = meta["rewrites"]["vecmath_grouped_calls"]
        assert counts[f"{meta['name']}_rhs"] > 0
        for f in sf.functions():
            assert counts[f.name()] == libm_calls(f), f.name()
