"""The settings of a run: ``simulate``'s and ``simulate_many``'s arguments, checked once.

``RunSettings.check`` turns the method, the end time, the tolerances, the step ``h``,
``max_steps``, ``time_limit``, the output times, ``project`` and the ``outputs`` / ``checks``
switches into one frozen record, refusing a bad one by name (``RunArgumentError``). Every
entry into a run (``Model.simulate``, ``runtime.batch``, the short way of
``runtime.fastpath``) reads that record, so the arguments are validated in one place.
"""
from __future__ import annotations

import math
import numbers
from dataclasses import dataclass

import numpy as np

from grasping_sym.errors import RunArgumentError
from grasping_sym.runtime import integrators, projection

#: Each method's tolerances ``(rtol, atol)`` when ``simulate`` / ``simulate_many`` get none.
DEFAULT_TOLERANCES = {"radau": (1e-6, 1e-9), "dopri5": (1e-8, 1e-10), "dop853": (1e-8, 1e-10),
                      "cvodes": (1e-10, 1e-12),
                      "idas": (1e-10, 1e-12), "rk4": (1e-10, 1e-12)}
#: Largest ``max_steps``: the C loops count steps in a 64-bit ``long``.
MAX_STEPS = 2**63 - 1
#: Largest ``time_limit`` (s); beyond it, give None (no limit).
MAX_TIME_LIMIT = 1e9
#: Most steps an RK4 run may take (``t_final / h``): far beyond any run that finishes, well
#: inside the C loop's step counter.
MAX_RK4_STEPS = 10**12
#: Shortest run (s) handed to SUNDIALS: below it IDAS's initial-condition step fails with
#: NaN and CVODES returns the initial state unchanged; the C loops integrate any length.
SUNDIALS_MIN_T = 1e-12
#: Most output rows of the default grid (one per ms); beyond, pass ``t_eval``.
MAX_DEFAULT_OUTPUTS = 10_000_000


@dataclass(slots=True, eq=False)
class RunSettings:
    """How a run integrates, checked (``RunSettings.check``).

    Attributes
    ----------
    method
        One of ``integrators.METHODS``.
    t_final
        End time (s).
    rtol, atol
        Tolerances (the method's defaults where none were given).
    h
        The RK4 step (s; as given for the other methods, which do not read it).
    max_steps
        The most steps the run may take.
    time_limit
        Seconds of wall time (None: no limit).
    t_eval
        Output times from 0 to ``t_final`` (s), 0 included.
    drop_first
        The caller's times did not start at 0: the first row is dropped from the result.
    proj
        ``projection.settings``'s ``(mask, tolerance)`` (``(None, tol)`` without projection).
    outputs, checks
        ``simulate``'s switches.
    mu
        The friction coefficient of every contact (``runtime.friction.resolve``), None
        without a friction limit.
    slip
        What a force outside its cone does: ``"stop"`` the run (``FrictionConeError``) or
        ``"record"`` it (the run goes on rolling; the outputs show the cone).
    watched
        The checks the C loop watches at every step (``runtime.watch.checks``), set by the
        run once its start is checked; empty: the checks read the rows.
    """

    method: str
    t_final: float
    rtol: float
    atol: float
    h: float
    max_steps: int
    time_limit: float | None
    t_eval: np.ndarray
    drop_first: bool
    proj: tuple
    outputs: bool
    checks: bool
    mu: np.ndarray | None = None
    slip: str = "stop"
    watched: tuple = ()

    @classmethod
    def check(cls, model, t_final, *, method: str, rtol, atol, t_eval, h, max_steps: int,
              project, outputs: bool, checks: bool, time_limit) -> RunSettings:
        """``simulate``'s arguments as a record; a bad one is refused by name
        (``RunArgumentError``). ``t_eval`` None: every millisecond from 0 to ``t_final``."""
        if method not in integrators.METHODS:
            raise RunArgumentError(f"method {method!r} unknown: choose one of {integrators.METHODS}")
        t_final, rtol, atol, max_steps, time_limit = run_settings(method, t_final, rtol, atol, h,
                                                                  max_steps, time_limit)
        flags(outputs=outputs, checks=checks)
        proj = projection.settings(model, project, method)
        grid, drop_first = output_times(t_eval, float(t_final))
        return cls(method=method, t_final=t_final, rtol=float(rtol), atol=float(atol),
                   h=float(h) if method == "rk4" else h, max_steps=max_steps, time_limit=time_limit, t_eval=grid,
                   drop_first=drop_first, proj=proj, outputs=outputs, checks=checks)


