"""Controllers: joint torques as expressions of a model's named quantities.

A controller is a law ``tau = law(m)``: given the quantities ``m`` of a scene (a
:class:`grasping_sym.derive.quantities.Quantities`: joint angles and rates, fingertip centres
and their Jacobians, gravity torques, the object's pose and velocity, time, parameters; all
CasADi SX), it returns the joint torques of every finger, as a list with one column per
finger (or one column of every joint). Laws add up: ``paper2d() + feedforward(...)``.

The controller is a layer of its own: the contact dynamics are derived once per structure
and take the torques as inputs, so a new law compiles only its scene's small C file
(``codegen.controller``). The law runs when the model is built (it is the user's code, run
once to make the expressions); the compiled model evaluates its expressions in C.

Presets: :func:`paper2d` (the 2D paper's law (32)), :func:`paper3d` (the 3D grasp law),
:func:`damping`, :func:`feedforward` (SymPy expressions of time), :func:`orientation2d`
(turn a pivoted object to an angle by rolling). :func:`law` makes a controller of any function.
"""
from __future__ import annotations

import math
from collections.abc import Callable, Mapping, Sequence

import casadi as ca
import numpy as np
import sympy as sp

from grasping_sym.errors import ControllerError, GraspingSymError
from grasping_sym.geometry.expressions import to_expression
from grasping_sym.model.law_keys import function_definition
from grasping_sym.symbolic.translate import SympyToCasadi

__all__ = ["Controller", "damping", "feedforward", "law", "orientation2d", "paper2d", "paper3d",
           "turn3d"]


class Controller:
    """A control law (see the module's docstring). ``name`` labels it in reprs and
    manifests; what a model's code depends on is the law's expressions, not its name.
    ``dimension``: 2 or 3 for a law written for the scenes of one dimension (its quantities),
    None for any scene. ``preset``: a preset's name and parameters (its definition, its code
    being the package's); a law of the user's is defined by its function's code
    (:attr:`definition`)."""

    def __init__(self, fn: Callable, name: str = "law", terms: tuple[Controller, ...] = (),
                 dimension: int | None = None, preset: str | None = None):
        if not callable(fn):
            raise TypeError(f"a controller's law must be a function of the model's quantities, "
                            f"got {type(fn).__name__}")
        self._fn = fn
        self.name = name
        self.dimension = dimension
        self.terms = terms or (self,)
        self._preset = preset

    @property
    def definition(self) -> str | None:
        """The law's definition as text, read without running it (``model.law_keys``): a
        preset's name and parameters, else its function's code and the values it reads;
        None where that cannot be read whole (``gs.build`` then keys the law by its
        expressions)."""
        return self.definition_in(frozenset())

    def definition_in(self, seen: frozenset) -> str | None:
        """:attr:`definition`, within the reading of the laws and functions ``seen`` (ids):
        a law that names itself is read once."""
        if id(self) in seen:
            return f"<recursion {self.name}>"
        seen = seen | {id(self)}
        if len(self.terms) > 1:
            parts = [t.definition_in(seen) for t in self.terms]
            return None if None in parts else "sum(" + ", ".join(parts) + ")"
        if self._preset is not None:
            return f"preset {self._preset}"
        text = function_definition(self._fn, seen)
        return None if text is None else f"law dimension={self.dimension}\n{text}"

    def torques(self, m) -> list:
        """The law's joint torques at the quantities ``m``: one SX column per finger. Raises
        :class:`ControllerError` naming the law for a law of the other dimension, a law that
        raises, or one that returns anything but torques."""
        dimension = m.tip[0].numel() if m.tip else None
        wrong = [t.name for t in self.terms if t.dimension not in (None, dimension)]
        if wrong and dimension is not None:
            other = "paper2d, orientation2d" if dimension == 2 else "paper3d, turn3d"
            raise ControllerError(
                f"controller {self.name!r}: {', '.join(wrong)} "
                f"{'is a law' if len(wrong) == 1 else 'are laws'} of {5 - dimension}D scenes, "
                f"written for their quantities; this scene is {dimension}D: use one of its "
                f"laws ({other}), or damping, feedforward or a law of your own (gs.controllers.law)")
        if len(self.terms) > 1:
            parts = [t.torques(m) for t in self.terms]
            return [sum(cols[1:], cols[0]) for cols in zip(*parts)]
        try:
            out = self._fn(m)
        except GraspingSymError:
            raise
        except Exception as exc:  # the user's code: named, with what it raised
            raise ControllerError(_failure(self.name, exc)) from exc
        try:
            return m.split(_torques(out, m.n_joints, self.name), self.name)
        except ValueError as exc:  # a shape that is not the model's joints
            raise ControllerError(str(exc)) from None

    def __add__(self, other: Controller) -> Controller:
        if not isinstance(other, Controller):
            return NotImplemented
        return Controller(_sum, " + ".join(t.name for t in (*self.terms, *other.terms)),
                          (*self.terms, *other.terms))

    def __repr__(self) -> str:
        return f"Controller({self.name})"


