"""The result of a simulation, filled the same way by every integrator."""
from __future__ import annotations

import csv
import html
import json
import math
import zipfile
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from grasping_sym.errors import InvalidResultError, ResultFileError
from grasping_sym.rotations import matrices

#: What ``SimulationResult.save`` writes (an ``.npz`` of arrays and JSON text, no pickles).
FORMAT = "grasping_sym.SimulationResult/1"
#: State-name tuples already found valid (strings, each once): a model's own, checked once.
_NAMES_OK: set[tuple[str, ...]] = set()


#: The quaternion states of a 3D object, scalar first.
QUATERNION = ("qw", "qx", "qy", "qz")


@dataclass
class SimulationResult:
    """A trajectory and its outputs.

    Attributes
    ----------
    t
        Times (s), shape ``(n,)``.
    x
        States, shape ``(n, n_states)``, columns ordered as ``state_names``.
    state_names
        Names of the state components.
    outputs
        Output name -> array of shape ``(n,)``.
    method
        Integrator used.
    stats
        Integrator counters (steps, function evaluations) and ``wall_time`` (s).
    params
        Values of the run-time parameters used.
    scene
        The scene of the model that ran it when that model was made by ``gs.build`` (what
        ``gs.viz.animate`` and ``gs.viz.view`` draw by default), else None.
    events
        A model with contact modes (``runtime.modes``): every switch, in time order, a dict
        with ``t``, ``contact``, ``from``, ``to``, ``witness`` (what crossed zero), ``value``
        (its value at the located time) and ``reset`` (the largest speed change the switch
        made, m/s), and ``located`` (``"dense output"``) on a slip's stop that integrating
        again could not locate (``docs/conventions.md`` section 7); empty otherwise.
    modes
        With contact modes: the contact's mode at each output time (``"rolling"``,
        ``"sliding"``, ``"separated"``), else None.
    charts
        A model whose surfaces have atlases (``geometry.atlas``): per chart parameter (e.g.
        ``"chart"``), the chart (0 or 1) each row's contact coordinates are in; else empty.
    chart_switches
        Every switch of chart, in time order, a dict with ``t``, ``chart`` (the parameter; None
        for a repeating chart's coordinates carried a period back), ``coordinates`` (the
        contact's state names), ``from``, ``to``, ``u`` and ``v`` (before, after) and ``delta``
        (the frame's turn, rad; ``runtime.atlas``).
    """

    t: np.ndarray
    x: np.ndarray
    state_names: tuple[str, ...]
    outputs: dict[str, np.ndarray]
    method: str
    stats: dict = field(default_factory=dict)
    params: dict[str, float] = field(default_factory=dict)
    scene: object = field(default=None, repr=False, compare=False)
    events: list = field(default_factory=list, repr=False, compare=False)
    modes: np.ndarray | None = field(default=None, repr=False, compare=False)
    charts: dict = field(default_factory=dict, repr=False, compare=False)
    chart_switches: list = field(default_factory=list, repr=False, compare=False)

    def __post_init__(self) -> None:
        # shapes only, every run makes one: one row per time, one column per state name, one
        # value per time in each output (0.5 us for a model's own names, checked once)
        t, x, names = self.t, self.x, self.state_names
        if type(t) is np.ndarray and type(x) is np.ndarray and t.ndim == 1 and \
                x.shape == (t.shape[0], len(names)) and not self.outputs and _known(names):
            return
        if problem := _shape_problem(t, x, names, self.outputs):
            raise InvalidResultError(f"SimulationResult: {problem}")
        if isinstance(names, tuple) and len(_NAMES_OK) < 64:
            _NAMES_OK.add(names)

    def __getitem__(self, name: str) -> np.ndarray:
        """A state or output by name."""
        if name in self.state_names:
            return self.x[:, self.state_names.index(name)]
        if name in self.outputs:
            return self.outputs[name]
        raise KeyError(f"{name!r} is neither a state {self.state_names} nor an output "
                       f"{tuple(self.outputs)}")

    def object_rotations(self) -> np.ndarray:
        """``(n, 3, 3)``: the 3D object's rotation (body to world) at every row, from its
        quaternion states ``qw, qx, qy, qz`` normalised (:func:`rotations`)."""
        missing = [k for k in QUATERNION if k not in self.state_names]
        if missing:
            raise KeyError(f"this run has no object quaternion (states {list(QUATERNION)}; missing "
                           f"{missing}): object_rotations() is for a 3D object's run")
        return matrices(self.x[:, [self.state_names.index(k) for k in QUATERNION]])

    def write_csv(self, path: Path | str) -> Path:
        """Write ``t``, the states and the outputs as columns (header row first)."""
        path = Path(path)
        path.parent.mkdir(parents=True, exist_ok=True)
        names = ["t", *self.state_names, *self.outputs]
        cols = [self.t, *self.x.T, *self.outputs.values()]
        with path.open("w", newline="") as fh:
            w = csv.writer(fh)
            w.writerow(names)
            for row in np.column_stack(cols):
                w.writerow([repr(float(v)) for v in row])
        return path

    # ------------------------------------------------------------ views
    def __repr__(self) -> str:
        t = self.t
        span = f"t = {t[0]:g} ... {t[-1]:g} s, {len(t)} samples" if len(t) else "no samples"
        steps = self.stats.get("n_steps")
        wall = self.stats.get("wall_time")
        run = (f", {steps} steps" if steps is not None else "") + \
            (f" in {wall * 1e3:.3g} ms" if isinstance(wall, float) else "")
        return (f"SimulationResult({self.method}: {span}; states {names_text(self.state_names)}; "
                f"outputs {names_text(tuple(self.outputs))}{run})")

    def _repr_html_(self) -> str:
        """A summary table for Jupyter: each state and output at the start and the end, and its
        range over the run."""
        rows = []
        for name in (*self.state_names, *self.outputs):
            v = np.asarray(self[name])
            cells = [v[0], v[-1], np.nanmin(v), np.nanmax(v)] if len(v) else [np.nan] * 4
            rows.append(f"<tr><td>{html.escape(name)}</td>"
                        + "".join(f"<td>{c:.6g}</td>" for c in cells) + "</tr>")
        head = html.escape(repr(self))
        return (f"<div><p><code>{head}</code></p><table><thead><tr><th>name</th><th>start</th>"
                "<th>end</th><th>min</th><th>max</th></tr></thead><tbody>" + "".join(rows)
                + "</tbody></table></div>")

    def to_dataframe(self):
        """A ``pandas.DataFrame`` indexed by ``t``, a column per state and output."""
        import pandas as pd  # noqa: PLC0415 - lazy: an optional dependency, only for this view

        cols = {k: self.x[:, i] for i, k in enumerate(self.state_names)}
        cols.update(self.outputs)
        return pd.DataFrame(cols, index=pd.Index(self.t, name="t"))

    def to_xarray(self):
        """An ``xarray.Dataset`` over ``t``, a variable per state and output; the method, the
        parameters and the integrator's counters as attributes."""
        import xarray as xr  # noqa: PLC0415 - lazy: xarray (0.3 s) only for this view

        data = {k: ("t", self.x[:, i]) for i, k in enumerate(self.state_names)}
        data.update({k: ("t", np.asarray(v)) for k, v in self.outputs.items()})
        data.update({k: ("t", np.asarray(v)) for k, v in self.charts.items()})
        attrs = {"method": self.method, "params": json.dumps(self.params),
                 "stats": json.dumps(_plain(self.stats))}
        return xr.Dataset(data, coords={"t": self.t}, attrs=attrs)

    def save(self, path: Path | str) -> Path:
        """Write the result to ``path`` (``.npz``: the arrays, and the names, method, parameters
        and counters as JSON text; nothing that runs as code). ``SimulationResult.load`` reads
        it back. ``.npz`` is appended to another suffix.

        Raises
        ------
        ResultFileError
            ``path`` is a directory, or the file cannot be written there.
        """
        given = Path(path)
        if given.name in ("", ".", "..") or given.is_dir():
            raise ResultFileError(f"cannot save a result as {str(path)!r}: it is a directory; pass a "
                                  "file name, e.g. 'runs/grasp.npz'")
        path = given if given.suffix == ".npz" else given.with_suffix(given.suffix + ".npz")
        if path.is_dir():
            raise ResultFileError(f"cannot save a result as {path}: it is a directory; pass "
                                  "another file name")
        meta = {"format": FORMAT, "state_names": list(self.state_names), "method": self.method,
                "outputs": list(self.outputs), "stats": _plain(self.stats),
                "params": _plain(self.params)}
        arrays = {f"output_{i}": np.asarray(v, dtype=float) for i, v in enumerate(self.outputs.values())}
        if self.charts:  # each row's charts (a row's (u, v) mean nothing without them)
            meta["charts"] = list(self.charts)
            arrays.update({f"chart_{i}": np.asarray(v, dtype=np.int8) for i, v in enumerate(self.charts.values())})
        try:
            path.parent.mkdir(parents=True, exist_ok=True)
            np.savez(path, t=self.t, x=self.x, meta=np.array(json.dumps(meta)), **arrays)
        except OSError as exc:
            raise ResultFileError(f"cannot write the result to {path}: {exc.strerror or exc}; "
                                  "pass a path in a writable directory") from exc
        return path

    @classmethod
    def load(cls, path: Path | str) -> SimulationResult:
        """A result written by ``save`` (pickled objects are refused: ``allow_pickle=False``).

        Every entry is checked before the result is made: the format, the names (strings, each
        once), one row of ``x`` per time and one column per state name, one value per time in
        each output, finite increasing times, numbers as parameters.

        Raises
        ------
        ResultFileError
            The file is not such a result, or its entries disagree (the file and the entry are
            named). ``FileNotFoundError`` when there is no file.
        """
        path = Path(path)
        if path.is_dir():
            raise ResultFileError(f"{path} is a directory: pass the .npz file SimulationResult.save "
                                  "wrote")
        try:
            f = np.load(path, allow_pickle=False)
        except FileNotFoundError:
            raise
        except (OSError, ValueError, EOFError, zipfile.BadZipFile) as exc:
            raise ResultFileError(f"{path} is not an .npz file that SimulationResult.save wrote "
                                  f"({exc}); pickled objects are never loaded") from None
        if not isinstance(f, np.lib.npyio.NpzFile):
            raise ResultFileError(f"{path} holds one array, not a saved SimulationResult (an .npz "
                                  "that SimulationResult.save wrote)")
        with f:
            try:
                _check_sizes(path)
                return _from_npz(cls, f, path)
            except (ValueError, KeyError, EOFError, OSError, zipfile.BadZipFile, RecursionError,
                    MemoryError) as exc:
                if isinstance(exc, ResultFileError):
                    raise
                raise ResultFileError(f"{path}: an entry cannot be read ({type(exc).__name__}: "
                                      f"{exc}); pickled objects are never loaded") from None


