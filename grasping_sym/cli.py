"""Command line: ``grasping-sym list | simulate | sweep | cache | generate | bench``.

Errors raised on purpose by the package (``GraspingSymError``), a bad argument and a value
the package refuses (``ValueError``) are printed as one message on stderr with exit code 2,
without a traceback. Every argument is checked before any work (building, simulating,
sweeping): the output directory, the parameters' values against the scene's rules, the
simulated time (at most ``MAX_T_FINAL``), the integrator's settings, what a sweep's figure
shows. Progress of slow stages (deriving, compiling, simulating, plotting) goes to stderr,
results to stdout.
"""
from __future__ import annotations

import argparse
import math
import os
import re
import subprocess
import sys
import tempfile
import time
from collections.abc import Sequence
from pathlib import Path

import numpy as np

from grasping_sym import __version__
from grasping_sym.errors import CompileError, GraspingSymError
from grasping_sym.runtime.integrators import METHODS
from grasping_sym.runtime.settings import DEFAULT_TOLERANCES, run_settings
from grasping_sym.store import paths as cache
from grasping_sym.store import safety
from grasping_sym.sweeps import check_store, parse_range, sweep

PROG = "grasping-sym"
EXIT_USER_ERROR = 2
#: The longest simulated time the command line runs (s): ``simulate`` writes an output every
#: millisecond (10^6 rows at this bound), a sweep integrates every point that long.
MAX_T_FINAL = 1000.0


class UsageError(GraspingSymError):
    """A bad command-line value (unknown scene name, non-positive time, ...)."""


class _Parser(argparse.ArgumentParser):
    """argparse with its errors as ``UsageError`` (one line, exit code 2, from ``main``)."""

    def error(self, message: str):
        raise UsageError(f"{message} (see `{self.prog} --help`)")


def _say(msg: str) -> None:
    print(f"[{PROG}] {msg}", file=sys.stderr, flush=True)


def _builtin() -> dict:
    from grasping_sym.model.scenes import BUILTIN  # noqa: PLC0415 - lazy: SymPy, only for the commands that name a scene

    return BUILTIN


def _describe(func) -> str:
    """The first sentence of ``func``'s docstring, on one line, without RST markup."""

    doc = (func.__doc__ or "").strip()
    if not doc:
        return "(no description)"
    paragraph = " ".join(line.strip() for line in doc.split("\n\n")[0].splitlines())
    text = re.sub(r"``([^`]*)``", r"\1", paragraph)
    text = re.sub(r":\w+:`([^`]*)`", r"\1", text)
    end = re.search(r"(?<!\be\.g)(?<!\bi\.e)\.(\s|$)", text)
    return text[:end.start() + 1] if end else text


def _scene_factory(name: str):
    scenes = _builtin()
    if name not in scenes:
        raise UsageError(f"unknown scene {name!r}: known scenes are {', '.join(sorted(scenes))} "
                         f"(see `{PROG} list`)")
    return scenes[name]


def simulate_settings(args: argparse.Namespace, scene) -> tuple[float, str, float, float]:
    """``(t_final, method, rtol, atol)``: the values given on the command line, else the
    scene's defaults (``scene.simulate_defaults``: simulated time, integrator, tolerances),
    those ``simulate`` takes (the manifest's ``defaults``; the method's own tolerances,
    ``runtime.settings.DEFAULT_TOLERANCES``, where the scene names none)."""
    d = scene.simulate_defaults
    method = args.method or d["method"]
    rtol, atol = d["tolerances"].get(method, DEFAULT_TOLERANCES.get(method, (1e-10, 1e-12)))
    return (args.t_final or d["t_final"], method, args.rtol or rtol, args.atol or atol)


def _positive_float(text: str) -> float:
    try:
        v = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not a number") from None
    if not (math.isfinite(v) and v > 0):
        raise argparse.ArgumentTypeError(f"{text!r} must be a finite number > 0")
    return v


def _positive_int(text: str) -> int:
    try:
        v = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not an integer") from None
    if v < 1:
        raise argparse.ArgumentTypeError(f"{text!r} must be an integer >= 1")
    return v


