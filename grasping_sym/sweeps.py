"""Parameter sweeps on Dask, stored in Zarr, that resume where they stopped: ``gs.sweep``
(``gs.sweep.points``, ``gs.sweep.open``).

``sweep(model, {"fd": np.linspace(0.2, 1, 50), "q1_0": np.linspace(0.55, 0.7, 50)}, 3.0,
store="sweep.zarr")`` runs every point of the grid and returns an ``xarray.Dataset`` with one
dimension per grid name.

- **Grid names**: ``mu`` (the contacts' friction coefficient) and, for a model with contact
  modes, ``e`` (the restitution at impacts); run-time parameters (``model.param_names``) and
  the start's run-time values
  (``model.start_params``); ``<state>_0``, a starting pose value (``q1_0``, ``theta_0``: the
  start solved with that state held, as ``Model.with_start``, no rebuild); the inputs
  (``u1``, ...: constant torques of a model with inputs). A mapping of names to 1-D values is
  their Cartesian product; ``points({...})`` is a list of points (equal-length arrays,
  dimension ``point``).
- **Variables**: the final states (named as the states), the outputs asked for (their final
  values), the measures asked for along the run (``"min:f"``, ``"max:theta"``,
  ``"settle:theta"``: the settling time, from which on the quantity stays within
  ``settle_tol`` of its final value, on ``samples`` output times), ``status`` (0, or
  ``runtime.batch.STATUS``'s code; ``START`` when the pose cannot be reached) and ``error``
  (the message, ``""`` on success).
- **Runs** go in chunks of ``chunk`` points (default ``default_chunk``) to ``Model.simulate_many``,
  one task each, on Dask: in this process on a thread per core by default (no cluster
  needed), on local worker processes with ``client="processes"``, or on any
  ``dask.distributed.Client``. The model reaches the workers pickled
  (``runtime.portable``: no shared filesystem needed).
- **The store**: a Zarr group in ``store`` named by the hash of the model, its start, the grid,
  the settings and the variables; only this process writes it, a chunk's values first and
  then its flag in ``done``. Rerunning the same sweep skips the chunks done (a sweep stopped
  by Ctrl-C, a crash or a lost worker resumes), and no point is run twice into the store.
  A chunk marked done whose files are missing or unreadable (deleted, damaged) is run again,
  with a warning. One sweep at a time writes a store: ``<store>.lock`` beside it, locked
  while it writes (``flock``: released when the process ends, however it ends), and a second
  writer is refused by name (``SweepStoreBusyError``). ``open(store)`` reads a sweep back.
"""
from __future__ import annotations

import fcntl
import hashlib
import json
import math
import numbers
import os
import socket
import warnings
from collections.abc import Mapping, Sequence
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path
from types import SimpleNamespace

import numpy as np

from grasping_sym.errors import GraspingSymError, SweepStoreBusyError, SweepStoreError
from grasping_sym.runtime import friction, modes
from grasping_sym.runtime.batch import default_threads
from grasping_sym.runtime.checks import first_crossing
from grasping_sym.runtime.model import Model
from grasping_sym.runtime.settings import run_defaults
from grasping_sym.runtime.start import start_point

#: Points per task by default: about ``TASKS_PER_THREAD`` tasks per worker thread, within
#: ``CHUNK`` (Dask's per-task overhead is 0.2-1 ms, one run ~0.07 ms; each task's results are
#: written by the client, which shares the cores on one machine: fewer, larger tasks cost less,
#: smaller ones resume and report progress in finer steps).
CHUNK = (1000, 20_000)
TASKS_PER_THREAD = 8
#: ``status`` of a point whose starting pose cannot be reached (``UnreachableStartError``).
START = -12
#: Output times per run for the measures along it, by default.
SAMPLES = 301
#: What ``settle:`` measures against, by default (the quantity's unit: rad, m, N).
SETTLE_TOL = 1e-3
_FORMAT = "grasping_sym.sweep/1"
#: The most values ``parse_range`` makes of one ``START:STOP:NUM`` (the command line's axes).
MAX_AXIS = 1_000_000


@dataclass(frozen=True)
class Grid:
    """The points of a sweep: the Cartesian product of ``axes`` (``product``) or a list of
    points (each axis one value per point, dimension ``point``)."""

    names: tuple[str, ...]
    axes: tuple[np.ndarray, ...]
    product: bool

    @property
    def shape(self) -> tuple[int, ...]:
        return tuple(len(a) for a in self.axes) if self.product else (len(self.axes[0]),)

    @property
    def size(self) -> int:
        return int(np.prod(self.shape)) if self.names else 0

    def values(self, a: int, b: int) -> dict[str, np.ndarray]:
        """Every name's value at the points ``a`` to ``b - 1`` (C order over the product)."""
        idx = np.arange(a, b)
        if not self.product:
            return {k: ax[idx] for k, ax in zip(self.names, self.axes)}
        sub = np.unravel_index(idx, self.shape)
        return {k: ax[i] for k, ax, i in zip(self.names, self.axes, sub)}

    def spec(self) -> dict:
        return {"names": list(self.names), "product": self.product,
                "axes": [a.tolist() for a in self.axes]}


