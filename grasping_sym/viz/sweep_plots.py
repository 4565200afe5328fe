"""Figures of a sweep (``gs.sweep``'s Dataset): a heat map over a 2-D grid, a curve over a 1-D
grid, with the failed points marked."""
from __future__ import annotations

from pathlib import Path

import numpy as np
from matplotlib import colormaps
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure

from grasping_sym.runtime.batch import STATUS
from grasping_sym.sweeps import START

#: What ``sweep_figure`` can show besides a variable of the Dataset.
FAILURE = "failure"


def sweep_figure(ds, show: str, path: str | Path) -> Path:
    """Write ``show`` (a variable of ``ds``, or ``"failure"``: which points failed, by
    status) over the sweep's grid to ``path`` (PNG)."""
    if show != FAILURE and show not in ds.data_vars:
        raise ValueError(f"nothing called {show!r} in this sweep: show one of "
                         f"{[v for v in ds.data_vars if v != 'error'] + [FAILURE]}")
    dims = [d for d in ds[show if show != FAILURE else "status"].dims]
    if len(dims) > 2 or dims == ["point"]:
        raise ValueError(f"a figure needs a grid of one or two names (a Cartesian product); this "
                         f"sweep has {dims}: plot from the Dataset with xarray instead")
    failed = ds["status"].values != 0
    if show == FAILURE:
        values = ds["status"].values.astype(float)
        label = "status (0: ok; <0: failure code)"
    else:
        values = ds[show].values
        label = _label(show)
    fig = Figure(figsize=(6.4, 4.8), layout="constrained")
    FigureCanvasAgg(fig)  # drawn off screen, whatever the user's backend
    ax = fig.subplots()
    if len(dims) == 2:
        y, x = (ds[d].values for d in dims)
        if show == FAILURE:
            codes = sorted(set(np.unique(values).tolist()))
            cmap = colormaps["tab10"].resampled(max(len(codes), 2))
            index = np.searchsorted(codes, values)
            mesh = ax.pcolormesh(x, y, index, cmap=cmap, vmin=-0.5, vmax=len(codes) - 0.5, shading="nearest")
            bar = fig.colorbar(mesh, ax=ax, ticks=range(len(codes)))
            bar.ax.set_yticklabels([_status_name(c) for c in codes])
        else:
            mesh = ax.pcolormesh(x, y, np.ma.masked_invalid(values), shading="nearest")
            fig.colorbar(mesh, ax=ax, label=label)
            if failed.any():
                yy, xx = np.meshgrid(y, x, indexing="ij")
                ax.scatter(xx[failed], yy[failed], marker="x", s=12, color="0.3", linewidths=0.8,
                           label="failed")
                ax.legend(loc="upper center", bbox_to_anchor=(0.5, -0.12), fontsize=8, ncols=1,
                          frameon=False)
        ax.set_xlabel(dims[1])
        ax.set_ylabel(dims[0])
    else:
        x = ds[dims[0]].values
        ax.plot(x, values, ".-")
        if failed.any() and show != FAILURE:
            ax.plot(x[failed], np.zeros(failed.sum()), "x", color="0.3", label="failed")
            ax.legend(fontsize=8)
        ax.set_xlabel(dims[0])
        ax.set_ylabel(label)
    ax.set_title(f"{ds.attrs.get('model', '')}: {label}", fontsize=10)
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=120)
    return path


def _label(name: str) -> str:
    kind, _, q = name.partition("_")
    if kind == "settle" and q:
        return f"settling time of {q} (s)"
    if kind in ("min", "max") and q:
        return f"{'minimum' if kind == 'min' else 'maximum'} of {q} along the run"
    return f"final {name}"


def _status_name(code: float) -> str:

    names = {**STATUS, START: "start unreachable"}
    return f"{int(code)}: {names.get(int(code), 'failed')}"
