"""Build and call costs against the object contour's complexity, up to splines of 1000 points.

Object contours (all against the paper's catenary fingertip, two contact parameters): circle,
ellipse, catenary (the paper's object), superellipse (n = 4), and the quintic spline
(``geometry.spline``) through 10, 100 and 1000 points of the README's ellipse. For each, in
fresh interpreters with private, empty caches (``GRASPING_SYM_CACHE``): a cold build (the
stages of ``Model.build_info``: validate, template, compose, write C, compile), then in the
same process the SX instruction counts, the C size, the SymPy size of the object's leaves and
the time to translate them alone, and the compiled rhs cost (``model.rhs(x0)`` per call, the C
loop of the library, ``model.rhs_batch`` per state); then a cached load in another fresh
interpreter.

Alternatives for the spline (what ``geometry.spline``'s design was chosen from):

- selection microbenchmark: 13 coefficients picked among m pieces plus two quintics, as SX
  compiled by gcc -O2 and timed in a C loop, for each way of picking (if_else chain = what a
  Piecewise becomes, balanced if_else tree, atan2 steps, sign steps = shipped, comparison
  steps, a CasADi B-spline call node);
- whole model with B-spline call nodes: the change to ``symbolic/translate.py`` the report
  proposes, emulated here by registering the call nodes in its translation table in a
  throw-away interpreter (not something the package does).

    python -m benchmarks.build_scaling [--quick]  ->  benchmarks/results/build_scaling.{md,json,png}

``--quick`` leaves out the microbenchmark's m = 1000 (its if_else variants take gcc ~1 min each).
"""
from __future__ import annotations

import argparse
import json
import math
import os
import subprocess
import tempfile
import time
from pathlib import Path

import numpy as np

from benchmarks.build_fingers import _exponent
from benchmarks.rhs_loop import rhs_loop_ns
from benchmarks.timing import best_per_call, in_fresh_process, median

RESULTS = Path(__file__).resolve().parent / "results"
SPLINE_POINTS = (10, 100, 1000)
SHAPES = ("circle", "ellipse", "catenary", "superellipse", *(f"spline{n}" for n in SPLINE_POINTS))
#: The README's ellipse (m) and the eccentric angle of the first contact.
ELLIPSE = (0.020, 0.015)
#: Cached loads per shape (each in a fresh interpreter); the median is reported.
CACHED_RUNS = 3
U1_ELLIPSE = math.pi + 0.3


def ellipse_points(n: int) -> np.ndarray:
    """``n`` points of the README's ellipse, clockwise from the eccentric angle ``U1_ELLIPSE``."""
    a, b = ELLIPSE
    t = U1_ELLIPSE + 2 * math.pi * np.arange(n) / n
    return np.c_[a * np.cos(-t), b * np.sin(-t)]


def shape_scene(shape: str):
    """The benchmark scene of ``shape`` (one of ``SHAPES``); name ``scaling_<shape>``."""
    import grasping_sym as gs
    from grasping_sym.geometry import library as lib

    a, b = ELLIPSE
    u1 = U1_ELLIPSE
    if shape == "circle":
        obj, u1 = lib.circle(0.02, start=math.pi, span=math.pi, clockwise=True, name="circle"), 0.004
    elif shape == "ellipse":
        obj = lib.ellipse(a, b, start=math.pi, span=math.pi, clockwise=True, name="ellipse")
    elif shape == "catenary":
        obj, u1 = lib.paper_object(), 0.001  # u1 != u0: the same two-parameter structure
    elif shape == "superellipse":
        obj = lib.superellipse(a, b, 4, start=math.pi, span=math.pi, clockwise=True, name="superellipse")
    elif shape.startswith("spline"):
        obj, u1 = lib.spline(ellipse_points(int(shape[6:])), closed=True, name=shape), 0.0
    else:
        raise ValueError(f"unknown shape {shape!r}: choose from {SHAPES}")
    return gs.scenes.planar_finger(lib.paper_fingertip(), obj, name=f"scaling_{shape}", u1_0=u1)


def _dag_size(exprs) -> int:
    seen, stack = set(), list(exprs)
    while stack:
        e = stack.pop()
        if id(e) in seen:
            continue
        seen.add(id(e))
        stack.extend(e.args)
    return len(seen)


