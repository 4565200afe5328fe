"""The friction cone at every contact of a run: its quantities, its check, its event.

A rolling contact transmits a normal force ``f`` and a tangential force ``F_t`` (the contact
multipliers: 2D ``f``, ``lam``; 3D ``f{i}`` and ``(lam{i}, eta{i})`` along the contact
frame's orthonormal tangents). Coulomb's law keeps it rolling while ``|F_t| <= mu f``
(``docs/conventions.md``, "Friction"). Every model compiles these multipliers for every contact
whatever outputs it shows (``scene.check_outputs()``), so with ``mu`` given:

- the outputs of a run gain, per contact ``i`` (1, 2, ...): ``normal_force{i}`` (N),
  ``tangential_force{i}`` (N), ``cone_ratio{i}`` = ``|F_t| / f`` and ``cone_margin{i}`` =
  ``mu f - |F_t|`` (N);
- the checks stop a run whose force leaves a cone: ``FrictionConeError`` at the time where
  the margin reaches zero, located by integrating again from the last output sample before
  it (``runtime.events``), with the contact, ``mu`` and the forces there.
"""
from __future__ import annotations

import math
import numbers

import numpy as np

from grasping_sym.contact import Coulomb
from grasping_sym.errors import FrictionConeError, GraspingSymError, RunArgumentError

#: The per-contact outputs a run with ``mu`` gains (``{i}``: the contact, from 1).
QUANTITIES = ("normal_force{i}", "tangential_force{i}", "cone_ratio{i}", "cone_margin{i}")


def contacts(model) -> tuple[tuple[str, tuple[str, ...]], ...]:
    """Per contact, the compiled outputs of its normal force and of its tangential force's
    components: ``(("f", ("lam",)),)`` for one 2D finger, ``(("f1", ("lam1", "eta1")), ...)``
    in 3D. Cached on the model."""
    cached = getattr(model, "_friction_contacts", None)
    if cached is not None:
        return cached
    cols = set(model.columns)
    if "f" in cols:
        found = (("f", ("lam",) if "lam" in cols else ()),)
    else:
        found, i = [], 1
        while f"f{i}" in cols:
            found.append((f"f{i}", tuple(k for k in (f"lam{i}", f"eta{i}") if k in cols)))
            i += 1
        found = tuple(found)
    model._friction_contacts = found
    return found


def resolve(model, mu) -> np.ndarray | None:
    """The friction coefficient of every contact for a run: ``mu`` (a number, one per contact,
    or a ``gs.contact.Coulomb``), else the model's own law (``model.friction``, from its
    scene); None when neither gives one (no friction limit: today's rolling forever) or every
    coefficient is ``inf``. A bad value is refused by name."""
    law = model.friction if mu is None else mu
    if law is None:
        return None
    found = contacts(model)
    n = len(found)
    if not n:
        raise RunArgumentError(f"mu given, but model {model.name!r} has no contact forces among its "
                               "compiled outputs: rebuild it (gs.build) with this version")
    if any(not tang for _, tang in found):
        raise RunArgumentError(f"mu given, but model {model.name!r} was built without its tangential "
                               "forces among the outputs its checks read: rebuild it (gs.build) "
                               "with this version")
    if isinstance(law, Coulomb):
        try:
            values = law.per_contact(n)
        except GraspingSymError as exc:
            raise RunArgumentError(str(exc)) from None
    else:
        values = _numbers(law, n)
    arr = np.array(values, dtype=float)
    return None if np.all(arr == math.inf) else arr


def _numbers(mu, n: int) -> tuple[float, ...]:
    if isinstance(mu, (bool, np.bool_, str, bytes)):
        raise RunArgumentError(f"mu = {mu!r} is {type(mu).__name__}: give a number >= 0, one per "
                               f"contact ({n}), or gs.contact.coulomb(mu)")
    if isinstance(mu, numbers.Real):
        vals = (float(mu),) * n
    else:
        arr = np.asarray(mu)
        if arr.dtype.kind not in "fiu" or arr.shape != (n,):
            raise RunArgumentError(f"mu = {mu!r:.60} must be one number >= 0 or {n} (one per contact)")
        vals = tuple(float(v) for v in arr)
    for k, v in enumerate(vals):
        if not (v >= 0 and (math.isfinite(v) or v == math.inf)):
            raise RunArgumentError(f"mu = {v!r} (contact {k + 1}) must be a number >= 0 (math.inf: "
                                   "the contact never slips)")
    return vals


def per_run(model, mu, n_runs: int) -> np.ndarray | None:
    """``simulate_many``'s ``mu``: None, one value for every run as ``resolve`` takes it (a
    number, a tuple with one per contact, a ``Coulomb``), or one per run (an array ``(N,)``, or
    ``(N, n_contacts)``); ``(N, n_contacts)`` or None."""
    if mu is None or isinstance(mu, (Coulomb, numbers.Real, tuple)) or np.ndim(mu) == 0:
        one = resolve(model, mu)
        return None if one is None else np.tile(one, (n_runs, 1))
    arr = np.asarray(mu)
    n = len(contacts(model))
    if arr.dtype.kind not in "fiu" or arr.ndim not in (1, 2) or len(arr) != n_runs \
            or (arr.ndim == 2 and arr.shape[1] != n):
        raise RunArgumentError(f"mu has shape {arr.shape}: give one number, ({n_runs},) one per run "
                               f"or ({n_runs}, {n}) one per run and contact")
    arr = arr.astype(float).reshape(n_runs, -1)
    arr = np.broadcast_to(arr, (n_runs, n)).copy()
    bad = ~((arr >= 0) & (np.isfinite(arr) | (arr == math.inf)))
    if bad.any():
        i = int(np.flatnonzero(bad.any(axis=1))[0])
        raise RunArgumentError(f"mu must be >= 0 (math.inf: never slips); run {i} has {arr[i].tolist()}")
    return arr