def _check_sizes(path: Path) -> None:
    """Refuse an entry whose header declares more data than the file holds for it (a
    tampered header would make numpy allocate that much before reading)."""
    with zipfile.ZipFile(path) as z:
        for info in z.infolist():
            if not info.filename.endswith(".npy"):
                continue
            with z.open(info) as fh:
                version = np.lib.format.read_magic(fh)
                read = (np.lib.format.read_array_header_1_0 if version == (1, 0)
                        else np.lib.format.read_array_header_2_0)
                shape, _, dtype = read(fh)
                need = math.prod(shape) * dtype.itemsize + fh.tell()
            if need > info.file_size:
                raise ResultFileError(
                    f"{path}: the entry {info.filename[:-4]!r} declares shape {shape} of {dtype} "
                    f"({need} bytes) but holds {info.file_size} bytes: the file was edited or "
                    "cut; save the result again with SimulationResult.save")


def _known(names) -> bool:
    try:
        return names in _NAMES_OK
    except TypeError:  # unhashable: not a tuple of strings
        return False


def _shape_problem(t, x, state_names, outputs) -> str | None:
    """What disagrees between the times, the states, their names and the outputs (None: nothing)."""
    if not isinstance(state_names, (tuple, list)) or not all(isinstance(n, str) for n in state_names):
        return f"state_names = {state_names!r} must be a tuple of strings"
    if len(set(state_names)) != len(state_names):
        twice = sorted({n for n in state_names if state_names.count(n) > 1})
        return f"state_names name {twice} more than once: each state once"
    if not isinstance(outputs, dict) or not all(isinstance(k, str) for k in outputs):
        return "outputs must map output names (strings) to arrays"
    nt = np.shape(t)
    if len(nt) != 1:
        return f"t has shape {nt}: give one time per row, shape (n,)"
    if np.shape(x) != (nt[0], len(state_names)):
        return (f"x has shape {np.shape(x)}, but there are {nt[0]} times and {len(state_names)} "
                f"state names {names_text(tuple(state_names))}: x must be ({nt[0]}, {len(state_names)}), "
                "a row per time and a column per state name")
    for k, v in outputs.items():
        if np.shape(v) != nt:
            return (f"output {k!r} has shape {np.shape(v)}, but there are {nt[0]} times: "
                    f"each output is one value per time, shape {nt}")
    return None