def points(values: Mapping[str, Sequence[float]]) -> Grid:
    """A list of points: ``values`` maps each name to one value per point (equal lengths)."""
    names = tuple(values)
    axes = tuple(_axis(k, v) for k, v in values.items())
    if len({len(a) for a in axes}) > 1:
        raise ValueError("points: every name needs one value per point; lengths "
                         + ", ".join(f"{k}: {len(a)}" for k, a in zip(names, axes)))
    return Grid(names, axes, product=False)


def grid_of(grid) -> Grid:
    """``grid`` as a :class:`Grid`: a Grid, or a mapping name -> values (the product)."""
    if isinstance(grid, Grid):
        return grid
    if not isinstance(grid, Mapping) or not grid:
        raise TypeError("grid must map names to values, e.g. {'fd': np.linspace(0.2, 1.0, 50)} "
                        "(their Cartesian product), or be gs.sweep.points({...}) for a list")
    return Grid(tuple(grid), tuple(_axis(k, v) for k, v in grid.items()), product=True)


def _axis(name: str, values) -> np.ndarray:
    arr = np.atleast_1d(np.asarray(values))
    if arr.dtype.kind not in "fiu" or arr.ndim != 1 or arr.size == 0:
        raise ValueError(f"grid[{name!r}] must be a non-empty 1-D array of numbers, got {values!r:.80}")
    arr = arr.astype(float)
    if not np.all(np.isfinite(arr)):
        raise ValueError(f"grid[{name!r}] has non-finite values: give finite numbers")
    return arr


def parse_range(text: str) -> tuple[str, np.ndarray]:
    """``NAME=START:STOP:NUM`` (``NUM`` values from START to STOP) or ``NAME=V1,V2,...``, as the
    command line takes them; the numbers are parsed as numbers, nothing is evaluated."""
    name, sep, rest = text.partition("=")
    name = name.strip()
    if not sep or not name or not rest.strip():
        raise ValueError(f"--param {text!r}: write NAME=START:STOP:NUM or NAME=V1,V2,...")
    try:
        if ":" in rest:
            start, stop, num = rest.split(":")
            n = int(num)
            if not 1 <= n <= MAX_AXIS:
                raise ValueError
            values = np.linspace(float(start), float(stop), n)
        else:
            values = np.array([float(v) for v in rest.split(",")])
    except ValueError:
        raise ValueError(f"--param {text!r}: write NAME=START:STOP:NUM (NUM an integer from 1 to "
                         f"{MAX_AXIS:,}) or "
                         "NAME=V1,V2,... with numbers") from None
    if not np.all(np.isfinite(values)):
        raise ValueError(f"--param {text!r}: the values must be finite numbers (no nan or inf)")
    return name, values


# ------------------------------------------------------------------ what a point is
def _roles(model, names) -> dict[str, tuple[str, str]]:
    """Each grid name's role: ("param", name), ("start", state) or ("input", name)."""
    roles, problems = {}, []
    for k in names:
        if k == "mu":  # the friction law's, before a body's own run-time parameter of that name
            roles[k] = ("mu", k)
        elif k == "e" and model.manifest.get("modes"):
            roles[k] = ("e", k)
        elif k in model.param_names or k in model.start_params:
            roles[k] = ("param", k)
        elif k.endswith("_0") and k[:-2] in model.state_names:
            roles[k] = ("start", k[:-2])
        elif k in model.input_names:
            roles[k] = ("input", k)
        else:
            problems.append(k)
    if problems:
        raise ValueError(
            f"grid names {problems} are not sweepable in {model.name!r}: use run-time parameters "
            f"{list(model.param_names) or '(none: build the scene with runtime=(...))'}, start values "
            f"{list(model.start_params)}, starting poses "
            f"{[s + '_0' for s in model.state_names[:len(model.state_names) // 2]]}..."
            + (f", inputs {list(model.input_names)}" if model.input_names else "")
            + ", or mu (the friction coefficient of every contact)"
            + (", e (the restitution at impacts)" if model.manifest.get("modes") else ""))
    return roles


def _check_values(model, g: Grid, roles) -> None:
    """The run-time parameters' values against the rule the scene sets for each (as
    ``simulate_many`` checks them, but before any task is sent)."""
    rules = model.manifest.get("param_rules", {})
    for k, ax in zip(g.names, g.axes):
        rule = rules.get(k, "finite") if roles[k][0] == "param" else \
            "nonnegative" if roles[k][0] in ("mu", "e") else "finite"
        bad = (ax <= 0) if rule == "positive" else (ax < 0) if rule == "nonnegative" else np.zeros(len(ax), bool)
        if bad.any():
            raise ValueError(f"grid[{k!r}] has {float(ax[bad][0])!r}: {k} must be "
                             f"{'> 0' if rule == 'positive' else '>= 0'} (as the scene requires); "
                             "give physical values")


def _cone_names(model) -> tuple[str, ...]:
    """The friction cone's outputs a run with ``mu`` gains (``runtime.friction.QUANTITIES``)."""
    n = len(friction.contacts(model))
    return tuple(q.format(i=i) for q in friction.QUANTITIES for i in range(1, n + 1))


