"""Consistent starting states chosen at run time, without a rebuild.

``Model.initial_state(q1=0.6, theta=0.1)`` holds the given state components at their values
and solves the others, starting from the model's stored start (the scene's):

1. positions: damped Gauss-Newton on every condition of a consistent contact, ``G(x) = 0``:
   the contact constraints (``Q, R`` in 2D) and the tangency that the contact's update law
   keeps along a run but that a start must meet (``tangency_defect``), with the least-norm
   change of the position states that were not given; G and its Jacobian are the compiled
   ``{name}_start`` (called through CasADi's ``external``). The
   scene names coordinates to hold at its start's values unless given (the manifest's
   ``start_hold``: the 2D object angle ``theta``) while the other free coordinates are
   enough to meet the constraints: ``initial_state(q1=0.6)`` turns the finger and rolls the
   contact, the object stays;
2. speeds: the least-norm change of the speeds that were not given to ``Cdot(x) = 0`` (the
   speeds not given start at the stored start's, at rest for the built-in scenes); ``Cdot`` is
   affine in the speeds, so one step solves it up to rounding.

What the start fixes in the code (the 2D pivot) stays: a pose that the bodies cannot take
with the pivot where it is, or that puts the contact outside a contour's domain, is refused
with ``UnreachableStartError``.
"""
from __future__ import annotations

import hashlib
import math

import numpy as np

from grasping_sym.errors import UnreachableStartError

#: max|C| (m) and max|Cdot| (m/s) of an accepted start.
START_TOL = 1e-13
#: Gauss-Newton iterations (each with step halving) of one corrector.
MAX_ITERATIONS = 30
#: Numbers of continuation steps tried in turn from the stored start to the given values.
CONTINUATION_STEPS = (1, 4, 16, 64)


def start_record(model, values: dict[str, float]) -> dict:
    """A start record (``runtime.stored``) for the state solved by ``solve``: the values of the
    start's run-time parameters that it implies (3D: the centre spring's rest point, the mean
    fingertip centre there), or the model's own where the scene fixes them (2D: the pivot)."""
    from grasping_sym.runtime import stored  # noqa: PLC0415

    x, start = start_point(model, values)
    key = hashlib.sha256(f"{model.start['key']}+{sorted(values.items())!r}".encode()).hexdigest()
    return stored.start_record(x, start, key, {"given": dict(values), "from": model.start["key"]})


def start_point(model, values: dict[str, float]) -> tuple[np.ndarray, dict[str, float]]:
    """``solve``'s state and the start's run-time values it implies (3D: the centre spring's
    rest point at the new mean fingertip centre; 2D: the model's own, the pivot stays)."""
    x = solve(model, values)
    implied = _conditions_function(model)(x)[2]
    if implied.size:
        return x, dict(zip(model.start_params, map(float, implied)))
    return x, dict(model.start_params)


def solve(model, values: dict[str, float]) -> np.ndarray:
    """The consistent state nearest the stored start with the state components ``values``."""
    names = model.state_names
    problems = [f"{k!r} is not a state of {model.name!r} (states: {', '.join(names)})"
                for k in values if k not in names]
    problems += [f"{k} = {v!r} must be a finite number" for k, v in values.items()
                 if k in names and not (isinstance(v, (int, float)) and math.isfinite(v))]
    if problems:
        raise ValueError("initial_state: " + "; ".join(problems))
    info = model.manifest.get("constraints") or {}
    conditions = model.manifest.get("start_conditions") or []
    if not conditions or not model.library.has_constraints:
        raise NotImplementedError(
            f"model {model.name!r} has no compiled start conditions ({model.name}_start): its "
            "kind of scene (the paper's moving-frame formulation) cannot solve a start at run "
            "time; give the new start in the scene and build it, or use formulation='regular'")
    x0 = model.initial_state()
    target = {names.index(k): float(v) for k, v in values.items()}
    positions = [names.index(k) for k in info["position_states"] if k not in values]
    hold = [names.index(k) for k in model.manifest.get("start_hold", []) if k not in values]
    if len(set(positions) - set(hold)) >= len(conditions):
        positions = [i for i in positions if i not in hold]
    speeds = [names.index(k) for k in info["velocity_states"] if k not in values]
    x = _positions(_conditions_function(model), names, x0, target, positions)
    x = _speeds(model, x, speeds, sorted(values))
    _check_domain(model, x)
    quat = [names.index(k) for k in ("qw", "qx", "qy", "qz") if k in names]
    if quat:  # the norm condition holds to rounding; make it exact
        x[quat] /= np.linalg.norm(x[quat])
    return x


