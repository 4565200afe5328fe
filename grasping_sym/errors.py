"""Exceptions raised by grasping_sym. Each message names the problem, its value and the fix."""
from __future__ import annotations

import errno
import math


class GraspingSymError(Exception):
    """Base class of every error this package raises on purpose."""


class CompileError(GraspingSymError):
    """The C compiler failed; the message carries the command and the compiler's stderr."""


class ProblemsError(GraspingSymError, ValueError):
    """Invalid input described by a list of problems, all reported at once.

    ``what`` names the thing ("contour 'ellipse'"); each problem names a quantity, its value
    and the fix.
    """

    def __init__(self, what: str, problems: list[str]):
        self.problems = list(problems)
        lines = "\n".join(f"  - {p}" for p in self.problems)
        super().__init__(f"{what} is invalid ({len(self.problems)} problem(s)):\n{lines}")


class InvalidCurveError(ProblemsError):
    """A contour is not a smooth regular curve on its declared domain."""

    def __init__(self, name: str, problems: list[str]):
        self.name = name
        super().__init__(f"contour '{name}'", problems)


class InvalidSceneError(ProblemsError):
    """A scene's parameters or initial configuration are invalid; lists every problem."""

    def __init__(self, problems: list[str]):
        super().__init__("scene", problems)


class IntegratorError(GraspingSymError, RuntimeError):
    """Integration failed: carries the time ``t`` (s), the state ``x`` and the ``reason``."""

    def __init__(self, t: float, x, reason: str, state_names=None):
        self.t = float(t)
        self.x = x
        self.reason = reason
        if state_names is not None and x is not None:
            state = ", ".join(f"{n}={v:.6g}" for n, v in zip(state_names, x))
        else:
            state = repr(x)
        super().__init__(f"integration failed at t = {self.t:.6g} s: {reason}; state: {state}")

    def __reduce__(self):
        # pickled whole (a Dask worker's error back to its client): the message as made, then
        # every attribute the raiser set (the subclasses' own __init__ arguments among them)
        return _restore, (type(self), self.args, self.__dict__)


def _restore(cls, args, state):
    """An ``IntegratorError`` (any subclass) from its pickle: ``args`` and attributes as they were."""
    err = cls.__new__(cls)
    Exception.__init__(err, *args)
    err.__dict__.update(state)
    return err


class StateLeftDomainError(IntegratorError):
    """A state component left its declared bounds, at the step where it happened: a contact
    its contour's domain (``ContactLeftContourError``) or a joint its limits
    (``JointLimitError``)."""


class ContactLeftContourError(StateLeftDomainError):
    """The contact point reached the end of a contour's declared domain."""


class JointLimitError(StateLeftDomainError):
    """A joint reached one end of its ``limits`` (``model.chains.RevoluteJoint``)."""


class InvalidSurfaceError(ProblemsError):
    """A surface is not a smooth regular patch on its declared domain; lists every problem."""

    def __init__(self, name: str, problems: list[str]):
        self.name = name
        super().__init__(f"surface '{name}'", problems)


class URDFError(ProblemsError):
    """A URDF file cannot be read as a hand (``gs.hands.from_urdf``); lists every problem
    and its fix."""

    def __init__(self, path, problems: list[str]):
        self.path = str(path)
        super().__init__(f"URDF file '{path}'", problems)


class InvalidBodyError(ProblemsError):
    """A body (finger chain or free object) has invalid parameters; lists every problem."""

    def __init__(self, name: str, problems: list[str]):
        self.name = name
        super().__init__(f"body '{name}'", problems)


class ContactOpenedError(IntegratorError):
    """The normal multiplier ``f`` reached zero or below: a unilateral contact would open.

    ``t`` is the time (s) where ``f`` crosses zero, located there (``runtime.watch``: by the
    C loop at its step, or between the two output rows around it) or interpolated between two
    rows when integrating again does not reproduce it; ``force`` the value of ``f`` (N) at
    ``t`` (0 to its noise where located; the first row's with ``f <= 0`` where interpolated)
    and ``force_before`` a positive value before it (the step's start, or the row before;
    NaN where ``f <= 0`` already where the integration starts).
    """