def _measures(model, outputs, measures, with_mu: bool = False) -> list[tuple[str, str, str]]:
    """``(variable, kind, quantity)`` for every output and measure asked for: ``min:Q``,
    ``max:Q``, ``settle:Q`` of a state, an output or (with a friction coefficient) a cone
    quantity; ``first_slip:<i>`` (contact ``i``, from 1) and ``held``."""
    out, problems = [], []
    cone = _cone_names(model)
    known = (*model.state_names, *model.output_names, *(cone if with_mu else ()))
    n_contacts = int(model.manifest.get("n_contacts", 1)) if model.manifest.get("modes") \
        else len(friction.contacts(model))
    for k in outputs:
        (out.append((k, "final", k)) if k in model.output_names else problems.append(k))
    for m in measures:
        kind, _, q = m.partition(":")
        if m == "held":
            if not (with_mu or model.manifest.get("modes")) or model.manifest.get("kind") == "body":
                problems.append(m)
                continue
            out.append(("held", "held", ""))
        elif kind == "first_slip" and q.isdigit() and 1 <= int(q) <= n_contacts:
            out.append((f"first_slip_{q}", "first_slip", q))
        elif m == "min:epsilon":
            scene = getattr(model, "scene", None)
            free = getattr(scene, "kind", None) == "grasp3d" or (
                getattr(scene, "kind", None) in ("planar", "planar_modes") and scene.free)
            if not with_mu or not hasattr(model, "grasp_quality") or not free:
                problems.append(m)
                continue
            out.append(("min_epsilon", "epsilon", ""))
        elif kind not in ("min", "max", "settle") or q not in known:
            problems.append(m)
        else:
            out.append((f"{kind}_{q}", kind, q))
    if problems:
        raise ValueError(f"sweep: {problems} are not outputs of {model.name!r} "
                         f"({list(model.output_names)}) or measures 'min:Q', 'max:Q', 'settle:Q' "
                         f"of a state or output Q (with mu also of {list(cone[:n_contacts * 4])}), "
                         f"'first_slip:i' (contact i = 1..{n_contacts}, with mu), 'held' (with mu, "
                         "for grasp scenes) or 'min:epsilon' (with mu, for a 3D grasp or a free 2D "
                         "object: the grasp quality's least lower bound along the run)")
    if not with_mu and not model.manifest.get("modes") and any(kind == "first_slip" for _, kind, _ in out):
        raise ValueError("sweep: 'first_slip:i' needs a friction coefficient: give mu=... (or a grid "
                         "axis 'mu'), or build the scene with friction=gs.contact.coulomb(mu)")
    return out


# ------------------------------------------------------------------ one task
def run_chunk(model, task: dict, a: int, b: int) -> dict[str, np.ndarray]:
    """The points ``a`` to ``b - 1`` of a sweep (``task``: the grid, the names' roles, the
    settings): every variable's values, ``status`` and ``error``. Runs on a Dask worker."""
    grid: Grid = task["grid"]
    vals = grid.values(a, b)
    n = b - a
    roles = task["roles"]
    params = {k: v for k, v in vals.items() if roles[k][0] == "param"}
    start_names = [k for k in grid.names if roles[k][0] == "start"]
    status = np.zeros(n, dtype=np.int64)
    error = np.full(n, "", dtype=object)
    x0 = None
    if start_names:
        x0, implied, bad = _starts(model, [(roles[k][1], vals[k]) for k in start_names])
        for k, v in implied.items():
            params[k] = v
        for i, msg in bad.items():
            status[i], error[i] = START, msg
    u = None
    if model.input_names:
        u = np.zeros((n, len(model.input_names)))
        for k, v in vals.items():
            if roles[k][0] == "input":
                u[:, model.input_names.index(k)] = v
    measures = task["measures"]
    settings = _per_run_mu(task["settings"], n)
    for k in ("mu", "e"):
        if k in vals:
            settings[k] = vals[k]
    cone = _cone_names(model)
    sliding = any(kind in ("first_slip", "held") or q in cone for _, kind, q in measures)
    if sliding and not model.manifest.get("modes"):  # the cone's measures read the whole rolling
        settings["slip"] = "record"                   # run: it goes on past a slip
    # the cone is checked at the output times: with a friction coefficient, always on samples
    quality_mu = settings.get("mu")  # the grasp quality's, before the runs take it
    dense = any(kind != "final" for _, kind, _ in measures) or (
        settings.get("mu") is not None and settings.get("checks", True) and not model.manifest.get("modes"))
    t_eval = np.linspace(0.0, task["t_final"], task["samples"]) if dense else None
    batch = model.simulate_many(task["t_final"], x0=x0, params=params or None, u=u, t_eval=t_eval,
                                outputs=(bool(model.output_names) or sliding) and any(
                                    q in model.output_names or q in cone or kind != "final"
                                    for _, kind, q in measures),
                                **settings)
    failed = status == 0
    status[failed] = batch.status[failed]
    error[failed] = batch.errors[failed]
    out = {k: batch.x_final[:, i] for i, k in enumerate(model.state_names)}
    keep = []
    for var, kind, q in measures:
        if kind == "held" and batch.modes is not None:
            out[var] = _held_modes(model, batch)
            keep.append(var)
            continue
        if kind == "held":
            out[var] = _held(model, batch, status, error)
            keep.append(var)
            continue
        if kind == "first_slip" and batch.modes is not None:
            out[var] = _first_slip_modes(batch, int(q))
            continue
        if kind == "first_slip":
            out[var] = _first_crossing(batch.t, batch.outputs[f"cone_margin{q}"])
            continue
        if kind == "epsilon":
            out[var] = _min_epsilon(model, batch, quality_mu, status)
            continue
        series = _series(model, batch, q, dense)
        if kind == "final":
            out[var] = series[:, -1] if series.ndim == 2 else series
        elif kind == "min":
            out[var] = series.min(axis=1)
        elif kind == "max":
            out[var] = series.max(axis=1)
        else:
            out[var] = _settling_time(batch.t, series, task["settle_tol"])
    bad = status != 0
    for k, v in out.items():
        if k not in keep:
            v[bad] = np.nan
    out["status"], out["error"] = status, error
    return out