def _conditions_function(model):
    """``x -> (G, dG/dx, v)`` of the compiled ``{name}_start`` (loaded once per model): the
    start conditions, their Jacobian and the start values ``x`` implies (empty in 2D)."""
    fn = getattr(model, "_start_conditions", None)
    if fn is None:
        import casadi as ca  # noqa: PLC0415 - only run-time starts need it

        ext = ca.external(f"{model.name}_start", str(model.library_path))
        p = model.default_params if model.p_names else np.zeros(0)

        def fn(x):
            G, J, v = ext(x, p)
            return np.asarray(G, float).ravel(), np.asarray(J, float), np.asarray(v, float).ravel()

        model._start_conditions = fn
    return fn


class _Stuck(Exception):
    """Newton's corrector did not reach the tolerance (``residual``: max|G| reached)."""

    def __init__(self, residual: float):
        self.residual = residual


def _positions(conditions, names, x0: np.ndarray, target: dict[int, float], free: list[int]) -> np.ndarray:
    """Continuation from the stored start ``x0`` to the given values ``target`` (state index
    -> value) in 1, 4, 16, then 64 equal steps, with Newton's corrector on the ``free``
    coordinates after each: far poses are reached along the family of consistent ones."""
    given = sorted(names[i] for i in target)
    worst = math.inf
    for n_steps in CONTINUATION_STEPS:
        x = x0.copy()
        try:
            for k in range(1, n_steps + 1):
                for i, v in target.items():
                    x[i] = x0[i] + (v - x0[i]) * k / n_steps
                x = _correct(conditions, names, x, free, given)
            return x
        except _Stuck as exc:
            worst = min(worst, exc.residual)
    raise UnreachableStartError(
        f"initial_state: no consistent pose with {', '.join(given)} as given: the bodies cannot "
        f"touch there with the pivot where the scene puts it (the contact conditions stay at "
        f"max|G| = {worst:.3g} along the way from the scene's start, in up to "
        f"{CONTINUATION_STEPS[-1]} steps): choose values nearer the scene's start, or build the "
        "scene with that start", worst)


def _correct(conditions, names, x: np.ndarray, free: list[int], given: list[str]) -> np.ndarray:
    """Damped Gauss-Newton on ``G(x) = 0`` over ``free``, least-norm steps, until max|G|
    falls to rounding (accepted at ``START_TOL``)."""
    G = conditions(x)[0]
    merit = float(G @ G)
    for _ in range(MAX_ITERATIONS):
        if float(np.max(np.abs(G))) <= START_TOL * 1e-3:  # past the tolerance, to rounding
            return x
        J = conditions(x)[1][:, free]
        if not free or np.linalg.matrix_rank(J) < J.shape[0]:
            raise UnreachableStartError(
                f"initial_state: with {', '.join(given)} given, the remaining coordinates "
                f"({', '.join(names[i] for i in free) or 'none'}) cannot meet the contact "
                f"conditions (max|G| = {np.max(np.abs(G)):.3g}): give fewer coordinates (in 2D "
                "with one contact parameter s, one of theta, q1, q2, s fixes the others)",
                float(np.max(np.abs(G))))
        step = -np.linalg.lstsq(J, G, rcond=None)[0]
        alpha = 1.0
        while alpha > 1e-6:
            trial = x.copy()
            trial[free] += alpha * step
            G_trial = conditions(trial)[0]
            if np.all(np.isfinite(G_trial)) and float(G_trial @ G_trial) < merit:
                x, G, merit = trial, G_trial, float(G_trial @ G_trial)
                break
            alpha *= 0.5
        else:
            break  # no decrease left: at rounding, or stuck
    residual = float(np.max(np.abs(G)))
    if residual <= START_TOL:
        return x
    raise _Stuck(residual)


def _speeds(model, x: np.ndarray, free: list[int], given: list[str]) -> np.ndarray:
    """Least-norm change of the ``free`` speeds to ``Cdot(x) = 0`` (affine in the speeds)."""
    lib = model.library  # its calls use the model's p
    for _ in range(3):
        _, _, Cd, JCd = lib.constraints(x)
        if float(np.max(np.abs(Cd))) <= START_TOL:
            return x
        if not free:
            break
        x = x.copy()
        x[free] -= np.linalg.lstsq(JCd[:, free], Cd, rcond=None)[0]
    rate = float(np.max(np.abs(lib.constraints(x)[2])))
    if rate <= START_TOL:
        return x
    raise UnreachableStartError(
        f"initial_state: the speeds given ({', '.join(given)}) leave the contact constraints' "
        f"rate at max|Cdot| = {rate:.3g} m/s: the bodies would separate or slip; give fewer speeds",
        rate)


def _check_domain(model, x: np.ndarray) -> None:
    bad = np.flatnonzero((x < model.lower) | (x > model.upper))
    if bad.size:
        i = int(bad[0])
        raise UnreachableStartError(
            f"initial_state: the consistent pose puts the contact parameter "
            f"{model.state_names[i]} = {x[i]:.6g} outside its contour's domain "
            f"[{model.lower[i]:.6g}, {model.upper[i]:.6g}]: choose values nearer the scene's start")
