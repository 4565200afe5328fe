"""A failed integration named: where a contact left its contour or a joint reached its limit,
or that the state blew up.

The C loops check the contact parameters after every step; SUNDIALS, run through CasADi, is
seen only at the output times, so an exit between two outputs is located by running the
interval again in the C Radau loop (``locate_exit``). A rejected step that overshot a domain
by far is a numerical blow-up of an explicit method on a stiff system (``blow_up``).
"""
from __future__ import annotations

import math

import numpy as np

from grasping_sym.errors import (
    ContactLeftContourError,
    ContactModeError,
    ContactOpenedError,
    FrictionConeError,
    IntegratorError,
    JointLimitError,
    RelativeCurvatureError,
    StateLeftDomainError,
)
from grasping_sym.runtime import c_loops

#: A batch's codes (``runtime.batch.STATUS``) beside the C loops' (-1 ... -9): a run whose
#: initial state ``simulate`` refuses, and a run stopped by an event along it.
REFUSED, EVENT = -10, -11


def status_of(exc: Exception) -> int:
    """A batch's code for the error ``simulate`` raised for one of its runs (the batches that
    run their runs by ``simulate``'s code: a model with contact modes, or with atlases)."""
    if isinstance(exc, ValueError):  # InconsistentInitialStateError among them: refused
        return REFUSED
    if isinstance(exc, (ContactModeError, ContactOpenedError, FrictionConeError, RelativeCurvatureError)):
        return EVENT
    if isinstance(exc, StateLeftDomainError):
        return c_loops.ERR_BOUNDS
    if getattr(exc, "stiff", False):
        return c_loops.ERR_STIFF
    return int(getattr(exc, "code", c_loops.ERR_EVAL))


#: Fraction of a contour's domain crossed in one rejected step that names a blow-up.
BLOW_UP_JUMP = 0.25
#: What a renamed error keeps of the integrator's.
_CARRIED = ("t_rejected", "x_rejected", "trajectory", "code", "stats", "stiff", "cause")


def left_domain(model, t: float, x, i: int, where: str) -> StateLeftDomainError:
    """The error of state component ``i`` outside its bounds at ``t`` (``x`` the last good
    state, ``where`` says where it was found): ``JointLimitError`` for a joint with limits
    (the manifest's ``joint_limits``), else ``ContactLeftContourError``."""
    name, lo, hi = model.state_names[i], model.lower[i], model.upper[i]
    if name in model.joint_limits:
        return JointLimitError(
            t, x, f"joint {name} reached its limits [{lo:.6g}, {hi:.6g}] rad ({where}); "
            "the finger cannot go on: change the motion or the law, or widen the joint's limits "
            "(RevoluteJoint.limits; a URDF joint's <limit>)", model.state_names)
    return ContactLeftContourError(
        t, x, f"contact parameter {name} left the contour's domain [{lo:.6g}, {hi:.6g}] "
        f"({where}); extend the contour's domain or shorten the simulation", model.state_names)


def _first_out(model, x) -> int | None:
    bad = np.flatnonzero((np.asarray(x) < model.lower) | (np.asarray(x) > model.upper))
    return int(bad[0]) if bad.size else None


def check_bounds(model, t: float, x: np.ndarray, previous=None) -> None:
    """Raise ``ContactLeftContourError`` (``JointLimitError`` for a joint) when ``x`` is
    outside a contour's domain or a joint's limits (at the crossing interpolated from
    ``previous = (t, x)``, when given)."""
    i = _first_out(model, x)
    if i is None:
        return
    t_cross, x_good = t, x
    if previous is not None:
        tp, xp = previous
        bound = model.lower[i] if x[i] < model.lower[i] else model.upper[i]
        frac = (bound - xp[i]) / (x[i] - xp[i])
        t_cross, x_good = tp + frac * (t - tp), xp
    raise left_domain(model, t_cross, x_good, i, f"{model.state_names[i]} = {x[i]:.6g}, crossing at "
                      f"about t = {t_cross:.6g} s")


def exit_at_failure(model, exc: IntegratorError, t_eval: np.ndarray, p, rtol: float,
                    atol: float) -> IntegratorError:
    """A CVODES failure caused by a contact leaving its contour (the guarded rhs is NaN
    outside the domains, so CVODES cannot step past the exit and fails there), named as
    such: the Radau loop, which checks the bounds after every step, is run from the last
    recovered state across the failure time; ``exc`` itself when it finds no exit."""
    traj = getattr(exc, "trajectory", None)
    if "rhs_guarded" not in model.manifest or traj is None or not math.isfinite(exc.t):
        return exc
    t_prev, x_prev = float(traj[0][-1]), traj[1][-1]
    t_end = min(float(t_eval[-1]), exc.t + 1e-6 * max(1.0, abs(exc.t)))
    if not t_end > t_prev:
        return exc
    found = ContactLeftContourError(exc.t, exc.x, "a contact left its contour",
                                    model.state_names)
    located = locate_exit(model, found, t_prev, x_prev, t_end, p, rtol, atol)
    return located if located is not found else exc