def _min_epsilon(model, batch, mu, status) -> np.ndarray:
    """Per run, the least lower bound of Ferrari and Canny's epsilon along its samples
    (``BuiltModel.grasp_quality`` of the run, with its friction coefficient);
    NaN for a run that failed. Two 3D contacts that squeeze cost about 1.4 us a sample
    (``quality.two_contacts_squeeze``: epsilon exactly 0); a grasp that may close, or contacts
    that do not squeeze, about 0.5 ms (the hulls): a measure to ask for where it is wanted."""
    out = np.full(len(status), np.nan)
    for i in np.flatnonzero(status == 0):
        run = SimpleNamespace(t=batch.t, x=batch.x[i], state_names=model.state_names, outputs={})
        mu_i = mu if np.ndim(mu) == 0 else np.asarray(mu)[i]
        out[i] = float(np.min(model.grasp_quality(run, mu_i)["epsilon_lower"]))
    return out


def _first_crossing(t: np.ndarray, margin: np.ndarray) -> np.ndarray:
    """Per run, the first time the cone margin reaches 0 (``checks.first_crossing``: linear
    between the samples, the start when it is <= 0 there; ``inf`` when it never does)."""
    hits = (first_crossing(t, row, 0.0) for row in margin)
    return np.array([math.inf if h is None else h[1] for h in hits])


def _held(model, batch, status, error) -> np.ndarray:
    """Per run: 1 when it ended with every contact closed and inside its cone all along (at the
    samples), 0 when a contact opened (``ContactOpenedError``) or left its cone, NaN when the
    run failed otherwise."""
    held = np.full(len(status), np.nan)
    ok = status == 0
    margins = [v for k, v in batch.outputs.items() if k.startswith("cone_margin")]
    inside = np.all([np.all(m > 0, axis=1) for m in margins], axis=0) if margins else np.ones(len(ok), bool)
    held[ok] = inside[ok].astype(float)
    opened = np.array([str(e).startswith("ContactOpenedError") for e in error])
    held[opened] = 0.0
    return held


def _mode_columns(modes) -> np.ndarray:
    """A run's modes as ``(samples, contacts)``."""
    m = np.asarray(modes)
    return m[:, None] if m.ndim == 1 else m


def _held_modes(model, batch) -> np.ndarray:
    """Per run of a model with modes: 1 when no finger contact is open at the end, 0 when one
    is, NaN when the run failed (the world's planes are not fingers)."""
    info = model.manifest.get("grasp_modes") or model.manifest.get("planar_fingers") or {}
    fingers = int(info.get("fingers", 1))
    return np.array([math.nan if m is None or not len(m) else
                     float(not np.any(_mode_columns(m)[-1, :fingers] == "separated"))
                     for m in batch.modes])


def _first_slip_modes(batch, contact: int) -> np.ndarray:
    """Per run of a model with modes: the time contact ``contact`` first slides (its switch's
    located time; the first output time it slides at when it slid from the start), ``inf``
    when it never does, NaN when the run failed."""
    out = []
    for m, events in zip(batch.modes, batch.events):
        if m is None or not len(m):
            out.append(math.nan)
            continue
        times = [e["t"] for e in events if e["contact"] == contact and e["to"] == "sliding"]
        sliding = np.flatnonzero(_mode_columns(m)[:, contact - 1] == "sliding")
        at_start = sliding.size and sliding[0] == 0
        out.append(float(batch.t[0]) if at_start else min(times) if times else math.inf)
    return np.array(out)


def _series(model, batch, q: str, dense: bool) -> np.ndarray:
    if q in model.state_names:
        i = model.state_names.index(q)
        return batch.x[:, :, i] if dense else batch.x_final[:, i].copy()
    return batch.outputs[q].copy()


def _settling_time(t: np.ndarray, y: np.ndarray, tol: float) -> np.ndarray:
    """Per run, the first output time from which ``y`` stays within ``tol`` of its final value."""
    outside = np.abs(y - y[:, -1:]) > tol
    last = np.where(outside.any(axis=1), outside.shape[1] - 1 - np.argmax(outside[:, ::-1], axis=1), -1)
    return np.where(last < 0, t[0], t[np.minimum(last + 1, len(t) - 1)])


_STARTS: dict = {}