def model_metrics(scene, model) -> dict:
    """Everything measured in the process that built ``model`` (after the build)."""
    import casadi as ca

    from grasping_sym.geometry.curves import T
    from grasping_sym.symbolic.contour_functions import OBJECT, leaf_expressions
    from grasping_sym.symbolic.translate import SympyToCasadi

    t0 = time.perf_counter()
    leaves = leaf_expressions(OBJECT, scene.object)
    t1 = time.perf_counter()
    tr = SympyToCasadi({T: ca.SX.sym("u")})
    [tr(leaves[c]) for c in OBJECT.leaves()]
    t2 = time.perf_counter()
    c_file = model.directory / f"{scene.name}.c"
    x0 = model.initial_state()
    rhs = best_per_call(lambda: model.rhs(x0), number=2000, repeat=5)
    # states spread over the contact parameters' domains: every piece of a spline in turn
    X = np.tile(x0, (1000, 1))
    for k, (lo, hi) in enumerate(zip(model.manifest["lower"], model.manifest["upper"])):
        if lo is not None and hi is not None:
            X[:, k] = np.linspace(lo + 0.01 * (hi - lo), hi - 0.01 * (hi - lo), len(X))
    batch = best_per_call(lambda: model.rhs_batch(X), number=3, repeat=5)
    loop_ns = min(rhs_loop_ns(model, x0, 20_000) for _ in range(3))
    pieces = len(scene.object.spline_data.breaks) - 1 if hasattr(scene.object, "spline_data") else None
    return {
        "op_counts": model.manifest["op_counts"], "c_bytes": c_file.stat().st_size,
        "c_lines": c_file.read_text().count("\n"), "so_bytes": Path(model.library_path).stat().st_size,
        "object_leaves_s": t1 - t0, "object_translate_s": t2 - t1,
        "object_leaf_dag_nodes": _dag_size([leaves[c] for c in OBJECT.leaves()]),
        "rhs_us": rhs * 1e6, "rhs_c_loop_ns": loop_ns, "rhs_batch_ns_per_state": batch / len(X) * 1e9,
        "spline_pieces": pieces, "n_states": len(model.state_names),
    }


_COLD = """
import json, time
import grasping_sym as gs
from benchmarks.build_scaling import shape_scene, model_metrics
t0 = time.perf_counter()
scene = shape_scene({shape!r})
t1 = time.perf_counter()
model = gs.build(scene, force=True)
t2 = time.perf_counter()
out = {{"scene_s": t1 - t0, "build_s": t2 - t1, "info": model.build_info}}
out.update(model_metrics(scene, model))
print(json.dumps(out))
"""

_CACHED = """
import json, time
import grasping_sym as gs
from benchmarks.build_scaling import shape_scene
t0 = time.perf_counter()
scene = shape_scene({shape!r})
t1 = time.perf_counter()
model = gs.build(scene)
t2 = time.perf_counter()
x0 = model.initial_state()
model.rhs(x0)
t3 = time.perf_counter()
print(json.dumps({{"scene_s": t1 - t0, "build_s": t2 - t1, "first_rhs_s": t3 - t2, "info": model.build_info}}))
"""


def run_shapes(caches: Path, log=print) -> list[dict]:
    """Cold build and cached loads of every shape, each shape in its cache ``caches / shape``."""
    rows = []
    for shape in SHAPES:
        cache = caches / shape
        t0 = time.perf_counter()
        cold = in_fresh_process(_COLD.format(shape=shape), cache, timeout=900)
        wall = time.perf_counter() - t0
        loads = [in_fresh_process(_CACHED.format(shape=shape), cache) for _ in range(CACHED_RUNS)]
        if any(c["info"].get("source") != "cache" for c in loads):
            raise RuntimeError(f"expected cached loads of {shape}, got {[c['info'] for c in loads]}")
        cached = {k: median([c[k] for c in loads]) for k in ("scene_s", "build_s", "first_rhs_s")}
        info = cold.pop("info")
        row = {"shape": shape, "n_points": int(shape[6:]) if shape.startswith("spline") else None,
               "cold": {"scene_s": cold.pop("scene_s"), "build_s": cold.pop("build_s"),
                        "process_wall_s": wall, **{k: v for k, v in info.items()}},
               "cached": {"scene_s": cached["scene_s"], "build_s": cached["build_s"],
                          "first_rhs_s": cached["first_rhs_s"]},
               **cold}
        rows.append(row)
        log(f"{shape}: scene {row['cold']['scene_s']:.2f} s, compose {info['compose']:.2f} s, "
            f"compile {info['compile']:.1f} s, cached load {cached['build_s'] * 1e3:.1f} ms, "
            f"rhs {row['rhs_us']:.2f} us, C {row['c_bytes'] / 1e3:.0f} kB, "
            f"rhs SX {row['op_counts']['rhs_sx_instructions']}")
    return rows


