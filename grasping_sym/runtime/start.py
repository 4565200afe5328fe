"""Consistent starting states chosen at run time, without a rebuild, on the stored start's branch.

``Model.initial_state(q1=0.6, theta=0.1)`` holds the given state components at their values
and solves the others, on the branch of the model's stored start (the scene's):

1. positions: every condition of a consistent contact, ``G(x) = 0``: the contact constraints
   (``Q, R`` in 2D) and the tangency that the contact's update law keeps along a run but
   that a start must meet (``tangency_defect``); G and its Jacobian are the compiled
   ``{name}_start`` (called through CasADi's ``external``). The scene names coordinates to
   hold at its start's values unless given (the manifest's ``start_hold``: the 2D object
   angle ``theta``) while the other free coordinates are enough to meet the conditions:
   ``initial_state(q1=0.6)`` turns the finger and rolls the contact, the object stays.

   The conditions have several solutions for the same given values (in 2D: two finger
   postures, each with its own contact point). The one returned is the stored start's,
   followed to the given values by continuation (``_continue``): the given values move on
   the straight line from the stored start's in adaptive steps; each step predicts along the
   family's tangent and corrects with Newton's method from there. A step is refused and
   halved when its corrector does not contract, when the corrector moves the pose by more
   than ``JUMP`` times the step (a jump to another root), when the branch's orientation
   changes (the sign of ``det dG/d(solved coordinates)``, which changes only where the
   family turns back), or when the contact leaves its contour's domain. So neighbouring
   values give neighbouring poses: the same branch, a contact point that moves continuously.

   Where the family turns back (a fold) or leaves the domain before the given values, the
   start is refused: ``StartBranchError`` when a consistent pose exists on another branch
   (Newton's method from the stored start in 1, 4, 16, then 64 steps finds the nearest;
   ``branch="any"`` accepts it), ``UnreachableStartError`` when none does;
2. speeds: the least-norm change of the speeds that were not given to ``Cdot(x) = 0`` (the
   speeds not given start at the stored start's, at rest for the built-in scenes); ``Cdot`` is
   affine in the speeds, so one step solves it up to rounding.

``solve_start`` (``Model.solve_start``) returns a ``StartSolution``: the state, the
coordinates solved, the contact point chosen and the branch, and whether it is the stored
start's. What the start fixes in the code (the 2D pivot) stays: a pose that the bodies cannot
take with the pivot where it is, or that puts the contact outside a contour's domain, is
refused with ``UnreachableStartError``.
"""
from __future__ import annotations

import hashlib
import math
from dataclasses import dataclass, field

import numpy as np

from grasping_sym.errors import ProblemsError, StartBranchError, UnreachableStartError
from grasping_sym.store import files as stored
from grasping_sym.store import safety

#: max|C| (m) and max|Cdot| (m/s) of an accepted start.
START_TOL = 1e-13
#: Gauss-Newton iterations (each with step halving) of one corrector.
MAX_ITERATIONS = 30
#: Numbers of equal steps tried in turn from the stored start when looking for the nearest
#: consistent pose on any branch (``branch="any"``, and the pose a refusal names).
CONTINUATION_STEPS = (1, 4, 16, 64)
#: What ``branch=`` accepts: ``"start"``, the stored start's branch only; ``"any"``, the
#: nearest consistent pose when the stored start's branch does not reach the given values.
BRANCHES = ("start", "any")
#: Continuation on the stored start's branch: the first step (a fraction of the way from the
#: stored start to the given values), the smallest (a step refused below it ends the branch),
#: the largest predicted change of any coordinate in one step (rad or m), the corrector's
#: move allowed per predicted move, the contraction each Newton step must achieve, the
#: Newton steps per continuation step and the continuation steps in all.
FIRST_STEP = 0.25
MIN_STEP = 2.0 ** -24
MAX_MOVE = 0.25
JUMP = 0.3
CONTRACTION = 0.5
STEP_ITERATIONS = 8
MAX_STEPS = 5000