def _starts(model, given: list[tuple[str, np.ndarray]]):
    """Each point's start (``with_start``: the pose held, the rest solved, the start's run-time
    values it implies), solved once per distinct pose in this process; the points whose pose
    cannot be reached, with the reason."""

    n = len(given[0][1])
    X0 = np.tile(model.initial_state(), (n, 1))
    implied = {k: np.full(n, v) for k, v in model.start_params.items()}
    bad = {}
    for i in range(n):
        values = {state: float(v[i]) for state, v in given}
        key = (model.manifest["hash"], model.start["key"], tuple(sorted(values.items())))
        if key not in _STARTS:
            try:
                _STARTS[key] = start_point(model, values)
            except (GraspingSymError, ValueError, NotImplementedError) as exc:
                _STARTS[key] = f"{type(exc).__name__}: {exc}"
            if len(_STARTS) > 100_000:
                _STARTS.clear()
        got = _STARTS[key]
        if isinstance(got, str):
            bad[i] = got
            continue
        X0[i] = got[0]
        for k, v in got[1].items():
            implied[k][i] = v
    return X0, {k: v for k, v in implied.items() if not np.all(v == model.start_params[k])}, bad


# ------------------------------------------------------------------ the sweep
def sweep(model, grid, t_final: float, *, store: str | Path = "sweep.zarr", client=None,
          chunk: int | None = None, outputs: Sequence[str] = (), measures: Sequence[str] = (),
          samples: int = SAMPLES, settle_tol: float = SETTLE_TOL, method: str | None = None,
          rtol: float | None = None, atol: float | None = None, project: bool | float | str | None = None,
          max_steps: int = 1_000_000, checks: bool = True, progress: bool = True, mu=None):
    """Run ``model`` (a built model, or a scene: built first) at every point of ``grid`` for
    ``t_final`` seconds and return the results as an ``xarray.Dataset`` (module docstring).

    ``client``: None (this process, a thread per core), ``"processes"`` (a local cluster of
    one worker process per core) or a ``dask.distributed.Client``. ``chunk``: points per task
    (default ``default_chunk``: about 8 tasks per thread, 1000 to 20 000 points). ``method``,
    ``rtol``, ``atol``, ``project``, ``max_steps``, ``checks``: as for ``simulate_many``.
    ``progress``: a progress bar on stderr. ``mu``: the contacts' friction coefficient (one,
    or one per contact; default the scene's ``friction``), unless the grid has an axis ``mu``:
    a run whose force leaves its cone stops (status ``-11``, ``FrictionConeError``), unless a
    measure of the cone is asked for (``first_slip:i``, ``held``, ``max:cone_ratio{i}``, ...),
    which reads the whole rolling run (``slip="record"``).
    """

    if not isinstance(model, Model):
        from grasping_sym.pipeline import build  # noqa: PLC0415 - lazy: a Dask worker that runs models never loads SymPy

        model = build(model)
    store = check_store(store)
    g = grid_of(grid)
    if isinstance(chunk, bool) or not (chunk is None or isinstance(chunk, numbers.Integral) and chunk >= 1):
        raise ValueError(f"chunk = {chunk!r} must be a positive integer (points per task)")
    if isinstance(samples, bool) or not isinstance(samples, numbers.Integral) or samples < 2:
        raise ValueError(f"samples = {samples!r} must be an integer >= 2 (output times per run)")
    if not (isinstance(settle_tol, numbers.Real) and math.isfinite(settle_tol) and settle_tol > 0):
        raise ValueError(f"settle_tol = {settle_tol!r} must be a number > 0")
    roles = _roles(model, g.names)
    _check_values(model, g, roles)
    if model.manifest.get("modes"):  # simulate checks the value
        fixed = None if mu is None else list(modes.friction_law(model, mu)[0])
    else:
        fixed = friction.resolve(model, mu)
    with_mu = fixed is not None or "mu" in g.names
    # the model's own method and tolerances where none are given, resolved once: every chunk
    # runs the same, and the store says which (a point that method finds stiff is recorded)
    method, rtol, atol, _ = run_defaults(model, method, rtol, atol)
    task = {"grid": g, "roles": roles, "t_final": float(t_final),
            "measures": _measures(model, tuple(outputs), tuple(measures), with_mu),
            "samples": int(samples), "settle_tol": float(settle_tol),
            "settings": dict(method=method, rtol=rtol, atol=atol, project=project,
                             max_steps=max_steps, checks=checks, threads=1,
                             mu=None if fixed is None else [None if m == math.inf else float(m)
                                                           for m in fixed])}
    _check_settings(model, task)  # bad settings are named here, before any task is sent
    if client is not None and any(kind == "epsilon" for _, kind, _ in task["measures"]):
        # a model sent to a Dask worker travels without its scene (its geometry's SymPy)
        raise ValueError("sweep: 'min:epsilon' reads the model's scene (its object's surface), which "
                         "a Dask worker's copy of the model does not carry: run this sweep with "
                         "client=None (threads in this process), or sweep without it and call "
                         "model.grasp_quality on the runs you keep")
    chunk = int(chunk or default_chunk(g.size, client))
    variables = [*model.state_names, *(v for v, _, _ in task["measures"])]
    key = _key(model, task, variables, chunk)
    with store_lock(store):
        group = _open_group(store, key, model, task, variables, chunk, g)
        done = _read_done(group)
        damaged = _damaged_chunks(store, group, [c for c in range(len(done)) if done[c]])
        if damaged:
            warnings.warn(f"{store}/{group.path}: {len(damaged)} chunks marked done are missing or "
                          f"unreadable and are run again: " + "; ".join(
                              f"chunk {c} ({', '.join(why)})" for c, why in list(damaged.items())[:5]),
                          stacklevel=2)
            for c in damaged:
                _forget_chunk(store, group, c)
                done[c] = False
        pending = [c for c in range(len(done)) if not done[c]]
        if pending:
            _run(model, task, group, pending, chunk, g.size, client, progress)
    ds = open(store, key)
    ds.attrs["chunks_run"] = len(pending)
    ds.attrs["chunks_damaged"] = sorted(damaged)
    return ds


