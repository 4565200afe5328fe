"""A run with contact modes over time: the modes as bands, the switches as lines.

Reads ``res.modes`` and ``res.events`` (``runtime.modes``) and the outputs every model with
modes has (``gap``, ``normal_force``, ``slip_speed``, ``cone_ratio``); any subset of them.
"""
from __future__ import annotations

from pathlib import Path

import numpy as np
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure

__all__ = ["modes_figure"]

#: Each mode's band colour.
COLOURS = {"rolling": "tab:green", "sliding": "tab:orange", "separated": "0.6"}
#: The panels, in order, where the run has the output: (output, label).
PANELS = (("gap", "gap (m)"), ("normal_force", "normal force f (N)"),
          ("slip_speed", "slip speed |v_t| (m/s)"), ("cone_ratio", "|F_t| / f"))


def _bands(ax, t: np.ndarray, modes: np.ndarray, legend: bool) -> None:
    """Shade each stretch of one mode (from one output time to the next)."""
    seen = set()
    start = 0
    for i in range(1, len(t) + 1):
        if i == len(t) or modes[i] != modes[start]:
            m = str(modes[start])
            label = m if legend and m not in seen else None
            seen.add(m)
            ax.axvspan(t[start], t[min(i, len(t) - 1)], color=COLOURS.get(m, "white"), alpha=0.2,
                       lw=0, label=label)
            start = i


def modes_figure(result, path: Path | str, *, dpi: float = 110) -> Path:
    """Write ``result``'s modes over time (bands), its switches (dotted lines) and the contact's
    gap, normal force, slip speed and cone ratio (the panels it has) to ``path``. A run of
    several contacts (``result.modes`` one column per contact) gets a strip per contact on
    top and one line per contact in each panel (``gap1``, ``gap2``, ...)."""
    if result.modes is None:
        raise ValueError("the run has no contact modes: a model with modes (gs.scenes.body_on_plane, "
                         "sphere_on_incline, gs.scenes.with_modes(gs.scenes.paper2d())) records them")
    modes = np.asarray(result.modes)
    t = np.asarray(result.t)
    if modes.ndim == 2:
        return _several(result, modes, t, Path(path), dpi)
    panels = [(k, lab) for k, lab in PANELS if k in result.outputs] or [(None, "mode")]
    fig = Figure(figsize=(7.0, 1.0 + 1.6 * len(panels)), layout="constrained")
    FigureCanvasAgg(fig)
    axes = fig.subplots(len(panels), 1, sharex=True, squeeze=False)[:, 0]
    for k, (ax, (name, label)) in enumerate(zip(axes, panels)):
        _bands(ax, t, modes, legend=k == 0)
        if name is not None:
            ax.plot(t, np.asarray(result.outputs[name], float), "k", lw=1.0)
        for ev in result.events:
            ax.axvline(ev["t"], color="tab:red", ls=":", lw=0.8)
        ax.set_ylabel(label)
        ax.grid(True, lw=0.3)
    axes[0].legend(loc="upper right", fontsize=8)
    axes[-1].set_xlabel("t (s)")
    fig.suptitle(f"Contact modes ({len(result.events)} switches, dotted)")
    fig.savefig(path, dpi=dpi)
    return Path(path)


def _several(result, modes: np.ndarray, t: np.ndarray, path: Path, dpi: float) -> Path:
    k = modes.shape[1]
    panels = [(name, label) for name, label in PANELS if f"{name}1" in result.outputs]
    fig = Figure(figsize=(7.0, 1.2 + 0.25 * k + 1.6 * len(panels)), layout="constrained")
    FigureCanvasAgg(fig)
    axes = fig.subplots(1 + len(panels), 1, sharex=True, squeeze=False,
                        height_ratios=[0.25 * k + 0.3] + [1.6] * len(panels))[:, 0]
    strip = axes[0]
    seen = set()
    for j in range(k):
        start = 0
        for i in range(1, len(t) + 1):
            if i == len(t) or modes[i, j] != modes[start, j]:
                m = str(modes[start, j])
                strip.fill_between([t[start], t[min(i, len(t) - 1)]], j + 0.6, j + 1.4,
                                   color=COLOURS.get(m, "white"), alpha=0.6, lw=0,
                                   label=m if m not in seen else None)
                seen.add(m)
                start = i
    strip.set_yticks(range(1, k + 1), [f"contact {j}" for j in range(1, k + 1)], fontsize=8)
    strip.legend(loc="upper right", fontsize=7, ncol=3)
    for ax, (name, label) in zip(axes[1:], panels):
        for j in range(1, k + 1):
            ax.plot(t, np.asarray(result.outputs[f"{name}{j}"], float), lw=1.0, label=f"contact {j}")
        ax.set_ylabel(label)
        ax.grid(True, lw=0.3)
    for ax in axes:
        for ev in result.events:
            ax.axvline(ev["t"], color="tab:red", ls=":", lw=0.8)
    if len(axes) > 1:
        axes[1].legend(loc="upper right", fontsize=7)
    axes[-1].set_xlabel("t (s)")
    fig.suptitle(f"Contact modes of {k} contacts ({len(result.events)} switches, dotted)")
    fig.savefig(path, dpi=dpi)
    return path