# ---------------------------------------------------------------------------- checks
# Everything a command is given is checked here, before it builds, simulates or sweeps.
def _check_out(text: str) -> Path:
    """``--out`` that is not a file (checked before anything is made)."""
    if not text.strip():
        raise UsageError("--out is empty: give a directory for the results (created if missing), "
                         "e.g. --out out/run1; '.' writes into this directory")
    out = Path(text)
    if out.exists() and not out.is_dir():
        raise UsageError(f"--out {out}: it is a file; give a directory (created if missing)")
    for parent in out.parents:
        if parent.exists():
            if not parent.is_dir():
                raise UsageError(f"--out {out}: {parent} is a file, not a directory; give another directory")
            break
    return out


def _make_out(out: Path) -> Path:
    """``--out`` made and writable (the last check before the work)."""
    try:
        out.mkdir(parents=True, exist_ok=True)
        with tempfile.TemporaryFile(dir=out):
            pass
    except OSError as exc:
        raise UsageError(f"--out {out}: cannot write there ({exc.strerror or exc}); give a directory "
                         "you may write") from None
    return out


#: ``--project``'s choices, as ``simulate``'s ``project``.
PROJECT = {"default": None, "steps": "steps", "rows": True, "off": False}


def _check_run(method: str, t_final: float, rtol, atol, h: float = 1e-4) -> None:
    """The simulated time (at most ``MAX_T_FINAL``) and the integrator's settings, as the
    model will check them (``runtime.settings.run_settings``)."""
    if t_final > MAX_T_FINAL:
        raise UsageError(f"--t-final {t_final:g}: at most {MAX_T_FINAL:g} s from the command line "
                         "(use the Python API, with its own t_eval, for longer runs)")
    try:
        run_settings(method, t_final, rtol, atol, h, 1_000_000, None)
    except (ValueError, TypeError) as exc:
        raise UsageError(f"the run's settings (--method {method}): {exc}") from None


def _check_param_values(scene, values: dict) -> None:
    """Each ``--param`` value against the rule the scene sets for that parameter (> 0 for a
    mass, a length or ``fd``; >= 0 for a gain), as the built model would check it."""
    extra = scene.manifest_extra() if hasattr(scene, "manifest_extra") else {}
    rules = extra.get("param_rules", {}) if isinstance(extra, dict) else {}
    for k, v in values.items():
        arr = np.atleast_1d(np.asarray(v, dtype=float))
        rule = rules.get(k, "finite")
        bad = ~np.isfinite(arr) | ((arr <= 0) if rule == "positive" else (arr < 0) if rule == "nonnegative"
                                   else np.zeros(arr.shape, dtype=bool))
        if bad.any():
            need = {"positive": "> 0", "nonnegative": ">= 0"}.get(rule, "finite")
            raise UsageError(f"--param {k}: the value {arr[bad][0]:g} is not allowed: {k} must be {need} "
                             f"(as the scene {scene.name!r} requires); give a physical value")


# ---------------------------------------------------------------------------- commands
def cmd_list(args: argparse.Namespace) -> int:
    scenes = _builtin()
    width = max(len(n) for n in scenes)
    for name, func in scenes.items():
        print(f"{name:<{width}}  {_describe(func)}")
    return 0