#: What ``simulate``'s ``slip`` may be.
SLIP = ("stop", "record")


def slip_mode(slip) -> str:
    """``slip`` checked: ``"stop"`` or ``"record"``."""
    if slip not in SLIP:
        raise RunArgumentError(f"slip = {slip!r:.40}: choose 'stop' (a force leaving its friction cone "
                               "stops the run with FrictionConeError) or 'record' (the run rolls on, "
                               "the outputs show the cone)")
    return slip


def run_defaults(model, method, rtol, atol) -> tuple[str, float | None, float | None, bool]:
    """``(method, rtol, atol, chosen)``: with no method given, the model's own (the manifest's
    ``defaults``, from its scene: measured the fastest reliable for its kind) and its
    tolerances where none are given (``chosen`` True: a stiff run may fall back to radau,
    ``Model.simulate``); else the method given, and None where no tolerance is (the
    method's ``DEFAULT_TOLERANCES``)."""
    if method is not None:
        return method, rtol, atol, False
    d = model.manifest.get("defaults") or {}
    return (d.get("method", "radau"), d.get("rtol") if rtol is None else rtol,
            d.get("atol") if atol is None else atol, True)


#: The smallest rtol the C loops (radau, dopri5, dop853) take: 100 times the double's epsilon
#: (they raised a smaller one to it silently; ``run_settings`` refuses it by name).
RTOL_FLOOR = 100 * 2.220446049250313e-16


def tolerances(method: str, rtol, atol) -> tuple:
    """``(rtol, atol)`` with the method's defaults where None."""
    d = DEFAULT_TOLERANCES.get(method, (1e-10, 1e-12))
    return (d[0] if rtol is None else rtol), (d[1] if atol is None else atol)


def run_settings(method: str, t_final, rtol, atol, h, max_steps, time_limit) -> tuple:
    """``(t_final, rtol, atol, max_steps, time_limit)`` of ``simulate`` / ``simulate_many``,
    checked, with the method's default tolerances where None; a bad one is refused by name."""
    rtol, atol = tolerances(method, rtol, atol)
    t_final = real("t_final", t_final, "seconds")
    if not t_final > 0:
        raise RunArgumentError(f"t_final = {t_final!r} must be > 0 (seconds)")
    if t_final < SUNDIALS_MIN_T and method in ("cvodes", "idas"):
        raise RunArgumentError(f"t_final = {t_final:g} s is shorter than {SUNDIALS_MIN_T:g} s, below "
                               f"what {method}'s step control starts on (IDAS fails, CVODES returns "
                               "x0): use method='radau', 'dopri5' or 'rk4' for so short a run")
    if time_limit is not None:
        time_limit = real("time_limit", time_limit, "seconds of wall time")
        if not time_limit > 0:
            raise RunArgumentError(f"time_limit = {time_limit!r} must be > 0 (seconds of wall time) or None")
    _tolerances_below_one(rtol, atol)
    if method in ("radau", "dopri5", "dop853") and rtol < RTOL_FLOOR:
        raise RunArgumentError(f"rtol = {rtol!r} is below {RTOL_FLOOR:.3g} (100 times the double's epsilon), "
                               f"where {method}'s error estimate is its own rounding (its C loop would raise "
                               f"it to that silently): give rtol >= {RTOL_FLOOR:.3g}; paper2d's and paper3d's "
                               "final states reach their rounding floor (1e-13) from rtol 1e-8 to 1e-10 "
                               "(benchmarks/results/tolerances.md)")
    if method == "rk4":
        positive("h", h, "the RK4 step (s); stable below ~9e-4 s for paper2d's CSM gains")
    if isinstance(max_steps, (bool, np.bool_)) or not isinstance(max_steps, numbers.Integral) \
            or not 0 < max_steps <= MAX_STEPS:
        raise RunArgumentError(f"max_steps = {max_steps!r:.40} must be an integer from 1 to "
                               f"{MAX_STEPS} (2**63 - 1, the C loops' step counter)")
    if time_limit is not None and time_limit > MAX_TIME_LIMIT:
        raise RunArgumentError(f"time_limit = {time_limit:g} s is more than {MAX_TIME_LIMIT:g} s "
                               "(about 30 years): give None for no limit")
    if method == "rk4" and t_final / h > MAX_RK4_STEPS:
        raise RunArgumentError(f"h = {h:g} s over t_final = {t_final:g} s means {t_final / h:.3g} "
                               f"RK4 steps, more than {MAX_RK4_STEPS:.0e}: give a larger h (or an "
                               "adaptive method, e.g. 'radau')")
    return t_final, rtol, atol, int(max_steps), time_limit