def default_chunk(n: int, client) -> int:
    """Points per task for ``n`` points on ``client``'s threads (module constants)."""

    threads = sum(client.nthreads().values()) if hasattr(client, "nthreads") else default_threads()
    return int(min(max(math.ceil(n / (TASKS_PER_THREAD * max(threads, 1))), CHUNK[0]), CHUNK[1]))


def _check_settings(model, task) -> None:
    """Refuse bad settings by name before any task runs: one short run with them."""
    s = _per_run_mu(task["settings"], 1)
    model.simulate_many(min(task["t_final"], 1e-3), x0=model.initial_state()[None, :],
                        **(s if model.manifest.get("modes") else {**s, "checks": False}))  # modes: always checked


def _per_run_mu(settings: dict, n: int) -> dict:
    """The settings with the sweep's one friction coefficient per contact as ``(n, contacts)``."""
    mu = settings.get("mu")
    if mu is None:
        return settings
    arr = np.tile(np.array([math.inf if m is None else m for m in mu], float), (n, 1))
    return {**settings, "mu": arr[:, 0] if arr.shape[1] == 1 else arr}


def _key(model, task, variables, chunk) -> str:
    spec = {"model": model.manifest["hash"], "start": model.start["key"], "grid": task["grid"].spec(),
            "t_final": task["t_final"], "measures": task["measures"], "samples": task["samples"],
            "settle_tol": task["settle_tol"], "variables": variables, "chunk": chunk,
            "friction": repr(model.friction),
            "settings": {k: v for k, v in task["settings"].items() if k != "threads"}}
    return hashlib.sha256(json.dumps(spec, sort_keys=True, default=str).encode()).hexdigest()


# ------------------------------------------------------------------ the store
#: Chunks are written even when they equal the fill value (NaN, 0, ""), so that a missing
#: chunk file always means a lost chunk (``_damaged_chunks``); new groups say so in this attribute.
_ALL_WRITTEN = "chunks_always_written"
_WRITE = {"write_empty_chunks": True}


def check_store(store: str | Path) -> Path:
    """``store`` as a path a sweep can write: missing (made), or a Zarr store; else
    :class:`SweepStoreError` naming what it is, before any work."""
    path = Path(store)
    if path.exists() or path.is_symlink():
        if not path.is_dir():
            raise SweepStoreError(f"the sweep store {path} is a file, not a Zarr store (a directory): "
                                  "give the path of a new directory or of an earlier sweep's store")
        if not (path / "zarr.json").is_file() and any(path.iterdir()):
            raise SweepStoreError(f"the sweep store {path} is a directory that is not a Zarr store (it "
                                  "holds files but no zarr.json): give the path of a new directory or "
                                  "of an earlier sweep's store")
        return path
    for parent in path.parents:
        if parent.exists() or parent.is_symlink():
            if not parent.is_dir():
                raise SweepStoreError(f"the sweep store {path} cannot be made: {parent} is a file, not "
                                      "a directory; give another path")
            break
    return path


def _lock_holder(fd: int) -> str:
    try:
        os.lseek(fd, 0, os.SEEK_SET)
        info = json.loads(os.read(fd, 4096).decode() or "{}")
        return f"pid {int(info['pid'])} on {info['host']}"
    except (OSError, ValueError, KeyError, TypeError):
        return "a process that has not yet written its pid"


@contextmanager
def store_lock(store: str | Path):
    """Hold ``<store>.lock`` (beside the store) while writing the sweep store ``store``:
    another writer gets :class:`SweepStoreBusyError` naming the process that holds it. The
    lock is ``flock``'s, which the system releases when the holder ends however it ends (a
    lock file left by a killed sweep does not block); the file records the holder's pid and
    host, and is removed on release."""
    path = Path(store)
    lock = path.parent / f"{path.name}.lock"
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise SweepStoreError(f"the sweep store {path} cannot be made in {path.parent}: "
                              f"{exc.strerror or exc}; give another path") from exc
    while True:
        try:
            fd = os.open(lock, os.O_RDWR | os.O_CREAT | getattr(os, "O_NOFOLLOW", 0), 0o644)
        except OSError as exc:
            raise SweepStoreError(f"cannot make the lock file {lock} of the sweep store {path}: "
                                  f"{exc.strerror or exc}; give a store in a directory you may write") from exc
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            holder = _lock_holder(fd)
            os.close(fd)
            raise SweepStoreBusyError(
                f"another sweep ({holder}) is writing the store {path}; wait for it to finish, or give "
                f"another store (its lock: {lock})") from None
        try:  # the holder before may have removed the file between our open and our lock
            same = os.fstat(fd).st_ino == os.stat(lock, follow_symlinks=False).st_ino
        except FileNotFoundError:
            same = False
        if same:
            break
        os.close(fd)
    try:
        os.ftruncate(fd, 0)
        os.write(fd, json.dumps({"pid": os.getpid(), "host": socket.gethostname()}).encode())
        yield lock
    finally:
        try:
            os.unlink(lock)
        except FileNotFoundError:
            pass
        os.close(fd)