def cmd_simulate(args: argparse.Namespace) -> int:
    from grasping_sym.pipeline import build  # noqa: PLC0415 - lazy: SymPy and CasADi, only to build
    from grasping_sym.viz import kinds as viz_kinds  # noqa: PLC0415 - lazy: matplotlib, only to draw

    params = _params(args.param)
    out = _check_out(args.out)
    _say(f"defining scene {args.name}")
    if args.name.endswith(".toml"):  # a scene file (grasping_sym.model.scene_files)
        from grasping_sym.model.scene_files import load_scene  # noqa: PLC0415 - lazy: SymPy, only for a scene file

        scene = load_scene(args.name)
        missing = [k for k in params if k not in scene.runtime]
        if missing:
            raise UsageError(f"--param {missing}: a scene file's run-time parameters are its "
                             f"runtime = [...] list ({list(scene.runtime)}); add them there")
    else:
        factory = _scene_factory(args.name)
        scene = factory(runtime=tuple(params)) if params else factory()
    t_final, method, rtol, atol = simulate_settings(args, scene)
    _check_run(method, t_final, rtol, atol, args.h)
    project = PROJECT[args.project]
    if project is None and method in ("cvodes", "idas") and scene.simulate_defaults.get("project"):
        raise UsageError(f"--method {method}: {scene.name} holds its contact constraints by projecting its "
                         f"steps, which {method} (SUNDIALS) cannot do: use --method dop853 or radau, or "
                         "give --project off to run it without (its constraints then drift)")
    _check_param_values(scene, params)
    _make_out(out)
    model = build(scene, progress=_say)
    info = model.build_info
    _say(f"simulating {scene.name} for {t_final:g} s with {method}")
    t0 = time.perf_counter()
    # no --method: the model's own, as simulate() takes it (a stiff run falls back to radau)
    result = model.simulate(t_final, method=args.method, rtol=rtol, atol=atol, h=args.h,
                            params=params or None, project=project)
    sim_wall = time.perf_counter() - t0
    csv_path = result.write_csv(out / "trajectory.csv")
    _say(f"writing figures into {out}")
    figures = viz_kinds.write_figures(scene, result, out)

    stats = result.stats
    lines = [
        f"scene            {scene.name}",
        f"build            {info.get('source', '?')}, {info.get('total', float('nan')):.3f} s",
        (f"simulation       {result.method}, t_final {t_final:g} s, "
         f"integration wall {stats.get('wall_time', sim_wall):.4f} s "
         f"(with outputs and checks {sim_wall:.4f} s)"),
        f"steps            {stats.get('n_steps', '?')}",
    ]
    for key in ("Q", "R"):
        if key in result.outputs:
            lines.append(f"max |{key}|{'':<10}{float(abs(result.outputs[key]).max()):.3e} m")
    for key in ("s", "u0", "u1"):
        if key in result.state_names:
            lines.append(f"final {key:<11}{float(result[key][-1]):.6e}")
    lines += viz_kinds.summary_lines(scene, result)
    lines.append(f"trajectory       {csv_path}")
    if len(figures) <= 6:
        lines += [f"figure           {path}" for path in figures]
    lines.append(f"figures          {len(figures)} PNG files in {out}")
    print("\n".join(lines))
    return 0


def _params(texts) -> dict[str, float]:
    """``NAME=VALUE`` pairs (numbers parsed as numbers, nothing evaluated)."""
    out = {}
    for text in texts or ():
        name, sep, value = text.partition("=")
        try:
            v = float(value)
        except ValueError:
            v = math.nan
        if not sep or not name.strip() or not math.isfinite(v):
            raise UsageError(f"--param {text!r}: write NAME=VALUE with a finite number, e.g. fd=0.8")
        if name.strip() in out:
            raise UsageError(f"--param {name.strip()}: given twice ({out[name.strip()]:g} and {v:g}); "
                             "give each parameter once")
        out[name.strip()] = v
    return out


# ---------------------------------------------------------------------------- cache
def cmd_cache(args: argparse.Namespace) -> int:


    root = cache.cache_root()
    if args.action == "clear":
        removed = cache.clear(args.names)  # refuses a root holding what the package did not make
        for p in removed:
            print(f"removed {p}")
        print(f"{len(removed)} entries removed from {root}")
        return 0
    if not root.exists():
        print(f"{root}: empty (no cache yet)")
        return 0
    safety.check_dir(root)  # another user's, or writable by others: refused by name
    made, foreign = cache.entries(root)
    made = cache.select(made, args.names, root)  # only the entries named (unknown ones refused)
    total = 0
    for p in made:
        size = sum(os.lstat(f).st_size for f in p.rglob("*") if not f.is_symlink() and f.is_file())
        total += size
        print(f"{p.name:<40} {size / 1e6:9.2f} MB")
    print(f"{len(made)} entries, {total / 1e6:.2f} MB in {root}")
    if foreign:
        print(f"{len(foreign)} other files or directories there that grasping_sym did not make "
              f"({', '.join(p.name for p in foreign[:5])}{', ...' if len(foreign) > 5 else ''}): "
              "`cache clear` refuses this root; point GRASPING_SYM_CACHE at a directory of its own")
    return 0