def _tolerances_below_one(rtol, atol) -> None:
    positive("rtol", rtol)
    positive("atol", atol)
    for name, value, unit in (("rtol", rtol, "a relative error of 100 %"),
                              ("atol", atol, "an error of 1 m or 1 rad in every state")):
        if not value < 1:
            raise RunArgumentError(f"{name} = {value!r} must be below 1 ({unit} or more accepts "
                                   "any step, and the run's failure would be blamed on the "
                                   "physics): give e.g. rtol=1e-6, atol=1e-9")


def flags(**values) -> None:
    """Refuse a switch of ``simulate`` / ``simulate_many`` (``outputs``, ``checks``) that is not
    True or False: a tuple of names given as ``outputs`` would read as True."""
    for name, value in values.items():
        if not isinstance(value, (bool, np.bool_)):
            hint = (": the outputs themselves are chosen when the scene is made, e.g. "
                    "gs.scenes.paper2d(outputs=('Q', 'f'))" if name == "outputs" else "")
            raise RunArgumentError(f"{name} = {value!r:.60} is {type(value).__name__}: give True "
                                   f"or False{hint}")


def real(name: str, value, what: str = "") -> float:
    """``value`` as a finite float: Python, NumPy and SymPy numbers are accepted; ``True``,
    strings and other objects are refused by name (a TypeError), as are NaN and infinities
    (a ValueError)."""
    extra = f" ({what})" if what else ""
    if isinstance(value, (bool, np.bool_, str, bytes)) or not (
            isinstance(value, numbers.Real) or getattr(value, "is_Number", False)
            and getattr(value, "is_real", False)):
        raise RunArgumentError(f"{name} = {value!r} is {type(value).__name__}: give a number{extra}")
    v = float(value)
    if not math.isfinite(v):
        raise RunArgumentError(f"{name} = {value!r} must be a finite number{extra}")
    return v


def numbers_array(name: str, value) -> np.ndarray:
    """An array of numbers (a TypeError for strings, booleans or objects)."""
    arr = np.asarray(value)
    if arr.dtype.kind not in "fiu":
        raise RunArgumentError(f"{name} must be numbers, got an array of {arr.dtype} ({value!r:.80})")
    return arr.astype(float)


def positive(name: str, value, what: str = "") -> None:
    """Refuse ``value`` unless it is a finite number > 0."""
    v = real(name, value, what)
    if not v > 0:
        extra = f" ({what})" if what else ""
        raise RunArgumentError(f"{name} = {value!r} must be a finite number > 0{extra}")


def output_times(t_eval, t_final: float) -> tuple[np.ndarray, bool]:
    """Validated output times from 0 to ``t_final``; a leading 0 is added if missing
    (``(times, added)``)."""
    if t_eval is None:
        n = max(2, math.ceil(t_final * 1000 - 1e-9) + 1)
        if n > MAX_DEFAULT_OUTPUTS:
            raise RunArgumentError(f"t_final = {t_final:g} s with the default output every ms means {n} "
                                   f"output rows (more than {MAX_DEFAULT_OUTPUTS}): pass t_eval with the "
                                   "times you need, e.g. np.linspace(0, t_final, 1001)")
        return np.linspace(0.0, t_final, n), False
    t_eval = numbers_array("t_eval", t_eval)
    if t_eval.ndim != 1 or len(t_eval) < 1:
        raise RunArgumentError(f"t_eval must be a 1-D array of output times, got shape {t_eval.shape}")
    if not np.all(np.isfinite(t_eval)):
        bad = np.flatnonzero(~np.isfinite(t_eval))
        listed = ", ".join(map(str, bad[:10])) + (f", ... ({len(bad)} in all)" if len(bad) > 10 else "")
        raise RunArgumentError(f"t_eval has non-finite entries at indices [{listed}]: give "
                               "finite times")
    if np.any(np.diff(t_eval) <= 0):
        raise RunArgumentError("t_eval must be strictly increasing")
    if t_eval[0] < 0:
        raise RunArgumentError(f"t_eval starts at {t_eval[0]} < 0: the initial state is at t = 0")
    if abs(t_eval[-1] - t_final) > 1e-12 * max(1.0, t_final):
        raise RunArgumentError(f"t_eval ends at {t_eval[-1]!r} but t_final = {t_final!r}: make the "
                               "last output time equal to t_final")
    if t_eval[0] > 0:
        return np.concatenate([[0.0], t_eval]), True
    if len(t_eval) < 2:
        raise RunArgumentError("t_eval needs a time after 0")
    return t_eval, False
