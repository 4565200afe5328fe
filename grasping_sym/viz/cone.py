"""The friction cone along a run: each contact's ``|F_t| / f`` against its ``mu``.

Reads the cone's outputs a run with ``mu`` has (``runtime.friction``: ``cone_ratio{i}``,
``cone_margin{i}``, ``normal_force{i}``); any kind of scene. The stretches where the rolling
model needs more friction than ``mu`` (``cone_margin{i} <= 0``, a run with
``slip="record"``) are shaded.
"""
from __future__ import annotations

import re
from pathlib import Path

import numpy as np
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure

__all__ = ["cone_figure"]


def _contacts(outputs) -> list[str]:
    return sorted((m.group(1) for k in outputs if (m := re.fullmatch(r"cone_ratio(\d+)", k))), key=int)


def cone_figure(result, path: Path | str, *, dpi: float = 110) -> Path:
    """Write the figure of ``result``'s cone ratios (one panel per contact, ``mu`` dashed, the
    stretches outside the cone shaded) to ``path`` (any format matplotlib writes)."""
    contacts = _contacts(result.outputs)
    if not contacts:
        raise ValueError("the run has no friction-cone outputs: simulate with mu=... (or build the "
                         "scene with friction=gs.contact.coulomb(mu)) and outputs=True")
    fig = Figure(figsize=(7.0, 1.2 + 1.8 * len(contacts)), layout="constrained")
    FigureCanvasAgg(fig)
    axes = fig.subplots(len(contacts), 1, sharex=True, squeeze=False)[:, 0]
    t = np.asarray(result.t)
    for ax, i in zip(axes, contacts):
        ratio = np.asarray(result.outputs[f"cone_ratio{i}"], float)
        margin = np.asarray(result.outputs[f"cone_margin{i}"], float)
        f = np.asarray(result.outputs[f"normal_force{i}"], float)
        with np.errstate(divide="ignore", invalid="ignore"):
            mu = np.where(f > 0, (margin + ratio * f) / f, np.nan)   # margin = mu f - |F_t|
        ax.plot(t, ratio, lw=1.2, label=f"|F_t| / f, contact {i}")
        if np.any(np.isfinite(mu)):
            ax.plot(t, mu, "k--", lw=0.9, label="mu")
        outside = ~(margin > 0)
        if outside.any():
            ax.fill_between(t, 0, 1, where=outside, transform=ax.get_xaxis_transform(),
                            color="tab:red", alpha=0.15, label="outside the cone (would slip)")
        ax.set_ylabel("|F_t| / f")
        ax.legend(loc="upper right", fontsize=8)
        ax.grid(True, lw=0.3)
    axes[-1].set_xlabel("t (s)")
    fig.suptitle("Friction cone along the run")
    path = Path(path)
    fig.savefig(path, dpi=dpi)
    return path