# ---------------------------------------------------------------------------- sweep
def _check_show(show: str, scene) -> None:
    """``--show``: a final state, ``settle_<state or output>``, ``min_``/``max_<...>``, or
    ``failure`` (what the sweep's store will hold)."""
    from grasping_sym.viz.sweep_plots import FAILURE  # noqa: PLC0415 - lazy: matplotlib, only to draw

    quantities = (*scene.state_names, *getattr(scene, "outputs", ()))
    known = [*scene.state_names, FAILURE] + [f"{kind}_{q}" for kind in ("settle", "min", "max")
                                             for q in quantities]
    if show not in known:
        outputs = quantities[len(scene.state_names):]
        example = "f" if "f" in outputs else (outputs or scene.state_names)[0]
        raise UsageError(f"--show {show!r}: show a final state ({', '.join(scene.state_names[:8])}"
                         f"{', ...' if len(scene.state_names) > 8 else ''}), settle_<state>, "
                         f"min_<output> or max_<output> (e.g. settle_{scene.state_names[0]}, min_{example}; "
                         f"outputs: {', '.join(outputs)}), or {FAILURE}")


def cmd_sweep(args: argparse.Namespace) -> int:
    from grasping_sym.pipeline import build  # noqa: PLC0415 - lazy: SymPy and CasADi, only to build
    from grasping_sym.viz.sweep_plots import FAILURE, sweep_figure  # noqa: PLC0415 - lazy: matplotlib, only to draw

    try:
        axes = [parse_range(text) for text in args.param]
    except ValueError as exc:
        raise UsageError(str(exc)) from None
    grid = dict(axes)
    if len(grid) < len(axes):
        raise UsageError(f"--param: each name once, got {[k for k, _ in axes]}")
    if not grid:
        raise UsageError("give at least one --param NAME=START:STOP:NUM")
    if len(grid) > 2:
        raise UsageError(f"--param: {len(grid)} axes ({', '.join(grid)}), the figure shows one or two; "
                         "sweep more with gs.sweep in Python")
    out = _check_out(args.out)
    factory = _scene_factory(args.name)
    probe = factory()
    runtime = tuple(k for k in grid if not (k.endswith("_0") and k[:-2] in probe.state_names)
                    and k not in getattr(probe, "input_names", ()))
    scene = factory(runtime=runtime) if runtime else probe
    show = args.show or ("theta" if "theta" in scene.state_names else scene.state_names[0])
    _check_show(show, scene)
    _check_run(args.method, args.t_final, args.rtol, args.atol)
    _check_param_values(scene, {k: v for k, v in grid.items() if k in runtime})
    check_store(out / "sweep.zarr")
    _make_out(out)
    model = build(scene, progress=_say)
    kind, _, quantity = show.partition("_")
    # the same measures whatever is shown, so that another --show reads the same store
    measures = ["settle:theta"] if "theta" in model.state_names else []
    measures += [f"min:{f}" for f in model.output_names if f == "f" or f[:1] == "f" and f[1:].isdigit()]
    if kind in ("min", "max", "settle") and quantity and f"{kind}:{quantity}" not in measures:
        measures.append(f"{kind}:{quantity}")
    n = int(np.prod([len(v) for v in grid.values()]))
    _say(f"sweeping {scene.name} over {' x '.join(f'{k} ({len(v)})' for k, v in grid.items())} = "
         f"{n} runs of {args.t_final:g} s")
    t0 = time.perf_counter()
    ds = sweep(model, grid, args.t_final, store=out / "sweep.zarr", measures=measures,
               method=args.method, rtol=args.rtol, atol=args.atol, chunk=args.chunk,
               client="processes" if args.processes else None, progress=not args.quiet)
    wall = time.perf_counter() - t0
    figure = sweep_figure(ds, show, out / f"{show}.png")
    status = ds["status"].values
    codes, counts = np.unique(status[status != 0], return_counts=True)
    lines = [f"scene            {scene.name}",
             f"points           {n} ({int((status == 0).sum())} ok"
             + "".join(f", {c} with status {k}" for k, c in zip(codes, counts)) + ")",
             f"run now          {ds.attrs['chunks_run']} of {ds.attrs['chunks_total']} chunks "
             f"({ds.attrs['chunks_total'] - ds.attrs['chunks_run']} were stored already)",
             f"wall time        {wall:.2f} s",
             f"store            {out / 'sweep.zarr'} (group {ds.attrs['group']})",
             f"figure           {figure}" + ("" if show != FAILURE else " (failures)")]
    print("\n".join(lines))
    return 0