_RETURN = ("return the joint torques (N m): a list with one column per finger, or one column "
           "(or a list) of every joint, as CasADi SX built from the quantities, or numbers")


def _failure(name: str, exc: Exception) -> str:
    """The message of a law that raised ``exc`` when run on the model's quantities."""
    text = exc.args[0] if isinstance(exc, KeyError) and exc.args else str(exc)
    if isinstance(exc, RuntimeError) and "truth value" in text:
        return (f"controller {name!r} decides with Python (if, and, or, not, min, max, a "
                "comparison) on a symbolic quantity: the law runs once, on CasADi SX symbols, to "
                "make the torques' expressions, so its branches must be expressions too: write "
                "ca.if_else(condition, a, b), ca.fmin, ca.fmax or ca.fabs")
    if isinstance(exc, (KeyError, AttributeError)) and "a control law asked for" in text:
        return f"controller {name!r}: {text}"
    return (f"controller {name!r} raised {type(exc).__name__}: {text}; a law runs once, when the "
            "model is built, on the model's quantities (CasADi SX symbols): check it on them "
            "(gs.controllers docstring)")


def _torques(out, n_joints: int, name: str):
    """What a law returned as SX: one SX, or a list of SX columns (a list of one scalar per
    joint becomes the column of every joint)."""
    if isinstance(out, (list, tuple)):
        items = [_sx(v, name, f"item {i}") for i, v in enumerate(out)]
        if len(items) == n_joints and all(v.numel() == 1 for v in items):
            return ca.vertcat(*items)
        return items
    return _sx(out, name, "its result")


def _sx(value, name: str, where: str) -> ca.SX:
    """One value of a law's result as SX, or a named error."""
    if isinstance(value, ca.SX):
        return value
    kind = type(value).__name__
    if isinstance(value, ca.MX):
        raise ControllerError(f"controller {name!r} returned an MX expression ({where}): the "
                              f"quantities are SX, and so must the torques be; {_RETURN}")
    if type(value).__module__.split(".")[0] == "sympy":
        raise ControllerError(f"controller {name!r} returned a SymPy expression ({where}: {value}): "
                              f"{_RETURN}; SymPy expressions of time go through "
                              "gs.controllers.feedforward")
    if isinstance(value, (list, tuple)) and value:
        return ca.vertcat(*[_sx(v, name, f"{where}[{k}]") for k, v in enumerate(value)])
    if isinstance(value, ca.DM):
        numbers = np.asarray(value)
    elif isinstance(value, (int, float, np.integer, np.floating, np.ndarray)) \
            and not isinstance(value, (bool, np.bool_)):
        numbers = np.asarray(value)
        if numbers.dtype.kind not in "iuf":
            raise ControllerError(f"controller {name!r} returned an array of {numbers.dtype} "
                                  f"({where}): {_RETURN}")
    else:
        raise ControllerError(f"controller {name!r} returned {kind} ({where}: {value!r:.60}): "
                              f"{_RETURN}")
    if not np.all(np.isfinite(numbers)):
        raise ControllerError(f"controller {name!r} returned a non-finite torque ({where}: "
                              f"{numbers.tolist()}): give finite torques (N m)")
    return ca.SX(ca.DM(numbers.astype(float)))


