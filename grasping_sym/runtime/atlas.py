"""A contact carried across the charts of an atlas (``geometry.atlas``; ``docs/conventions.md``
section 15).

A surface with an atlas is compiled once, its chart a run-time parameter (0 or 1). The
integration stops, at the step where it happens, where a contact's coordinates reach the
chart's edge (its bounds: latitude +-1.3, longitude +-3 pi). There the state is mapped onto
the chart that covers the point best, and the run goes on in it:

- ``(u, v)`` through the point's direction ``d``: ``d = P_c e(u, v)``, ``e' = P_c'^T d``,
  ``u' = atan2(e'_2, e'_1)``, ``v' = asin(e'_3)`` (exact: the same point, the same normal);
- the contact's frame angle ``psi`` (a grasp's; a body on a plane has none) by the angle
  ``delta`` from the old chart's frame axis ``x = S_u / |S_u|`` to the new one's, about the
  surface's own normal: ``psi' = psi + delta`` for either surface of the contact.

A longitude past +-3 pi is the same point 2 pi round: the chart stays and ``u`` wraps. A
surface whose one chart repeats (a torus, a surface of revolution: ``kind`` ``periodic``, no
chart parameter) wraps each repeating coordinate so, a whole period toward its domain's middle.
Nothing is located: any point of the charts' overlap serves, and the step's end is one.
Those wraps are made inside the C loops at the step (``c/wrap.c``, with ``wrap_slots``; the
loop goes on, and ``wrapped`` makes their records), and so is a change of chart where the run
allows it (the loop starts again from the mapped state, the chart in its own copy of ``p``; a
sliding contact's slip turned there with its fingertip's frame, ``runtime.modes``); elsewhere
(``wrap_only``: a table of inputs, an integration again) a change stops the loop and
``switch`` makes it.
"""
from __future__ import annotations

import math

import numpy as np

from grasping_sym.errors import ContactLeftContourError

#: The longitude's period (rad).
TURN = 2.0 * math.pi


def _cross(a, b) -> tuple[float, float, float]:
    return (a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0])


def _dot(a, b) -> float:
    return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]


def _unit(a) -> tuple[float, float, float]:
    n = math.sqrt(_dot(a, a))
    return (a[0] / n, a[1] / n, a[2] / n)


def _turn(chart: int, e) -> tuple[float, float, float]:
    """``P e`` for chart 1 (``P``: ``(e1, e2, e3) -> (e3, e1, e2)``), ``e`` for chart 0."""
    return (e[2], e[0], e[1]) if chart else tuple(e)


def _frame(entry: dict, chart: int, u: float, v: float):
    """``(d, x, n)`` of the atlas ``entry`` (its manifest) at ``(u, v)`` of ``chart``: the
    direction, the frame's unit ``S_u`` and the outward normal, in the shape's frame (Python
    floats: NumPy's overhead on 3-vectors would be most of a switch's cost)."""
    cu, su, cv, sv = math.cos(u), math.sin(u), math.cos(v), math.sin(v)
    e = _turn(chart, (cv * cu, cv * su, sv))
    e_u = _turn(chart, (-cv * su, cv * cu, 0.0))
    e_v = _turn(chart, (-sv * cu, -sv * su, cv))
    a = entry["axes"]
    if entry["kind"] == "linear":               # F(d) = diag(a) d
        S_u = (a[0] * e_u[0], a[1] * e_u[1], a[2] * e_u[2])
        S_v = (a[0] * e_v[0], a[1] * e_v[1], a[2] * e_v[2])
    else:  # F(d) = rho(d) d, rho = (sum (d_i/a_i)^n)^(-1/n): DF w = rho w + d (grad rho . w)
        n = int(entry["n"])
        s = sum((e[i] / a[i]) ** n for i in range(3))
        rho = s ** (-1.0 / n)
        grad = [-(s ** (-1.0 / n - 1.0)) * e[i] ** (n - 1) / a[i] ** n for i in range(3)]
        gu, gv = _dot(grad, e_u), _dot(grad, e_v)
        S_u = tuple(rho * e_u[i] + e[i] * gu for i in range(3))
        S_v = tuple(rho * e_v[i] + e[i] * gv for i in range(3))
    return e, _unit(S_u), _unit(_cross(S_u, S_v))


def coordinates(d, chart: int) -> tuple[float, float]:
    """``(u, v)`` in ``chart`` of the unit direction ``d``, ``u`` in ``(-pi, pi]``
    (``e = P^T d`` for chart 1)."""
    e = (d[1], d[2], d[0]) if chart else d
    return math.atan2(e[1], e[0]), math.asin(max(-1.0, min(1.0, float(e[2]))))


