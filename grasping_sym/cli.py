"""Command line: ``grasping-sym list | simulate | generate``.

Errors raised on purpose by the package (``GraspingSymError``) are printed as one message
on stderr with exit code 2, without a traceback. Progress of slow stages (deriving,
compiling, simulating, plotting) goes to stderr, results to stdout.
"""
from __future__ import annotations

import argparse
import math
import sys
import time
from collections.abc import Sequence
from pathlib import Path

from grasping_sym.errors import GraspingSymError
from grasping_sym.runtime.integrators import METHODS

PROG = "grasping-sym"
EXIT_USER_ERROR = 2


class UsageError(GraspingSymError):
    """A bad command-line value (unknown scene name, non-positive time, ...)."""


def _say(msg: str) -> None:
    print(f"[{PROG}] {msg}", file=sys.stderr, flush=True)


def _builtin() -> dict:
    from grasping_sym.scenes import BUILTIN  # lazy: keeps `--help` fast

    return BUILTIN


def _describe(func) -> str:
    doc = (func.__doc__ or "").strip()
    return doc.splitlines()[0] if doc else "(no description)"


def _scene_factory(name: str):
    scenes = _builtin()
    if name not in scenes:
        raise UsageError(f"unknown scene {name!r}: known scenes are {', '.join(sorted(scenes))} "
                         f"(see `{PROG} list`)")
    return scenes[name]


def _positive_float(text: str) -> float:
    try:
        v = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not a number") from None
    if not (math.isfinite(v) and v > 0):
        raise argparse.ArgumentTypeError(f"{text!r} must be a finite number > 0")
    return v


# ---------------------------------------------------------------------------- commands
def cmd_list(args: argparse.Namespace) -> int:
    scenes = _builtin()
    width = max(len(n) for n in scenes)
    for name, func in scenes.items():
        print(f"{name:<{width}}  {_describe(func)}")
    return 0


def cmd_simulate(args: argparse.Namespace) -> int:
    from grasping_sym.pipeline import build
    from grasping_sym.plots import write_figures

    factory = _scene_factory(args.name)
    _say(f"defining scene {args.name}")
    scene = factory()
    model = build(scene, progress=_say)
    info = model.build_info
    _say(f"simulating {scene.name} for {args.t_final:g} s with {args.method}")
    t0 = time.perf_counter()
    result = model.simulate(args.t_final, method=args.method, rtol=args.rtol, atol=args.atol,
                            h=args.h)
    sim_wall = time.perf_counter() - t0
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    csv_path = result.write_csv(out / "trajectory.csv")
    _say(f"writing figures into {out}")
    figures = write_figures(scene, result, out)

    stats = result.stats
    lines = [
        f"scene            {scene.name}",
        f"build            {info.get('source', '?')}, {info.get('total', float('nan')):.3f} s",
        (f"simulation       {result.method}, t_final {args.t_final:g} s, "
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
    lines.append(f"trajectory       {csv_path}")
    lines.append(f"figures          {len(figures)} PNG files in {out}")
    print("\n".join(lines))
    return 0


# ---------------------------------------------------------------------------- generate
# Regenerates the committed C of built-in scenes (generated/<name>/) or, with --check,
# verifies it is up to date (grasping_sym.pipeline.generate_committed).
def cmd_generate(args: argparse.Namespace) -> int:
    from grasping_sym.pipeline import generate_committed

    names = sorted(_builtin()) if args.all or not args.names else list(args.names)
    for name in names:
        _scene_factory(name)  # validates the name
    _say(f"{'checking' if args.check else 'generating'} the planar templates and "
         f"{', '.join(names)} (derivation with SymPy)")
    differ = generate_committed(names, check=args.check)
    stale = False
    for name in ["templates", *names]:
        files = list(differ.get(name, [])) if isinstance(differ, dict) else []
        if not files:
            print(f"{name}: up to date")
        elif args.check:
            stale = True
            print(f"{name}: out of date: {', '.join(files)} (run `{PROG} generate {name}`)")
        else:
            print(f"{name}: regenerated {', '.join(files)}")
    return 1 if stale else 0


# ---------------------------------------------------------------------------- parser
def make_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog=PROG,
        description="Rolling contact between smooth shapes: build, simulate and plot scenes.",
    )
    sub = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")

    p = sub.add_parser("list", help="list the built-in scenes")
    p.set_defaults(func=cmd_list)

    p = sub.add_parser("simulate", help="build a scene, simulate it, write CSV and figures")
    p.add_argument("name", metavar="NAME", help="built-in scene (see `list`)")
    p.add_argument("--t-final", type=_positive_float, default=3.0,
                   help="simulated time in s (default 3)")
    p.add_argument("--out", required=True, help="output directory (created if missing)")
    p.add_argument("--method", choices=METHODS, default="cvodes",
                   help="integrator (default cvodes)")
    p.add_argument("--rtol", type=_positive_float, default=1e-10,
                   help="relative tolerance of cvodes/idas (default 1e-10)")
    p.add_argument("--atol", type=_positive_float, default=1e-12,
                   help="absolute tolerance of cvodes/idas (default 1e-12)")
    p.add_argument("--h", type=_positive_float, default=1e-4,
                   help="fixed step of rk4 in s (default 1e-4)")
    p.set_defaults(func=cmd_simulate)

    p = sub.add_parser("generate", help="regenerate (or --check) the committed C of built-ins")
    p.add_argument("names", nargs="*", metavar="NAMES", help="scenes (default: all)")
    p.add_argument("--all", action="store_true", help="every built-in scene")
    p.add_argument("--check", action="store_true",
                   help="only check that generated/<name>/ is up to date")
    p.set_defaults(func=cmd_generate)
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    """Entry point of ``grasping-sym``; returns the exit code."""
    args = make_parser().parse_args(argv)
    try:
        return args.func(args)
    except GraspingSymError as exc:
        print(f"{PROG}: error: {exc}", file=sys.stderr)
        return EXIT_USER_ERROR


if __name__ == "__main__":
    sys.exit(main())