def locate_exit(model, exc: ContactLeftContourError, t0: float, x0: np.ndarray, t1: float,
                p, rtol: float, atol: float) -> ContactLeftContourError:
    """Where between the outputs ``t0`` and ``t1`` the contact left its contour: the
    interval is integrated again from ``x0`` by the C Radau loop, which checks the bounds
    after every step, so the exit is found at the step where it happens (SUNDIALS, run
    through CasADi, is seen only at the output times). Returns ``exc`` with that time and
    state (``exc`` itself if the second run does not leave the domain)."""
    try:
        model.library.radau5(x0, np.array([t0, t1]), p=p, rtol=rtol, atol=max(atol, 1e-14),
                             lo=model.lower, hi=model.upper)
    except IntegratorError as inner:
        if getattr(inner, "code", None) == -2:  # GS_ERR_BOUNDS
            i = _first_out(model, getattr(inner, "x_rejected", inner.x))
            if i is None:
                return exc
            located = left_domain(model, inner.t, inner.x, i,
                                  f"in the Radau step from t = {inner.t:.9g} s, found between "
                                  f"the outputs at {t0:.6g} and {t1:.6g} s")
            located.x_rejected = getattr(inner, "x_rejected", None)
            return located
    return exc


def classify(model, exc: IntegratorError) -> IntegratorError:
    """A C loop's "left [...]" failure as a ``ContactLeftContourError`` (a contact reached the
    end of a contour's domain) or a ``JointLimitError``; others unchanged."""
    if "left [" in exc.reason:
        bad = getattr(exc, "x_rejected", None)
        bad = exc.x if bad is None else bad
        i = _first_out(model, bad) if bad is not None else None
        if i is not None and model.state_names[i] in model.joint_limits:
            new = left_domain(model, exc.t, exc.x, i, exc.reason)
        else:
            new = ContactLeftContourError(exc.t, exc.x, exc.reason + ": the contact point "
                                          "reached the end of a contour's domain",
                                          model.state_names)
        _carry(exc, new)
        return new
    return exc


def blow_up(model, err: IntegratorError, method: str, h: float) -> IntegratorError:
    """A "left the contour's domain" whose rejected step overshot the domain by more than
    1e3 times its width, jumped across more than ``BLOW_UP_JUMP`` of the domain's width in
    that one step (a contact reaching the end of its contour creeps up to it), or went
    non-finite is a numerical blow-up: name it as such (an explicit method beyond its
    stability limit, i.e. a stiff system)."""
    if not isinstance(err, StateLeftDomainError):
        return err
    x_bad = getattr(err, "x_rejected", None)
    if x_bad is None:
        return err
    x_bad = np.asarray(x_bad, dtype=float)
    width = np.where(np.isfinite(model.upper - model.lower), model.upper - model.lower, np.inf)
    over = np.maximum(model.lower - x_bad, x_bad - model.upper)
    jumped = False
    if err.x is not None:
        jump = np.abs(x_bad - np.asarray(err.x, dtype=float))
        jumped = bool(np.any((over > 0) & (jump > BLOW_UP_JUMP * width)))
    if not (np.any(~np.isfinite(x_bad)) or np.any(over > 1e3 * width) or jumped):
        return err
    with np.errstate(invalid="ignore", divide="ignore"):
        ratio = np.where(np.isfinite(width), over / width, -np.inf)
    i = int(np.argmax(np.where(np.isfinite(x_bad), ratio, np.inf)))
    step = f" at h = {h:g} s" if method == "rk4" else ""
    new = IntegratorError(
        err.t, err.x,
        f"{method}: the state blew up (non-finite or exploding values: "
        f"{model.state_names[i]} = {x_bad[i]:.6g} in the rejected step): the method is unstable"
        f"{step} because the system is stiff (large CSM gains); reduce h or use 'radau' or "
        "'cvodes'", model.state_names)
    _carry(err, new)
    new.stiff = method in ("dopri5", "dop853")  # type: ignore[attr-defined]
    return new


def _carry(old: IntegratorError, new: IntegratorError) -> None:
    for key in _CARRIED:
        if hasattr(old, key):
            setattr(new, key, getattr(old, key))


def out_of_time(time_limit: float) -> str:
    """The message of a run a batch's wall-time limit (``time_limit``, s) stopped."""
    return (f"stopped: the batch's wall-time limit of {time_limit:g} s was reached before this "
            "run finished (raise time_limit, or run fewer at a time)")


def batch_entry(exc: Exception, time_limit: float | None) -> tuple[int, str]:
    """``(status, message)`` of a batch's run that raised ``exc``: a stop by the wall-time
    limit (``exc.cause``; the run's limit was what the batch's had left) is the batch's
    (``c_loops.ERR_INTERRUPT``, :func:`out_of_time`), as the batch's C loop of many runs gives
    it; any other, its own."""
    if getattr(exc, "cause", None) == "time_limit" and time_limit is not None:
        return c_loops.ERR_INTERRUPT, out_of_time(time_limit)
    return status_of(exc), f"{type(exc).__name__}: {exc}"
