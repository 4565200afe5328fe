"""The result of a simulation, filled the same way by every integrator."""
from __future__ import annotations

import csv
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np


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