def _number(what: str, value, unit: str, *, minimum: float | None = None,
            positive: bool = False) -> float:
    """``value`` as a finite float (``minimum``: its least value; ``positive``: > 0), or a
    :class:`ControllerError` naming ``what``."""
    try:
        number = float(value)
    except (TypeError, ValueError):
        raise ControllerError(f"{what} = {value!r}: give a number ({unit})") from None
    if not math.isfinite(number):
        raise ControllerError(f"{what} = {value!r}: give a finite number ({unit})")
    if positive and not number > 0:
        raise ControllerError(f"{what} = {value!r} must be > 0 ({unit})")
    if minimum is not None and number < minimum:
        raise ControllerError(f"{what} = {value!r} must be >= {minimum:g} ({unit}): a negative "
                              "gain feeds energy in instead of taking it out")
    return number


def _sum(m):  # never called: a sum's torques add its terms' (Controller.torques)
    raise AssertionError("a sum of controllers has no law of its own")


def law(fn: Callable | None = None, *, name: str | None = None):
    """A controller of ``fn(m)`` (usable as a decorator): ``m`` holds the model's quantities
    (``derive.quantities.Quantities``); return the joint torques (N m): a list with one column
    per finger, or the column of every joint (one SX, or a list with one value per joint), as
    CasADi SX built from ``m``'s quantities, or numbers. The law runs once, when the model is
    built, on SX symbols: a choice between branches is an expression (``ca.if_else``), not a
    Python ``if``; a gain is a number or a scene parameter (``m.param(name)``), not a symbol of
    its own. Anything else is refused by name (:class:`grasping_sym.errors.ControllerError`)."""
    if fn is None:
        return lambda f: law(f, name=name)
    return Controller(fn, name or getattr(fn, "__name__", "law"))


def paper2d() -> Controller:
    """Yoshida-Arimoto-Tahara 2009, eq. (32), for every finger ``i`` of a 2D scene:
    ``tau_i = -c q_i' - J_i^T (fd / r) (O_i - Om) + dV_i/dq_i``, the pull of the fingertip
    centre toward the pivot, joint damping, and (when gravity is modelled) the finger's weight
    held. No object information."""
    def paper(m):
        fd, r, c = m.param("fd"), m.param("r"), m.param("c")
        return [-c * dq - J.T @ ((fd / r) * (tip - m.pivot)) + g
                for dq, J, tip, g in zip(m.dq, m.J, m.tip, m.gravity_torque)]
    return Controller(paper, "paper2d", dimension=2, preset="paper2d")


def paper3d() -> Controller:
    """The 3D grasp law (docs/conventions.md section 2), finger ``i`` of ``N``:
    ``tau_i = dP_i/dq_i - c q_i' - J_i^T [(fd / r_ctrl) sum_j (r_i - r_j)
    + (k_center / N)(r_bar - r_bar0)]``. One finger pulls toward a fixed point instead: the
    pivot of a pivoted object; for a free object (held against a surface of the world,
    ``with_modes``), the scene's ``position`` (the object's centre as given, before the start
    is solved). No object information."""
    def paper(m):
        N = len(m.tip)
        fd, c = m.param("fd"), m.param("c")
        r_bar = sum(m.tip[1:], m.tip[0]) / N
        out = []
        for i, (dq, J, tip, g) in enumerate(zip(m.dq, m.J, m.tip, m.gravity_torque)):
            if N == 1:
                anchor = m.param("position0") if m.has_param("position0") else m.pivot
                pull = (fd / m.param("r_ctrl")) * (tip - anchor)
            else:
                pull = (fd / m.param("r_ctrl")) * sum((tip - m.tip[j] for j in range(N) if j != i),
                                                      0 * tip)
            if m.has_param("r_bar0"):
                pull = pull + (m.param("k_center") / N) * (r_bar - m.param("r_bar0"))
            out.append(-c * dq - J.T @ pull + g)
        return out
    return Controller(paper, "paper3d", dimension=3, preset="paper3d")