def _wrapped(value: float, period, center: float) -> float:
    """``value`` moved by whole ``period``s into ``[center - period/2, center + period/2]``
    (unchanged where ``period`` is None: a coordinate that does not repeat)."""
    return value if period is None else center + math.remainder(value - center, period)


def transition(entry: dict, chart: int, u: float, v: float) -> tuple[int, float, float, float]:
    """``(chart', u', v', delta)``: the point ``(u, v)`` of ``chart`` in the chart where its
    latitude is smaller (the same chart, ``u`` wrapped into ``(-pi, pi]``, if that is this
    one), and the angle ``delta`` from the old frame's ``x`` to the new one's about the normal.
    A repeating chart (``periodic``): the same chart, each repeating coordinate wrapped toward
    its domain's middle, nothing turned."""
    if entry["kind"] == "periodic":
        (pu, pv), (cu, cv) = entry["periods"], entry["centers"]
        return chart, _wrapped(u, pu, cu), _wrapped(v, pv, cv), 0.0
    d, x_old, n = _frame(entry, chart, u, v)
    other = 1 - chart
    u1, v1 = coordinates(d, other)
    if abs(v1) >= abs(v):                       # the seam: the same chart, the same frame
        return chart, math.remainder(u, TURN), v, 0.0
    _, x_new, _ = _frame(entry, other, u1, v1)
    y_old = _cross(n, x_old)
    return other, u1, v1, math.atan2(_dot(x_new, y_old), _dot(x_new, x_old))


def _wrap_slot(entry: dict, i_chart: int | None, cols, change: bool) -> list[float]:
    """A slot's row of ``c/wrap.c``'s table: u's and v's columns; 0 for a repeating chart, its
    periods (0: none) and middles; 1 (``F = diag(a) d``) or 2 (``F = rho(d) d``) for an atlas, its
    longitude's turn about 0, its chart parameter's and frame angle's indices (-1: none), its
    semi-axes and exponent, and whether the loop changes its chart (``change``); then -1, -1:
    no slip to turn with its frame (a run with modes gives a sliding contact's,
    ``runtime.modes``)."""
    if entry["kind"] == "periodic":
        (pu, pv), (cu, cv) = entry["periods"], entry["centers"]
        return [cols[0], cols[1], 0, pu or 0.0, pv or 0.0, cu, cv, -1, -1, 1.0, 1.0, 1.0, 0, 0, -1, -1]
    kind = 1 if entry["kind"] == "linear" else 2
    return [cols[0], cols[1], kind, TURN, 0.0, 0.0, 0.0, i_chart, -1 if cols[2] is None else cols[2],
            *entry["axes"], entry["n"], int(change), -1, -1]


def by_charts(p_names, t: np.ndarray, p, records, turn=None) -> list[tuple[int, int, np.ndarray]]:
    """The rows ``t`` (in time order) cut where ``records`` (switches, in time order) change a
    chart: ``[a, b)`` and each piece's ``p`` (``p``: the first piece's; a row at a change's
    time is before it; ``turn(p, record)``, where given, what else a change turns in ``p``: a
    sliding contact's slip direction, ``runtime.modes``). Wraps cut nothing: they keep their
    chart."""
    changed = [rec for rec in records if rec["chart"] is not None and rec["from"] != rec["to"]]
    if not changed:
        return [(0, len(t), p)]
    out, a, pk = [], 0, np.array(p, dtype=float)
    for rec in changed:
        b = max(a, int(np.searchsorted(t, rec["t"], side="right")))
        out.append((a, b, pk.copy()))
        pk[p_names.index(rec["chart"])] = rec["to"]
        if turn is not None:
            turn(pk, rec)
        a = b
    out.append((a, len(t), pk))
    return [piece for piece in out if piece[1] > piece[0]] or [(0, len(t), pk)]


def repeated(switches: list[dict], record: dict) -> bool:
    """Whether ``record`` carries the same coordinates at the same time as the last of
    ``switches``: a state carried across and straight back out, which no chart's edge makes
    (the run stops by name rather than going round)."""
    last = switches[-1] if switches else None
    return last is not None and last["coordinates"] == record["coordinates"] and \
        abs(last["t"] - record["t"]) <= 1e-12 * max(1.0, abs(record["t"]))


def name_charts(err, charts: dict[str, int]):
    """``err`` (an ``IntegratorError`` of a run on atlases) with the chart each chart
    parameter names where its state was written (``charts``): as ``err.charts`` and at the
    end of its message (its contact coordinates mean nothing without them). Once: an error
    already named keeps its charts. Returns ``err``."""
    if not charts or getattr(err, "charts", None) is not None or not err.args:
        return err
    err.charts = dict(charts)
    named = ", ".join(f"{k} = {v}" for k, v in charts.items())
    err.args = (f"{err.args[0]}; its contact coordinates in charts {named}", *err.args[1:])
    return err