class FrictionConeError(IntegratorError):
    """A contact's force left its friction cone: ``|F_t| > mu f``, the contact would slip.

    ``t`` is the time (s) where the cone margin ``mu f - |F_t|`` reaches zero, located by
    integrating again between the output samples around it; ``x`` the state there.
    ``contact`` (1, 2, ...), ``mu``, ``normal`` (``f``, N), ``tangential`` (``|F_t|``, N)
    and ``ratio`` (``|F_t| / f``) at that time.
    """

    def __init__(self, t: float, x, reason: str, state_names=None, *, contact: int = 0,
                 mu: float = math.nan, normal: float = math.nan, tangential: float = math.nan):
        super().__init__(t, x, reason, state_names)
        self.contact, self.mu = int(contact), float(mu)
        self.normal, self.tangential = float(normal), float(tangential)
        self.ratio = self.tangential / self.normal if self.normal > 0 else math.inf


class RelativeCurvatureError(IntegratorError):
    """The relative curvature ``kappa0 + kappa1`` fell to (or below) its threshold.

    The update law (29) divides by it: the contact point would race along the contours and
    the state blow up. ``t`` is the time (s), ``kappa_sum`` the value (1/m) found there and
    ``threshold`` the limit (1/m) that was crossed.
    """


class MovingFrameSingularityError(IntegratorError):
    """The paper's moving-frame formulation is 0/0: ``D = omega0.e0 + omega1.e1 = -(kn0 + kn1) s'``
    fell to its threshold (the contact has stopped; the trace direction is undefined).

    ``t`` (s), ``denominator`` (rad/s) and ``threshold`` (rad/s); ``contact`` names the output
    (``frame_denominator{i}``), ``None`` if unknown.
    """

    def __init__(self, t: float, x, reason: str, state_names=None, *, denominator: float = math.nan,
                 threshold: float = math.nan, contact: str | None = None):
        super().__init__(t, x, reason, state_names)
        self.denominator, self.threshold, self.contact = float(denominator), float(threshold), contact


class InconsistentInitialStateError(GraspingSymError, ValueError):
    """The initial state is off the contact constraints: ``residual`` = max(|Q|, |R|) in m."""

    def __init__(self, residual: float, message: str):
        self.residual = float(residual)
        super().__init__(message)


class UnreachableStartError(GraspingSymError, ValueError):
    """A starting pose asked of ``model.initial_state(...)`` has no consistent state near it:
    the given coordinates cannot all hold while the bodies touch (``residual``, m, is the
    smallest constraint violation reached), or the contact would leave a contour's domain."""

    def __init__(self, message: str, residual: float = math.nan):
        self.residual = float(residual)
        super().__init__(message)


class StartBranchError(UnreachableStartError):
    """A starting pose asked of ``model.initial_state(...)`` cannot be reached on the branch of
    the model's stored start (continued in small steps from it, the solution family turns back
    or ends first), while a consistent pose exists on another branch (another finger posture
    and contact point): ``found`` holds that pose's state, ``reached`` the furthest point of
    the start's branch. ``initial_state(..., branch="any")`` accepts the other branch."""

    def __init__(self, message: str, found=None, reached=None):
        self.found, self.reached = found, reached
        super().__init__(message, 0.0)


class UnsafeCacheError(GraspingSymError, PermissionError):
    """A cache path is a symbolic link, belongs to another user, or others may write it."""

    def __init__(self, path, problem: str):
        self.path, self.problem = path, problem
        super().__init__(
            f"refusing to use the cache path {path}: {problem}. Code is loaded from the cache, "
            "so it must be yours alone: fix it with `chmod go-w` (or remove it), or point "
            "GRASPING_SYM_CACHE at a private directory, e.g. under your home")


class CorruptCacheError(GraspingSymError, RuntimeError):
    """A cached model is damaged (its library's checksum or its manifest is wrong) and could
    not be rebuilt here."""