def damping(c: float) -> Controller:
    """Joint damping ``-c q'`` on every joint (``c`` in N m s, finite, >= 0)."""
    c = _number("damping c", c, "N m s", minimum=0.0)
    return Controller(lambda m: [-c * dq for dq in m.dq], f"damping({c:g})",
                      preset=f"damping({c!r})")


def feedforward(torques: Sequence | Mapping, t=None) -> Controller:
    """Joint torques given as SymPy expressions of time (N m), one per joint in the order of
    the model's joints, or a mapping from input-style names (``u1``, ``u2``, ...; the others
    0). ``t``: the time symbol of the expressions (default ``sympy.Symbol('t')``). Parsed
    without evaluation of any text (strings go through ``geometry.expressions``)."""


    tsym = t if t is not None else sp.Symbol("t")

    def expr(e):
        e = to_expression(e, {str(tsym): tsym}, "a feedforward torque")
        # any symbol named as the time is the time (whatever its assumptions)
        e = e.xreplace({s: tsym for s in e.free_symbols if str(s) == str(tsym)})
        extra = e.free_symbols - {tsym}
        if extra:
            raise ControllerError(f"feedforward torque {e} has symbols {sorted(map(str, extra))} "
                             f"besides the time {tsym}: give expressions of time only")
        return e

    items = dict(torques) if isinstance(torques, Mapping) else None
    exprs = None if items is not None else [expr(e) for e in torques]
    fixed = {k: expr(v) for k, v in items.items()} if items is not None else None

    def ff(m):

        tr = SympyToCasadi({tsym: m.t})
        n = m.n_joints
        if fixed is not None:
            unknown = [k for k in fixed if k not in m.input_style_names]
            if unknown:
                raise ControllerError(f"feedforward names {unknown} are not joints of this model: use "
                                 f"{list(m.input_style_names)}")
            vals = [tr(fixed.get(k, sp.Integer(0))) for k in m.input_style_names]
        else:
            if len(exprs) != n:
                raise ControllerError(f"feedforward has {len(exprs)} torques; the model has {n} joints")
            vals = [tr(e) for e in exprs]
        return m.column(vals)
    given = exprs if fixed is None else sorted(fixed.items())
    return Controller(ff, "feedforward", preset=f"feedforward({sp.srepr(tsym)}, {sp.srepr(given)})")


def orientation2d(theta_d: float, gain: float, damping_gain: float = 0.0,
                  max_force: float = 0.2) -> Controller:
    """Turn a pivoted object to the angle ``theta_d`` (rad) by rolling, and hold it there: to
    the paper's law (32), finger 1 adds the torque of the force
    ``F e = -max_force tanh((gain (theta - theta_d) + damping_gain theta') / max_force) e``
    (``gain`` in N/rad, ``damping_gain`` in N s/rad, ``max_force`` in N) at its fingertip
    centre, ``e`` the unit vector perpendicular to the line from the pivot to the centre (the
    direction in which the finger rolls the object about its pivot). The saturation keeps the
    push gentle far from the target, so that the contact stays closed; near it the law is a
    spring-damper of stiffness ``gain`` against the torque of (32), which leaves an offset
    that shrinks as ``1/gain``. Uses object information (``theta``, ``theta'``)."""
    theta_d = _number("orientation2d theta_d", theta_d, "rad")
    k = _number("orientation2d gain", gain, "N/rad", minimum=0.0)
    kd = _number("orientation2d damping_gain", damping_gain, "N s/rad", minimum=0.0)
    fmax = _number("orientation2d max_force", max_force, "N", positive=True)

    def orient(m):
        d = m.tip[0] - m.pivot
        e = ca.vertcat(d[1], -d[0]) / ca.norm_2(d)  # clockwise about the pivot: theta grows
        force = -fmax * ca.tanh((k * (m.theta - theta_d) + kd * m.dtheta) / fmax)
        cols = [0 * dq for dq in m.dq]
        cols[0] = m.J[0].T @ (force * e)
        return cols
    return paper2d() + Controller(orient, f"orientation2d({theta_d:g})", dimension=2,
                                 preset=f"orientation2d({theta_d!r}, {k!r}, {kd!r}, {fmax!r})")