# ---------------------------------------------------------------------------- generate
# Regenerates the committed C of built-in scenes (generated/<name>/) or, with --check,
# verifies it is up to date (grasping_sym.pipeline.generate_committed).
def cmd_generate(args: argparse.Namespace) -> int:
    from grasping_sym.pipeline import generate_committed  # noqa: PLC0415 - lazy: SymPy and CasADi, only to generate

    names = sorted(_builtin()) if args.all or not args.names else list(args.names)
    for name in names:
        _scene_factory(name)  # validates the name
    _say(f"{'checking' if args.check else 'generating'} the planar templates, structures and "
         f"{', '.join(names)} (derivation with SymPy)")
    differ = generate_committed(names, check=args.check)
    stale = False
    for name in ["templates", "structures", *names]:
        files = differ.get(name, {})
        if not files:
            print(f"{name}: up to date")
        elif args.check:
            stale = True
            print(f"{name}: out of date: {', '.join(files)} (run `{PROG} generate {name}`)")
            for diff in files.values():
                print(diff)
        else:
            print(f"{name}: regenerated {', '.join(files)}")
    return 1 if stale else 0


# `bench` runs the benchmark suite of the source tree (benchmarks/ is not installed with the
# package: it needs the repository, like `make bench`).
def cmd_bench(args: argparse.Namespace) -> int:

    root = Path(__file__).resolve().parent.parent
    if not (root / "benchmarks" / "run.py").is_file():
        raise UsageError(f"no benchmarks/ beside the package at {root}: the benchmarks ship with the "
                         "source repository; run `grasping-sym bench` from an editable install of a "
                         "clone (pip install -e .)")
    opts = (["--quick"] if args.quick else []) + (["--only", args.only] if args.only else []) + \
        (["--out", args.out] if args.out else [])
    cmd = [sys.executable, "-m", "benchmarks.run", *opts]
    _say(f"running {' '.join(cmd[1:])} in {root}")
    return subprocess.call(cmd, cwd=root)