@dataclass(frozen=True)
class StartSolution:
    """A start solved at run time (``Model.solve_start``) and the branch it lies on.

    Attributes
    ----------
    x
        The consistent state, ordered as ``model.state_names``.
    given
        The state components held, by name.
    solved
        The position coordinates solved, e.g. ``("q1", "q2", "s")`` with ``theta`` given in 2D.
    contact
        The contact point chosen: the contact parameters at ``x`` (the position states that
        have a contour's domain: ``s`` in 2D, in m; ``u_f1, v_f1, ...`` in 3D), by name.
    branch, start_branch
        The orientation of the solution family at ``x`` and at the stored start: the sign
        (+1 or -1) of ``det dG/d(solved)``, the start conditions' Jacobian in the solved
        coordinates; it changes only where the family turns back, so two poses with
        different signs lie on different branches. 0 where more coordinates are solved than
        there are conditions (3D: least-norm changes), where no sign is defined.
    on_start_branch
        True when ``x`` was reached by continuation from the stored start (always so with
        ``branch="start"``); False for a pose on another branch, accepted with ``branch="any"``.
    steps
        The continuation steps accepted on the stored start's branch.
    """

    x: np.ndarray = field(repr=False)
    given: dict[str, float]
    solved: tuple[str, ...]
    contact: dict[str, float]
    branch: int
    start_branch: int
    on_start_branch: bool
    steps: int

    def info(self) -> dict:
        """The record as plain JSON values (a ``with_start`` record's ``info["branch"]``)."""
        return {"given": dict(self.given), "solved": list(self.solved),
                "contact": dict(self.contact), "branch": self.branch,
                "start_branch": self.start_branch, "on_start_branch": self.on_start_branch,
                "steps": self.steps}


def initial_state(model, values: dict[str, float], branch: str = "start") -> np.ndarray:
    """``Model.initial_state``: the stored start (a fresh array) without ``values``, else the
    state ``solve`` finds on ``branch``."""
    if not values:
        if branch not in BRANCHES:
            return solve_start(model, values, branch).x  # refuses the bad branch
        return np.array(model.start["initial_state"], dtype=float)
    return solve(model, values, branch)


def store(model, record: dict) -> None:
    """Write the start ``record`` (``start_record``) beside the model, where
    ``grasping_sym.load`` finds it (``<directory>/starts/<key>.json``)."""
    starts = safety.ensure_dir(model.directory / stored.STARTS_DIR, root=model.directory)
    stored.write_json(starts / f"{record['key'][:16]}.json", record)


def start_record(model, values: dict[str, float], branch: str = "start") -> dict:
    """A start record (``runtime.stored``) for the state solved by ``solve_start``: the values
    of the start's run-time parameters that it implies (3D: the centre spring's rest point,
    the mean fingertip centre there), or the model's own where the scene fixes them (2D: the
    pivot), and the branch chosen (``info["branch"]``: ``StartSolution.info()``)."""
    solution, start = _solution_and_params(model, values, branch)
    tag = "" if branch == "start" else f"+branch={branch}"
    key = hashlib.sha256(f"{model.start['key']}+{sorted(values.items())!r}{tag}".encode()).hexdigest()
    charts = (model.start.get("info") or {}).get("charts")   # the state is in the model's charts
    return stored.start_record(solution.x, start, key, {"given": dict(values), "from": model.start["key"],
                                                       "branch": solution.info(),
                                                       **({"charts": dict(charts)} if charts else {})})


def start_point(model, values: dict[str, float], branch: str = "start") -> tuple[np.ndarray, dict[str, float]]:
    """``solve``'s state and the start's run-time values it implies (3D: the centre spring's
    rest point at the new mean fingertip centre; 2D: the model's own, the pivot stays; a free
    2D object's start centre moves with it)."""
    solution, start = _solution_and_params(model, values, branch)
    return solution.x, start


def _solution_and_params(model, values, branch):
    solution = solve_start(model, values, branch)
    implied = _conditions_function(model)(solution.x)[2]
    if implied.size:
        return solution, dict(zip(model.start_params, map(float, implied)))
    # start values that are states of the start (the manifest's ``start_implied``: a free 2D
    # object's start centre ``xm, ym``, which the paper's law pulls toward, is its ``x, y``)
    taken = model.manifest.get("start_implied", {})
    names = list(model.state_names)
    return solution, {k: float(solution.x[names.index(taken[k])]) if k in taken else float(v)
                      for k, v in model.start_params.items()}


def solve(model, values: dict[str, float], branch: str = "start") -> np.ndarray:
    """The consistent state on the stored start's branch with the state components ``values``
    (``solve_start(...).x``)."""
    return solve_start(model, values, branch).x


