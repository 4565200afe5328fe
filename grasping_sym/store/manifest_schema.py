"""The schema of ``manifest.json``: every key the runtime reads, with its type and what it
must agree with. A manifest that fails it is never used: the build regenerates the model,
``gs.load`` refuses it by name.

Written out here rather than as a JSON Schema for ``jsonschema``: that package's import alone
takes 42 ms, about half of ``gs.load``'s budget, and the checks that matter most are across
keys (sizes agree with names, states' bounds, identifiers that become C macros), which a
schema language states no more clearly than these lines.
"""
from __future__ import annotations

import math
import re

from grasping_sym.names import name_problems

__all__ = ["manifest_problems"]

_IDENT = re.compile(r"[A-Za-z_][A-Za-z0-9_]*\Z", re.ASCII)
_HEX64 = re.compile(r"[0-9a-f]{64}\Z")
_FILE = re.compile(r"[A-Za-z0-9][A-Za-z0-9_.-]*\.[ch]\Z", re.ASCII)


def _is_num(v) -> bool:
    return isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v)


def _strings(m: dict, key: str, out: list[str], ident: bool = False) -> list:
    v = m.get(key)
    if not isinstance(v, list) or not all(isinstance(s, str) for s in v):
        out.append(f"{key} must be a list of strings")
        return []
    if ident and not all(_IDENT.match(s) for s in v):
        out.append(f"{key} must hold C identifiers")
    return v