def _chunk_file(store: Path, array, c: int) -> Path:
    return Path(store) / array.path / array.metadata.encode_chunk_key((c,))


def _damaged_chunks(store: Path, group, chunks: Sequence[int]) -> dict[int, list[str]]:
    """Of the chunks ``chunks`` (marked done), those whose stored values are missing or
    unreadable: chunk -> what is wrong, per variable."""
    if not chunks:
        return {}
    attrs = group.attrs
    names = [*attrs["variables"], "status", "error"]
    if not attrs.get(_ALL_WRITTEN):  # stores of earlier versions skipped chunks of fill values
        names = list(attrs["variables"])
    bad: dict[int, list[str]] = {}
    for v in names:
        try:
            arr = group[v]
        except KeyError:
            raise SweepStoreError(f"the sweep store {store} has lost the array {group.path}/{v} (its "
                                  f"zarr.json): remove {store}/{group.path} and run the sweep again") from None
        for c in chunks:
            if not _chunk_file(store, arr, c).is_file():
                bad.setdefault(c, []).append(f"{v} missing")
        try:
            arr[:]
        except Exception:  # noqa: BLE001 - whatever the codec raises: find the chunk
            for c in chunks:
                try:
                    arr.get_block_selection((c,))
                except Exception as exc:  # noqa: BLE001
                    bad.setdefault(c, []).append(f"{v} unreadable: {exc}")
    return dict(sorted(bad.items()))


def _forget_chunk(store: Path, group, c: int) -> None:
    """Mark chunk ``c`` not done and remove its files (only those: they are rewritten)."""
    group["done"].with_config(_WRITE)[c] = False
    for v in [*group.attrs["variables"], "status", "error"]:
        f = _chunk_file(store, group[v], c)
        if f.is_file() and not f.is_symlink():
            f.unlink()


def _read_done(group) -> np.ndarray:
    """The ``done`` flags; a flag that cannot be read counts as not done (its file removed)."""
    arr = group["done"]
    try:
        return np.asarray(arr[:], dtype=bool)
    except Exception:  # noqa: BLE001 - a damaged flag chunk: read them one by one
        done = np.zeros(arr.shape[0], dtype=bool)
        for c in range(arr.shape[0]):
            try:
                done[c] = bool(arr[c])
            except Exception:  # noqa: BLE001
                arr.with_config(_WRITE)[c] = False
        return done


def _zarr_root(store: Path, mode: str):
    import zarr  # noqa: PLC0415 - lazy: the store is opened only when a sweep writes or reads it

    try:
        return zarr.open_group(str(store), mode=mode)
    except FileNotFoundError:
        raise SweepStoreError(f"no sweep store at {store}: run gs.sweep(..., store={str(store)!r}) "
                              "first") from None
    except Exception as exc:  # noqa: BLE001 - zarr's errors for a damaged store's metadata vary
        raise SweepStoreError(f"the sweep store {store} cannot be opened ({type(exc).__name__}: {exc}): "
                              "its metadata (zarr.json) is damaged; remove the store and run the "
                              "sweep again") from exc


def _open_group(store, key, model, task, variables, chunk, g: Grid):
    root = _zarr_root(store, "a")
    name = f"sweep-{key[:16]}"
    if name in root:
        group = root[name]
        if group.attrs.get("key") != key:
            raise SweepStoreError(
                f"{store}/{name} holds another sweep (key {group.attrs.get('key')!r:.20}...): remove "
                f"{store}/{name}, or give another store")
        for k, ax in zip(g.names, g.axes):  # the grid's values, as they were (the key covers them)
            group[f"axis_{k}"].with_config(_WRITE)[:] = ax
        return group
    group = root.create_group(name)
    n, n_chunks = g.size, math.ceil(g.size / chunk)
    for v in variables:
        group.create_array(v, shape=(n,), chunks=(chunk,), dtype="f8", fill_value=np.nan,
                           dimension_names=["point"])
    group.create_array("status", shape=(n,), chunks=(chunk,), dtype="i8", fill_value=0,
                       dimension_names=["point"])
    group.create_array("error", shape=(n,), chunks=(chunk,), dtype=str, dimension_names=["point"])
    for k, ax in zip(g.names, g.axes):
        group.create_array(f"axis_{k}", shape=ax.shape, dtype="f8",
                           dimension_names=[k if g.product else "point"])[:] = ax
    group.create_array("done", shape=(n_chunks,), chunks=(1,), dtype=bool, fill_value=False,
                       dimension_names=["chunk"])
    group.attrs.update({"format": _FORMAT, "key": key, "model": model.name,
                        "model_hash": model.manifest["hash"], "start_key": model.start["key"],
                        "grid": {"names": list(g.names), "product": g.product},
                        "variables": variables, "chunk": chunk, "t_final": task["t_final"],
                        "measures": [list(m) for m in task["measures"]],
                        "settings": {k: v for k, v in task["settings"].items() if k != "threads"},
                        _ALL_WRITTEN: True})
    return group