def solve_start(model, values: dict[str, float], branch: str = "start") -> StartSolution:
    """The consistent state with the state components ``values`` held, continued from the
    stored start on its branch (module docstring); ``branch="any"``: where that branch does
    not reach the values, the nearest consistent pose on another branch, reported as such."""
    names = model.state_names
    problems = [f"{k!r} is not a state of {model.name!r} (states: {', '.join(names)})"
                for k in values if k not in names]
    problems += [f"{k} = {v!r} must be a finite number" for k, v in values.items()
                 if k in names and not (isinstance(v, (int, float)) and math.isfinite(v))]
    if not (isinstance(branch, str) and branch in BRANCHES):
        problems.append(f"branch = {branch!r} must be 'start' (stay on the branch of the model's "
                        "stored start, the default) or 'any' (accept the nearest consistent pose "
                        "on another branch)")
    if problems:
        raise ProblemsError("the start asked of initial_state", problems)
    info = model.manifest.get("constraints") or {}
    conditions = model.manifest.get("start_conditions") or []
    has_conditions = bool(conditions) and model.library.has_constraints
    x0 = model.initial_state()
    if not values:
        return _stored_start(model, x0, info, has_conditions)
    if not has_conditions:
        modes = bool(model.manifest.get("modes"))
        why = ("a model with contact modes starts from its scene's start or from any state "
               "given whole (simulate(x0=...): each contact's mode is found there)" if modes else
               "its kind of scene (the paper's moving-frame formulation) cannot solve a start at "
               "run time")
        fix = ("give the state whole: x0 = model.initial_state(), change it, simulate(x0=x0)"
               if modes else "give the new start in the scene and build it, or use "
               "formulation='regular'")
        raise NotImplementedError(
            f"model {model.name!r} has no compiled start conditions ({model.name}_start): {why}; {fix}")
    target = {names.index(k): float(v) for k, v in values.items()}
    for i, v in target.items():  # a given value outside its bounds: refused now
        if not model.lower[i] <= v <= model.upper[i]:
            raise UnreachableStartError(
                f"initial_state: the given {names[i]} = {v:.6g} is outside {_bounds_of(model, i)} "
                f"[{model.lower[i]:.6g}, {model.upper[i]:.6g}]: give a value inside it")
    free = _free(model, info, values, len(conditions))
    speeds = [names.index(k) for k in info["velocity_states"] if k not in values]
    fn = _conditions_function(model)
    J0 = fn(x0)[1][:, free]
    if len(free) < len(conditions) or np.linalg.matrix_rank(J0) < len(conditions):
        raise UnreachableStartError(
            f"initial_state: with {', '.join(sorted(values))} given, the remaining coordinates "
            f"({', '.join(names[i] for i in free) or 'none'}) cannot meet the contact "
            f"conditions ({', '.join(conditions)}): give fewer coordinates (in 2D with one "
            "contact parameter s, one of theta, q1, q2, s fixes the others)")
    sign0 = _orientation(J0)
    try:
        x, steps = _continue(fn, model, x0, target, free, sign0)
        x = _correct(fn, names, x, free, sorted(values))
        on_branch = True
    except _BranchEnds as end:
        x = _other_branch(model, fn, x0, target, free, sorted(values), end, sign0, branch)
        steps, on_branch = end.steps, False
    x = _speeds(model, x, speeds, sorted(values))
    _check_domain(model, x)
    quat = [names.index(k) for k in ("qw", "qx", "qy", "qz") if k in names]
    if quat:  # the norm condition holds to rounding; make it exact
        x[quat] /= np.linalg.norm(x[quat])
    return StartSolution(x=x, given={k: float(v) for k, v in values.items()},
                         solved=tuple(names[i] for i in free), contact=_contact(model, x),
                         branch=_orientation(fn(x)[1][:, free]), start_branch=sign0,
                         on_start_branch=on_branch, steps=steps)


def _stored_start(model, x0, info, has_conditions) -> StartSolution:
    """The stored start as a ``StartSolution`` (its branch: with the scene's held
    coordinates and the given value of the first free one, as ``initial_state`` would solve)."""
    sign, solved = 0, ()
    if has_conditions:
        n = len(model.manifest["start_conditions"])
        free = _free(model, info, {}, n)
        if len(free) > n:  # one coordinate given: the first position not held
            free = free[1:]
        solved = tuple(model.state_names[i] for i in free)
        sign = _orientation(_conditions_function(model)(x0)[1][:, free])
    return StartSolution(x=x0, given={}, solved=solved, contact=_contact(model, x0), branch=sign,
                         start_branch=sign, on_start_branch=True, steps=0)