def manifest_problems(m: object) -> list[str]:
    """Every way ``m`` is not a valid manifest (empty when it is)."""
    if not isinstance(m, dict):
        return ["the manifest is not a JSON object"]
    out: list[str] = []
    if not isinstance(m.get("name"), str) or name_problems(m["name"]):
        out.append(f"name {m.get('name')!r} is not a valid scene name")
    if not isinstance(m.get("hash"), str) or not _HEX64.match(m["hash"]):
        out.append("hash must be 64 lower-case hex digits")
    states = _strings(m, "state_names", out, ident=True)
    if not states:
        out.append("state_names must not be empty")
    outputs = _strings(m, "output_names", out, ident=True)
    hidden = m.get("check_outputs", [])
    if not isinstance(hidden, list) or not all(isinstance(k, str) for k in hidden) \
            or not set(hidden) <= set(outputs):
        out.append("check_outputs must list output_names the checks read")
    params = _strings(m, "param_names", out, ident=True)
    starts = _strings(m, "start_param_names", out, ident=True)
    inputs = _strings(m, "input_names", out, ident=True)
    charts = _strings(m, "chart_param_names", out, ident=True) if "chart_param_names" in m else []
    _strings(m, "start_conditions", out)
    _strings(m, "c_symbols", out, ident=True)
    values = m.get("param_values")
    if not isinstance(values, list) or len(values) != len(params) or not all(map(_is_num, values)):
        out.append("param_values must be one finite number per param_names entry")
    bounds = {}
    for key in ("lower", "upper"):
        b = m.get(key)
        if not isinstance(b, list) or len(b) != len(states):
            out.append(f"{key} must be one bound (a finite number or null) per state")
        elif wrong := [f"{key}[{i}] = {v!r} (state {name!r})" for i, (name, v) in enumerate(zip(states, b))
                       if not (v is None or _is_num(v))]:
            out.append(f"{', '.join(wrong[:5])}: each bound must be a finite number or null")
        else:
            bounds[key] = b
    if len(bounds) == 2:  # a NaN or an empty interval would turn the domain check off
        for name, lo, hi in zip(states, bounds["lower"], bounds["upper"]):
            if lo is not None and hi is not None and not lo < hi:
                out.append(f"the bounds of state {name!r} are inverted or empty: lower = {lo!r}, "
                           f"upper = {hi!r}")
    files = m.get("files")
    if not isinstance(files, list) or not files or \
            not all(isinstance(f, str) and _FILE.match(f) for f in files):
        out.append("files must list the model's .c and .h files by plain name")
    d = m.get("driver_defines")
    if not isinstance(d, dict):
        out.append("driver_defines must be an object")
    else:
        for k, v in d.items():
            if not _IDENT.match(str(k)) or not (isinstance(v, int) and not isinstance(v, bool)
                                                or isinstance(v, str) and _IDENT.match(v)):
                out.append(f"driver_defines[{k!r}] = {v!r}: names and values must be C identifiers "
                           "or integers")
        if d.get("GS_NX") != len(states):
            out.append(f"driver_defines GS_NX = {d.get('GS_NX')!r}, but there are {len(states)} states")
        # p: the run-time parameters, the start's, each input's a and b (u = a + b t), then the
        # charts of the surfaces with atlases (geometry.atlas)
        n_p = len(params) + len(starts) + 2 * len(inputs) + len(charts)
        if d.get("GS_NP") != n_p:
            out.append(f"driver_defines GS_NP = {d.get('GS_NP')!r}, but the parameters, the start's, "
                       f"two per input and the charts make {n_p}")
        for k in ("GS_RHS", "GS_SZ_ARG", "GS_SZ_RES", "GS_SZ_IW", "GS_SZ_W"):
            if k not in d:
                out.append(f"driver_defines lacks {k}")
    c = m.get("constraints")
    if not isinstance(c, dict):
        out.append("constraints must be an object")
    else:
        for k in ("names", "position_states", "velocity_states"):
            v = c.get(k)
            if not isinstance(v, list) or not all(isinstance(s, str) for s in v):
                out.append(f"constraints.{k} must be a list of strings")
            elif k != "names" and not set(v) <= set(states):
                out.append(f"constraints.{k} names states the model does not have")
    s = m.get("structure")
    if s is not None and not (isinstance(s, dict) and isinstance(s.get("name"), str)
                              and _IDENT.match(s["name"]) and isinstance(s.get("hash"), str)
                              and _HEX64.match(s["hash"])):
        out.append("structure must be {name: a C identifier, hash: 64 hex digits}")
    libs = m.get("libraries", {})
    if not isinstance(libs, dict) or not all(isinstance(k, str) and "/" not in k and isinstance(v, str)
                                             and _HEX64.match(v) for k, v in libs.items()):
        out.append("libraries must map library file names to SHA-256 digests")
    for key in ("rewrites", "op_counts", "hash_inputs"):
        if not isinstance(m.get(key), dict):
            out.append(f"{key} must be an object")
    guard = m.get("rhs_guarded")
    if guard is not None and not (isinstance(guard, str) and _IDENT.match(guard)
                                  and guard in m.get("c_symbols", [])):
        out.append("rhs_guarded must name one of the model's C symbols")
    folded = m.get("outputs_folded")
    if folded is not None and not (isinstance(folded, str) and folded in m.get("c_symbols", [])):
        out.append("outputs_folded must name one of the model's C symbols")
    modes = m.get("folded_modes")
    if modes is not None and not (isinstance(modes, list) and len(modes) == m.get("n_contacts")
                                  and all(type(v) is int and v in (0, 1, 2) for v in modes)):
        out.append("folded_modes must list each contact's mode (n_contacts integers: 0 rolling, 1 sliding, "
                   "2 separated)")
    if folded is not None and modes is None:
        out.append("outputs_folded needs folded_modes (the modes it folds in)")
    internal = m.get("internal_outputs")
    if internal is not None and not (
            isinstance(internal, dict) and set(internal) == {"function", "names"}
            and isinstance(internal["function"], str) and internal["function"] in m.get("c_symbols", [])
            and isinstance(internal["names"], list) and internal["names"]
            and all(isinstance(k, str) and _IDENT.match(k) for k in internal["names"])):
        out.append("internal_outputs must be {function: one of the model's C symbols, names: "
                   "identifiers}")
    rules = m.get("param_rules", {})
    if not isinstance(rules, dict) or not set(rules) <= set(params) or \
            not set(rules.values()) <= {"positive", "nonnegative", "finite"}:
        out.append("param_rules must map run-time parameters to positive, nonnegative or finite")
    hold = m.get("start_hold", [])
    if not isinstance(hold, list) or not set(hold) <= set(states):
        out.append("start_hold must list states of the model")
    defaults = m.get("defaults")
    if defaults is not None and not (
            isinstance(defaults, dict) and set(defaults) == {"method", "rtol", "atol", "project"}
            and isinstance(defaults["method"], str) and _IDENT.match(defaults["method"])
            and all(v is None or (_is_num(v) and 0 < v < 1) for v in (defaults["rtol"], defaults["atol"]))
            and isinstance(defaults["project"], bool)):
        out.append("defaults must be {method: a method's name, rtol, atol: numbers in (0, 1) or null, "
                   "project: true or false}")
    rolling = m.get("rolling_map")
    if rolling is not None and not (
            isinstance(rolling, dict) and set(rolling) == {"to", "from"}
            and all(isinstance(v, list) and all(isinstance(i, int) and not isinstance(i, bool) for i in v)
                    for v in rolling.values())
            and len(rolling["from"]) == len(states) and all(0 <= i < len(states) for i in rolling["to"])
            and all(0 <= i < len(rolling["to"]) for i in rolling["from"])):
        out.append("rolling_map must be {to: indices of the states, from: one index of the rolling "
                   "model's states per state}")
    return out