class Atlases:
    """A model's atlases (its manifest's ``atlas``): each slot's chart parameter (None: a
    repeating chart), state columns and map; ``switch`` carries a state across."""

    def __init__(self, model):
        names, p_names = model.state_names, model.p_names
        self.model = model
        self.slots = []
        for entry in model.manifest.get("atlas", ()):
            cols = (names.index(entry["u"]), names.index(entry["v"]),
                    None if entry["psi"] is None else names.index(entry["psi"]))
            self.slots.append((entry, None if entry["param"] is None else p_names.index(entry["param"]), cols))
        # the columns whose edge is a switch: an atlas's u and v; a repeating chart's
        # repeating coordinates only (a revolved open contour's end is its surface's end)
        self.columns = {c: k for k, (entry, _, cols) in enumerate(self.slots) for j, c in enumerate(cols[:2])
                        if entry["kind"] != "periodic" or entry["periods"][j] is not None}
        #: the slots as the C loops take them (``c/wrap.c``: ``transition`` made there, at the
        #: step): wraps and changes of chart; wraps only (a change stops the loop)
        self.wrap_slots = np.array([_wrap_slot(entry, i, cols, True) for entry, i, cols in self.slots], dtype=float)
        self.wrap_only = np.array([_wrap_slot(entry, i, cols, False) for entry, i, cols in self.slots], dtype=float)

    def entry(self, chart: str) -> dict:
        """The atlas entry of the chart parameter ``chart``."""
        return next(entry for entry, _, _ in self.slots if entry["param"] == chart)

    def charts(self, p) -> dict[str, int]:
        """Each chart parameter's chart in ``p``."""
        return {entry["param"]: int(round(float(p[i]))) for entry, i, _ in self.slots if i is not None}

    def wrapped(self, raw) -> list[dict]:
        """The records of what the C loops made (``raw``: ``CompiledLibrary.wrapping``'s rows),
        as :meth:`switch`'s."""
        out = []
        for t, k, u0, v0, u1, v1, c0, c1, delta in raw:
            entry = self.slots[int(k)][0]
            out.append({"t": t, "chart": entry["param"], "coordinates": (entry["u"], entry["v"]),
                        "from": int(c0), "to": int(c1), "u": (u0, u1), "v": (v0, v1), "delta": delta,
                        "in_loop": True})
        return out

    def after(self, records: list[dict], p):
        """``p`` with the charts ``records`` end in (a copy; ``p`` itself where none changes)."""
        changed = [rec for rec in records if rec["from"] != rec["to"]]
        if not changed:
            return p
        p = np.array(p, dtype=float)
        for rec in changed:
            p[self.model.p_names.index(rec["chart"])] = rec["to"]
        return p

    def slot_of(self, err) -> int | None:
        """The atlas slot whose coordinates left their chart in ``err`` (a
        ``ContactLeftContourError`` of this model), or None (another state's bound)."""
        if not isinstance(err, ContactLeftContourError) or err.x is None:
            return None
        bad = getattr(err, "x_rejected", None)
        bad = np.asarray(err.x if bad is None else bad, dtype=float)
        m = self.model
        out = np.flatnonzero((bad < m.lower) | (bad > m.upper) | ~np.isfinite(bad))
        if not out.size or int(out[0]) not in self.columns:
            return None
        return self.columns[int(out[0])]

    def switch(self, k: int, t: float, x: np.ndarray, p: np.ndarray) -> tuple[np.ndarray, np.ndarray, dict]:
        """``(x', p', record)``: the state ``x`` and parameters ``p`` at ``t`` with slot ``k``
        carried to the chart that covers its point best (``transition``); ``p`` None (a model
        with no parameters: its atlases' charts all repeat) stays None."""
        entry, i_chart, (iu, iv, ipsi) = self.slots[k]
        chart = 0 if i_chart is None else int(round(float(p[i_chart])))
        new, u1, v1, delta = transition(entry, chart, float(x[iu]), float(x[iv]))
        x2, p2 = np.array(x, dtype=float), None if p is None else np.array(p, dtype=float)
        x2[iu], x2[iv] = u1, v1
        if ipsi is not None:
            x2[ipsi] = x2[ipsi] + delta
        if i_chart is not None:
            p2[i_chart] = float(new)
        record = {"t": float(t), "chart": entry["param"], "coordinates": (entry["u"], entry["v"]),
                  "from": chart, "to": new, "u": (float(x[iu]), u1), "v": (float(x[iv]), v1), "delta": delta,
                  "in_loop": False}
        return x2, p2, record