# ---------------------------------------------------------------------------- parser
def make_parser() -> argparse.ArgumentParser:
    parser = _Parser(
        prog=PROG,
        description="Rolling contact between smooth shapes: build, simulate and plot scenes.",
    )

    parser.add_argument("--version", action="version", version=f"{PROG} {__version__}")
    sub = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")

    p = sub.add_parser("list", help="list the built-in scenes")
    p.set_defaults(func=cmd_list)

    p = sub.add_parser("simulate", help="build a scene, simulate it, write CSV and figures")
    p.add_argument("name", metavar="NAME", help="built-in scene (see `list`), or a scene file "
                                                "(.toml: grasping_sym.model.scene_files)")
    p.add_argument("--t-final", type=_positive_float, default=None,
                   help=f"simulated time in s (default 3 for 2D scenes, 5 for 3D scenes; at most "
                        f"{MAX_T_FINAL:g})")
    p.add_argument("--out", required=True, help="output directory (created if missing)")
    p.add_argument("--method", choices=METHODS, default=None,
                   help="integrator (default the scene's: radau for 2D scenes, dop853 for 3D grasps)")
    p.add_argument("--project", choices=tuple(PROJECT), default="default",
                   help="projection onto the contact constraints: 'steps' after every step, 'rows' at "
                        "every output row too, 'off' none; default the scene's ('steps' for a 3D "
                        "grasp without a stabilisation gain, else none)")
    p.add_argument("--rtol", type=_positive_float, default=None,
                   help="relative tolerance of the adaptive integrators (default the scene's for "
                        "its method, else the method's own)")
    p.add_argument("--atol", type=_positive_float, default=None,
                   help="absolute tolerance of the adaptive integrators (default the scene's for "
                        "its method, else the method's own)")
    p.add_argument("--h", type=_positive_float, default=1e-4,
                   help="fixed step of rk4 in s (default 1e-4)")
    p.add_argument("--param", action="append", default=[], metavar="NAME=VALUE",
                   help="a scene parameter's value for this run (made a run-time parameter: no "
                        "rebuild for the next value), e.g. --param fd=0.8; repeat for more")
    p.set_defaults(func=cmd_simulate)

    p = sub.add_parser("sweep", help="simulate a scene over a grid of parameters and starting poses, "
                                     "store the results (Zarr) and draw a heat map",
                       description="Runs every point of the grid (the Cartesian product of the --param "
                                   "ranges) with simulate_many on Dask, stores the results in "
                                   "OUT/sweep.zarr (a rerun resumes) and draws --show over the grid.")
    p.add_argument("name", metavar="NAME", help="built-in scene (see `list`)")
    p.add_argument("--param", action="append", default=[], metavar="NAME=START:STOP:NUM",
                   help="a grid axis: a run-time parameter (e.g. fd), a starting pose value "
                        "(e.g. q1_0) or an input; NUM values from START to STOP, or V1,V2,...; "
                        "repeat for more axes")
    p.add_argument("--t-final", type=_positive_float, default=3.0,
                   help=f"simulated time in s (default 3; at most {MAX_T_FINAL:g})")
    p.add_argument("--out", required=True, help="output directory (created if missing)")
    p.add_argument("--show", default=None,
                   help="what the figure shows: a final state (e.g. theta, the default), "
                        "settle_<state> (settling time), min_<output> (e.g. min_f, the smallest "
                        "normal force), max_<output>, or failure")
    p.add_argument("--method", choices=("radau", "dopri5", "dop853", "rk4"), default=None,
                   help="integrator (default: the model's own, as simulate_many's: radau in 2D, dop853 "
                        "for a 3D grasp)")
    p.add_argument("--rtol", type=_positive_float, default=None,
                   help="relative tolerance (default: the method's, radau 1e-6)")
    p.add_argument("--atol", type=_positive_float, default=None,
                   help="absolute tolerance (default: the method's, radau 1e-9)")
    p.add_argument("--chunk", type=_positive_int, default=None,
                   help="runs per Dask task (default: about 8 tasks per thread, 1000 to 20000 runs)")
    p.add_argument("--processes", action="store_true",
                   help="run on a local cluster of worker processes (default: threads here)")
    p.add_argument("--quiet", action="store_true", help="no progress bar")
    p.set_defaults(func=cmd_sweep)

    p = sub.add_parser("generate", help="regenerate (or --check) the committed C of built-ins")
    p.add_argument("names", nargs="*", metavar="NAMES", help="scenes (default: all)")
    p.add_argument("--all", action="store_true", help="every built-in scene")
    p.add_argument("--check", action="store_true",
                   help="only check that generated/<name>/ is up to date")
    p.set_defaults(func=cmd_generate)

    p = sub.add_parser("bench", help="run the benchmarks, write benchmarks/results/ (as `make bench`)",
                       description="Runs `python -m benchmarks.run` in the source checkout: build "
                                   "stages, rhs costs and work-precision of paper2d and paper3d "
                                   "against the peers (about 9 minutes; --quick about 2). The other "
                                   "benchmarks: `make bench-control`, `make bench-batch`.")
    p.add_argument("--quick", action="store_true", help="fewer settings and repeats (a smoke test)")
    p.add_argument("--only", choices=("paper2d", "paper3d"), default=None,
                   help="the benchmarks of one scene only (default: both)")
    p.add_argument("--out", default=None,
                   help="output directory (default benchmarks/results, or results/quick)")
    p.set_defaults(func=cmd_bench)

    p = sub.add_parser("cache", help="list or clear the cache of built models",
                       description="The cache root is $GRASPING_SYM_CACHE, else "
                                   "$XDG_CACHE_HOME/grasping_sym (~/.cache/grasping_sym).")
    p.add_argument("action", choices=("list", "clear"), help="list the entries, or remove them")
    p.add_argument("names", nargs="*", metavar="NAME",
                   help="clear: only these entries (a directory name, or a scene name for all its "
                        "builds); default every entry")
    p.set_defaults(func=cmd_cache)
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    """Entry point of ``grasping-sym``; returns the exit code."""
    parser = make_parser()
    try:
        args = parser.parse_args(argv)
        return args.func(args)
    except (GraspingSymError, ValueError) as exc:  # refused by name: the message, no traceback
        print(f"{PROG}: error: {_one_line(exc)}", file=sys.stderr)
        return EXIT_USER_ERROR


def _one_line(exc: Exception) -> str:
    """The message of ``exc`` on one line (a list of problems joined), except a compiler's
    output, which keeps its lines."""
    text = str(exc)
    if isinstance(exc, CompileError):
        return text
    return " ".join(part.strip() for part in text.splitlines() if part.strip())


if __name__ == "__main__":
    sys.exit(main())