def _client(client):
    """``(client, owned)``: the Dask client to run on."""
    from distributed import Client, LocalCluster  # noqa: PLC0415 - lazy: distributed (0.5 s) only for a sweep on Dask


    if client is None:
        return Client(processes=False, n_workers=1, threads_per_worker=default_threads(),
                      dashboard_address=":0"), True
    if client == "processes":
        cluster = LocalCluster(n_workers=default_threads(), threads_per_worker=1, processes=True,
                               dashboard_address=":0")
        return Client(cluster), True
    if not hasattr(client, "submit"):
        raise TypeError(f"client = {client!r}: give None (threads here), 'processes' or a "
                        "dask.distributed.Client")
    return client, False


def _run(model, task, group, pending, chunk, n, client, progress) -> None:
    """Send the pending chunks to Dask and write each into the store as it comes back."""
    from distributed import as_completed  # noqa: PLC0415 - lazy: as above
    from tqdm.auto import tqdm  # noqa: PLC0415 - lazy: only for a progress bar

    client, owned = _client(client)
    try:
        remote_model = client.scatter(model, broadcast=True)
        futures = {}
        for c in pending:
            a, b = c * chunk, min(n, (c + 1) * chunk)
            futures[client.submit(run_chunk, remote_model, task, a, b, pure=False,
                                  key=f"gs-sweep-{c}-{group.attrs['key'][:12]}")] = (c, a, b)
        bar = tqdm(total=sum(b - a for _, a, b in futures.values()), unit="run",
                   disable=not progress, desc=f"sweep {model.name}")
        try:
            for fut in as_completed(futures):
                c, a, b = futures.pop(fut)
                result = fut.result()
                for k, v in result.items():
                    group[k].with_config(_WRITE)[a:b] = v
                group["done"].with_config(_WRITE)[c] = True  # last: a chunk counts once its values are stored
                bar.update(b - a)
        finally:
            bar.close()
            for fut in futures:
                fut.cancel()
    finally:
        if owned:
            cluster = getattr(client, "cluster", None)
            client.close()
            if cluster is not None:
                cluster.close()


def open(store: str | Path, key: str | None = None):  # noqa: A001 - the module's reader
    """The sweep stored in ``store`` (its ``key``, or the only one there) as an
    ``xarray.Dataset``: one dimension per grid name (``point`` for a list of points), one
    variable per final state, output and measure, ``status`` and ``error``; ``done`` says which
    chunks are in (a sweep stopped early has NaN and empty errors elsewhere)."""
    import xarray as xr  # noqa: PLC0415 - lazy: xarray (0.3 s) only when a Dataset is made

    store = check_store(store)
    root = _zarr_root(store, "r")
    names = [k for k in root.group_keys() if k.startswith("sweep-")]
    if key is not None:
        names = [k for k in names if k == f"sweep-{key[:16]}"]
    if len(names) != 1:
        raise SweepStoreError(f"{store} holds {len(names)} sweeps{' with that key' if key else ''} "
                         f"({names}): name one by its key")
    group = root[names[0]]
    attrs = dict(group.attrs)
    done = _read_done(group)
    damaged = _damaged_chunks(store, group, [c for c in range(len(done)) if done[c]])
    if damaged:
        c, why = next(iter(damaged.items()))
        raise SweepStoreError(
            f"the sweep store {store} ({names[0]}) has {len(damaged)} chunks marked done whose values are "
            f"missing or unreadable, e.g. chunk {c} (points {c * attrs['chunk']} to "
            f"{(c + 1) * attrs['chunk'] - 1}): {'; '.join(why)}. Run the same gs.sweep(...) (or "
            f"`grasping-sym sweep`) again: it runs those chunks again")
    gnames = attrs["grid"]["names"]
    try:
        axes = {k: group[f"axis_{k}"][:] for k in gnames}
    except Exception as exc:  # noqa: BLE001 - a damaged or lost axis
        raise SweepStoreError(f"the sweep store {store} ({names[0]}): the grid's values cannot be read "
                              f"({exc}): run the same sweep again (it writes them again)") from exc
    if lost := [k for k, a in axes.items() if not np.all(np.isfinite(a))]:
        raise SweepStoreError(f"the sweep store {store} ({names[0]}): the grid's values of {lost} are "
                              "missing (a deleted file): run the same sweep again (it writes them again)")
    product = attrs["grid"]["product"]
    shape = tuple(len(a) for a in axes.values()) if product else (len(axes[gnames[0]]),)
    dims = tuple(gnames) if product else ("point",)
    data = {v: (dims, group[v][:].reshape(shape)) for v in [*attrs["variables"], "status"]}
    data["error"] = (dims, np.asarray(group["error"][:], dtype=object).reshape(shape))
    coords = {k: (k, a) for k, a in axes.items()} if product else {k: ("point", a) for k, a in axes.items()}
    ds = xr.Dataset(data, coords=coords, attrs={k: attrs[k] for k in ("model", "model_hash", "key",
                                                                       "t_final", "chunk")})
    ds.attrs.update(chunks_done=int(done.sum()), chunks_total=len(done), store=str(store),
                    group=names[0])
    return ds


sweep.points = points  # type: ignore[attr-defined]
sweep.open = open  # type: ignore[attr-defined]