def _free(model, info, values, n_conditions) -> list[int]:
    """The position coordinates solved: those not given, less the scene's held ones
    (``start_hold``) while enough remain for the conditions."""
    names = model.state_names
    positions = [names.index(k) for k in info["position_states"] if k not in values]
    hold = [names.index(k) for k in model.manifest.get("start_hold", []) if k not in values]
    if len(set(positions) - set(hold)) >= n_conditions:
        positions = [i for i in positions if i not in hold]
    return positions


def _contact(model, x) -> dict[str, float]:
    """The contact parameters at ``x``: the position states with a contour's domain (not the
    joints with limits)."""
    positions = (model.manifest.get("constraints") or {}).get("position_states", model.state_names)
    names = model.state_names
    return {k: float(x[names.index(k)]) for k in positions if k not in model.joint_limits and (
        math.isfinite(model.lower[names.index(k)]) or math.isfinite(model.upper[names.index(k)]))}


def _bounds_of(model, i: int) -> str:
    """What bounds state ``i``: its joint's limits or its contour's domain."""
    return "its joint's limits" if model.state_names[i] in model.joint_limits else "its contour's domain"


def _orientation(J: np.ndarray) -> int:
    """sign(det J) of a square Jacobian (+1, -1; 0 if singular or not square)."""
    if J.shape[0] != J.shape[1] or not np.all(np.isfinite(J)):
        return 0
    sign, _ = np.linalg.slogdet(J)
    return int(sign)


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


class _BranchEnds(Exception):
    """Continuation on the stored start's branch stopped short: ``why`` (``"fold"`` or
    ``("domain", state index)``), at ``x`` (``lam`` of the way), after ``steps`` steps."""

    def __init__(self, why, lam: float, x: np.ndarray, steps: int):
        self.why, self.lam, self.x, self.steps = why, lam, x, steps


def _continue(conditions, model, x0: np.ndarray, target: dict[int, float], free: list[int],
              sign0: int) -> tuple[np.ndarray, int]:
    """From the stored start ``x0`` to the given values ``target`` (state index -> value) on
    ``x0``'s branch: adaptive predictor-corrector steps (module docstring). Returns the state
    (conditions met to ``START_TOL``) and the steps taken; raises ``_BranchEnds``."""
    idx = np.array(sorted(target))
    a, b = x0[idx], np.array([target[i] for i in idx])
    x, lam, h, steps = x0.copy(), 0.0, FIRST_STEP, 0
    J = conditions(x)[1]
    why = "fold"
    for _ in range(MAX_STEPS):
        if lam >= 1.0:
            return x, steps
        tangent = -np.linalg.lstsq(J[:, free], J[:, idx] @ (b - a), rcond=None)[0]
        speed = max(float(np.max(np.abs(tangent), initial=0.0)), float(np.max(np.abs(b - a))))
        if speed * h > MAX_MOVE:
            h = MAX_MOVE / speed
        if h < MIN_STEP or not math.isfinite(speed):
            break
        last = lam + h >= 1.0
        trial = x.copy()
        trial[idx] = b if last else a + (b - a) * (lam + h)
        trial[free] += min(h, 1.0 - lam) * tangent
        got, why = _step(conditions, model, x, trial, free, sign0)
        if got is None:
            h *= 0.5
            if h < MIN_STEP:
                break
            continue
        x, J = got
        lam, steps, h = (1.0 if last else lam + h), steps + 1, 2.0 * h
    raise _BranchEnds(why, lam, x, steps)


def _step(conditions, model, x_prev, trial, free, sign0):
    """Newton's corrector from the predicted ``trial``: ``((x, dG/dx), None)`` for an accepted
    step, ``(None, why)`` for a refused one."""
    moved = float(np.max(np.abs(trial - x_prev)))
    x, last = trial.copy(), math.inf
    for _ in range(STEP_ITERATIONS + 1):
        G, J, _ = conditions(x)
        if not (np.all(np.isfinite(G)) and np.all(np.isfinite(J))):
            return None, "fold"
        if float(np.max(np.abs(G))) <= START_TOL:
            break
        d = np.linalg.lstsq(J[:, free], G, rcond=None)[0]
        size = float(np.max(np.abs(d)))
        if size > CONTRACTION * last and size > 1e-14:
            return None, "fold"
        x[free] -= d
        last = size
    else:
        return None, "fold"
    if float(np.max(np.abs(x - trial))) > JUMP * moved:
        return None, "fold"
    if sign0 and _orientation(J[:, free]) != sign0:
        return None, "fold"
    bad = np.flatnonzero((x[free] < model.lower[free]) | (x[free] > model.upper[free]))
    if bad.size:
        return None, ("domain", free[int(bad[0])])
    return (x, J), None