def turn3d(angle: float, gain: float, damping_gain: float = 0.0, max_torque: float = 2e-3,
           axis=(0.0, 0.0, 1.0), reference=None) -> Controller:
    """Turn a held object by ``angle`` (rad) about the world ``axis`` (through the fingertips'
    mean centre, perpendicular to the line between them) and hold it: to :func:`paper3d`, the
    fingers add the tangential forces of the couple
    ``M = -max_torque tanh((gain (phi - angle) + damping_gain phi') / max_torque)`` (N m per
    rad, N m s per rad, N m) about ``axis``, finger ``i`` at its fingertip centre
    ``F_i = (M / N) axis x d_i / |d_i|^2``, ``d_i`` its offset from the mean centre (no net
    force). ``phi`` is the object's turn about ``axis`` from ``reference`` (a rotation matrix,
    body to world; default the scene's ``rotation``, the guess of its start: pass the solved
    start's to turn from there): ``atan2`` of the turned frame's components in the plane
    normal to ``axis``. Uses object information (its rotation and angular velocity).

    The axis must be across the grasp: a turn about the line through the two contacts is the
    grasp's free spin, which rolling fingertips cannot drive (only a torsional friction
    couples it)."""
    angle = _number("turn3d angle", angle, "rad")
    k = _number("turn3d gain", gain, "N m/rad", minimum=0.0)
    kd = _number("turn3d damping_gain", damping_gain, "N m s/rad", minimum=0.0)
    mmax = _number("turn3d max_torque", max_torque, "N m", positive=True)
    try:
        a = np.asarray(axis, dtype=float)
    except (TypeError, ValueError):
        a = np.zeros(0)
    if a.shape != (3,) or not np.all(np.isfinite(a)) or not np.linalg.norm(a) > 0:
        raise ControllerError(f"turn3d axis = {axis!r}: give three finite numbers, not all 0")
    a = a / np.linalg.norm(a)
    # two unit vectors spanning the plane normal to the axis
    e1 = np.cross(a, [1.0, 0.0, 0.0] if abs(a[0]) < 0.9 else [0.0, 1.0, 0.0])
    e1 /= np.linalg.norm(e1)
    e2 = np.cross(a, e1)
    ref = None
    if reference is not None:
        try:
            ref = np.asarray(reference, dtype=float)
        except (TypeError, ValueError):
            ref = np.zeros(0)
        if ref.shape != (3, 3) or not np.all(np.isfinite(ref)) \
                or not np.allclose(ref @ ref.T, np.eye(3), atol=1e-9):
            raise ControllerError("turn3d reference must be a 3 x 3 rotation matrix (orthonormal "
                                  "to 1e-9)")

    def turn(m):
        A, E1, E2 = ca.DM(a), ca.DM(e1), ca.DM(e2)
        R0 = m.param("rotation0") if ref is None else ca.DM(ref)
        turned = m.rotation @ R0.T @ E1   # e1 carried by the object's turn
        phi = ca.atan2(ca.dot(turned, E2), ca.dot(turned, E1))
        rate = ca.dot(m.rotation @ m.omega, A)
        couple = -mmax * ca.tanh((k * (phi - angle) + kd * rate) / mmax)
        N = len(m.tip)
        centre = sum(m.tip[1:], m.tip[0]) / N
        cols = []
        for J, tip in zip(m.J, m.tip):
            d = tip - centre
            cols.append(J.T @ ((couple / N) * ca.cross(A, d) / ca.dot(d, d)))
        return cols
    return paper3d() + Controller(turn, f"turn3d({angle:g})", dimension=3, preset=(
        f"turn3d({angle!r}, {k!r}, {kd!r}, {mmax!r}, {a.tolist()!r}, "
        f"{None if ref is None else ref.tolist()!r})"))
