"""The result of a simulation, filled the same way by every integrator."""
from __future__ import annotations

import csv
import html
import json
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

#: What ``SimulationResult.save`` writes (an ``.npz`` of arrays and JSON text, no pickles).
FORMAT = "grasping_sym.SimulationResult/1"


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
    """

    t: np.ndarray
    x: np.ndarray
    state_names: tuple[str, ...]
    outputs: dict[str, np.ndarray]
    method: str
    stats: dict = field(default_factory=dict)
    params: dict[str, float] = field(default_factory=dict)

    def __getitem__(self, name: str) -> np.ndarray:
        """A state or output by name."""
        if name in self.state_names:
            return self.x[:, self.state_names.index(name)]
        if name in self.outputs:
            return self.outputs[name]
        raise KeyError(f"{name!r} is neither a state {self.state_names} nor an output "
                       f"{tuple(self.outputs)}")

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
        return (f"SimulationResult({self.method}: {span}; states {_names(self.state_names)}; "
                f"outputs {_names(tuple(self.outputs))}{run})")

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
        import pandas as pd  # noqa: PLC0415

        cols = {k: self.x[:, i] for i, k in enumerate(self.state_names)}
        cols.update(self.outputs)
        return pd.DataFrame(cols, index=pd.Index(self.t, name="t"))

    def to_xarray(self):
        """An ``xarray.Dataset`` over ``t``, a variable per state and output; the method, the
        parameters and the integrator's counters as attributes."""
        import xarray as xr  # noqa: PLC0415

        data = {k: ("t", self.x[:, i]) for i, k in enumerate(self.state_names)}
        data.update({k: ("t", np.asarray(v)) for k, v in self.outputs.items()})
        attrs = {"method": self.method, "params": json.dumps(self.params),
                 "stats": json.dumps(_plain(self.stats))}
        return xr.Dataset(data, coords={"t": self.t}, attrs=attrs)

    def animate(self, path: Path | str, scene=None, **options) -> Path:
        """Write the motion to ``path`` (``.gif``, or ``.mp4`` with ffmpeg): the scene drawn at
        evenly spaced times (``grasping_sym.animation``; ``fps``, ``seconds``, ``dpi``).
        ``scene`` defaults to the run's (a model made by ``gs.build`` sets it)."""
        from grasping_sym.animation import animate  # noqa: PLC0415

        return animate(self, path, scene, **options)

    def view(self, path: Path | str, scene=None, **options) -> Path:
        """Write an interactive 3D viewer of the run to ``path`` (one self-contained ``.html``:
        no network, nothing to install; ``grasping_sym.viewer``)."""
        from grasping_sym.viewer import write_viewer  # noqa: PLC0415

        return write_viewer(self, path, scene, **options)

    # ------------------------------------------------------------ files
    def save(self, path: Path | str) -> Path:
        """Write the result to ``path`` (``.npz``: the arrays, and the names, method, parameters
        and counters as JSON text; nothing that runs as code). ``SimulationResult.load`` reads
        it back."""
        path = Path(path)
        if path.suffix != ".npz":
            path = path.with_suffix(path.suffix + ".npz")
        path.parent.mkdir(parents=True, exist_ok=True)
        meta = {"format": FORMAT, "state_names": list(self.state_names), "method": self.method,
                "outputs": list(self.outputs), "stats": _plain(self.stats),
                "params": _plain(self.params)}
        arrays = {f"output_{i}": np.asarray(v, dtype=float) for i, v in enumerate(self.outputs.values())}
        np.savez(path, t=self.t, x=self.x, meta=np.array(json.dumps(meta)), **arrays)
        return path

    @classmethod
    def load(cls, path: Path | str) -> SimulationResult:
        """A result written by ``save`` (pickled objects are refused: ``allow_pickle=False``)."""
        with np.load(Path(path), allow_pickle=False) as f:
            try:
                meta = json.loads(str(f["meta"]))
            except KeyError:
                raise ValueError(f"{path} is not a saved SimulationResult (no 'meta' entry)") from None
            if meta.get("format") != FORMAT:
                raise ValueError(f"{path} is a {meta.get('format')!r} file, not {FORMAT!r}")
            outputs = {k: f[f"output_{i}"].copy() for i, k in enumerate(meta["outputs"])}
            return cls(t=f["t"].copy(), x=f["x"].copy(), state_names=tuple(meta["state_names"]),
                       outputs=outputs, method=meta["method"], stats=meta["stats"],
                       params=meta["params"])


def _names(names: tuple[str, ...], most: int = 6) -> str:
    if len(names) <= most:
        return "(" + ", ".join(names) + ")"
    return "(" + ", ".join(names[:most]) + f", ... {len(names)} in all)"


def _plain(d: dict) -> dict:
    """``d`` with NumPy scalars as Python numbers (for JSON)."""
    return {k: (v.item() if isinstance(v, np.generic) else v) for k, v in d.items()
            if isinstance(v, (int, float, str, bool, np.generic)) or v is None}