def _other_branch(model, conditions, x0, target, free, given, end: _BranchEnds, sign0: int,
                  branch: str) -> np.ndarray:
    """Where the stored start's branch ends short of the given values: the nearest consistent
    pose on another branch (``branch="any"``), or the refusal naming it and the branch's end."""
    names = model.state_names
    asked = ", ".join(f"{names[i]} = {v:.6g}" for i, v in sorted(target.items()))
    solved = ", ".join(names[i] for i in free)
    if end.why == "fold":
        where = "the family of consistent poses turns back (a fold) or becomes singular"
    else:
        i = end.why[1]
        where = (f"the contact parameter {names[i]} reaches the end of its contour's domain "
                 f"[{model.lower[i]:.6g}, {model.upper[i]:.6g}]")
    ended = (f"on the branch of the scene's start ({_pose(names, x0, [*sorted(target), *free])}; "
             f"{_sign_text(sign0, solved)}), continued in small steps, {where} at "
             f"{_pose(names, end.x, sorted(target))} ({_pose(names, end.x, free)}), "
             f"{100 * end.lam:.3g} % of the way")
    fix = ("choose values between the scene's start and where its branch ends, or build the scene "
           "with a start near the pose you mean")
    try:
        other = _positions(conditions, names, x0, target, free)
    except UnreachableStartError as exc:
        raise UnreachableStartError(
            f"initial_state: no consistent pose with {asked}: {ended}; and Newton's method from "
            f"the scene's start finds none on another branch either (max|G| = {exc.residual:.3g} "
            f"in up to {CONTINUATION_STEPS[-1]} steps): the bodies cannot touch there with the "
            f"pivot where the scene puts it. Fix: {fix}", exc.residual) from None
    outside = [i for i in free if not model.lower[i] <= other[i] <= model.upper[i]]
    if outside:
        i = outside[0]
        raise UnreachableStartError(
            f"initial_state: no consistent pose with {asked}: {ended}; the nearest pose on "
            f"another branch puts the contact parameter {names[i]} = {other[i]:.6g} outside its "
            f"contour's domain [{model.lower[i]:.6g}, {model.upper[i]:.6g}]. Fix: {fix}")
    if branch == "any":
        return other
    sign = _orientation(conditions(other)[1][:, free])
    raise StartBranchError(
        f"initial_state: {asked} is not reached on the branch of the scene's start: {ended}. The "
        f"nearest consistent pose, {_pose(names, other, free)} ({_sign_text(sign, solved)}), "
        f"lies on another branch: another finger posture and contact point, which a sweep would "
        f"show as a jump. Fix: {fix}; or pass branch='any' to accept the other branch "
        f"(model.solve_start(..., branch='any') reports the branch chosen)",
        found=other, reached=end.x)


def _pose(names, x, indices) -> str:
    return ", ".join(f"{names[i]} = {x[i]:.6g}" for i in indices)


def _sign_text(sign: int, solved: str) -> str:
    if not sign:
        return "no orientation defined"
    return f"det dG/d({solved}) {'>' if sign > 0 else '<'} 0"


def _positions(conditions, names, x0: np.ndarray, target: dict[int, float], free: list[int]) -> np.ndarray:
    """The nearest consistent pose on any branch: from the stored start ``x0`` to the given
    values ``target`` (state index -> value) in 1, 4, 16, then 64 equal steps, with Newton's
    corrector on the ``free`` coordinates after each, and no branch check."""
    given = sorted(names[i] for i in target)
    worst = math.inf
    for n_steps in CONTINUATION_STEPS:
        x = x0.copy()
        try:
            for k in range(1, n_steps + 1):
                for i, v in target.items():
                    x[i] = v if k == n_steps else x0[i] + (v - x0[i]) * k / n_steps
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
            f"initial_state: the consistent pose puts {model.state_names[i]} = {x[i]:.6g} outside "
            f"{_bounds_of(model, i)} [{model.lower[i]:.6g}, {model.upper[i]:.6g}]: choose values "
            "nearer the scene's start")