# ---------------------------------------------------------------------- alternatives
SELECTION_VARIANTS = {
    "chain": "if_else chain (what a Piecewise becomes in translate.py)",
    "tree": "balanced if_else tree on t",
    "atan2": "steps atan2(0, t_k - t) / pi",
    "sign": "steps sign(d)(sign(d) + 1) / 2 (shipped before 9dd7d99)",
    "cmp": "steps (t > t_k) (SX comparison; no SymPy route in translate.py)",
    "bspline_call": "CasADi B-spline call node, O(log m) lookup (what the spline now uses, degree 1)",
}

_HARNESS = r"""
#include <stdio.h>
#include <time.h>
typedef double casadi_real; typedef long long int casadi_int;
int f(const casadi_real** arg, casadi_real** res, casadi_int* iw, casadi_real* w, int mem);
int main(void) {
  double r[2], acc = 0, w[%(nw)d]; long long iw[%(niw)d]; long n = %(n)d;
  struct timespec a, b;
  clock_gettime(CLOCK_MONOTONIC, &a);
  for (long i = 0; i < n; ++i) {
    double t = %(tmax)r * (double)(i %% 997) / 997.0;
    const double* arg[1] = {&t}; double* res[1] = {r};
    f(arg, res, iw, w, 0); acc += r[0];
  }
  clock_gettime(CLOCK_MONOTONIC, &b);
  printf("%%.3f %%g\n", ((b.tv_sec - a.tv_sec) * 1e9 + (b.tv_nsec - a.tv_nsec)) / n, acc);
  return 0;
}
"""


def selection_function(variant: str, m: int):
    """SX function ``t -> (x(t), y(t))``: 13 coefficients selected among ``m`` pieces, then
    two quintics in the local variable (random data on increasing knots)."""
    import casadi as ca

    rng = np.random.default_rng(0)
    knots = np.concatenate([[0.0], np.cumsum(rng.uniform(0.5, 1.5, m))])
    vals = rng.normal(size=(13, m))
    t = ca.SX.sym("t")
    if variant in ("atan2", "sign", "cmp"):
        H = []
        for k in range(1, m):
            d = t - knots[k]
            if variant == "atan2":
                H.append(ca.atan2(0, -d) * (1 / np.pi))
            elif variant == "sign":
                s = ca.sign(d)
                H.append(s * (s + 1) * 0.5)
            else:
                H.append(d > 0)
        ind = [1 - H[0]] + [H[k - 1] - H[k] for k in range(1, m - 1)] + [H[m - 2]] if m > 1 else [1]
        sel = [sum((vals[j, k] * ind[k] for k in range(m)), ca.SX(0)) for j in range(13)]
    elif variant == "chain":
        conds = [t < knots[k + 1] for k in range(m - 1)]
        sel = []
        for j in range(13):
            out = ca.SX(vals[j, m - 1])
            for k in reversed(range(m - 1)):
                out = ca.if_else(conds[k], vals[j, k], out)
            sel.append(out)
    elif variant == "tree":
        def tree(j, lo, hi):
            if hi - lo == 1:
                return ca.SX(vals[j, lo])
            mid = (lo + hi) // 2
            return ca.if_else(t < knots[mid], tree(j, lo, mid), tree(j, mid, hi))
        sel = [tree(j, 0, m) for j in range(13)]
    elif variant == "bspline_call":
        lut = ca.Function.bspline("lut", [knots.tolist()], vals.T.ravel().tolist(), [0], 13, {})
        out = lut.call([t], False, True)[0]
        sel = [out[j] for j in range(13)]
    else:
        raise ValueError(variant)
    U = t - sel[0]
    polys = []
    for k in range(2):
        p = sel[1 + 6 * k + 5]
        for j in reversed(range(5)):
            p = p * U + sel[1 + 6 * k + j]
        polys.append(p)
    return ca.Function("f", [t], [ca.vertcat(*polys)], {"cse": True}), float(knots[-1])