def forces(model, outs: dict) -> tuple[list[np.ndarray], list[np.ndarray]]:
    """Per contact, its normal force ``f`` and tangential magnitude ``|F_t|`` from the
    compiled outputs ``outs`` (name -> values)."""
    normal, tangential = [], []
    for f, tang in contacts(model):
        normal.append(np.asarray(outs[f], dtype=float))
        comps = [np.asarray(outs[k], dtype=float) for k in tang]
        tangential.append(np.abs(comps[0]) if len(comps) == 1 else np.hypot(*comps))
    return normal, tangential


def quantities(model, outs: dict, mu: np.ndarray) -> dict[str, np.ndarray]:
    """``QUANTITIES`` of every contact from the compiled outputs ``outs``; ``mu`` per contact
    (``(n_contacts,)``, or ``(N, n_contacts)`` for outputs over N runs on their first axis)."""
    out = {}
    normal, tangential = forces(model, outs)
    mu = np.asarray(mu, dtype=float)
    for i, (f, ft) in enumerate(zip(normal, tangential)):
        m = mu[..., i]
        if m.ndim and f.ndim > 1:
            m = m.reshape(-1, *([1] * (f.ndim - 1)))
        with np.errstate(divide="ignore", invalid="ignore"):
            ratio = ft / f
        ratio[~(f > 0)] = np.inf
        out[f"normal_force{i + 1}"] = f.copy()
        out[f"tangential_force{i + 1}"] = ft
        out[f"cone_ratio{i + 1}"] = ratio
        out[f"cone_margin{i + 1}"] = m * f - ft if np.all(np.isfinite(m)) else \
            np.where(np.isinf(m), np.inf, m * f - ft)
    return out


def margins(model, outs: dict, mu) -> np.ndarray:
    """``cone_margin{i}`` of ``quantities``, one contact per entry of the last axis."""
    q = quantities(model, outs, mu)
    return np.stack([q[f"cone_margin{i}"] for i in range(1, len(contacts(model)) + 1)], axis=-1)


def witness(model, mu: np.ndarray, contact: int):
    """The cone margin of one contact (0-based) as a function of one state's compiled outputs
    (name -> value): the function ``runtime.events`` finds the root of."""
    f, tang = contacts(model)[contact]
    m = float(mu[contact])

    def margin(y: dict) -> float:
        return m * y[f] - math.hypot(*(y[k] for k in tang))
    return margin


def first_exit(margins: np.ndarray):
    """The first sample where a contact's margin (``(samples, contacts)``) is <= 0 (NaN
    counts): ``(sample, contact)`` (0-based), None if none."""
    bad = ~(margins > 0)
    rows = np.flatnonzero(bad.any(axis=1))
    if not rows.size:
        return None
    i = int(rows[0])
    return i, int(np.flatnonzero(bad[i])[0])


def clean(model, outs: dict, mu: np.ndarray) -> np.ndarray:
    """Per run (outputs ``(N, m)`` by name, ``mu`` ``(N, n_contacts)``): True where every
    contact stays inside its cone at every sample."""
    return np.all(margins(model, outs, mu) > 0, axis=(1, 2))


def cone_error(model, t: float, x, y: dict, mu: np.ndarray, contact: int, located: str) -> FrictionConeError:
    """The named error of contact ``contact`` (0-based) leaving its cone at ``t`` (state ``x``,
    its compiled outputs ``y``); ``located`` says how the time was found."""
    f_name, tang = contacts(model)[contact]
    f = float(y[f_name])
    ft = math.hypot(*(float(y[k]) for k in tang))
    m = float(mu[contact])
    ratio = ft / f if f > 0 else math.inf
    return FrictionConeError(
        t, x,
        f"contact {contact + 1} leaves its friction cone at t = {t:.10g} s: |F_t| = {ft:.6g} N, "
        f"f = {f:.6g} N, |F_t|/f = {ratio:.6g} reaches mu = {m:g} ({located}); the rolling model "
        "needs more friction than the contact has, and the contact would slip. Raise mu, "
        "squeeze harder (fd) or move more gently; or pass mu=math.inf (or checks=False) to "
        "integrate the rolling model on regardless",
        model.state_names, contact=contact + 1, mu=m, normal=f, tangential=ft)


def inside(model, X: np.ndarray, mu: np.ndarray) -> bool:
    """True when every contact's force is strictly inside its cone at every row of ``X`` (the
    compiled outputs at the model's own run-time parameters): the short way's check
    (``runtime.fastpath``, a few microseconds); False sends the run the full way, which names
    the event."""
    idx = getattr(model, "_friction_columns", None)
    if idx is None:
        cols = {k: i for i, k in enumerate(model.columns)}
        found = contacts(model)
        idx = model._friction_columns = (np.array([cols[f] for f, _ in found]),
                                          np.array([[cols[k] for k in tang] for _, tang in found]))
    Y = model.library.outputs_batch(X, model.default_params if model.p_names else None)
    T = Y[:, idx[1]]
    return bool((mu * Y[:, idx[0]] > np.sqrt((T * T).sum(axis=2))).all())