def _from_npz(cls, f, path: Path) -> SimulationResult:
    """``load``'s result from the open ``.npz`` ``f``: every entry checked first."""
    def bad(what: str) -> ResultFileError:
        return ResultFileError(f"{path} is not a valid saved SimulationResult: {what}; save the "
                               "result again with SimulationResult.save (do not edit the file)")

    if "meta" not in f.files:
        raise ResultFileError(f"{path} is not a saved SimulationResult (no 'meta' entry)")
    raw = f["meta"]
    if raw.ndim != 0 or raw.dtype.kind != "U":
        raise bad(f"'meta' is an array of shape {raw.shape} and type {raw.dtype}, not JSON text")
    try:
        meta = json.loads(str(raw))
    except ValueError as exc:
        raise bad(f"'meta' is not JSON ({exc})") from None
    if not isinstance(meta, dict):
        raise bad(f"'meta' is a JSON {type(meta).__name__}, not an object")
    if meta.get("format") != FORMAT:
        raise ResultFileError(f"{path} is a {meta.get('format')!r} file, not {FORMAT!r}")
    missing = [k for k in ("state_names", "method", "outputs", "stats", "params") if k not in meta]
    if missing:
        raise bad(f"'meta' lacks {missing}")
    for key in ("state_names", "outputs"):
        names = meta[key]
        if not isinstance(names, list) or not all(isinstance(n, str) for n in names):
            raise bad(f"meta {key!r} = {_short(names)} is not a list of names")
        if len(set(names)) != len(names):
            raise bad(f"meta {key!r} names {sorted({n for n in names if names.count(n) > 1})} "
                      "more than once")
    if not isinstance(meta["method"], str):
        raise bad(f"meta 'method' = {_short(meta['method'])} is not a string")
    for key in ("stats", "params"):
        if not isinstance(meta[key], dict):
            raise bad(f"meta {key!r} is a JSON {type(meta[key]).__name__}, not an object")
    if wrong := [k for k, v in meta["params"].items()
                 if not isinstance(v, (int, float)) or isinstance(v, bool) or not math.isfinite(v)]:
        raise bad(f"meta 'params' {wrong} are not finite numbers")
    if wrong := [k for k, v in meta["stats"].items()
                 if not (v is None or isinstance(v, (int, float, str, bool)))]:
        raise bad(f"meta 'stats' {wrong} are not plain numbers or text")
    n_out = len(meta["outputs"])
    charts = meta.get("charts", [])
    if not isinstance(charts, list) or not all(isinstance(n, str) for n in charts) or len(set(charts)) != len(charts):
        raise bad(f"meta 'charts' = {_short(charts)} is not a list of names, each once")
    expected = {"meta", "t", "x", *(f"output_{i}" for i in range(n_out)), *(f"chart_{i}" for i in range(len(charts)))}
    if absent := sorted(expected - set(f.files)):
        raise bad(f"the entries {absent} are missing (meta lists {len(meta['state_names'])} states "
                  f"and {n_out} outputs)")
    if extra := sorted(set(f.files) - expected):
        raise bad(f"the entries {extra} are not listed in 'meta' ({n_out} outputs)")
    arrays = {}
    for key in sorted(expected - {"meta"}):
        a = f[key]
        if a.dtype.kind not in "fiu":
            raise bad(f"{key!r} holds {a.dtype} values, not numbers")
        arrays[key] = a.astype(float)
    t, x = arrays.pop("t"), arrays.pop("x")
    if t.ndim == 1 and not np.all(np.isfinite(t)):
        raise bad(f"'t' holds {int(np.sum(~np.isfinite(t)))} non-finite times")
    if t.ndim == 1 and np.any(np.diff(t) <= 0):
        raise bad("'t' is not strictly increasing")
    outputs = {k: arrays[f"output_{i}"] for i, k in enumerate(meta["outputs"])}
    if problem := _shape_problem(t, x, tuple(meta["state_names"]), outputs):
        raise bad(problem)
    rows = {k: arrays[f"chart_{i}"] for i, k in enumerate(charts)}
    if wrong := [k for k, v in rows.items() if v.shape != t.shape or not np.isin(v, (0.0, 1.0)).all()]:
        raise bad(f"the charts {wrong} are not one 0 or 1 per time")
    return cls(t=t, x=x, state_names=tuple(meta["state_names"]), outputs=outputs,
               method=meta["method"], stats=meta["stats"], params=meta["params"],
               charts={k: v.astype(int) for k, v in rows.items()})


def _short(v, most: int = 80) -> str:
    text = repr(v)
    return text if len(text) <= most else text[:most] + "..."

def names_text(names: tuple[str, ...], most: int = 6) -> str:
    """``names`` for a message: the first ``most`` of them and how many in all."""
    if len(names) <= most:
        return "(" + ", ".join(names) + ")"
    return "(" + ", ".join(names[:most]) + f", ... {len(names)} in all)"


def _plain(d: dict) -> dict:
    """``d`` with NumPy scalars as Python numbers (for JSON)."""
    return {k: (v.item() if isinstance(v, np.generic) else v) for k, v in d.items()
            if isinstance(v, (int, float, str, bool, np.generic)) or v is None}