def selection_benchmark(variant: str, m: int, workdir: Path) -> dict:
    import casadi as ca

    from grasping_sym.toolchain.compiler import compiler_command

    d = workdir / f"{variant}_{m}"
    d.mkdir(parents=True, exist_ok=True)
    t0 = time.perf_counter()
    f, tmax = selection_function(variant, m)
    t1 = time.perf_counter()
    cg = ca.CodeGenerator("f.c", {"casadi_int": "long long int"})
    cg.add(f)
    cg.generate(str(d) + os.sep)
    n_calls = max(2000, 20_000_000 // (30 * m))
    (d / "main.c").write_text(_HARNESS % {"nw": max(1, f.sz_w()), "niw": max(1, f.sz_iw()),
                                          "n": n_calls, "tmax": tmax})
    t2 = time.perf_counter()
    subprocess.run([*compiler_command(), "-O2", "-o", str(d / "a.out"), str(d / "f.c"), str(d / "main.c"),
                    "-lm"], check=True, capture_output=True)
    t3 = time.perf_counter()
    ns = min(float(subprocess.run([str(d / "a.out")], capture_output=True, text=True, check=True)
                   .stdout.split()[0]) for _ in range(3))
    return {"variant": variant, "m": m, "sx_instructions": f.n_instructions(), "build_sx_s": t1 - t0,
            "c_bytes": (d / "f.c").stat().st_size, "compile_s": t3 - t2, "ns_per_call": ns}


#: Variants timed at m = 1000 by default (the others only with ``--full``: gcc takes 20-70 s
#: on each, and they are dominated already at m = 100).
DEFAULT_AT_1000 = ("chain", "sign", "bspline_call")


def run_selection(ms, *, full: bool, log=print) -> list[dict]:
    rows = []
    with tempfile.TemporaryDirectory(prefix="gs-bench-selection-") as tmp:
        for m in ms:
            for variant in SELECTION_VARIANTS:
                if m >= 1000 and not full and variant not in DEFAULT_AT_1000:
                    continue
                r = selection_benchmark(variant, m, Path(tmp))
                rows.append(r)
                log(f"  selection {variant:>12} m={m:>4}: {r['ns_per_call']:9.1f} ns/call, "
                    f"{r['sx_instructions']:6d} SX, gcc {r['compile_s']:.1f} s")
    return rows


_CALLNODE = """
import json, math, time, hashlib
import numpy as np, sympy as sp, casadi as ca
from scipy.interpolate import make_interp_spline
import grasping_sym as gs
from grasping_sym.symbolic import translate
from grasping_sym.geometry.curves import PlanarCurve, T
from benchmarks.build_scaling import shape_scene, model_metrics

# EMULATION of the proposed translate.py change (a SymPy function carrying a CasADi
# implementation, here registered in translate.py's table): call nodes in the SX graph.
t0 = time.perf_counter()
ship_scene = shape_scene("spline{n}")
d = ship_scene.object.spline_data
tag = hashlib.sha256(d.cx.tobytes() + d.cy.tobytes()).hexdigest()[:12]
variant = {variant!r}
if variant == "bspline5":
    # x(t), y(t) and their first three derivatives: eight degree-5..2 B-spline functions
    b = make_interp_spline(d.params, np.vstack([d.points, d.points[:1]]), k=5, bc_type="periodic")
    fcls = {{}}
    for k, coord in enumerate("xy"):
        for order in range(4):
            bd = b.derivative(order) if order else b
            fn = ca.Function.bspline(f"bs{{coord}}{{order}}_{{tag}}", [bd.t.tolist()],
                                     bd.c[:len(bd.t) - bd.k - 1, k].tolist(), [bd.k], 1, {{}})
            def fdiff(self, argindex=1, coord=coord, order=order):
                return fcls[(coord, order + 1)](self.args[0])
            cls = type(f"S{{coord}}{{order}}_{{tag}}", (sp.Function,), {{"nargs": 1, "fdiff": fdiff,
                       "_imp_": staticmethod(lambda t, bd=bd, k=k: bd(t)[..., k])}})
            fcls[(coord, order)] = cls
            translate._UNARY[cls] = (lambda a, fn=fn: fn.call([a], False, True)[0])
    x, y = fcls[("x", 0)](T), fcls[("y", 0)](T)
else:
    # one piecewise-constant lookup (degree-0 B-spline) of the 13 coefficients of the piece,
    # shared by all of them; the quintics stay inline SX, as in the shipped spline
    vals = np.vstack([d.breaks[:-1], d.cx, d.cy])          # (13, m)
    lut = ca.Function.bspline(f"lut_{{tag}}", [d.breaks.tolist()], vals.T.ravel().tolist(), [0], 13, {{}})
    calls = {{}}
    def pick(a, j):
        key = id(a)
        if key not in calls:
            calls[key] = (a, lut.call([a], False, True)[0])
        return calls[key][1][j]
    def numeric(t, j):
        return vals[j][d.piece(np.asarray(t, dtype=float))]
    C = []
    for j in range(13):
        cls = type(f"C{{j}}_{{tag}}", (sp.Function,), {{"nargs": 1, "fdiff": lambda self, argindex=1: sp.S.Zero,
                   "_imp_": staticmethod(lambda t, j=j: numeric(t, j))}})
        translate._UNARY[cls] = (lambda a, j=j: pick(a, j))
        C.append(cls(T))
    U = T - C[0]
    def horner(cs):
        out = cs[-1]
        for c in reversed(cs[:-1]):
            out = c + U * out
        return out
    x, y = horner(C[1:7]), horner(C[7:13])
obj = PlanarCurve(x, y, T, (0.0, d.length), "callnode")
scene = gs.scenes.planar_finger(gs.curves.paper_fingertip(), obj, name="callnode_{variant}{n}", u1_0=0.0)
t1 = time.perf_counter()
model = gs.build(scene, force=True)
t2 = time.perf_counter()
out = {{"n_points": {n}, "variant": variant, "scene_s": t1 - t0, "build_s": t2 - t1, "info": model.build_info}}
m = model_metrics(scene, model)
out.update({{k: m[k] for k in ("op_counts", "c_bytes", "rhs_us", "rhs_c_loop_ns", "rhs_batch_ns_per_state")}})
ship = gs.build(ship_scene)   # the shipped spline's model, from the cache of the shapes run
assert ship.build_info["source"] == "cache", ship.build_info
x0 = ship.initial_state()
out["rhs_rel_diff_vs_shipped"] = float(np.max(np.abs(model.rhs(x0) - ship.rhs(x0))) / np.max(np.abs(ship.rhs(x0))))
print(json.dumps(out))
"""

#: Call-node emulations: eight B-spline functions (x, y and three derivatives each), or one
#: lookup of the piece's 13 coefficients with the quintics inline.
CALLNODE_VARIANTS = {
    "bspline5": "x, y and 3 derivatives each as B-spline call nodes (8 calls)",
    "lookup": "one lookup call of the piece's 13 coefficients, quintics inline",
}


def run_callnode(caches: Path, log=print) -> list[dict]:
    """Call-node models for 100 and 1000 points; ``caches / f"spline{n}"`` holds the shipped model."""
    rows = []
    for n in (100, 1000):
        for variant in CALLNODE_VARIANTS:
            try:
                r = in_fresh_process(_CALLNODE.format(n=n, variant=variant), caches / f"spline{n}", timeout=900)
            except RuntimeError as exc:  # e.g. translate.py's table renamed: report, do not fail
                r = {"n_points": n, "variant": variant, "error": str(exc)[-500:]}
            rows.append(r)
            if "error" not in r:
                log(f"  call nodes ({variant}), {n} points: build {r['build_s']:.1f} s (compile "
                    f"{r['info']['compile']:.1f} s), rhs {r['rhs_us']:.2f} us, C loop {r['rhs_c_loop_ns']:.0f} ns, "
                    f"C {r['c_bytes'] / 1e3:.0f} kB, rel. diff {r['rhs_rel_diff_vs_shipped']:.1e}")
            else:
                log(f"  call nodes ({variant}), {n} points: failed ({r['error'][-200:]})")
    return rows


# ---------------------------------------------------------------------- report
def _fit_linear(ns, ys) -> tuple[float, float]:
    """Least-squares ``y = a + b n``."""
    A = np.c_[np.ones(len(ns)), ns]
    (a, b), *_ = np.linalg.lstsq(A, np.asarray(ys, dtype=float), rcond=None)
    return float(a), float(b)


_METRICS = [
    ("scene construction (spline fit), s", lambda r: r["cold"]["scene_s"], "{:.3f}"),
    ("validate, s", lambda r: r["cold"]["validate"], "{:.3f}"),
    ("template (committed), s", lambda r: r["cold"]["template"], "{:.3f}"),
    ("compose (leaves -> SX, CasADi functions, Jacobian), s", lambda r: r["cold"]["compose"], "{:.3f}"),
    ("  of which: object leaves (SymPy), s", lambda r: r["object_leaves_s"], "{:.3f}"),
    ("  of which: translate object leaves, s", lambda r: r["object_translate_s"], "{:.3f}"),
    ("write C, s", lambda r: r["cold"]["write_c"], "{:.3f}"),
    ("compile (gcc -O2), s", lambda r: r["cold"]["compile"], "{:.2f}"),
    ("cold gs.build total, s", lambda r: r["cold"]["build_s"], "{:.2f}"),
    ("cached load (fresh process, median of 3), ms", lambda r: r["cached"]["build_s"] * 1e3, "{:.1f}"),
    ("object leaves, SymPy DAG nodes", lambda r: r["object_leaf_dag_nodes"], "{:.0f}"),
    ("rhs SX instructions (after CSE)", lambda r: r["op_counts"]["rhs_sx_instructions"], "{:.0f}"),
    ("Jacobian SX instructions", lambda r: r["op_counts"]["jac_sx_instructions"], "{:.0f}"),
    ("outputs SX instructions", lambda r: r["op_counts"].get("outputs_sx_instructions", 0), "{:.0f}"),
    ("constraints SX instructions", lambda r: r["op_counts"].get("constraints_sx_instructions", 0), "{:.0f}"),
    ("C file, kB", lambda r: r["c_bytes"] / 1e3, "{:.0f}"),
    ("compiled rhs, C loop, ns/call", lambda r: r["rhs_c_loop_ns"], "{:.0f}"),
    ("compiled rhs, model.rhs(x0), us/call", lambda r: r["rhs_us"], "{:.2f}"),
    ("compiled rhs, rhs_batch of 1000, ns/state", lambda r: r["rhs_batch_ns_per_state"], "{:.0f}"),
]


def write(result: dict, out: Path = RESULTS) -> Path:
    out.mkdir(parents=True, exist_ok=True)
    (out / "build_scaling.json").write_text(json.dumps(result, indent=2, default=float) + "\n")
    rows = result["shapes"]
    splines = [r for r in rows if r["n_points"]]
    lines = [
        "# Build and call costs against the object contour's complexity",
        "",
        "Generated by `python -m benchmarks.build_scaling`. Every scene: the paper's fingertip on the "
        "named object contour, two contact parameters (8 states), default outputs; `splineN`: "
        "`gs.curves.spline` (closed, arclength parameter) through N points of the README's ellipse "
        "(20 x 15 mm). Each cold build runs in a fresh interpreter with an empty private cache "
        "(`GRASPING_SYM_CACHE`); the counts, sizes and rhs timings are taken in that process after "
        "the build; the cached loads run in other fresh interpreters. The template of the structure "
        "is the committed one (derived once per structure, not per shape). Times are one run each "
        f"(machine: {_machine_text(result['machine'])}).",
        "",
        "| quantity | " + " | ".join(r["shape"] for r in rows) + " |",
        "|---|" + "---|" * len(rows),
    ]
    for label, get, fmt in _METRICS:
        lines.append(f"| {label} | " + " | ".join(fmt.format(get(r)) for r in rows) + " |")
    pieces = [r["spline_pieces"] for r in splines]
    growth = len(splines) >= 3
    lines += [
        "",
        f"Spline pieces (between breakpoints): {', '.join(map(str, pieces))} for "
        f"{', '.join(str(r['n_points']) for r in splines)} points. The spline's scene construction "
        "includes the first import of scipy.interpolate (~0.3-0.4 s); the fit itself is the growth.",
        "",
        "## Growth with the number of spline points" + ("" if growth else " (needs 3 spline sizes: skipped)"),
        "",
        "`k`: least-squares slope of log(value) against log(n) over n = 10, 100, 1000; `k (100->1000)`: "
        "the slope between the last two; `a + b n`: least-squares line (b per point). A cost that "
        "is a constant plus a linear part shows k < 1 over the whole range and k -> 1 at the top.",
        "",
        "| quantity | " + " | ".join(f"n = {r['n_points']}" for r in splines)
        + " | k | k (100->1000) | a + b n |",
        "|---|" + "---|" * (len(splines) + 3),
    ]
    for label, get, fmt in (_METRICS[:1] + _METRICS[2:]) if growth else ():
        vals = [get(r) for r in splines]
        fake = [{"n": r["n_points"], "v": get(r)} for r in splines]
        k = _exponent(fake, lambda r: r["v"]) if all(v > 0 for v in vals) else float("nan")
        k2 = (math.log(vals[-1] / vals[-2]) / math.log(splines[-1]["n_points"] / splines[-2]["n_points"])
              if vals[-2] > 0 and vals[-1] > 0 else float("nan"))
        a, b = _fit_linear([r["n_points"] for r in splines], vals)
        lines.append(f"| {label} | " + " | ".join(fmt.format(v) for v in vals)
                     + f" | {k:.2f} | {k2:.2f} | {a:.3g} + {b:.3g} n |")
    sel = result.get("selection", [])
    if sel:
        ms = sorted({r["m"] for r in sel})
        lines += [
            "",
            "## Alternatives: picking the piece (microbenchmark)",
            "",
            "An SX function `t -> (x(t), y(t))` that selects 13 coefficients (the knot and two quintics' "
            "coefficients) among m pieces and evaluates the two quintics, compiled alone with gcc -O2 "
            "and timed in a C loop with t cycling through 997 values across the domain (random data; "
            "`benchmarks.build_scaling.selection_function`). SX code has no branches: every variant but "
            "the call node evaluates all m pieces; if_else evaluates both branches (its short-circuit "
            "flag is ignored for SX), so a balanced tree is no cheaper in operations than a chain.",
            "",
            "| variant | " + " | ".join(f"m = {m}: ns/call" for m in ms) + " | "
            + " | ".join(f"m = {m}: SX / gcc s" for m in ms) + " |",
            "|---|" + "---|" * (2 * len(ms)),
        ]
        for v, label in SELECTION_VARIANTS.items():
            cells = {r["m"]: r for r in sel if r["variant"] == v}
            ns = [f"{cells[m]['ns_per_call']:.0f}" if m in cells else "-" for m in ms]
            sx = [f"{cells[m]['sx_instructions']} / {cells[m]['compile_s']:.1f}" if m in cells else "-" for m in ms]
            lines.append(f"| {label} | " + " | ".join(ns) + " | " + " | ".join(sx) + " |")
        if any(c == "-" for r in lines[-len(SELECTION_VARIANTS):] for c in r.split(" | ")):
            lines += ["", "`-`: not run (by default m = 1000 only for " + ", ".join(DEFAULT_AT_1000)
                      + ": gcc takes 20-70 s on each of the others; `--full` runs them)."]
    cn = [r for r in result.get("callnode", []) if "error" not in r]
    failed = [r for r in result.get("callnode", []) if "error" in r]
    if cn or failed:
        ship = {r["n_points"]: r for r in splines}
        lines += [
            "",
            "## The whole model with a call node (an emulation of what the spline now does, degree-0 table)",
            "",
            "The same spline evaluated through CasADi functions called from the SX graph as call nodes "
            "(`Function.call(..., never_inline=True)`): the generated C holds the data as arrays and "
            "finds the piece by binary search (`casadi_low`). Two ways: " + "; ".join(
                f"`{k}`: {v}" for k, v in CALLNODE_VARIANTS.items()) + ". Emulated by registering SymPy "
            "functions in translate.py's translation table inside a throw-away interpreter, with a degree-0 "
            "table (measured before the package got its `_casadi_` hook; CasADi 3.8.2 can corrupt memory "
            "there at the knots, so the shipped spline uses degree 1 with doubled breaks); the last "
            "column compares the rhs at the "
            "start with the shipped spline's (same points, same state).",
            "",
            "| points | variant | cold build, s | compose, s | compile, s | rhs SX | Jacobian SX | C, kB | "
            "rhs C loop, ns | model.rhs, us | rel. diff of rhs vs shipped |",
            "|---|---|---|---|---|---|---|---|---|---|---|",
        ]
        for n in sorted({r["n_points"] for r in cn}):
            for r in (r for r in cn if r["n_points"] == n):
                lines.append(f"| {n} | {r['variant']} | {r['build_s']:.2f} | {r['info']['compose']:.3f} | "
                             f"{r['info']['compile']:.2f} | {r['op_counts']['rhs_sx_instructions']} | "
                             f"{r['op_counts']['jac_sx_instructions']} | {r['c_bytes'] / 1e3:.0f} | "
                             f"{r['rhs_c_loop_ns']:.0f} | {r['rhs_us']:.2f} | {r['rhs_rel_diff_vs_shipped']:.1e} |")
            if n in ship:
                s = ship[n]
                lines.append(f"| {n} | shipped (call node) | {s['cold']['build_s']:.2f} | "
                             f"{s['cold']['compose']:.3f} | {s['cold']['compile']:.2f} | "
                             f"{s['op_counts']['rhs_sx_instructions']} | {s['op_counts']['jac_sx_instructions']} | "
                             f"{s['c_bytes'] / 1e3:.0f} | {s['rhs_c_loop_ns']:.0f} | {s['rhs_us']:.2f} | - |")
        for r in failed:
            lines.append(f"\nCall nodes ({r['variant']}, {r['n_points']} points) failed: `{r['error'][-300:]}`")
    lines += ["", f"Whole run: {result['run_s']:.0f} s.", ""]
    if result.get("plot"):
        lines += [f"![costs against spline points]({result['plot']})", ""]
    (out / "build_scaling.md").write_text("\n".join(lines))
    return out / "build_scaling.md"


def plot(result: dict, out: Path = RESULTS) -> str | None:
    try:
        import matplotlib
        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
    except ImportError:  # pragma: no cover
        return None
    splines = [r for r in result["shapes"] if r["n_points"]]
    n = [r["n_points"] for r in splines]
    fig, ax = plt.subplots(1, 2, figsize=(9, 3.4))
    for label, get in (("compile", lambda r: r["cold"]["compile"]), ("compose", lambda r: r["cold"]["compose"]),
                       ("scene (fit)", lambda r: r["cold"]["scene_s"]), ("write C", lambda r: r["cold"]["write_c"])):
        ax[0].loglog(n, [get(r) for r in splines], "o-", label=label)
    for variant in CALLNODE_VARIANTS:
        cn = [r for r in result.get("callnode", []) if "error" not in r and r["variant"] == variant]
        if cn:
            ax[0].loglog([r["n_points"] for r in cn], [r["info"]["compile"] for r in cn], "s--",
                         label=f"compile, call nodes ({variant})")
            ax[1].loglog([r["n_points"] for r in cn], [r["rhs_c_loop_ns"] for r in cn], "s--",
                         label=f"call nodes ({variant})")
    ax[1].loglog(n, [r["rhs_c_loop_ns"] for r in splines], "o-", label="shipped (call node)")
    ax[0].set(xlabel="spline points", ylabel="s", title="build stages")
    ax[1].set(xlabel="spline points", ylabel="ns per rhs call (C loop)", title="rhs cost")
    for a in ax:
        a.grid(True, which="both", alpha=0.3)
        a.legend(fontsize=7)
    fig.tight_layout()
    fig.savefig(out / "build_scaling.png", dpi=90)
    plt.close(fig)
    return "build_scaling.png"


def _machine() -> dict:
    from benchmarks.machine import machine_info

    return machine_info()


def _machine_text(m: dict) -> str:
    return (f"{m['cpu']}, {m['usable_cores']} usable cores, load {m['load_average_1_5_15'][0]:.2f} at the start, "
            f"{m['gcc']}, CasADi {m['versions']['casadi']}, SymPy {m['versions']['sympy']}, "
            f"commit {m['git_commit']}")


def rewrite(path: Path = RESULTS / "build_scaling.json") -> Path:
    """Regenerate the .md (and plot) from a saved .json, without measuring again."""
    result = json.loads(Path(path).read_text())
    result["plot"] = plot(result, Path(path).parent)
    return write(result, Path(path).parent)


def main(argv=None) -> Path:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--quick", action="store_true", help="no m = 1000 in the selection microbenchmark")
    parser.add_argument("--full", action="store_true", help="every selection variant at m = 1000 (+3 min)")
    args = parser.parse_args(argv)
    t0 = time.perf_counter()
    result: dict = {"machine": _machine(), "args": {"quick": args.quick, "full": args.full}}
    with tempfile.TemporaryDirectory(prefix="gs-bench-scaling-") as tmp:
        print("shapes (cold build and cached loads, each in a fresh interpreter):")
        result["shapes"] = run_shapes(Path(tmp))
        print("selection microbenchmark:")
        result["selection"] = run_selection((10, 100) if args.quick else (10, 100, 1000), full=args.full)
        print("whole model with call nodes (emulated translate.py change):")
        result["callnode"] = run_callnode(Path(tmp))
    result["run_s"] = time.perf_counter() - t0
    result["plot"] = plot(result)
    path = write(result)
    print(f"wrote {path} ({result['run_s']:.0f} s)")
    return path


if __name__ == "__main__":
    main()