class CacheWriteError(GraspingSymError, OSError):
    """The cache cannot be written (full disk, read-only file system, no permission)."""

    def __init__(self, path, exc: OSError):
        self.path = path
        reason = {errno.ENOSPC: "the disk is full", errno.EDQUOT: "the disk quota is exceeded",
                  errno.EROFS: "the file system is read-only",
                  errno.EACCES: "permission denied", errno.EPERM: "permission denied"}.get(
                      exc.errno, exc.strerror or str(exc))
        super().__init__(exc.errno, f"cannot write the cache at {path}: {reason}. Free space, "
                                    "or point GRASPING_SYM_CACHE at a writable directory of your own")


class SourcesChangedError(GraspingSymError, RuntimeError):
    """The package's source files changed (an edit, a checkout) since this process first
    keyed a build by their stamp: the code in memory is not the code on disk, and a model built
    now would be stored under the edited sources' hash. Restart Python to build with them."""


class CacheContentsError(GraspingSymError, ValueError):
    """``grasping-sym cache clear`` refused: the cache root holds files the package did not
    make (it is not a cache of its own), or a name given is not one of its entries. Nothing
    is removed."""


class SweepStoreError(GraspingSymError, ValueError):
    """A sweep's Zarr store cannot be used: the path is a file or a directory that is not a
    Zarr store, a stored chunk is missing or unreadable, or it holds another sweep."""


class SweepStoreBusyError(SweepStoreError):
    """Another sweep is writing the same store (its lock file names the process)."""


class UnsafeTemplateError(GraspingSymError, ValueError):
    """A stored template holds something that would load or compile code when deserialized."""


class ExpressionError(GraspingSymError, ValueError):
    """A formula given as text is not one ``geometry.expressions.parse_expression`` reads
    (formulas are parsed, never run)."""


class RunInterruptedError(GraspingSymError, RuntimeError):
    """A run was stopped by SIGINT (Ctrl-C) while the process's Python SIGINT handler is not
    Python's default one (which raises ``KeyboardInterrupt`` instead): the handler was called,
    and returned, and the run does not pretend to have finished."""


class InvalidResultError(GraspingSymError, ValueError):
    """A ``SimulationResult``'s parts disagree: times, states, names and outputs must have one
    row per time and one column per name (the message names the field and its shape)."""


class ResultFileError(InvalidResultError):
    """A file is not a ``SimulationResult`` that ``save`` wrote, or cannot be one: the path is
    a directory, an entry is missing or of the wrong kind, or the arrays and the names in it
    disagree (the message names the file and the field)."""


class ViewOptionError(GraspingSymError, ValueError):
    """``res.animate`` or ``res.view`` cannot honour an option or draw this run (file type,
    ``fps``, ``seconds``, ``dpi``, ``frames``, the scene): the message names the option, its
    value and its bounds."""


class RunArgumentError(GraspingSymError, ValueError, TypeError):
    """An argument of a run (``simulate``, ``simulate_many``) is of the wrong kind or out of its
    range (``max_steps`` beyond a C ``long``, a non-finite time, ``outputs`` not a bool ...);
    the message names it, its value and the range. Both a ValueError and a TypeError, as the
    plain errors these checks raised before."""


class ControllerError(GraspingSymError, ValueError):
    """A control law (``gs.controllers``) cannot give the model's joint torques: a bad argument
    of a preset, a law for the other dimension, or a law that raised, returned something that
    is not torques, or used a symbol that is not one of the model's quantities (the message
    names the law and the fix)."""


class InputScheduleError(GraspingSymError, ValueError):
    """A ``gs.inputs.Schedule`` (or the table it is made from) is not one: knot times not finite
    and strictly increasing, a number of rows that is not one per segment, non-finite values,
    or a number of inputs that is not the model's (the message names the field and its shape)."""


class ContactModeError(IntegratorError):
    """A switch of contact modes has no consistent answer (``runtime.modes``); the run stops
    at ``t`` (s), state ``x``, with the numbers in the message: never a guess."""


class PainleveError(ContactModeError):
    """Sliding with no or several consistent normal forces: the normal row's coefficient
    ``n . K (n - mu d)`` (``painleve``, 1/kg: the normal's effective inverse mass corrected by
    the friction direction) fell to 0 or below."""


class ChatteringError(ContactModeError):
    """More than ``max_switches`` switches within ``window`` seconds (a Zeno run)."""


class EventLocationError(ContactModeError):
    """An event seen between two output samples could not be located by integrating again."""
