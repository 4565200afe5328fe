"""The files of a built model's directory that the runtime reads: no SymPy, no code generation.

- ``manifest.json``: what the C is (names, sizes, domains, how to compile it) and the content
  hash of the exact inputs it was generated from. A function of exact inputs only, so it is
  byte-identical on every machine.
- ``start.json``: the start layer, numbers solved numerically from the scene's start (the
  consistent initial state and the values of the run-time parameters the start fixes, e.g. the
  2D pivot ``Om``). Solves go through BLAS and libm, whose last digits differ between CPUs, so
  these numbers are kept apart from the manifest and compared with a tolerance
  (``START_RTOL``), never byte for byte. The build cache keeps one start per scene definition
  under ``starts/<key>.json``; ``start.json`` is the latest built (``grasping_sym.load``'s
  default).
"""
from __future__ import annotations

import json
import math
from pathlib import Path

from grasping_sym.store import safety

MANIFEST = "manifest.json"
START = "start.json"
STARTS_DIR = "starts"
#: Relative tolerance of two solved starts that count as the same (on top of an absolute
#: 1e-12 for entries near zero): far above the last-digit differences between CPUs.
START_RTOL = 1e-9
START_ATOL = 1e-12


def write_json(path: Path, data: dict) -> Path:
    """Write ``data`` as stable JSON (sorted keys), atomically and never through a link
    (``safety.write_text``); the directory must exist."""
    return safety.write_text(Path(path), json.dumps(data, indent=2, sort_keys=True) + "\n")


def read_json(path: Path) -> dict | None:
    """The JSON object in ``path``, or None when absent or unreadable."""
    try:
        data = json.loads(Path(path).read_text())
    except (OSError, ValueError):
        return None
    return data if isinstance(data, dict) else None


def read_manifest(directory: Path) -> dict | None:
    return read_json(Path(directory) / MANIFEST)


def write_manifest(directory: Path, manifest: dict) -> Path:
    return write_json(Path(directory) / MANIFEST, manifest)


def start_record(x0, values: dict[str, float], key: str, info: dict | None = None) -> dict:
    """The content of a start file: the initial state, the start's parameter values, the
    hash ``key`` of the scene definition it was solved for, and what the solver reports."""
    return {"key": key, "initial_state": [float(v) for v in x0],
            "start_params": {k: float(v) for k, v in values.items()}, "info": dict(info or {})}


def _finite(v) -> bool:
    return isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v)


def start_problems(start: dict, manifest: dict) -> list[str]:
    """Every way the start record ``start`` does not fit the model of ``manifest`` (empty
    when it fits): a ``key`` string, one finite ``initial_state`` entry per state, and a
    finite number in ``start_params`` for each of the manifest's ``start_param_names``."""
    out = []
    if not isinstance(start.get("key"), str) or not start["key"]:
        out.append(f"key = {start.get('key')!r} is not the scene definition's hash (a string)")
    states = manifest.get("state_names", [])
    x0 = start.get("initial_state")
    if not isinstance(x0, list) or len(x0) != len(states):
        got = f"{len(x0)} entries" if isinstance(x0, list) else f"a {type(x0).__name__}"
        out.append(f"initial_state is {got}: expected a list of {len(states)} numbers, one per state")
    elif wrong := [f"initial_state[{i}] = {v!r} (state {name!r})"
                   for i, (name, v) in enumerate(zip(states, x0)) if not _finite(v)]:
        out.append(f"{', '.join(wrong[:5])}{' ...' if len(wrong) > 5 else ''}: each entry must be a "
                   "finite number")
    values = start.get("start_params")
    names = manifest.get("start_param_names", [])
    if not isinstance(values, dict):
        out.append(f"start_params is a {type(values).__name__}, not an object mapping "
                   f"{names} to numbers")
    else:
        if missing := [k for k in names if k not in values]:
            out.append(f"start_params lacks {missing}")
        if wrong := [f"start_params[{k!r}] = {values[k]!r}" for k in names
                     if k in values and not _finite(values[k])]:
            out.append(f"{', '.join(wrong)}: each value must be a finite number")
    if not isinstance(start.get("info", {}), dict):
        out.append("info must be an object")
    return out


def starts_agree(a: dict, b: dict) -> list[str]:
    """Where two start records differ beyond ``START_RTOL`` (empty when they agree)."""
    problems = []
    xa, xb = a.get("initial_state", []), b.get("initial_state", [])
    pa, pb = a.get("start_params", {}), b.get("start_params", {})
    if len(xa) != len(xb) or sorted(pa) != sorted(pb):
        return [f"different shapes: {len(xa)} vs {len(xb)} states, params {sorted(pa)} vs {sorted(pb)}"]
    pairs = [(f"initial_state[{i}]", u, v) for i, (u, v) in enumerate(zip(xa, xb))]
    pairs += [(f"start_params[{k}]", pa[k], pb[k]) for k in sorted(pa)]
    for label, u, v in pairs:
        if not math.isclose(u, v, rel_tol=START_RTOL, abs_tol=START_ATOL):
            problems.append(f"{label}: {u!r} vs {v!r}")
    return problems
