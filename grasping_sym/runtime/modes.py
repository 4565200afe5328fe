"""Contact that can change: a run of a model with contact modes, switching at located events.

A model with modes (a body on a plane, ``model.body``; the manifest's ``modes``) is compiled
once with its mode a run-time parameter (0 rolling, 1 sliding, 2 separated) and the slip
direction at the start of a slide (``slip_x``, ``slip_y``, ``slip_z``). A run integrates one
segment per mode by the run's C loop (``METHODS``: radau, dopri5, dop853), which watches the
mode's witnesses itself (``c/watch.c``) at every step's end and at points of its dense output
at most ``WATCH_DT`` s apart (so a sparse ``t_eval`` misses no switch that lasts longer), and
stops at the first sign change, found on the dense output; the event is then located on the
trajectory integrated again from that step's start (``gs_watch_refine`` in C, else
``runtime.events.refine``), where the run switches (``docs/conventions.md`` section 7). A
segment in which every contact rolls is integrated by the base scene's rolling model where
the model has one (``Model.rolling``, ``_Leg``; sections 8 and 9):

- rolling: ``mu f - |F_t|`` reaching 0 -> sliding, the slip starting where the sliding
  equations accelerate it (the fixed point of ``d -> a_t(d)/|a_t(d)|`` from
  ``-F_t/|F_t|``); ``f`` reaching 0 -> separated;
- sliding: ``f`` reaching 0 -> separated; the slip velocity along its direction ``d`` at the
  slide's start, ``v_t . d``, reaching 0 -> the slip stopped if ``|v_t| <= STOP_SPEED`` there
  (else it turned past 90 degrees, a 3D grasp's past ``REAIM_ANGLE`` (its witness
  ``v_t . d - cos(REAIM_ANGLE) |v_t|``): the slide goes on along the new ``v_t``, no
  switch): the contact velocity is set to
  0 (a reset, recorded) and the run rolls if rolling is consistent there (``|F_t| <= mu f``
  in the rolling solution, ``f > 0``), else slides on in the direction the equations give;
- separated: the gap reaching 0 while approaching -> an impact: Newton's restitution ``e``
  along the normal and Coulomb friction on the impulse (stick if the impulse that stops the
  tangential motion lies in the cone, else slide with the impulse on the cone's edge along
  the incoming slip), then separated again (bouncing) or in contact.

Every switch is recorded in ``res.events``; ``res.modes`` holds the mode at each output time.
Cases with no consistent answer stop by name (``errors.ContactModeError``): Painleve (the
sliding normal row's coefficient ``painleve`` <= 0), chattering (more than ``MAX_SWITCHES``
switches within ``SWITCH_WINDOW`` s), an event that cannot be located.
"""
from __future__ import annotations

import dataclasses
import itertools
import math
from time import perf_counter

import numpy as np

from grasping_sym.contact import Coulomb
from grasping_sym.errors import (
    ChatteringError,
    ContactLeftContourError,
    ContactModeError,
    EventLocationError,
    GraspingSymError,
    IntegratorError,
    JointLimitError,
    PainleveError,
    RunArgumentError,
    RunInterruptedError,
)
from grasping_sym.runtime import c_loops, events, failures, fastpath, friction, integrators, parameters, pool
from grasping_sym.runtime import outputs as outputs_
from grasping_sym.runtime import run as run_
from grasping_sym.runtime.atlas import Atlases, by_charts, name_charts, repeated
from grasping_sym.runtime.parameters import complete
from grasping_sym.runtime.result import SimulationResult
from grasping_sym.runtime.watch import WATCH_DT, WATCH_SAFETY

ROLLING, SLIDING, SEPARATED = 0, 1, 2
#: The methods a run with modes takes: the adaptive loops in C (implicit and explicit).
METHODS = ("radau", "dopri5", "dop853")
#: Those whose slides from rest have an onset (``_Run.onset_slip``).
IMPLICIT = ("radau",)
#: How another closed contact takes an impulse at an impact (``_GraspRun._impulse``): held,
#: let go, or ``(SLIDE, d)``: sliding along the slip direction ``d``.
HOLD, OPEN, SLIDE = "hold", "open", "slide"
NAMES = ("rolling", "sliding", "separated")
#: Gap (m) within which a start counts as in contact.
CONTACT_GAP = 1e-9
#: Slip speed (m/s) at or below which a contact counts as at rest of the slip (rolling if
#: consistent): the round-off of a contact velocity that a reset set to 0.
SLIP_SPEED = 1e-10
#: Slip speed (m/s) at the located zero of ``v_t . slip`` above which the slip did not stop but
#: turned past 90 degrees from ``slip`` (a 3D grasp's: ``REAIM_ANGLE``): the slide goes on,
#: re-aimed (no switch, no reset).
STOP_SPEED = 1e-6
#: rad: a 3D grasp's slide is re-aimed where it has turned this far from ``slip``
#: (``_GraspRun.slip_terms``)
REAIM_ANGLE = math.pi / 3
#: Most switches within ``SWITCH_WINDOW`` seconds before a run stops as chattering.
MAX_SWITCHES = 50
SWITCH_WINDOW = 1e-3
#: Most iterations of the sliding impulse's direction (Moreau's law: the impulse on the cone's
#: edge opposes the slip it leaves).
MOREAU_ITERATIONS = 100
#: An impact slower than this (m/s, normal approach) is plastic whatever ``e``: the bounces
#: of a body coming to rest would otherwise accumulate (Zeno).
REST_SPEED = 1e-3
#: m: a separated contact's gap is watched for its return once it was seen above this; one
#: that closes again first (within the watched interval that opened it) hits once its gap
#: falls below ``-GAP_RETURN``: the round-off of a gap at its opening does not count.
GAP_RETURN = 1e-12


#: The relative step of ``c/jac.c``'s forward differences (``sqrt(eps)``): a Jacobian not
#: generated is taken with it (``_Run._slip_noise``).
FD_STEP = math.sqrt(2.220446049250313e-16)
#: An onset's scale is at least this many times the change of the slip velocity under those
#: steps (``_Run.onset_slip``): an onset narrower made that Jacobian wrong (a 3D pinch's onset
#: took 6 188 steps of radau at rtol 1e-11, against 8 without the onset; 2 with this floor);
#: 10 times it made the rows inside a grasp's onset differ by 4e-7 rad/s between two watches
#: of the same run at rtol 1e-9 (the onset's own scale), 1 time by 2e-9, as without an onset.
FD_ONSET = 1.0
#: A slide's slip witness is armed above this many times the run's ``atol`` (m/s), if more than
#: ``SLIP_SPEED``: the integration's own noise on a contact velocity (``_arming``).
SLIP_NOISE = 10.0


def _arming(name: str, atol: float = 0.0) -> float:
    """The witness's ``tol`` of ``c/watch.c``: it is watched for a return to 0 once it was seen
    above it, and, when > 0, for a fall below ``-tol`` before that: a gap's (``GAP_RETURN``)
    and a slide's slip, whose start from rest is noise below ``SLIP_SPEED`` or the run's
    ``SLIP_NOISE atol`` (a slide starting at the cone's edge gains speed as the square of the
    time; at rtol 1e-6 the noise of a loose run's velocities crossed -SLIP_SPEED first, and
    paper3d's fingers chattered between rolling and sliding); the others start > 0."""
    if name == "slip":
        return max(SLIP_SPEED, SLIP_NOISE * atol)
    return GAP_RETURN if name == "gap" else 0.0


def friction_law(model, mu, e=None) -> tuple[tuple[float, ...], float]:
    """``(mu per contact, e)`` of a run: ``mu`` (a number or a ``Coulomb``) else the model's
    law, ``e`` (a number in [0, 1]) else the law's; no law at all: ``mu = inf`` (the contact
    never slides), ``e = 0``."""
    k = int(model.manifest.get("n_contacts", 1))
    law = model.friction if mu is None else mu
    if law is None:
        mu_, e_law = (math.inf,) * k, 0.0
    elif isinstance(law, Coulomb):
        mu_, e_law = tuple(float(v) for v in law.per_contact(k)), float(law.e)
    elif isinstance(law, (tuple, list, np.ndarray)) and np.ndim(law) == 1:  # one per contact
        if len(law) != k or not all(isinstance(v, (int, float, np.floating, np.integer))
                                    and not isinstance(v, (bool, np.bool_)) and float(v) >= 0 for v in law):
            raise RunArgumentError(f"mu = {tuple(law)!r:.60}: give {k} numbers >= 0, one per contact")
        mu_ = tuple(float(v) for v in law)
        e_law = float(model.friction.e) if isinstance(model.friction, Coulomb) else 0.0
    else:
        if isinstance(law, (bool, np.bool_)) or not isinstance(law, (int, float, np.floating, np.integer)):
            raise RunArgumentError(f"mu = {law!r:.40} must be a number >= 0 or gs.contact.coulomb(mu, e)")
        if not float(law) >= 0:
            raise RunArgumentError(f"mu = {law!r} must be a number >= 0 (math.inf: never slides)")
        mu_ = (float(law),) * k
        e_law = float(model.friction.e) if isinstance(model.friction, Coulomb) else 0.0
    if e is None:
        return mu_, e_law
    if isinstance(e, (bool, np.bool_)) or not isinstance(e, (int, float, np.floating, np.integer)) \
            or not 0 <= float(e) <= 1:
        raise RunArgumentError(f"e = {e!r:.40} must be a number in [0, 1] (Newton's restitution)")
    return mu_, float(e)


@dataclasses.dataclass(frozen=True, eq=False)
class _Leg:
    """What integrates a segment (``_segment``): the model with modes itself, or, where every
    contact rolls, the base scene's rolling model (``Model.rolling``; the manifest's
    ``rolling_map``): the same equations with their generated Jacobian and none of the other
    modes' branches. Its state is ``x[to]`` of the model with modes' ``x``, which is its
    ``X[..., back]``; ``watched``: its witnesses (the model with modes': ``_Run.witnesses``)."""

    model: object
    #: each compiled output's column; the inputs' slots in p, ``(first, how many)``
    col: dict
    input_slots: tuple[int, int]
    to: np.ndarray | None = None
    back: np.ndarray | None = None
    watched: tuple = ()
    #: ``to[back]``, as a tuple: ``x`` is one of the leg's states where ``x[round_trip] == x``
    round_trip: tuple = ()

    @classmethod
    def of(cls, model, to=None, back=None, watched=()) -> _Leg:
        """``model``'s leg: its outputs' columns and its inputs' slots read from it."""
        names = model.p_names
        slots = (names.index(model.input_names[0]), len(model.input_names)) if model.input_names else (0, 0)
        to_a = None if to is None else np.array(to, dtype=int)
        back_a = None if back is None else np.array(back, dtype=int)
        trip = () if to_a is None or back_a is None else tuple(to_a[back_a].tolist())
        return cls(model, {k: i for i, k in enumerate(model.columns)}, slots, to_a, back_a,
                   tuple(watched), trip)

    def state(self, x: np.ndarray) -> np.ndarray:
        """This leg's state of the model with modes' ``x``."""
        return x if self.to is None else np.asarray(x)[self.to]

    def states(self, X: np.ndarray) -> np.ndarray:
        """The model with modes' states of this leg's ``X`` (a state, or rows of them)."""
        return X if self.back is None else np.asarray(X)[..., self.back]


class _Run:
    """One run's state: the model, its settings, the parameters per mode; what every kind of
    model with modes shares (a subclass per kind gives its contacts' geometry).

    Contacts are numbered from 1; ``modes`` and ``slips`` hold each contact's mode and slip
    direction (None: the parameter's default). A model of one contact names its outputs
    without a number (``gap``), one of several with it (``gap1``, ``gap2``).
    """

    #: the run-time parameters of contact j: its mode, its slip direction's first entry
    MODE, SLIP = "mode", "slip"

    def __init__(self, model, s, mus: tuple[float, ...], e: float):
        self.model, self.s, self.mus, self.e = model, s, tuple(mus), e
        self.k = len(self.mus)
        static = model.run_cache.get("modes")
        if static is None or static["defaults"] is not model.default_params:
            # what a run of this model reads of it, every run alike
            names = model.p_names
            static = model.run_cache["modes"] = {
                "defaults": model.default_params, "p": np.array(model.default_params, dtype=float),
                "mode": [names.index(self.key(self.MODE, j)) for j in self.contacts],
                "slip": [names.index(self.key(self.SLIP, j)) for j in self.contacts],
                "mu": [names.index(self.key("mu", j)) for j in self.contacts],
                "own": _Leg.of(model), "rolling": {},
                "atlases": Atlases(model) if model.manifest.get("atlas") else None}
        self.p = static["p"].copy()
        self.i_mode, self.i_slip = static["mode"], static["slip"]
        for j, i in zip(self.contacts, static["mu"]):
            self.p[i] = min(self.mus[j - 1], 1e300)
        self.events: list[dict] = []
        #: the model's atlases (``runtime.atlas``; None: no surface has one) and the run's
        #: chart switches, in time order
        self.atlases = static["atlases"]
        self.chart_switches: list[dict] = []
        #: ``switch_time``: seconds spent locating the switches and making them
        #: segments: one per mode's stretch (the start's and one after each switch); chunks:
        #: the integrations they were run in (one per segment, and per piece of an inputs' table)
        #: rolling_model_segments: the segments the base scene's rolling model ran (``_Leg``)
        #: watched: the points the witnesses were evaluated at; left_unwatched: the points (steps'
        #: ends, points of their dense output) they were not (``WATCH_SAFETY``, ``c/watch.c``);
        #: loop_time: the seconds spent in the C loops (the rest of ``wall_time`` is Python's)
        self.stats = {"n_steps": 0, "n_rhs": 0, "segments": 0, "chunks": 0, "rolling_model_segments": 0,
                      "switch_time": 0.0, "watched": 0, "left_unwatched": 0, "loop_time": 0.0}
        #: the inputs' table (``runtime.inputs``; None: a model without inputs) and the time at
        #: which ``outputs`` reads them
        self.sched, self.t = None, 0.0
        #: contact -> its slide's onset's scale, of the contacts at their onset (``witnesses``)
        self.slip_levels: dict[int, float] = {}
        self.own_leg = static["own"]
        legs, rolling = static["rolling"], getattr(model, "rolling", None)
        if self.mus not in legs or legs[self.mus][0] is not rolling:  # its witnesses read mu
            if len(legs) >= 64:
                legs.clear()
            legs[self.mus] = (rolling, self._rolling_leg(rolling, model.manifest.get("rolling_map")))
        self.rolling_leg = legs[self.mus][1]

    def _rolling_leg(self, rolling, where: dict | None) -> _Leg | None:
        """The leg of the base scene's rolling model (``_Leg``), watching each contact's cone
        ``mu f - |F_t|`` and normal force on its own outputs; None when there is none, or it
        cannot (no watch, no tangential forces among its outputs, other inputs)."""
        if rolling is None or where is None or not rolling.library.can_watch \
                or tuple(rolling.input_names) != tuple(self.model.input_names):
            return None
        found = friction.contacts(rolling)
        if len(found) != self.k or not all(tangential for _, tangential in found):
            return None
        watched = []
        for j, (fk, tangential) in zip(self.contacts, found):
            if self.mus[j - 1] != math.inf:
                watched.append(("cone", j, [(fk, self.mus[j - 1]), *((k, 1.0, True) for k in tangential)]))
            watched.append(("normal_force", j, [(fk, 1.0)]))
        return _Leg.of(rolling, where["to"], where["from"], watched)

    def check_start(self, x0: np.ndarray, y: dict) -> None:
        """Refuse by name an ``x0`` this kind of run cannot start from (``y``: its outputs with
        every contact rolling); here none."""

    def leg(self, modes, x: np.ndarray) -> _Leg:
        """The leg that runs a segment from ``x`` with contacts in ``modes``: the rolling
        model's where every contact rolls and ``x`` is one of its states (a shared contact
        parameter: ``u0 = u1``, to 1e-12), else the model with modes itself."""
        leg = self.rolling_leg
        if leg is None or any(m != ROLLING for m in modes):
            return self.own_leg
        v = np.asarray(x, dtype=float).tolist()  # Python floats: NumPy's overhead on a few
        scale = 1e-12 * max(1.0, *map(abs, v))    # entries was 10 us of a short run's 65
        if any(abs(v[j] - vi) > scale for j, vi in zip(leg.round_trip, v)):
            return self.own_leg
        return leg

    @property
    def contacts(self) -> range:
        return range(1, self.k + 1)

    @property
    def mu(self) -> float:
        """The friction coefficient of a model of one contact."""
        return self.mus[0]

    def key(self, name: str, j: int) -> str:
        """Contact ``j``'s output or parameter ``name``."""
        return name if self.k == 1 else f"{name}{j}"

    def slip_keys(self, j: int) -> tuple[str, ...]:
        """The outputs of contact ``j``'s slip velocity, whose slide from rest of the slip has an
        onset (``onset_slip``); none: a contact in a plane (its slip's direction is a sign)."""
        return ()

    def onset_slip(self, d: np.ndarray, t: float, x: np.ndarray, p: np.ndarray, j: int) -> np.ndarray:
        """The slip parameter of contact ``j``'s slide that starts from rest of the slip (at the
        cone's edge, or past it: at a start, after a stop or an impact) along ``d`` at
        ``(t, x)`` (``p``: the parameters there, rolling): ``d`` and the onset's scale ``s``
        (the parameter ``slip_onset{j}``; ``derive.body_plane``, ``derive.grasp3d_modes``): the
        sliding direction continuous where ``v_t`` is within a few times the integration's
        noise on it, until the output ``onset_left{j}`` reaches 0 (the witness ``onset``: no
        switch recorded). ``s`` is ``SLIP_NOISE`` times that noise (``_slip_noise``), at least
        ``SLIP_SPEED`` and, on a difference Jacobian, ``FD_ONSET`` times the slip's
        change under its steps; the onset's slip witness is armed above ``s`` (``arming``).
        An explicit method keeps ``d`` alone (the former rules): the onset's stiffness bounds
        its step (dop853 at rtol 1e-10 stopped as stiff at each slide of paper3d's grasp,
        h = 1e-9 s)."""
        keys = self.slip_keys(j)
        if not keys or self.s.method not in IMPLICIT:
            return d
        noise, fd = self._slip_noise(t, x, p, keys)
        return np.append(np.asarray(d, dtype=float), max(SLIP_SPEED, SLIP_NOISE * noise, FD_ONSET * fd))

    def _slip_noise(self, t: float, x: np.ndarray, p: np.ndarray, keys: tuple[str, ...]) -> tuple[float, float]:
        """The integration's noise on the slip velocity (outputs ``keys``) at ``(t, x)``: the sum
        over the state's components of the change of ``v_t`` when each moves by its own
        tolerance ``atol + rtol |x_i|``; and, for radau on a model without a generated
        Jacobian (radau's, ``c/jac.c``), the same sum for the forward differences' steps, else
        0 (one batch of the compiled outputs)."""
        x = np.asarray(x, dtype=float)
        steps = [self.s.atol + self.s.rtol * np.abs(x)]
        if not self.model.manifest.get("driver_defines", {}).get("GS_HAS_JAC"):
            steps.append(FD_STEP * np.maximum(np.abs(x), max(self.s.atol, 1e-8) * 1e3))
        X = np.vstack([x, *(x + np.diag(h) for h in steps)])
        Y = outputs_.along_rows(self.model, np.full(len(X), t), X, p, self.sched)
        cols = [self.model.columns.index(k) for k in keys]
        dv = Y[1:, cols] - Y[0, cols]
        sums = np.sqrt((dv * dv).sum(axis=1)).reshape(len(steps), len(x)).sum(axis=1)
        return float(sums[0]), float(sums[1]) if len(steps) > 1 else 0.0

    def arming(self, name: str, j: int) -> float:
        """The arming level of contact ``j``'s witness ``name`` (``_arming``; a slide's slip at
        its onset: the onset's width ``s``), as the last ``witnesses`` gave them. A slide whose
        slip peaks below ``s`` stops where its witness last crossed 0 (``_last_zero``): armed
        at ``s`` alone, a shaken belt's short slide stopped 1.1-2 ms late at the default
        tolerances, friction feeding its reversed slip; armed at ``s/10`` (the noise estimate,
        which the integration's error on the slip exceeds at an onset), paper3d's grasp took
        eight spurious stops within 3 us of its slide's start at rtol 1e-8 (mu 0.04)."""
        base = _arming(name, self.s.atol)
        if name == "slip" and j in self.slip_levels:
            return max(base, self.slip_levels[j])
        return base

    def params(self, modes, slips=None) -> np.ndarray:
        """``p`` with each contact's mode and, where given, slip direction."""
        p = self.p.copy()
        for j in self.contacts:
            p[self.i_mode[j - 1]] = float(modes[j - 1])
            d = None if slips is None else slips[j - 1]
            if d is not None:
                p[self.i_slip[j - 1]:self.i_slip[j - 1] + len(d)] = d
        return p

    def outputs(self, x: np.ndarray, p: np.ndarray, model=None) -> dict[str, float]:
        """Every output of ``model`` (default: the model with modes) at ``x`` with ``p``, the
        inputs at ``self.t``; those only a switch reads (the manifest's ``internal_outputs``)
        computed when first read (``_Outputs``)."""
        model = self.model if model is None else model
        if self.sched is not None:
            p = model.with_inputs(p, self.sched(self.t))
        if not model.columns:
            return {}
        timed = bool(model.manifest.get("outputs_time"))
        p = complete(model, p)
        y = outputs_.row(model, x, p, self.t if timed else None)
        out = _Outputs(zip(model.columns, y.tolist()))
        out.at = (model, x, p if not timed else np.append(p, self.t))
        return out

    def with_mode(self, x, modes, slips, j: int, mode: int, slip=None) -> dict[str, float]:
        """The outputs at ``x`` with contact ``j`` in ``mode`` (the others as they are)."""
        m, sl = list(modes), list(slips)
        m[j - 1], sl[j - 1] = mode, slip
        return self.outputs(x, self.params(m, sl))

    def contact_start(self, t: float, x: np.ndarray, modes, slips, j: int,
                      y: dict | None = None) -> tuple[int, np.ndarray | None]:
        """The mode of contact ``j`` in contact (gap and normal speed 0) and its slip direction,
        the others in their modes: a slipping contact slides if its sliding normal force is
        > 0; one at rest of the slip rolls if rolling is consistent (``f > 0``,
        ``|F_t| <= mu f``), else slides where the sliding equations take it if that is
        consistent; a contact that can do neither separates if its free normal acceleration
        is >= 0. Otherwise there is no consistent mode: a named error. ``y``: the outputs at
        ``x`` in ``modes`` where contact ``j`` rolls, if at hand."""
        y = self.with_mode(x, modes, slips, j, ROLLING) if y is None else y
        mu = self.mus[j - 1]
        vt = self.slip_velocity(y, j)
        f, ft = y[self.key("normal_force", j)], y[self.key("tangential_force", j)]
        if _norm(vt) > SLIP_SPEED:
            return self._slide_or_leave(t, x, modes, slips, j, y, vt / _norm(vt))
        if f > 0 and (ft < mu * f or mu == math.inf):
            return ROLLING, None
        if f > 0:  # a slide from rest of the slip: its onset (onset_slip)
            m = list(modes)
            m[j - 1] = ROLLING
            d = self.slip_direction(x, y, j, modes=modes, slips=slips)
            return self._slide_or_leave(t, x, modes, slips, j, y, self.onset_slip(d, t, x, self.params(m, slips), j))
        return self._slide_or_leave(t, x, modes, slips, j, y, None)

    def _slide_or_leave(self, t, x, modes, slips, j, y, d):
        if d is not None:
            ys = self.with_mode(x, modes, slips, j, SLIDING, d)
            if not ys[self.key("painleve", j)] > 0:
                _painleve(self.model, t, x, ys[self.key("painleve", j)], self.mus[j - 1], j)
            if ys[self.key("normal_force", j)] > 0:
                return SLIDING, d
        if self.free_normal_acceleration(x, modes, slips, j, y) >= 0:
            return SEPARATED, None
        raise ContactModeError(t, x, f"no mode of contact {j} is consistent: rolling needs f = "
                               f"{y[self.key('normal_force', j)]:.6g} N <= 0 or more friction than mu = "
                               f"{self.mus[j - 1]:g}, sliding a normal force <= 0, and the free bodies "
                               "would accelerate into each other; the rigid model has no answer here",
                               self.model.state_names)

    def witnesses(self, modes, slips) -> list[tuple[str, int, list[tuple[str, float]]]]:
        """``(name, contact, terms)`` of the events of every contact in its mode: each witness
        is ``sum(c * y[k] for k, c in terms)`` over the compiled outputs ``y`` (``value``); a
        sliding contact stops where ``v_t . slip`` reaches 0, a separated one hits where its
        gap does."""
        out = []
        self.slip_levels = {}
        for j in self.contacts:
            mode, mu = modes[j - 1], self.mus[j - 1]
            fk = self.key("normal_force", j)
            if mode == ROLLING:
                if mu != math.inf:  # no friction limit: no cone to leave
                    out.append(("cone", j, [(fk, mu), (self.key("tangential_force", j), -1.0)]))
                out.append(("normal_force", j, [(fk, 1.0)]))
            elif mode == SLIDING:
                d = np.asarray(slips[j - 1], dtype=float)
                out += [("normal_force", j, [(fk, 1.0)]), ("slip", j, self.slip_terms(d, j)),
                        ("painleve", j, [(self.key("painleve", j), 1.0)])]
                if d.ndim == 1 and len(d) > len(self.slip_keys(j)) > 0 and d[-1] > 0:  # its onset
                    out.append(("onset", j, [(self.key("onset_left", j), 1.0)]))
                    self.slip_levels[j] = float(d[-1])
            else:
                out.append(("gap", j, [(self.key("gap", j), 1.0)]))
        return out


class _Outputs(dict):
    """A state's outputs (``_Run.outputs``); the outputs only a switch reads (an impact's
    terms, the manifest's ``internal_outputs``: a compiled function of their own, not
    evaluated at every output time) computed at the first read of one of them."""

    #: ``(model, x, p)``: where they were computed (p with the time last, for outputs that read it)
    at: tuple

    def __missing__(self, key: str) -> float:
        model, x, p = self.at
        spec = model.manifest.get("internal_outputs")
        if spec is None or key not in spec["names"]:
            raise KeyError(key)
        fn = model.run_cache.get("internal")
        if fn is None:
            fn = model.run_cache["internal"] = model.library.function(spec["function"])
        self.update(zip(spec["names"], fn(x, p).tolist()))
        return self[key]


def value(terms: list[tuple], y: dict) -> float:
    """A witness (``_Run.witnesses``) at one state's outputs ``y``: ``sum(c * y[k])`` over its
    terms ``(k, c)``, less ``sqrt(sum((c * y[k])**2))`` over those given as ``(k, c, True)``
    (a norm: a cone's ``|F_t|`` from its components; ``c/watch.c``)."""
    linear = sum(term[1] * y[term[0]] for term in terms if len(term) == 2 or not term[2])
    return linear - math.sqrt(sum((term[1] * y[term[0]]) ** 2 for term in terms if len(term) > 2 and term[2]))


class _BodyRun(_Run):
    """A body on a plane (``model.body``): the contact's quantities in the world frame."""

    SLIP = "slip_x"

    def __init__(self, model, s, mus, e: float):
        super().__init__(model, s, mus, e)
        info = model.manifest["body"]
        self.m = float(info["mass"])
        self.H = np.array(info["inertia"], dtype=float)
        self.Hinv = np.linalg.inv(self.H)
        self.n = np.array(info["plane_normal"], dtype=float)
        self.gain = float(info["gain"])
        self._n, self._Hinv = self.n.tolist(), self.Hinv.tolist()  # Python floats: 3-vectors

    #: ``support_facing = |R N + n| = 2 sin(a/2)`` above which ``x0``'s support point is
    #: refused on a surface with an atlas: its normal ``a`` > 30 degrees from facing the plane
    #: (a point read in the other chart is another point of the surface; one a little off is
    #: pulled back by its rate's gain, as without an atlas)
    FACING_TOL = 2 * math.sin(math.radians(15.0))

    def check_start(self, x0: np.ndarray, y: dict) -> None:
        """On a surface with an atlas, ``x0``'s support point ``(u, v)``, read in the run's
        chart (``params`` names it), must face the plane (``FACING_TOL``)."""
        charts = parameters.charts_of(self.model)
        facing = y.get("support_facing")
        if charts and facing is not None and not facing <= self.FACING_TOL:
            raise RunArgumentError(
                f"x0's support point (u, v) = ({x0[-2]:.6g}, {x0[-1]:.6g}), read in chart "
                f"{int(self.p[self.model.p_names.index(charts[0])])}, does not face the plane (|R N + n| = "
                f"{facing:.3g}: more than 30 degrees off): a row of a run is written in that row's chart: "
                "give it, params={'chart': result.charts['chart'][i]}, or start from model.initial_state()")

    _K = tuple(tuple(f"K_{i}{j}" for j in range(3)) for i in range(3))
    _VC, _RC, _FT = (tuple(f"{v}_{c}" for c in "xyz") for v in ("vc", "rc", "rolling_Ft"))

    def contact(self, y: dict) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """From one state's outputs: the contact's inverse effective mass ``K`` (1/kg), its
        velocity relative to the plane ``v_c``, its point from the centre ``r_c`` (world) and
        the rolling solution's force ``F_roll``."""
        K = np.array([[y[k] for k in row] for row in self._K])
        vc = np.array([y[k] for k in self._VC])
        rc = np.array([y[k] for k in self._RC])
        F_roll = y["rolling_normal_force"] * self.n + np.array([y[k] for k in self._FT])
        return K, vc, rc, F_roll

    def slip_velocity(self, y: dict, j: int = 1) -> np.ndarray:
        return np.array([y[f"vt_{c}"] for c in "xyz"])

    def slip_terms(self, d: np.ndarray, j: int = 1) -> list[tuple[str, float]]:
        return [("vt_x", d[0]), ("vt_y", d[1]), ("vt_z", d[2])]

    def slip_keys(self, j: int = 1) -> tuple[str, ...]:
        return ("vt_x", "vt_y", "vt_z")

    def apart(self, x: np.ndarray) -> np.ndarray:
        """A body apart from the plane: its support point is the model's to keep."""
        return np.asarray(x, dtype=float)

    # ------------------------------------------------------------------ what a mode is
    def slip_direction(self, x: np.ndarray, y: dict, j: int = 1, modes=None, slips=None) -> np.ndarray:
        """The direction a slide starts in from rest of the slip (module docstring)."""
        n = self.n
        K, _, _, F_roll = self.contact(y)
        ft = F_roll - np.dot(F_roll, n) * n
        d = -ft / _norm(ft) if _norm(ft) > 0 else np.cross(n, [1.0, 0.0, 0.0])
        def slip_acceleration(d):  # at v_c = 0 and gap = 0 the rolling acceleration is 0
            dirn = n - self.mu * d
            a = K @ (np.dot(n, K @ F_roll) / np.dot(n, K @ dirn) * dirn - F_roll)
            return a - np.dot(a, n) * n, 1e-12 * max(_norm(a), 1.0)

        return _direction(d, slip_acceleration, normal=n)

    def free_normal_acceleration(self, x, modes, slips, j: int, y: dict) -> float:
        """The contact's normal acceleration with no contact force (m/s^2)."""
        n = self.n
        K, vc, _, F_roll = self.contact(y)
        target = -2 * self.gain * vc - self.gain**2 * y["gap"] * n
        return float(np.dot(n, target - K @ F_roll))

    # ------------------------------------------------------------------ the maps at a switch
    def stop_slip(self, x: np.ndarray, y: dict, modes, j: int = 1) -> tuple[np.ndarray, float]:
        """The contact velocity set to 0 (the impulse that does it); the largest change."""
        K, vc, rc, _ = self.contact(y)
        P = _solve3(K, -vc)
        return self._apply(x, P, rc), float(np.max(np.abs(vc)))

    def _stuck_impact(self, x: np.ndarray, y: dict):
        """``impact``'s answer when the impulse that makes the contact's velocity Newton's
        ``-e v_n n`` is inside the cone (stuck), on Python floats; None when it is not."""
        n = self._n
        K = [[y[k] for k in row] for row in self._K]
        vc = [y[k] for k in self._VC]
        vn = n[0] * vc[0] + n[1] * vc[1] + n[2] * vc[2]
        e = self.e if -vn > REST_SPEED else 0.0
        P = _solve3_floats(K, [-e * vn * n[i] - vc[i] for i in range(3)])
        Pn = P[0] * n[0] + P[1] * n[1] + P[2] * n[2]
        if not math.hypot(*(P[i] - Pn * n[i] for i in range(3))) <= self.mu * Pn:
            return None
        rc = [y[k] for k in self._RC]
        dv = max(abs(K[i][0] * P[0] + K[i][1] * P[1] + K[i][2] * P[2]) for i in range(3))
        return self._apply(x, P, rc), dv, True, e > 0

    def _apply(self, x: np.ndarray, P, rc) -> np.ndarray:
        """``x`` after the impulse ``P`` (N s, world) at the contact point ``rc`` (world,
        from the centre), on Python floats (NumPy's overhead on 3-vectors is a switch's
        largest part)."""
        P, rc = [float(v) for v in P], [float(v) for v in rc]
        v = x.tolist()
        w, qx, qy, qz = v[3:7]
        s = w * w + qx * qx + qy * qy + qz * qz
        r00, r01, r02 = w * w + qx * qx - qy * qy - qz * qz, 2 * (qx * qy - w * qz), 2 * (qx * qz + w * qy)
        r10, r11, r12 = 2 * (qx * qy + w * qz), w * w - qx * qx + qy * qy - qz * qz, 2 * (qy * qz - w * qx)
        r20, r21, r22 = 2 * (qx * qz - w * qy), 2 * (qy * qz + w * qx), w * w - qx * qx - qy * qy + qz * qz
        a0, a1, a2 = ((r00 * rc[0] + r10 * rc[1] + r20 * rc[2]) / s, (r01 * rc[0] + r11 * rc[1] + r21 * rc[2]) / s,
                      (r02 * rc[0] + r12 * rc[1] + r22 * rc[2]) / s)  # R^T rc
        b0, b1, b2 = ((r00 * P[0] + r10 * P[1] + r20 * P[2]) / s, (r01 * P[0] + r11 * P[1] + r21 * P[2]) / s,
                      (r02 * P[0] + r12 * P[1] + r22 * P[2]) / s)  # R^T P
        c0, c1, c2 = a1 * b2 - a2 * b1, a2 * b0 - a0 * b2, a0 * b1 - a1 * b0
        (h00, h01, h02), (h10, h11, h12), (h20, h21, h22) = self._Hinv
        m = self.m
        v[7:13] = (v[7] + P[0] / m, v[8] + P[1] / m, v[9] + P[2] / m, v[10] + (h00 * c0 + h01 * c1 + h02 * c2),
                   v[11] + (h10 * c0 + h11 * c1 + h12 * c2), v[12] + (h20 * c0 + h21 * c1 + h22 * c2))
        return np.array(v)

    def impact(self, t: float, x: np.ndarray, y: dict, modes, j: int = 1,
               slips=None) -> tuple[np.ndarray, float, bool, bool]:
        """Newton's restitution and Coulomb friction on the impulse (module docstring):
        ``(x after, largest speed change, stuck, bounced)``: a bounce when ``e > 0`` and the
        approach is faster than ``REST_SPEED``."""
        n, mu = self.n, self.mu
        stuck = self._stuck_impact(x, y)  # Python floats: a switch's largest part in NumPy
        if stuck is not None:
            return stuck
        K, vc, rc, _ = self.contact(y)
        vn = float(np.dot(n, vc))
        e = self.e if -vn > REST_SPEED else 0.0
        target = -e * vn * n
        P = _solve3(K, target - vc)
        Pn = float(np.dot(P, n))
        Pt = P - Pn * n
        vt = vc - vn * n
        stuck = bool(_norm(Pt) <= mu * Pn)
        if not stuck:  # on the cone's edge, against the slip
            if _norm(vt) > SLIP_SPEED:
                d = vt / _norm(vt)
            else:  # no incoming slip: the slip the frictionless impulse would make
                after0 = vc + K @ n * (-(1 + e) * vn / float(n @ K @ n))
                a_t = after0 - np.dot(after0, n) * n
                d = a_t / _norm(a_t) if _norm(a_t) > 0 else -Pt / _norm(Pt)
            denominator = float(np.dot(n, K @ (n - mu * d)))
            if not denominator > 0:
                raise PainleveError(t, x, f"an impact with mu = {mu:g} has no consistent impulse: "
                                    f"n . K (n - mu d) = {denominator:.6g} 1/kg <= 0 (Painleve's "
                                    "paradox at an impact); the rigid model has no answer here",
                                    self.model.state_names)
            def impulse(d):
                denominator = float(np.dot(n, K @ (n - mu * d)))
                return None if not denominator > 0 else -(1 + e) * vn / denominator * (n - mu * d)

            def slip_left(d):  # Moreau: the impulse opposes the slip it leaves
                P = impulse(d)
                after_v = vc + K @ (np.zeros(3) if P is None else P)
                return after_v - np.dot(after_v, n) * n, SLIP_SPEED

            d = _direction(d, slip_left, MOREAU_ITERATIONS, normal=n)
            P = impulse(d)
            after_t = slip_left(d)[0]
            if P is None or np.dot(after_t, d) < -1e-12 * max(1.0, _norm(vt)):
                raise PainleveError(t, x, f"an impact with mu = {mu:g} has no impulse on the cone's edge "
                                    "that opposes the slip it leaves (Moreau's law); the rigid model "
                                    "has no answer here", self.model.state_names)
        after = self._apply(x, P, rc)
        return after, float(np.max(np.abs(K @ P))), bool(stuck), e > 0


class _LineBodyRun(_Run):
    """A 2D body on a line (``model.body_line``): the contact's quantities in the world
    frame, the slip a signed speed along the line's tangent ``t = (-n_y, n_x)``."""

    def __init__(self, model, s, mus, e: float):
        super().__init__(model, s, mus, e)
        info = model.manifest["body2d"]
        self.m = float(info["mass"])
        self.inertia = float(info["inertia"])
        self.n = np.array(info["line_normal"], dtype=float)
        self.tan = np.array([-self.n[1], self.n[0]])
        self.gain = float(info["gain"])

    def contact(self, y: dict) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """From one state's outputs: ``K`` (1/kg), ``v_c``, ``r_c`` (from the centre) and the
        rolling solution's force ``F_roll``, world frame."""
        K = np.array([[y["K_00"], y["K_01"]], [y["K_10"], y["K_11"]]])
        vc = np.array([y["vc_x"], y["vc_y"]])
        rc = np.array([y["rc_x"], y["rc_y"]])
        F_roll = y["rolling_normal_force"] * self.n + y["rolling_Ft"] * self.tan
        return K, vc, rc, F_roll

    def slip_velocity(self, y: dict, j: int = 1) -> np.ndarray:
        return np.array([y["vt"]])

    def slip_terms(self, d: np.ndarray, j: int = 1) -> list[tuple[str, float]]:
        return [("vt", d[0])]

    def apart(self, x: np.ndarray) -> np.ndarray:
        """A body apart from the line: its support point is the model's to keep."""
        return np.asarray(x, dtype=float)

    def slip_direction(self, x: np.ndarray, y: dict, j: int = 1, modes=None, slips=None) -> np.ndarray:
        """A slide from rest of the slip starts against the friction rolling needs and the
        cone cannot give: ``-sign(F_t)`` of the rolling solution."""
        return np.array([-1.0 if y["rolling_Ft"] >= 0 else 1.0])

    def free_normal_acceleration(self, x, modes, slips, j: int, y: dict) -> float:
        """The contact's normal acceleration with no contact force (m/s^2)."""
        K, vc, _, F_roll = self.contact(y)
        target = -2 * self.gain * vc - self.gain**2 * y["gap"] * self.n
        return float(np.dot(self.n, target - K @ F_roll))

    def _apply(self, x: np.ndarray, P: np.ndarray, rc: np.ndarray) -> np.ndarray:
        """``x`` after the impulse ``P`` (N s, world) at ``rc`` (world, from the centre): the
        angular velocity ``w = -theta'`` changes by ``(rc x P) / I``."""
        x = x.copy()
        x[3:5] += P / self.m
        x[5] -= (rc[0] * P[1] - rc[1] * P[0]) / self.inertia
        return x

    def stop_slip(self, x: np.ndarray, y: dict, modes, j: int = 1) -> tuple[np.ndarray, float]:
        """The contact velocity set to 0 (the impulse that does it); the largest change."""
        K, vc, rc, _ = self.contact(y)
        return self._apply(x, _solve2(K, -vc), rc), float(np.max(np.abs(vc)))

    def impact(self, t: float, x: np.ndarray, y: dict, modes, j: int = 1,
               slips=None) -> tuple[np.ndarray, float, bool, bool]:
        """Newton's restitution and Coulomb friction on the impulse (``_BodyRun.impact`` in
        2D): the impulse that stops the tangential motion if it lies in the cone, else the one
        on the cone's edge whose slip after the impact it opposes (Moreau's law)."""
        n, tan, mu = self.n, self.tan, self.mu
        K, vc, rc, _ = self.contact(y)
        vn = float(np.dot(n, vc))
        e = self.e if -vn > REST_SPEED else 0.0
        P = _solve2(K, -e * vn * n - vc)
        stuck = bool(abs(np.dot(P, tan)) <= mu * np.dot(P, n))
        if not stuck:
            s0 = -math.copysign(1.0, float(np.dot(P, tan)))   # the slip the impulse opposes
            for d in (s0, -s0):
                dirn = n - mu * d * tan
                denominator = float(np.dot(n, K @ dirn))
                if not denominator > 0:
                    continue
                trial = -(1 + e) * vn / denominator * dirn
                if np.dot(trial, n) >= 0 and np.dot(vc + K @ trial, tan) * d >= -SLIP_SPEED:
                    P = trial
                    break
            else:
                raise PainleveError(t, x, f"an impact with mu = {mu:g} has no impulse on the cone's edge "
                                    "that opposes the slip it leaves with a positive normal row's "
                                    "coefficient (Painleve's paradox at an impact); the rigid model has "
                                    "no answer here", self.model.state_names)
        return self._apply(x, P, rc), float(np.max(np.abs(K @ P))), stuck, e > 0


class _PlanarRun(_Run):
    """A planar finger (``model.planar_modes``): the contact's quantities in its own frame,
    the normal row ``gQ`` (``gQ . v``: the rate of ``Q``, minus the gap's) and the tangent row
    ``gR`` (``v_t = gR . v``), ``W = [gQ; gR] M^-1 [gQ; gR]^T`` (``docs/conventions.md``
    section 8). A contact impulse ``(P_n, P_t)`` changes the speeds by
    ``-M^-1 (P_n gQ + P_t gR)``."""

    def slip_velocity(self, y: dict, j: int = 1) -> np.ndarray:
        return np.array([y["vt"]])

    def apart(self, x: np.ndarray) -> np.ndarray:
        """``x`` with its contact parameters on the contours' common normal (``R = 0`` and
        ``delta = 0``, Newton's method on ``(u0, u1)``): a start apart need not give them."""
        return _on_common_normal(self, np.array(x, dtype=float), 1, 6)

    def slip_terms(self, d: np.ndarray, j: int = 1) -> list[tuple[str, float]]:
        return [("vt", d[0])]

    def slip_direction(self, x: np.ndarray, y: dict, j: int = 1, modes=None, slips=None) -> np.ndarray:
        """A slide from rest of the slip starts along the rolling solution's tangential force
        (the friction it needs and the cone cannot give)."""
        return np.array([1.0 if y["rolling_lam"] >= 0 else -1.0])

    def free_normal_acceleration(self, x, modes, slips, j: int, y: dict) -> float:
        return float(y["free_normal_acceleration"])

    def _W(self, y: dict) -> tuple[float, float, float]:
        """``W``'s entries ``(W_nn, W_nt, W_tt)`` (symmetric). The maps of a switch are on
        Python floats: NumPy's calls on 2-vectors, from the caches a run leaves cold, were
        most of a switch's cost (``np.linalg.solve`` alone ~40 us)."""
        return float(y["W_nn"]), float(y["W_nt"]), float(y["W_tt"])

    def _solve(self, W: tuple[float, float, float], b0: float, b1: float) -> tuple[float, float]:
        """``W^-1 (b0, b1)`` (``_solve2_floats``)."""
        return _solve2_floats(W[0], W[1], W[1], W[2], b0, b1)

    _MQ = tuple(f"Minv_gQ_{i}" for i in range(3))
    _MR = tuple(f"Minv_gR_{i}" for i in range(3))

    def _apply(self, x: np.ndarray, y: dict, P) -> np.ndarray:
        v = x.tolist()
        p0, p1 = float(P[0]), float(P[1])
        for i, (kq, kr) in enumerate(zip(self._MQ, self._MR)):
            v[3 + i] -= p0 * y[kq] + p1 * y[kr]
        return np.array(v)

    def _sliding_impulse(self, t, x, W, vn: float, vt: float, e: float, s0: float) -> tuple[float, float]:
        """The impulse on the cone's edge, ``P_t = mu s P_n``, whose slip after the impact
        ``v_t+`` has the sign ``s`` (friction opposes the slip it leaves; Moreau's law), tried
        along the stick impulse's sign ``s0`` first."""
        mu = self.mu
        w_nn, w_nt, w_tt = W
        for s in (s0, -s0):
            denominator = w_nn + mu * s * w_nt
            if not denominator > 0:
                continue
            Pn = (1 + e) * vn / denominator
            vt_after = vt - Pn * (w_nt + mu * s * w_tt)
            if Pn >= 0 and vt_after * s >= 0:
                return Pn, mu * s * Pn
        raise PainleveError(t, x, f"an impact with mu = {mu:g} has no consistent impulse: no impulse "
                            "on the cone's edge leaves a slip it opposes with a positive normal "
                            "row's coefficient (Painleve's paradox at an impact); the rigid model "
                            "has no answer here", self.model.state_names)

    def stop_slip(self, x: np.ndarray, y: dict, modes, j: int = 1) -> tuple[np.ndarray, float]:
        """The contact's normal and slip speeds set to 0 (the impulse that does it)."""
        vn, vt = float(y["vn_fixed"]), float(y["vt"])
        return self._apply(x, y, self._solve(self._W(y), vn, vt)), max(abs(vn), abs(vt))

    def impact(self, t: float, x: np.ndarray, y: dict, modes, j: int = 1,
               slips=None) -> tuple[np.ndarray, float, bool, bool]:
        """Newton's restitution and Coulomb friction on the impulse (``_BodyRun.impact``, in
        the contact's frame); the kinetic energy must not grow (a named error otherwise)."""
        mu, W = self.mu, self._W(y)
        vn, vt = float(y["vn_fixed"]), float(y["vt"])
        e = self.e if vn > REST_SPEED else 0.0
        P = self._solve(W, (1 + e) * vn, vt)
        stuck = bool(abs(P[1]) <= mu * P[0])
        if not stuck:  # on the cone's edge, against the slip after the impact (Moreau)
            P = self._sliding_impulse(t, x, W, vn, vt, e, math.copysign(1.0, P[1]))
        after = self._apply(x, y, P)
        before_k = float(y["kinetic_energy"])
        after_k = float(self.outputs(after, self.params([ROLLING]))["kinetic_energy"])
        if after_k > before_k * (1 + 1e-9) + 1e-15:
            raise ContactModeError(t, x, f"the impact with mu = {mu:g}, e = {e:g} would raise the kinetic "
                                   f"energy from {before_k:.9g} J to {after_k:.9g} J (Newton's "
                                   "restitution with friction can when e > 0); the rigid model has no "
                                   "answer here: give e = 0", self.model.state_names)
        w_nn, w_nt, w_tt = W
        return after, max(abs(w_nn * P[0] + w_nt * P[1]), abs(w_nt * P[0] + w_tt * P[1])), stuck, e > 0


class _GraspRun(_Run):
    """A 3D grasp (``model.grasp3d_modes``): each contact's rows ``(n, x_f, y_f)`` of
    ``A = dC/dV`` in its fingertip's contact frame, ``J V = (vn_fixed, vt_x, vt_y)`` per contact,
    ``W = A M^-1 A^T`` and ``M^-1 A^T`` (``docs/conventions.md`` section 9). An impulse ``P``
    (three per contact) changes the speeds by ``-M^-1 A^T P``."""

    SLIP = "slip_x"
    #: rows per contact: the normal and the tangents
    ROWS = 3
    #: the manifest's entry of this kind: the fingers, where the speeds start and how many
    INFO = "grasp_modes"

    def __init__(self, model, s, mus, e: float):
        super().__init__(model, s, mus, e)
        info = model.manifest[self.INFO]
        self.v0, self.nv = int(info["speeds"][0]), int(info["speeds"][1])
        n = self.ROWS * self.k
        self._w_rows, self._w_cols = np.triu_indices(n)
        self._w_keys = [f"W_{r}_{c}" for r, c in zip(self._w_rows, self._w_cols)]
        self._jv_keys = [f"{k}{j}" for j in self.contacts for k in self.JV_KEYS]
        self._contact_rows = [list(range(self.ROWS * (j - 1), self.ROWS * j)) for j in self.contacts]
        #: the outputs ``M^-1 A^T`` of every row, by speed
        self._b_keys = [[f"MinvAT_{i}_{r}" for r in range(n)] for i in range(self.nv)]
        self._w_of = self._jv_of = None  # the outputs W and J V were last read from

    #: ``J V``'s outputs, per contact (its rows: normal, tangential)
    JV_KEYS = ("vn_fixed", "vt_x", "vt_y")

    def key(self, name: str, j: int) -> str:
        """Contact ``j``'s output or parameter ``name``: a grasp numbers them with one contact
        too (``mode1``, ``gap1``: a grasp of one finger, pivot3d's)."""
        return f"{name}{j}"

    #: m: the fingers' contact constraints' residual above which an ``x0`` of a grasp on
    #: atlases is refused (``runtime.checks``' bound for a plain run's start)
    RESIDUAL_TOL = 1e-8

    def check_start(self, x0: np.ndarray, y: dict) -> None:
        """On surfaces with atlases, ``x0`` read in the run's charts must be on the fingers'
        contact constraints (a row read in other charts is off them: its points are others)."""
        charts = parameters.charts_of(self.model)
        residual = y.get("constraint_residual")
        if charts and residual is not None and not abs(residual) <= self.RESIDUAL_TOL:
            read = {k: int(self.p[self.model.p_names.index(k)]) for k in charts}
            raise RunArgumentError(
                f"x0 is off the fingers' contact constraints (constraint_residual = {residual:.6g} m), read "
                f"in the charts {read}: a row of a run is written in that row's charts: give them, "
                "params={name: result.charts[name][i]}, or start from model.initial_state()")

    def slip_velocity(self, y: dict, j: int) -> np.ndarray:
        return np.array([y[f"vt_x{j}"], y[f"vt_y{j}"]])

    def slip_keys(self, j: int) -> tuple[str, ...]:
        return (f"vt_x{j}", f"vt_y{j}")

    def slip_terms(self, d: np.ndarray, j: int) -> list[tuple]:
        """``v_t . slip - cos(REAIM_ANGLE) |v_t|``: 0 where the slip stops, or where a slide has
        turned by ``REAIM_ANGLE`` from ``slip`` (then re-aimed, ``_switch``). The sliding
        equations' direction blends toward ``slip`` where ``v_t . slip`` falls below
        ``SLIP_FULL`` (``derive.grasp3d_modes``); re-aimed at 90 degrees, a fast slide met that
        blend just before its event, and its speeds took a kick of ~1e-7 m/s whatever the
        tolerance (found by a slide across an atlas's charts, against one chart)."""
        c = math.cos(REAIM_ANGLE)
        return [(f"vt_x{j}", d[0]), (f"vt_y{j}", d[1]), (f"vt_x{j}", c, True), (f"vt_y{j}", c, True)]

    def slip_direction(self, x: np.ndarray, y: dict, j: int, modes=None, slips=None) -> np.ndarray:
        """The direction a slide starts in from rest of the slip: the fixed point of
        ``d -> a_t(d)/|a_t(d)|`` (the slip's acceleration in the sliding equations) from the
        rolling solution's tangential force (at the cone's edge Coulomb's force equals it)."""
        ft = np.array([y[f"lam{j}"], y[f"eta{j}"]])
        d = ft / _norm(ft) if _norm(ft) > 0 else np.array([1.0, 0.0])
        if modes is None:
            return d

        def slip_acceleration(d):
            ys = self.with_mode(x, modes, slips, j, SLIDING, d)
            return np.array([ys[f"at_x{j}"], ys[f"at_y{j}"]]), 1e-9

        return _direction(d, slip_acceleration)

    def free_normal_acceleration(self, x, modes, slips, j: int, y: dict) -> float:
        return float(self.with_mode(x, modes, slips, j, SEPARATED)[f"normal_acceleration{j}"])

    def apart(self, x: np.ndarray) -> np.ndarray:
        """A start with a plane of the world apart is the scene's own (its support points solved
        at the build); a finger apart is refused: the grasp starts closed."""
        y = self.outputs(x, self.params([ROLLING] * self.k))
        n_fingers = int(self.model.manifest[self.INFO]["fingers"])
        open_ = [j for j in range(1, n_fingers + 1) if y[f"gap{j}"] > CONTACT_GAP]
        if open_:
            raise RunArgumentError(f"x0 has finger contact(s) {open_} apart: a grasp with modes starts "
                                   "with every finger closed (its solved start); open contacts come "
                                   "from the run")
        return np.asarray(x, dtype=float)

    def _rows(self, j: int) -> list[int]:
        return self._contact_rows[j - 1]

    def _W(self, y: dict) -> np.ndarray:
        """``W = A M^-1 A^T`` of the outputs ``y`` (the last ``y``'s kept: an impact's Moreau
        iteration reads it at every step)."""
        if self._w_of is not y:
            n = self.ROWS * self.k
            upper = np.array([y[k] for k in self._w_keys])
            W = np.empty((n, n))
            W[self._w_rows, self._w_cols] = upper
            W[self._w_cols, self._w_rows] = upper
            self._w_of, self._w = y, W
        return self._w

    def _JV(self, y: dict) -> np.ndarray:
        if self._jv_of is not y:
            self._jv_of, self._jv = y, np.array([y[k] for k in self._jv_keys])
        return self._jv

    def _apply(self, x: np.ndarray, y: dict, P: np.ndarray) -> np.ndarray:
        """``x`` after the impulses ``P`` (every contact's rows)."""
        x = x.copy()
        B = np.array([[y[k] for k in keys] for keys in self._b_keys])
        x[self.v0:self.v0 + self.nv] -= B @ P
        return x

    def _impulse(self, y, modes, j: int, target_j: np.ndarray, slide_j=None, treat=None):
        """The impulses of an impact (or a stop) at contact ``j``: ``j``'s rows reach
        ``target_j`` (normal, and tangential unless ``slide_j``, a direction on its cone's
        edge); every other closed contact as ``treat[c]`` says, by default as its mode: held
        (``HOLD``: its velocity stays 0), sliding along ``d`` (``(SLIDE, d)``: its normal speed
        stays 0, its tangential impulse on its cone's edge along ``d``, the slip's direction) or
        let go (``OPEN``: no impulse). Returns ``(P over every row, W, J V)``."""
        n3 = self.ROWS * self.k
        W, JV = self._W(y), self._JV(y)
        treat = self._treatment(y, modes, j) if treat is None else treat
        # B's columns: a held contact's unit rows, a sliding one's normal plus mu d on its
        # tangents (its entries gathered, then written at once: NumPy's calls per column were
        # most of an impulse's cost)
        at, values, eqs, rhs = ([], []), [], [], []
        for c in self.contacts:
            rows = self._rows(c)
            how = (SLIDE, slide_j) if c == j and slide_j is not None else HOLD if c == j else treat[c]
            if how == OPEN:
                continue
            target = target_j if c == j else (0.0,) * self.ROWS
            if how != HOLD:
                col = len(eqs)
                at[0].extend(rows)
                at[1].extend([col] * len(rows))
                values.append(1.0)
                values.extend(self.mus[c - 1] * float(dk) for dk in how[1])
                eqs.append(rows[0])
                rhs.append(JV[rows[0]] - target[0])
            else:
                for k_, r_ in enumerate(rows):
                    at[0].append(r_)
                    at[1].append(len(eqs))
                    values.append(1.0)
                    eqs.append(r_)
                    rhs.append(JV[r_] - target[k_])
        B = np.zeros((n3, len(eqs)))
        B[at] = values
        u = np.linalg.solve(W[eqs, :] @ B, np.array(rhs))
        return B @ u, W, JV

    def _treatment(self, y, modes, j: int) -> dict:
        """How every other contact takes an impulse at ``j``, by its mode: a rolling one is
        held, a sliding one slides on along its slip, a separated one is let go."""
        out = {}
        for c in self.contacts:
            if c == j:
                continue
            if modes[c - 1] == ROLLING:
                out[c] = HOLD
            elif modes[c - 1] == SLIDING:
                vt = self.slip_velocity(y, c)
                out[c] = (SLIDE, vt / max(_norm(vt), 1e-300))
            else:
                out[c] = OPEN
        return out

    def _impulse_problem(self, modes, j, P, W, JV, treat, what: str) -> str | None:
        """What makes the impulse ``P`` (``_impulse`` with ``treat``) inconsistent at another
        contact than ``j``, None where it is consistent (a complementarity problem's solution):
        a held contact pushes (``P_n >= 0``) within its cone; a sliding one pushes and its slip
        does not reverse (Moreau: the friction impulse opposes the slip it leaves); a contact let
        go does not approach after it (``J V - W P`` along its normal <= 0)."""
        after = JV - W @ P
        scale = max(1.0, float(np.max(np.abs(P))))
        for c in self.contacts:
            if c == j or modes[c - 1] == SEPARATED:
                continue
            rows = self._rows(c)
            pn, pt, how = P[rows[0]], P[rows[1:]], treat[c]
            if how == OPEN:
                if after[rows[0]] > 1e-12 * max(1.0, float(np.max(np.abs(JV)))):
                    return f"{what} at contact {j} would leave contact {c} approaching"
                continue
            if not pn >= -1e-12 * scale:
                return (f"{what} at contact {j} would pull at contact {c} (normal impulse {pn:.6g} N s): "
                        f"contact {c} would open through an impulse")
            if how == HOLD and not _norm(pt) <= self.mus[c - 1] * pn + 1e-12:
                return (f"{what} at contact {j} pushes contact {c} out of its cone (impulse {pn:.6g} N s "
                        f"normal, {_norm(pt):.6g} N s tangential): a slip started by an impulse "
                        "at another contact")
            if how != HOLD and np.dot(after[rows[1:]], how[1]) < -1e-12 * max(1.0, float(np.max(np.abs(JV)))):
                return f"{what} at contact {j} would reverse contact {c}'s slip"
        return None

    def _treatments(self, y, modes, j: int, held):
        """Every way the other closed contacts may take an impulse at ``j``, their modes' first,
        then those that change one contact, then two, ...: held, let go, or sliding along the
        tangential impulse that holding it needs or its opposite (``held()``: the impulse with
        every one held, solved only when the modes' way is not consistent)."""
        base = self._treatment(y, modes, j)
        yield base
        closed = [c for c in self.contacts if c != j and modes[c - 1] != SEPARATED]
        P = held()
        options = {}
        for c in closed:
            pt = P[self._rows(c)[1:]]
            d = pt / _norm(pt) if _norm(pt) > 0 else np.eye(self.ROWS - 1)[0]
            opts = [HOLD, OPEN, (SLIDE, d), (SLIDE, -d)]
            if base[c] != HOLD:
                opts = [base[c], *opts]
            options[c] = opts
        combos = [dict(zip(closed, pick)) for pick in itertools.product(*(options[c] for c in closed))]
        changed = lambda t: sum(not _same(t[c], base[c]) for c in closed)  # noqa: E731
        for combo in sorted(combos, key=changed):
            if changed(combo):        # the modes' own way was the first
                yield {**base, **combo}

    def _contact_impulse(self, t, x, y, modes, j, target, treat):
        """The impulse at ``j`` with the others as ``treat`` says: held if it lies in ``j``'s
        cone, else on its edge along the direction whose slip after the impact it opposes
        (Moreau). ``(P, W, J V, stuck)``; a named error where no direction does."""
        mu = self.mus[j - 1]
        rows = self._rows(j)
        P, W, JV = self._impulse(y, modes, j, target, treat=treat)
        stuck = bool(_norm(P[rows[1:]]) <= mu * P[rows[0]])
        if stuck:
            return P, W, JV, True
        vt = JV[rows[1:]]
        pt = P[rows[1:]]
        d = vt / _norm(vt) if _norm(vt) > SLIP_SPEED else pt / _norm(pt)

        def slip_left(d):  # Moreau: the impulse opposes the slip it leaves
            P, W, JV = self._impulse(y, modes, j, target, slide_j=d, treat=treat)
            return (JV - W @ P)[rows[1:]], SLIP_SPEED

        d = _direction(d, slip_left, MOREAU_ITERATIONS)
        P, W, JV = self._impulse(y, modes, j, target, slide_j=d, treat=treat)
        after_vt = (JV - W @ P)[rows[1:]]
        if not (P[rows[0]] > 0 and np.dot(after_vt, d) >= -1e-12 * max(1.0, _norm(vt))):
            raise PainleveError(t, x, f"the impact at contact {j} with mu = {mu:g} has no impulse on "
                                "the cone's edge that opposes the slip it leaves (Moreau's law) with "
                                "a pushing normal impulse; the rigid model has no answer here",
                                self.model.state_names)
        return P, W, JV, False

    def stop_slip(self, x: np.ndarray, y: dict, modes, j: int) -> tuple[np.ndarray, float]:
        """Contact ``j``'s velocity set to 0, the other closed contacts as at an impact."""
        P, W, JV = self._impulse(y, modes, j, np.zeros(self.ROWS))
        return self._apply(x, y, P), float(np.max(np.abs(JV[self._rows(j)])))

    def impact(self, t: float, x: np.ndarray, y: dict, modes, j: int,
               slips=None) -> tuple[np.ndarray, float, bool, bool]:
        """Newton's restitution and Coulomb friction on the impulse at contact ``j``: stick if
        its impulse lies in its cone, else on the cone's edge along the incoming slip; the
        other closed contacts as their modes say if that is consistent
        (``_impulse_problem``), else the first consistent way among the others
        (``_treatments``: a contact may be let go, start or stop sliding through the impulse),
        written into ``modes`` and ``slips`` (lists, changed in place); the kinetic energy must
        not grow. Where no way is consistent, a named error."""
        JV = self._JV(y)
        vn = float(JV[self._rows(j)[0]])
        e = self.e if vn > REST_SPEED else 0.0
        target = np.array([-e * vn] + [0.0] * (self.ROWS - 1))
        def held():
            return self._impulse(y, modes, j, target, treat={c: HOLD for c in self.contacts if c != j})[0]

        first = None
        for treat in self._treatments(y, modes, j, held):
            try:
                P, W, JV, stuck = self._contact_impulse(t, x, y, modes, j, target, treat)
            except PainleveError as exc:   # no consistent impulse at j this way: try the next
                first = first or exc
                continue
            problem = self._impulse_problem(modes, j, P, W, JV, treat, "the impact")
            if problem is None:
                break
            first = first or problem
        else:
            if isinstance(first, PainleveError):
                raise first
            raise ContactModeError(t, x, f"{first}, and no other way of the other contacts (held, let go, "
                                   "sliding) is consistent; the rigid model has no answer here",
                                   self.model.state_names)
        after = self._apply(x, y, P)
        before_k = float(y["kinetic_energy"])
        after_v = JV - W @ P
        for c, how in treat.items():
            if c == j or modes[c - 1] == SEPARATED:
                continue
            if how == OPEN:
                modes[c - 1] = SEPARATED
                if slips is not None:
                    slips[c - 1] = None
            elif how == HOLD:
                modes[c - 1] = ROLLING
                if slips is not None:
                    slips[c - 1] = None
            else:
                vt = after_v[self._rows(c)[1:]]
                modes[c - 1] = SLIDING
                if slips is not None:
                    slips[c - 1] = vt / _norm(vt) if _norm(vt) > SLIP_SPEED else np.asarray(how[1])
        after_k = float(self.outputs(after, self.params(modes, slips))["kinetic_energy"])
        driven = set(self.model.manifest[self.INFO].get("driven", []))
        pushed = j in driven or any(c in driven and modes[c - 1] != SEPARATED for c in self.contacts)
        # a driven plane in the impact gives energy (it is driven): the test is for the others
        if not pushed and after_k > before_k * (1 + 1e-9) + 1e-15:
            raise ContactModeError(t, x, f"the impact at contact {j} would raise the kinetic energy from "
                                   f"{before_k:.9g} J to {after_k:.9g} J; the rigid model has no answer "
                                   "here: give e = 0", self.model.state_names)
        return after, float(np.max(np.abs(W @ P))), stuck, e > 0


def _same(a, b) -> bool:
    """Two ways of taking an impulse (``_GraspRun._treatment``) are one."""
    if isinstance(a, str) or isinstance(b, str):
        return a == b
    return bool(np.allclose(a[1], b[1]))


class _FingersRun(_GraspRun):
    """A 2D scene of several fingers (``model.planar_modes``, ``planar_fingers``): each
    contact's rows ``(gQ_i, gR_i)`` (``J V = (vn_fixed{i}, vt{i})``), ``W = A M^-1 A^T`` and
    ``M^-1 A^T`` as the 3D grasp's (``docs/conventions.md`` section 8); a slide's direction is
    a sign."""

    SLIP = "slip"
    ROWS = 2
    INFO = "planar_fingers"

    def slip_velocity(self, y: dict, j: int) -> np.ndarray:
        return np.array([y[f"vt{j}"]])

    def slip_keys(self, j: int) -> tuple[str, ...]:
        return ()

    def slip_terms(self, d: np.ndarray, j: int) -> list[tuple[str, float]]:
        return [(f"vt{j}", d[0])]

    def slip_direction(self, x: np.ndarray, y: dict, j: int, modes=None, slips=None) -> np.ndarray:
        """A slide from rest of the slip starts along the rolling solution's tangential force
        (``y``: the outputs with contact ``j`` rolling), as one finger's (``_PlanarRun``)."""
        return np.array([1.0 if y[f"lam{j}"] >= 0 else -1.0])

    #: ``J V``'s outputs, per contact
    JV_KEYS = ("vn_fixed", "vt")

    def apart(self, x: np.ndarray) -> np.ndarray:
        """``x`` with each open contact's parameters ``(u0_j, u1_j)`` on the contours' common
        normal (``_PlanarRun.apart``): a finger may start apart."""
        x = np.array(x, dtype=float)
        y = self.outputs(x, self.params([ROLLING] * self.k))
        fingers = int(self.model.manifest[self.INFO]["fingers"])
        for j in range(1, fingers + 1):    # a line's support point is the model's to keep
            if y[f"gap{j}"] > CONTACT_GAP:
                x = _on_common_normal(self, x, j, 2 * self.nv + 2 * (j - 1))
        return x


def _on_common_normal(r: _Run, x: np.ndarray, j: int, at: int) -> np.ndarray:
    """``x`` with contact ``j``'s parameters ``x[at:at + 2] = (u0, u1)`` on the contours' common
    normal (``R = 0``, ``delta = 0``: Newton's method), every contact separated; a named error
    where none is found near them."""
    x = np.array(x, dtype=float)
    p = r.params([SEPARATED] * r.k)
    rk, dk = r.key("R", j), r.key("tangency_defect", j)

    def G(u):
        z = x.copy()
        z[at:at + 2] = u
        y = r.outputs(z, p)
        return np.array([y[rk], y[dk]])

    u = x[at:at + 2].copy()
    for _ in range(50):
        g = G(u)
        if np.max(np.abs(g)) < 1e-14:
            break
        h = 1e-7 * np.maximum(1.0, np.abs(u))
        J = np.column_stack([(G(u + h[k] * np.eye(2)[k]) - g) / h[k] for k in range(2)])
        u = u - np.linalg.solve(J, g)
    if not np.max(np.abs(G(u))) < 1e-12:
        names = r.model.state_names[at:at + 2]
        raise RunArgumentError(f"x0 is apart at contact {j}, but no pair of points on a common normal "
                               f"was found near {names[0]}, {names[1]} = {tuple(x[at:at + 2])} (R, delta = "
                               f"{tuple(G(u))}): give them near the closest points of the contours")
    x[at:at + 2] = u
    return x


#: the kind of a model with modes (its manifest's ``kind``) -> how its contacts are run
_RUNS = {"body": _BodyRun, "body2d": _LineBodyRun, "planar_modes": _PlanarRun, "grasp3d_modes": _GraspRun,
         "planar_fingers": _FingersRun}


def _norm(v) -> float:
    """``|v|`` of a short vector (a slip, a force, an impulse: 1 to 3 entries) on Python
    floats: NumPy's norm costs a switch 10-30 us a call from the caches a run leaves cold."""
    return math.hypot(*v)


def _solve2(K: np.ndarray, b: np.ndarray) -> np.ndarray:
    """``K^-1 b`` for a 2 x 2 ``K`` by Cramer's rule on Python floats (NumPy's checks from cold
    caches were most of a switch); a singular ``K`` is refused as ``np.linalg.solve`` refuses it
    (not inf or NaN as ``_solve3`` gives)."""
    return np.array(_solve2_floats(*np.ravel(K).tolist(), *np.ravel(b).tolist()))


def _solve2_floats(a: float, b: float, c: float, d: float, u: float, v: float) -> tuple[float, float]:
    """``[[a, b], [c, d]]^-1 (u, v)`` (``_solve2``) on Python floats."""
    det = a * d - b * c
    if not det != 0.0 or not math.isfinite(det):
        return tuple(np.linalg.solve(np.array([[a, b], [c, d]]), np.array([u, v])))
    return (d * u - b * v) / det, (a * v - c * u) / det


def _solve3(K: np.ndarray, b: np.ndarray) -> np.ndarray:
    """``K^-1 b`` for a 3 x 3 ``K`` by Cramer's rule on Python floats (``np.linalg.solve``
    spends ~10 us on its checks, a switch's largest part); a singular ``K`` gives inf or NaN."""
    return np.array(_solve3_floats(K.tolist(), b.tolist()))


def _solve3_floats(K, b) -> list[float]:
    """``_solve3`` of nested lists, as a list."""
    (a, b_, c), (d, e, f), (g, h, i) = K
    u, v, w = b
    det = a * (e * i - f * h) - b_ * (d * i - f * g) + c * (d * h - e * g)
    if det == 0.0:
        return [math.nan] * 3
    return [(u * (e * i - f * h) - b_ * (v * i - f * w) + c * (v * h - e * w)) / det,
            (a * (v * i - f * w) - u * (d * i - f * g) + c * (d * w - v * g)) / det,
            (a * (e * w - v * h) - b_ * (d * w - v * g) + u * (d * h - e * g)) / det]


def _direction(d: np.ndarray, along, iterations: int = 50, normal: np.ndarray | None = None) -> np.ndarray:
    """The fixed point of ``d -> v(d)/|v(d)|`` from ``d`` (``along(d) -> (v, small)``): where
    ``|v| <= small`` (nothing to follow: on the cone's edge) the direction is kept. A
    direction in a plane (two entries, or three in the plane of the unit ``normal``) is found
    by secant steps on its angle (``_angle``).

    Three entries with no ``normal`` are followed by the plain iteration, which can circle
    where ``v``'s direction turns faster than ``d`` (a 3D body's slip on a plane did: its
    callers give the plane's normal).

    ``d`` itself is the answer where ``|v(d)|`` is at most ``EDGE`` times ``|v(-d)|``: a slide
    that starts where the rolling force crosses the cone's edge (located to the witness's
    accuracy, not exactly) starts along ``d``, its slip's acceleration there ~0 whichever way
    the rest of ``v`` points (followed, it sent a grasp's slide 90 degrees off at rtol 1e-6,
    where ``|v(d)|`` was 8e-8 m/s^2 of ~10, and the run chattered)."""
    v, small = along(d)
    try:  # the scale of the map's image; none where it cannot be had there (a singular solve)
        scale = _norm(along(-d)[0])
    except np.linalg.LinAlgError:
        scale = 0.0
    if not _norm(v) > max(small, EDGE * scale):
        return d
    if normal is not None:
        e1 = np.asarray(d, dtype=float) - np.dot(d, normal) * normal
        if not _norm(e1) > 0:
            e1 = np.cross(normal, [1.0, 0.0, 0.0] if abs(normal[0]) < 0.9 else [0.0, 1.0, 0.0])
        e1 = e1 / _norm(e1)
        e2 = np.cross(normal, e1)

        def in_plane(c):
            v, small = along(c[0] * e1 + c[1] * e2)
            return np.array([np.dot(v, e1), np.dot(v, e2)]), small

        c = _angle(np.array([1.0, 0.0]), in_plane, iterations)
        return c[0] * e1 + c[1] * e2
    if len(d) == 2:
        return _angle(d, along, iterations)
    for _ in range(iterations):
        v, small = along(d)
        if not _norm(v) > small:
            break
        nd = v / _norm(v)
        if _norm(nd - d) < 1e-14:
            break
        d = nd
    return d


#: ``_direction`` keeps its first direction ``d`` where the map's image there is at most this
#: share of its image at ``-d``: the fixed point is then within about this angle (rad) of ``d``.
EDGE = 1e-6
#: Angles sampled round the circle (``_scan``) where ``_angle``'s secant steps do not converge.
SCAN_ANGLES = 64
#: rad: how far a direction ``_angle`` returns may be from its image (``g``): its secant
#: steps end at 1e-14 rad, or stall where ``g`` jumps by 2 pi (its wrap), which this tells apart.
ANGLE_TOL = 1e-10


def _angle(d: np.ndarray, along, iterations: int) -> np.ndarray:
    """``_direction`` of a direction in a plane: the root of ``g(a) = angle(v(d(a))) - a``
    (wrapped to ``(-pi, pi]``) by secant steps from the fixed point's first step, each taken
    only where it shrinks ``|g|`` (else the fixed point's step): the same fixed point in
    fewer evaluations of ``along`` (an impulse solved each, at an impact). Where they end
    farther than ``ANGLE_TOL`` from a root (not converged in ``iterations``, or stalled at
    ``g``'s jump), the root of ``g`` nearest ``d``'s angle among those bracketed round the
    circle (``_scan``); none there: the last direction evaluated (its callers test what it
    gives, and refuse it by name)."""
    def g(a: float):
        v, small = along(np.array([math.cos(a), math.sin(a)]))
        if not _norm(v) > small:
            return None
        return (math.atan2(v[1], v[0]) - a + math.pi) % (2 * math.pi) - math.pi

    start = a0 = math.atan2(d[1], d[0])
    g0 = g(a0)
    if g0 is None:
        return d
    a1 = a0 + g0
    for _ in range(iterations):
        if abs(a1 - a0) < 1e-14:  # converged, or stalled where g jumps by 2 pi: tested below
            break
        g1 = g(a1)
        if g1 is None:  # on the cone's edge: nothing to follow, the direction kept
            return np.array([math.cos(a1), math.sin(a1)])
        step = -g1 * (a1 - a0) / (g1 - g0) if g1 != g0 else g1
        if abs(g1) >= abs(g0):  # not shrinking: the fixed point's step
            step = g1
        a0, g0, a1 = a1, g1, a1 + step
    last = g(a1)
    if last is None or abs(last) <= ANGLE_TOL:
        return np.array([math.cos(a1), math.sin(a1)])
    found = _scan(along, start)  # not converged: a bracketed root, else the last direction evaluated
    a1 = a0 if found is None else found
    return np.array([math.cos(a1), math.sin(a1)])


def _scan(along, start: float) -> float | None:
    """The angle ``a`` nearest ``start`` whose direction ``d(a)`` the map ``along`` sends along
    itself (``v x d = 0`` and ``v . d >= 0``, or ``|v|`` within its ``small``): ``v x d``
    sampled at ``SCAN_ANGLES`` angles round the circle from ``start``, each change of its sign
    bisected to 1e-14 rad; None where there is none. ``v x d`` is continuous where ``v``'s
    angle is not (it turns by pi across a point where ``v`` is 0, as it does near the cone's
    edge), so no root is lost to ``_angle``'s wrapped difference."""
    def h(a: float):
        """``(v x d, v . d, small)`` at the angle ``a``; None where ``along`` has no answer
        there (a singular solve) or a non-finite one."""
        c, s = math.cos(a), math.sin(a)
        try:
            v, small = along(np.array([c, s]))
        except np.linalg.LinAlgError:
            return None
        out = (float(v[0] * s - v[1] * c), float(v[0] * c + v[1] * s), small)
        return out if math.isfinite(out[0]) and math.isfinite(out[1]) else None

    grid = [start + math.pi * (2.0 * k / SCAN_ANGLES - 1.0) for k in range(SCAN_ANGLES + 1)]
    values = [h(a) for a in grid]
    roots = []
    for (a, ha), (b, hb) in zip(zip(grid, values), zip(grid[1:], values[1:])):
        if ha is None or hb is None or not ha[0] * hb[0] <= 0:
            continue
        ha = ha[0]
        while b - a > 1e-14:
            m = 0.5 * (a + b)
            hm = h(m)
            if hm is None:
                break
            if hm[0] == 0:
                a = b = m
            elif (hm[0] > 0) == (ha > 0):
                a, ha = m, hm[0]
            else:
                b = m
        root = 0.5 * (a + b)
        at = h(root) if b - a <= 1e-12 else None  # (a bisection cut short by a failed solve: none)
        if at is not None and (at[1] >= 0 or math.hypot(at[0], at[1]) <= at[2]):  # along d, not against it
            roots.append(root)
    return min(roots, key=lambda r: abs(r - start)) if roots else None


def refuse_unused(*, params, u, slip, inputs: bool = False, charts=(), checks: bool = True) -> None:
    """Refuse by name what a run with modes does not read (it would be ignored silently);
    ``inputs``: ``u`` is read (a model with inputs); ``charts``: the model's chart parameters,
    which ``params`` may name (the charts ``x0`` is written in); ``checks``: False is refused
    (a model with modes switches where a check would stop another run: they are its witnesses)."""
    if not checks:
        raise RunArgumentError("checks=False given, but a model with contact modes switches mode where "
                               "a check would stop a run (a contact whose force reaches 0 separates, "
                               "one that leaves its cone slides): its checks are its witnesses and "
                               "cannot be turned off; leave checks unset")
    other = None if params is None else sorted(set(params) - set(charts))
    given = [k for k, v in ((f"params {other}", other or None), ("u", None if inputs else u)) if v is not None]
    if slip != "stop":
        given.append("slip")
    if given:
        raise RunArgumentError(f"{', '.join(given)} given, but a model with contact modes takes none: "
                               "its mode and slip direction are its own, its friction is mu= and e= "
                               "(or the scene's law), and it has no inputs"
                               + (f"; params may name its charts {tuple(charts)} (0 or 1)" if charts else ""))


def rotation(q: np.ndarray) -> np.ndarray:
    """The rotation of a (not necessarily unit) quaternion ``(w, x, y, z)``, in the homogeneous
    form the compiled model uses (``derive.bodies3d.object_rotation``)."""
    w, x, y, z = (float(c) for c in q)
    s = w * w + x * x + y * y + z * z
    return np.array([[w * w + x * x - y * y - z * z, 2 * (x * y - w * z), 2 * (x * z + w * y)],
                     [2 * (x * y + w * z), w * w - x * x + y * y - z * z, 2 * (y * z - w * x)],
                     [2 * (x * z - w * y), 2 * (y * z + w * x), w * w - x * x - y * y + z * z]]) / s


def run(model, s, x0: np.ndarray, mu_arg=None, e_arg=None, u=None, short=None,
        charts: dict | None = None) -> SimulationResult:
    """``Model.simulate`` of a model with modes (module docstring); ``u``: the inputs of a
    model with inputs (``runtime.inputs``: numbers, or a table; each mode's segment restarts
    at the table's knots); ``short``: ``(plan key, start key)`` under which a run that ends
    well keeps its settings and its start for the short way (``short_way``), or None;
    ``charts``: the charts ``x0`` is written in (name -> 0 or 1; None: the start's)."""
    start = perf_counter()
    if s.method not in METHODS:
        raise RunArgumentError(f"method {s.method!r}: a model with contact modes runs one of {METHODS} "
                               "(the loops in C, with which its switches are located by integrating "
                               "again)")
    mus, e = friction_law(model, mu_arg, e_arg)
    r = _new_run(model, s, mus, e)
    try:
        return _run(r, x0, u, short, charts, start)
    except IntegratorError as err:  # on atlases: its state's charts named (a segment's own, if
        if r.atlases is not None:   # its loop changed one: _segment), else the run's
            name_charts(err, r.atlases.charts(r.p))
        raise


def _run(r: _Run, x0: np.ndarray, u, short, charts: dict | None, start: float) -> SimulationResult:
    """``run`` once its run ``r`` is made."""
    model, s = r.model, r.s
    for k, c in (charts or {}).items():
        r.p[model.p_names.index(k)] = parameters.chart_value(k, c)
    t_eval = s.t_eval
    r.sched = run_.schedule(model, u, s.method, t_eval)
    x_now, modes, slips, y_now = _start(r, np.asarray(x0, dtype=float))
    rolls = (x_now, list(modes), list(slips)) if y_now is not None and not r.events else None
    rows_t, rows_x, rows_mode, rows_p = [], [], [], []
    t_now = 0.0
    last_t = -math.inf
    recent: list[float] = []
    h_next = 0.0
    while True:
        p = r.params(modes, slips)
        r.t = t_now
        y_now = r.outputs(x_now, p) if y_now is None else y_now  # _start's, at the start
        for j in r.contacts:
            if modes[j - 1] == SLIDING and not y_now[r.key("painleve", j)] > 0:
                _painleve(model, t_now, x_now, y_now[r.key("painleve", j)], r.mus[j - 1], j)
        grid = np.concatenate([[t_now], t_eval[int(np.searchsorted(t_eval, t_now, side="right")):]])
        if grid[-1] - t_now <= _END_AT_SWITCH * max(1.0, abs(t_now)):
            # the run ends at a switch, or within the event's location tolerance after it (no
            # step can be that short): its last output times, the state after the switch
            ends = [tm for tm in grid if tm > last_t and (tm > t_now or tm in t_eval)]
            if ends:
                rows_t.append(np.array(ends, dtype=float))
                rows_x.append(np.tile(np.asarray(x_now, dtype=float), (len(ends), 1)))
                rows_mode.append(_mode_rows(modes, len(ends)))
                rows_p.append(p)
            break
        at_start = _at_start(r, modes, slips, y_now)
        if at_start is not None and not r.events:
            rolls = None  # a witness past its event at the start: the short way cannot take it
        y_at, y_now = y_now, None
        if at_start is not None:  # a witness already past its event: it switches now
            name, j, terms = at_start
            h_next = 0.0  # a mode switch: the next segment chooses its first step
            t_ev, x_ev, value_ = t_now, x_now, value(terms, y_at)
            if name != "onset":  # (an onset's end is no switch)
                recent = _chatter(model, recent, t_ev, x_ev)
            before = list(modes)
            modes, slips, x_now, reset = _switch(r, modes, slips, name, j, t_ev, x_ev)
            if reset is not None:  # None: a slide re-aimed, or its onset ended: no switch
                _record(r, t_ev, j, name, value_, reset, before, modes)
            continue
        # max_steps and time_limit bound the whole run, whatever its segments
        r.s = dataclasses.replace(s, max_steps=max(s.max_steps - r.stats["n_steps"], 1),
                                  time_limit=None if s.time_limit is None else
                                  max(s.time_limit - (perf_counter() - start), 1e-9))
        leg = r.leg(modes, x_now)
        own = leg is r.own_leg
        watched = r.witnesses(modes, slips) if own else leg.watched
        pl = p if own else leg.model.default_params
        t, X, st, hit = _segment(r, leg, leg.state(x_now), grid, pl, watched, h_next)
        made = r.atlases.wrapped(st["wraps"]) if st["wraps"] else []  # what the loop made (c/wrap.c)
        r.chart_switches += made
        p_rows, changed = p, [rec for rec in made if rec["from"] != rec["to"]]
        if changed:  # charts the loop changed: the run goes on in them (its rows before, in theirs),
            # a sliding contact's slip turned with its fingertip's frame as the loop turned it
            for rec in changed:
                r.p[model.p_names.index(rec["chart"])] = rec["to"]
                slips = _slip_across(r.atlases.entry(rec["chart"]), rec, modes, slips)
            p = pl = r.params(modes, slips)
            watched = r.witnesses(modes, slips)
        h_next = 0.0
        _count(r, st, own)
        t_look = perf_counter()
        at_edge = hit is not None and "atlas" in hit
        # integrated again from the segment's states (it may have wrapped a coordinate, c/wrap.c,
        # since its start): wrapped alike, the records left (the segment's are the run's)
        with leg.model.library.wrapping(st["slots_again"], []):
            found = None if hit is None or at_edge else _locate(r, leg, pl, watched, hit)
            if found is not None and found[2] == "slip" and not hit["armed"] and found[3] in r.slip_levels:
                found = _last_zero(r, leg, pl, watched[hit["which"]], hit, found, t, X, (grid[0], leg.state(x_now)))
            keep = len(t) if found is None else int(np.searchsorted(t, found[0], side="left"))
            if found is not None and found[0] > hit["t"]:  # output times between the dense output's
                late = t_eval[(t_eval >= hit["t"]) & (t_eval < found[0])]  # root and the event's
                if len(late):
                    t = np.concatenate([t[:keep], late])
                    X = np.concatenate([X[:keep], [events.state_at(leg.model, r.s, r.sched, pl, hit["t_step"],
                                                                   hit["x_step"], float(tm), one_step=True,
                                                                   projection=(None, 0.0))
                                                   for tm in late]])
                    keep = len(t)
        X = leg.states(X)
        # the samples are at grid's times (t_eval's) but its first, the segment's start
        on_grid = t[:keep] > last_t
        if keep and on_grid[0]:
            on_grid[0] = bool(t_eval[min(int(np.searchsorted(t_eval, t[0])), len(t_eval) - 1)] == t[0])
        t_rows, X_rows = t[:keep][on_grid], X[:keep][on_grid]
        for a, b, pk in by_charts(model.p_names, t_rows, p_rows, changed, lambda pk, rec: _turn_slip(r, pk, rec)):
            rows_t.append(t_rows[a:b])
            rows_x.append(X_rows[a:b])
            rows_mode.append(_mode_rows(modes, b - a))
            rows_p.append(pk)
        if on_grid.any():
            last_t = float(t[:keep][on_grid][-1])
        if at_edge:  # a contact at its chart's edge: on in the chart that covers it
            x_now, p_new, record = r.atlases.switch(hit["atlas"], hit["t"], hit["x"], p)
            _chart_switch(r, record, hit["x"], p_new)
            slips = _slip_across(r.atlases.slots[hit["atlas"]][0], record, modes, slips)
            h_next = hit["h"]  # on from the step size reached (not a restart from a first guess)
            r.stats["switch_time"] += perf_counter() - t_look
            t_now = hit["t"]
            continue
        if found is None:
            break
        t_ev, x_ev, name, j, value_ = found[:5]
        located = found[5] if len(found) > 5 else None  # (only _locate_one's own: a later pick is not)
        x_ev = leg.states(x_ev)
        if name != "onset":
            recent = _chatter(model, recent, t_ev, x_ev)
        before = list(modes)
        r.t = t_ev
        modes, slips, x_now, reset = _switch(r, modes, slips, name, j, t_ev, x_ev, hit["armed"])
        r.stats["switch_time"] += perf_counter() - t_look
        if reset is not None:  # None: a slide re-aimed, or its onset ended: no switch
            _record(r, t_ev, j, name, value_, reset, before, modes, located)
        t_now = t_ev
    res = _finish(r, s, start, rows_t, rows_x, rows_mode, rows_p)
    # (a run whose loop changed a chart: the short way would run it and give it up at its end)
    if short is not None and rolls is not None and r.sched is None and not r.events \
            and all(rec["from"] == rec["to"] for rec in r.chart_switches):
        _remember(model, short, s, r, rolls)
    return res


def _chart_switch(r: _Run, record: dict, x_at: np.ndarray, p_new: np.ndarray) -> None:
    """Keep a chart switch (``runtime.atlas``): its record, and the new chart in the run's
    parameters. A second switch of the same contact at the same time (its state mapped back
    onto the chart's edge) stops the run by name rather than going round."""
    if repeated(r.chart_switches, record):
        raise ContactLeftContourError(record["t"], x_at, f"{record['chart']}: the contact left both charts of "
                                      f"its atlas at the same time (u, v = {record['u'][0]:.6g}, "
                                      f"{record['v'][0]:.6g}): report this scene", r.model.state_names)
    if record["chart"] is not None:  # None: a repeating chart's coordinates wrapped
        i = r.model.p_names.index(record["chart"])
        r.p[i] = p_new[i]
    r.chart_switches.append(record)


def _turn_slip(r: _Run, p: np.ndarray, record: dict) -> None:
    """``p`` (in place) after the chart change ``record``: a sliding contact's slip direction
    (its parameters ``slip_x``, ``slip_y``) turned with its fingertip's frame, as
    ``_slip_across`` turns it in ``slips`` and ``c/wrap.c`` in the loop's ``p``."""
    j = r.atlases.entry(record["chart"]).get("slip_frame")
    if j is None or p[r.i_mode[j - 1]] != SLIDING:
        return
    i = r.i_slip[j - 1]
    p[i], p[i + 1] = _turned(p[i], p[i + 1], record["delta"])


def _after(r: _Run, records: list[dict], p: np.ndarray) -> np.ndarray:
    """``p`` after the switches ``records`` the loop made: their charts (``Atlases.after``) and
    a sliding contact's slip turned with its fingertip's frame (``_turn_slip``)."""
    p = r.atlases.after(records, p)
    for rec in records:
        if rec["from"] != rec["to"]:
            _turn_slip(r, p, rec)
    return p


def _wrap_slots(r: _Run, p: np.ndarray, watched) -> np.ndarray:
    """The atlases' slots as a segment's loop takes them (``c/wrap.c``): it changes a chart
    itself, and where the chart is a fingertip's whose contact slides, it turns the slip with
    the fingertip's frame: its direction in ``p`` (``slip_x``, ``slip_y``) and the first two
    terms of the watch's slip witness (``_GraspRun.slip_terms``). A slip witness of another
    shape leaves that chart's change to Python (the loop stops at the edge), and so does a
    slide in its onset (``r.slip_levels``, set by ``r.witnesses``): its stop may be looked for
    at the slip's last zero (``_last_zero``), among the segment's rows and integrated again
    from its start, all of which must be in one set of charts."""
    if r.slip_levels:
        return r.atlases.wrap_only
    slots = r.atlases.wrap_slots
    for k, (entry, _, _) in enumerate(r.atlases.slots):
        j = entry.get("slip_frame")
        if j is None or p[r.i_mode[j - 1]] != SLIDING:
            continue
        slots = slots.copy() if slots is r.atlases.wrap_slots else slots
        w = next((i for i, (name, c, _) in enumerate(watched) if name == "slip" and c == j), None)
        if w is None or [term[0] for term in watched[w][2][:2]] != list(r.slip_keys(j)) or \
                any(len(term) > 2 for term in watched[w][2][:2]):
            slots[k, 13] = 0.0
            continue
        slots[k, 14], slots[k, 15] = r.i_slip[j - 1], w
    return slots


def _slip_across(entry: dict, record: dict, modes, slips) -> list:
    """``slips`` after a chart switch (``record``) of the atlas ``entry``: a sliding contact's
    slip direction is in its fingertip's frame (``(x_f, y_f)``, the rows of ``J V``), whose
    ``x_f`` turns by the switch's ``delta`` about the normal when the fingertip's chart changes
    (``x' = cos delta x + sin delta y``): the same direction in the new frame."""
    j = entry.get("slip_frame")
    if j is None or modes[j - 1] != SLIDING or slips[j - 1] is None:
        return slips
    slips = list(slips)
    slips[j - 1] = np.array([*_turned(slips[j - 1][0], slips[j - 1][1], record["delta"]),
                             *slips[j - 1][2:]])  # (an onset's scale kept)
    return slips


def _turned(a, b, delta: float) -> tuple[float, float]:
    """A vector's components ``(a, b)`` in a frame ``(x, y)`` turned by ``delta`` about the
    normal (``x' = cos delta x + sin delta y``): its components in the new frame (what
    ``c/gs_internal.h``'s ``gs_turn2`` computes in the loop)."""
    a, b, c, s = float(a), float(b), math.cos(delta), math.sin(delta)
    return a * c + b * s, b * c - a * s


def _new_run(model, s, mus, e: float) -> _Run:
    """The run's state for ``model``'s kind (``_RUNS``)."""
    kind = "planar_fingers" if "planar_fingers" in model.manifest else model.manifest.get("kind", "body")
    return _RUNS[kind](model, s, mus, e)


def _count(r: _Run, st: dict, own: bool) -> None:
    """Add a segment's counts (``st``, its loop's stats; ``own``: run by the model with modes
    itself) to the run's."""
    r.stats["n_steps"] += int(st.get("n_steps", 0))
    r.stats["n_rhs"] += int(st.get("n_rhs", 0))
    r.stats["loop_time"] += float(st.get("loop_time", 0.0))
    r.stats["segments"] += 1
    r.stats["rolling_model_segments"] += 0 if own else 1


def _finish(r: _Run, s, start: float, rows_t, rows_x, rows_mode, rows_p) -> SimulationResult:
    """The run's result from its segments' rows (their times, states, modes and parameters);
    ``start``: the ``perf_counter`` at the run's start."""
    model, mus, e = r.model, r.mus, r.e
    t_all = np.concatenate(rows_t)
    X_all = np.concatenate(rows_x)
    modes_all = np.concatenate(rows_mode) if rows_mode else np.zeros((0, r.k), dtype=int)
    outs = {}
    if s.outputs:  # each segment's rows with its parameters (one compiled batch call each)
        parts = [_segment_outputs(r, tt, xx, pp, mm) for tt, xx, pp, mm in zip(rows_t, rows_x, rows_p, rows_mode)
                 if len(tt)]
        Y = parts[0] if len(parts) == 1 else np.concatenate(parts) if parts else \
            np.zeros((0, len(model.columns)))
        outs = outputs_.by_name(model, Y, shown=True) if model.columns else {}
    first = bool(s.drop_first and len(t_all) and t_all[0] == 0.0)
    if first:
        t_all, X_all, modes_all = t_all[1:], X_all[1:], modes_all[1:]
        outs = {k: v[1:] for k, v in outs.items()}
    charts = {}
    for entry, i, _ in (() if r.atlases is None else r.atlases.slots):
        if i is None:
            continue
        rows = [np.full(len(tt), int(pp[i])) for tt, pp in zip(rows_t, rows_p)]
        charts[entry["param"]] = np.concatenate(rows) if rows else np.zeros(0, dtype=int)
    if first:
        charts = {k: v[1:] for k, v in charts.items()}
    stats = {**r.stats, "n_events": len(r.events), "wall_time": perf_counter() - start}
    if r.atlases is not None:
        stats["chart_switches"] = len(r.chart_switches)
    pdict = {"mu": mus[0] if r.k == 1 else mus, "e": e}
    names = np.array(NAMES)[modes_all.astype(int)]
    return SimulationResult(t=t_all, x=X_all, state_names=model.state_names, outputs=outs,
                            method=s.method, stats=stats, params=pdict, scene=model.scene,
                            events=r.events, modes=names[:, 0] if r.k == 1 else names,
                            charts=charts, chart_switches=r.chart_switches)


#: Start states the short way keeps per set of settings (the oldest dropped beyond this).
SHORT_STARTS = 64


def _remember(model, short, s, r: _Run, rolls) -> None:
    """Keep, for the short way, the settings ``s`` a full run accepted (under the plan key
    ``short[0]``) and its start (under ``short[1]``): ``rolls``, the state the run's first
    segment started from and every contact's mode and slip there, all rolling, with no
    witness past its event (a run that made no switch)."""
    plans = model.run_cache.setdefault("modes_short", {})
    key, at = short
    plan = plans.get(key)
    if plan is None or plan[1] != r.mus or plan[2] != r.e:
        if len(plans) >= SHORT_STARTS:
            plans.clear()
        plan = plans[key] = (s, r.mus, r.e, {})
    starts = plan[3]
    starts[at] = rolls
    if len(starts) > SHORT_STARTS:
        starts.pop(next(iter(starts)), None)  # another thread may have dropped it


def short_way(model, key, t_final, t_eval, x0) -> SimulationResult | None:
    """A run on the short way (``runtime.fastpath``'s, for a model with modes), or None for the
    full way: settings a previous full run accepted (``key``, with no inputs, no time limit)
    and a start ``x0`` (None: the model's own) it began rolling from, run as that run's first
    segment, whose numbers are the full way's bit for bit. None when a witness fires (the
    full way locates the switch and makes it; the start is forgotten, so a call that
    switches pays its first segment twice once), the loop fails (the full way names it), or
    ``x0`` or the output times are not plainly a state and ``0 .. t_final``."""
    plan = model.run_cache.get("modes_short", {}).get(key)
    if plan is None:
        return None
    if x0 is None:
        at = b""
    elif isinstance(x0, np.ndarray) and x0.dtype == np.float64 and x0.shape == (len(model.state_names),):
        at = np.ascontiguousarray(x0).tobytes()
    else:
        return None
    rolls = plan[3].get(at)
    t = fastpath.plain_times(t_eval, t_final)
    if rolls is None or t is None or not t[-1] > _END_AT_SWITCH:
        return None
    start = perf_counter()
    s = dataclasses.replace(plan[0], t_final=float(t_final), t_eval=t, drop_first=False)
    x_now, modes, slips = rolls
    r = _new_run(model, s, plan[1], plan[2])
    p = r.params(modes, slips)
    leg = r.leg(modes, x_now)
    own = leg is r.own_leg
    try:
        tt, X, st, hit = _segment(r, leg, leg.state(x_now), t, p if own else leg.model.default_params,
                                  r.witnesses(modes, slips) if own else leg.watched)
    except RunInterruptedError:
        raise  # Ctrl-C (under a handler of the user's): the call's, not a reason to go the full way
    except GraspingSymError:
        return None
    if hit is not None or len(tt) != len(t) or any(rec[6] != rec[7] for rec in st["wraps"]):
        plan[3].pop(at, None)  # it switches from there: the next such call goes the full way at once
        return None
    r.chart_switches += r.atlases.wrapped(st["wraps"]) if st["wraps"] else []  # (c/wrap.c's)
    _count(r, st, own)
    return _finish(r, s, start, [tt], [leg.states(X)], [_mode_rows(modes, len(tt))], [p])


def _segment_outputs(r: _Run, t, X, p, modes) -> np.ndarray:
    """The outputs at a segment's rows (``outputs_.along_rows``; ``modes``: the contacts' modes
    at each row, one segment's); where the contacts are in the
    modes the outputs have a branch for (the manifest's ``folded_modes``: every finger rolling,
    every surface of the world apart), no inputs vary and the outputs do not read the time, by
    that branch (``outputs_folded``: the same numbers, the other modes' branches left out)."""
    model = r.model
    symbol = model.manifest.get("outputs_folded")
    if symbol is None or r.sched is not None or model.manifest.get("outputs_time") \
            or (np.asarray(modes) != model.manifest["folded_modes"]).any():
        return outputs_.along_rows(model, t, X, p, r.sched)
    fn = model.run_cache.get("outputs_folded")
    if fn is None:
        fn = model.run_cache["outputs_folded"] = model.library.rows(symbol)
    return fn(X, complete(model, p))


def _mode_rows(modes, n: int) -> np.ndarray:
    """``n`` rows of each contact's mode."""
    out = np.empty((n, len(modes)), dtype=int)
    out[:] = modes
    return out


#: A run whose last output time is within this (relative to the time, at least 1 s) after a
#: switch ends at the switch: 4 times the events' location tolerance (``events.TIME_TOL``).
_END_AT_SWITCH = 4 * events.TIME_TOL


def _chatter(model, recent: list[float], t_ev: float, x_ev: np.ndarray) -> list[float]:
    """The switches' times within ``SWITCH_WINDOW`` up to ``t_ev``; ``ChatteringError`` when
    they are more than ``MAX_SWITCHES``."""
    recent = [tt for tt in recent if tt > t_ev - SWITCH_WINDOW] + [t_ev]
    if len(recent) > MAX_SWITCHES:
        raise ChatteringError(t_ev, x_ev, f"{len(recent)} switches of contact modes within "
                              f"{SWITCH_WINDOW:g} s up to t = {t_ev:.9g} s (a Zeno run): the "
                              "contact chatters; give a plastic impact (e = 0) or a larger "
                              "friction coefficient; or, where a slide starts from the cone's edge "
                              "at a loose tolerance (its slip then grows slower than the "
                              "integration's noise), a tighter one (e.g. rtol=1e-8, atol=1e-10)",
                              model.state_names)
    return recent


def _at_start(r: _Run, modes, slips, y: dict) -> tuple[str, int, list] | None:
    """``(witness, contact, terms)`` of a force or cone witness that starts a segment at or below 0:
    past its event already (another contact's impact or switch took it there, or it crossed
    within the dense output's error of the event just made), so it switches at once; it
    could not be watched (``c/watch.c`` arms it only above 0)."""
    for name, j, terms in r.witnesses(modes, slips):
        if _arming(name) == 0.0 and name != "painleve" and not value(terms, y) > 0:
            return name, j, terms
    return None


def _segment(r: _Run, leg: _Leg, x: np.ndarray, grid: np.ndarray, p: np.ndarray, watched, h0: float = 0.0):
    """``(t, X, stats, hit)``: one mode's integration over ``grid`` by ``leg`` (from its state
    ``x``, with its parameters ``p``), the C loop watching the mode's witnesses (``watched``,
    ``c/watch.c``) and stopping at the first event: ``hit`` (None: none) holds its witness,
    its time and state on the dense output, the watched points around it and its step's
    start (``CompiledLibrary.watch_result``); the samples before it (``leg``'s states).
    Restarted at the inputs' knots inside ``grid`` (each piece with its inputs ``a + b t``)."""
    s, model = r.s, leg.model
    lib, cols = model.library, leg.col
    lib.watch([[(cols[term[0]], *term[1:]) for term in terms] for _, _, terms in watched],
              [r.arming(name, j) if leg is r.own_leg else _arming(name, s.atol) for name, j, _ in watched],
              inputs=leg.input_slots, dt=WATCH_DT, probe=[name == "gap" for name, _, _ in watched],
              safety=WATCH_SAFETY)
    try:
        pieces = [(float(grid[0]), float(grid[-1]), None, None)] if r.sched is None else \
            r.sched.segments(float(grid[0]), float(grid[-1]))
        rows_t, rows_x, stats = [], [], {}
        # the coordinates the C loops wrap at the step (c/wrap.c): the model with modes' own
        wraps: list = []
        wrap_slots = again = None
        if r.atlases is not None and leg.back is None and s.method != "rk4":
            # the loop changes a chart itself (turning a sliding contact's slip with its
            # fingertip's frame: _wrap_slots) unless a table of inputs restarts it (each piece from
            # the segment's p); integrated again, it only wraps (from a state of the segment's
            # end's charts)
            wrap_slots = r.atlases.wrap_only if r.sched is not None else _wrap_slots(r, p, watched)
            again = r.atlases.wrap_only
        stats["wraps"], stats["slots_again"] = wraps, again
        deadline = None if s.time_limit is None else perf_counter() + s.time_limit  # the pieces' in all
        for k, (a0, a1, a, b) in enumerate(pieces):
            g = grid if r.sched is None else np.concatenate([[a0], grid[(grid > a0) & (grid < a1)], [a1]])
            pk = p if r.sched is None else model.with_inputs(p, a, b)
            r.stats["chunks"] += 1
            if deadline is not None and perf_counter() > deadline:  # (a piece's loop reads the clock
                # every 16th step only: a table's short pieces would never)
                err = IntegratorError(a0, leg.states(np.asarray(x, dtype=float)),
                                      f"{s.method}: the wall-time limit was reached at t = {a0:.6g} s, "
                                      "at a knot of the inputs' table (raise time_limit, or loosen the "
                                      "tolerances)", r.model.state_names)
                err.cause = "time_limit"  # type: ignore[attr-defined]
                raise err
            if k:  # past a knot: the witnesses stay armed as they were
                lib.watch_resume()
            try:
                with lib.wrapping(wrap_slots, wraps):
                    t, X, st = integrators.c_loop(
                        model, s.method, x, g, pk, rtol=s.rtol, atol=s.atol,
                        max_steps=max(s.max_steps - stats.get("n_steps", 0), 1), h=s.h,
                        time_limit=None if deadline is None else max(deadline - perf_counter(), 1e-9),
                        h0=h0 if k == 0 else 0.0)
            except IntegratorError as exc:
                err = _in_own_state(r, leg, failures.classify(model, exc))
                slot = None if r.atlases is None or leg.back is not None else r.atlases.slot_of(err)
                if slot is None:
                    if r.atlases is not None:  # in the charts the loop left
                        name_charts(err, r.atlases.charts(r.atlases.after(r.atlases.wrapped(wraps), r.p)))
                    raise err from None
                # a contact at its chart's edge: the rows up to the step there, and where it is
                t, X = err.trajectory
                rows_t.append(t if k == 0 else t[1:])
                rows_x.append(X if k == 0 else X[1:])
                got = getattr(err, "stats", {})
                for key in ("n_steps", "n_rhs"):
                    stats[key] = stats.get(key, 0) + int(got.get(key, 0))
                stats["loop_time"] = stats.get("loop_time", 0.0) + float(got.get("wall_time", 0.0))
                _watched(r, lib)
                hit = {"atlas": slot, "t": float(err.t), "x": np.asarray(err.x, dtype=float),
                       "h": float(got.get("h_last", 0.0))}
                return _on_grid(rows_t, rows_x, grid) + (stats, hit)
            rows_t.append(t if k == 0 else t[1:])
            rows_x.append(X if k == 0 else X[1:])
            for key in ("n_steps", "n_rhs"):
                stats[key] = stats.get(key, 0) + int(st.get(key, 0))
            stats["loop_time"] = stats.get("loop_time", 0.0) + float(st.get("wall_time", 0.0))
            if "event" in st:
                # (p with the charts the loop changed: the event's step is in them)
                hit = {**st["event"], **_watched(r, lib),
                       "p": _after(r, r.atlases.wrapped(wraps), pk) if wraps else pk}
                return _on_grid(rows_t, rows_x, grid) + (stats, hit)
            x = X[-1]
        _watched(r, lib)
        return _on_grid(rows_t, rows_x, grid) + (stats, None)
    finally:
        lib.unwatch()


#: Times of a slide's segment integrated again, among which ``_last_zero`` looks for the
#: latest where the slip witness is > 0 (the run's output times may be few: with 14, a shaken
#: belt's short slide stopped 3.5 ms late).
LAST_ZERO_POINTS = 64


def _last_zero(r: _Run, leg: _Leg, p: np.ndarray, witness, hit: dict, found, t, X, start):
    """An onset's slip witness that fell below minus its level before it was armed (``found``:
    located there): where its slip peaked above 0 but below the level, the slip stopped (or
    turned past 90 degrees) where the witness last crossed 0, not at ``-level`` (there it came
    late, friction feeding the reversed slip meanwhile: a shaken belt's slide peaking at
    7e-7 m/s stopped 20 ms late at rtol 1e-4). That crossing, located from the latest state
    after the segment's ``start`` (the slide's) and before it where the witness is > 0: the
    step's start, a sample ``(t, X)`` of the segment, or one of ``LAST_ZERO_POINTS`` states of
    the segment integrated again from its start. ``found`` where there is none: at the
    slide's start itself ``v_t . slip`` is 0 but for its noise, and a zero found from there
    stopped paper3d's grasp 1e-10 s into its slides, again and again (with the witness armed
    lower than the onset's width, ``_Run.arming``)."""
    _, j, terms = witness
    model = leg.model
    t0 = float(start[0])

    def above(tk: float, xk) -> bool:
        r.t = float(tk)
        return value(terms, r.outputs(np.asarray(xk, dtype=float), p, model)) > 0

    before = [(float(tk), xk) for tk, xk in zip(t, X) if t0 < tk < found[0]]
    if t0 < hit["t_step"] < found[0]:
        before.append((float(hit["t_step"]), hit["x_step"]))
    if r.sched is None:  # the segment again, at LAST_ZERO_POINTS times: its output times may be few
        grid = np.linspace(t0, found[0], LAST_ZERO_POINTS + 1)
        try:
            tg, Xg, _ = integrators.c_loop(model, r.s.method, np.asarray(start[1], dtype=float), grid, p,
                                           rtol=r.s.rtol, atol=r.s.atol, max_steps=r.s.max_steps, h=r.s.h)
            before += [(float(tk), xk) for tk, xk in zip(tg, Xg) if t0 < tk < found[0]]
        except IntegratorError:
            pass
    for tk, xk in sorted(before, key=lambda c: -c[0]):   # the latest first
        if above(tk, xk):
            zero = events.locate(model, r.s, r.sched, p, tk, np.asarray(xk, dtype=float), found[0],
                                 lambda y: value(terms, y))
            if zero is None or not tk < zero[0] < found[0]:
                break
            r.t = zero[0]
            return zero[0], zero[1], "slip", j, float(value(terms, r.outputs(zero[1], p, model)))
    r.t = found[0]
    return found


def _watched(r: _Run, lib) -> dict:
    """``lib.watch_result()``, its counts of the points watched and the steps' ends left
    unwatched added to ``r.stats``."""
    res = lib.watch_result()
    r.stats["watched"] += res["watched"]
    r.stats["left_unwatched"] += res["left"]
    return res


def _in_own_state(r: _Run, leg: _Leg, err: IntegratorError) -> IntegratorError:
    """``err`` of a segment ``leg`` ran, in the model with modes' state and names (its state,
    its rejected state and its trajectory mapped back from the rolling model's)."""
    if leg.back is None or type(err) not in (IntegratorError, ContactLeftContourError, JointLimitError):
        return err
    new = type(err)(err.t, None if err.x is None else leg.states(err.x), err.reason, r.model.state_names)
    for key in ("code", "stats", "stiff", "t_rejected", "cause"):
        if hasattr(err, key):
            setattr(new, key, getattr(err, key))
    if getattr(err, "x_rejected", None) is not None:
        new.x_rejected = leg.states(err.x_rejected)  # type: ignore[attr-defined]
    if getattr(err, "trajectory", None) is not None:
        new.trajectory = (err.trajectory[0], leg.states(err.trajectory[1]))  # type: ignore[attr-defined]
    return new


def _on_grid(rows_t, rows_x, grid):
    """The samples at ``grid``'s times (the pieces' knots left out)."""
    t, X = np.concatenate(rows_t), np.concatenate(rows_x)
    if len(rows_t) == 1:
        return t, X
    keep = np.isin(t, grid)
    return t[keep], X[keep]


def _locate(r: _Run, leg: _Leg, p: np.ndarray, watched, hit: dict):
    """``(t, x, witness, contact, value)`` of the event the C loop stopped at (``_segment``'s
    ``hit``), located on the trajectory integrated again by ``leg`` from its step's start
    (``events.refine``); ``x`` is ``leg``'s state. Where several witnesses fired in a step
    whose end was left unwatched (``c/watch.c``: their order is the secants' guess), any that
    is already below 0 at the located event crossed first: it is located in turn."""
    found = _locate_one(r, leg, p, watched, hit)
    for _ in range(len(watched) if hit.get("fired", 0) > 1 else 0):
        tc, xc = found[0], found[1]
        r.t = tc
        y = r.outputs(xc, p, leg.model)
        # every witness was armed (none is left unwatched otherwise): below 0 is past its event
        earlier = [k for k, (name, c, terms) in enumerate(watched)
                   if (name, c) != (found[2], found[3]) and value(terms, y) < 0]
        if not earlier:
            break
        k = earlier[0]
        name, j, terms = watched[k]
        again = events.refine(leg.model, r.s, r.sched, p, hit["t_step"], hit["x_step"], hit["t_lo"], tc,
                              0.5 * (hit["t_lo"] + tc), math.nan, lambda y, terms=terms: value(terms, y))
        if again is None or not again[0] < tc:
            break
        r.t = float(again[0])
        found = (float(again[0]), again[1], name, j, float(value(terms, r.outputs(again[1], p, leg.model))))
    r.t = found[0]
    return found


def _locate_one(r: _Run, leg: _Leg, p: np.ndarray, watched, hit: dict):
    """``_locate`` of the witness the C loop named."""
    name, j, terms = watched[hit["which"]]
    model = leg.model
    level = 0.0 if hit["armed"] else -(r.arming(name, j) if leg is r.own_leg else _arming(name, r.s.atol))
    # (unarmed: it fell below -tol, c/watch.c)
    w = lambda y: value(terms, y) - level  # noqa: E731 - one witness
    t_lo, t_guess, slope = hit["t_lo"], hit["t"], hit["slope"]
    t_step, x_step = hit["t_step"], hit["x_step"]
    if not hit["armed"] and name == "gap":  # it closes again within the interval that opened it
        sk = r.key("normal_speed", j)
        apex = events.locate(model, r.s, r.sched, p, t_step, x_step, hit["t_hi"], lambda y: y[sk])
        r.t = apex[0] if apex is not None else t_step
        if apex is None or not r.outputs(apex[1], p, model)[r.key("gap", j)] > 0:
            raise EventLocationError(hit["t_hi"], leg.states(hit["x"]), f"contact {j}, apart from {t_step:.9g} s, "
                                     f"returns before {hit['t_hi']:.9g} s, but no time apart is found "
                                     "between: give tighter tolerances", r.model.state_names)
        found = events.locate(model, r.s, r.sched, p, apex[0], apex[1], hit["t_hi"],
                              lambda y: value(terms, y))
    else:  # in C (gs_watch_refine), else the same in Python, with Brent's method behind it
        found = model.library.watch_refine(r.s.method, x_step, hit["p"], r.s.rtol, r.s.atol, r.s.max_steps,
                                           model.lower, model.upper, events.TIME_TOL, events.SECANT_STEPS)
        if found is not None:  # the witness there, less its level, comes with it
            r.t = found[0]
            return found[0], found[1], name, j, found[2] + level
        found = events.refine(model, r.s, r.sched, p, t_step, x_step, t_lo, hit["t_hi"], t_guess, slope, w)
    if found is None:
        t_d, x_d = float(hit["t"]), np.asarray(hit["x"], dtype=float)
        if name == "slip" and not hit.get("fired", 0) and t_lo < t_d <= hit["t_hi"] and np.isfinite(x_d).all():
            # a slip that stops within the tolerances' noise (integrating again does not
            # reproduce its sign change): the dense output's root (on a watched step: the
            # loop's own solution to its tolerances), and the event says so (its sixth entry)
            r.t = t_d
            return t_d, x_d, name, j, float(value(terms, r.outputs(x_d, p, model))), "dense output"
        raise EventLocationError(hit["t_hi"], leg.states(hit["x"]), f"the {name} witness of contact {j} changes "
                                 f"sign between {t_lo:.9g} and {hit['t_hi']:.9g} s on the integration's dense "
                                 "output, but integrating again does not find where: give tighter "
                                 "tolerances", r.model.state_names)
    tc, xc = float(found[0]), found[1]
    r.t = tc
    return tc, xc, name, j, float(value(terms, r.outputs(xc, p, model)))


def _start(r: _Run, x0: np.ndarray) -> tuple[np.ndarray, list[int], list, dict | None]:
    """The start's state and each contact's mode: apart (gap > CONTACT_GAP; the contact
    coordinates put on the common normal), leaving (separated), approaching (an impact at
    once, recorded), or in contact (``contact_start``); the outputs there in those modes
    when they are at hand (every contact rolling, else None)."""
    k = r.k
    modes, slips = [ROLLING] * k, [None] * k
    y = r.outputs(x0, r.params(modes))
    r.check_start(x0, y)
    if any(y[r.key("gap", j)] > CONTACT_GAP for j in r.contacts):
        x0 = r.apart(x0)
        y = r.outputs(x0, r.params(modes))
    hits = []
    for j in r.contacts:
        gap, speed = y[r.key("gap", j)], y[r.key("normal_speed", j)]
        if gap < -CONTACT_GAP:
            raise RunArgumentError(f"x0 penetrates at contact {j}: gap = {gap:.6g} m < 0; start in "
                                   "contact (a body: start='contact'; a finger: the scene's start) or apart")
        if gap > CONTACT_GAP or speed > STOP_SPEED:
            modes[j - 1] = SEPARATED
        elif speed < -STOP_SPEED:
            modes[j - 1] = SEPARATED
            hits.append(j)
    if len(hits) > 1:
        raise ContactModeError(0.0, x0, f"contacts {hits} hit at once: simultaneous impacts have no "
                               "answer here (the impulses' order would decide)", r.model.state_names)
    for j in hits:
        gap = y[r.key("gap", j)]
        before = list(modes)
        modes, slips, x0, reset = _switch(r, modes, slips, "gap", j, 0.0, x0)
        _record(r, 0.0, j, "gap", float(gap), reset, before, modes)
    for j in r.contacts:  # y: the outputs at x0 with every contact rolling
        if modes[j - 1] == ROLLING:
            same = not hits and all(m == ROLLING for m in modes)
            modes[j - 1], slips[j - 1] = r.contact_start(0.0, x0, modes, slips, j, y if same else None)
    return x0, modes, slips, y if not hits and all(m == ROLLING for m in modes) else None


def _record(r: _Run, t: float, j: int, name: str, value_: float, reset, before, modes,
            located: str | None = None) -> None:
    """The switch of contact ``j`` at ``t`` in ``r.events``, then each other contact's that
    the switch's impulse changed (witness ``"impulse"``: let go, or sliding or held through
    it, ``_GraspRun.impact``)."""
    r.events.append({"t": t, "contact": j, "from": NAMES[before[j - 1]], "to": NAMES[modes[j - 1]],
                     "witness": name, "value": value_, "reset": reset, **({"located": located} if located else {})})
    for c in r.contacts:
        if c != j and modes[c - 1] != before[c - 1]:
            r.events.append({"t": t, "contact": c, "from": NAMES[before[c - 1]], "to": NAMES[modes[c - 1]],
                             "witness": "impulse", "value": 0.0, "reset": 0.0})


def _switch(r: _Run, modes, slips, name: str, j: int, t: float, x: np.ndarray, armed: bool = True):
    """``(modes, slips, state after, reset)`` at an event of contact ``j`` (``armed``: its witness
    was seen above its ``_arming`` level first, ``c/watch.c``)."""
    modes, slips = list(modes), list(slips)
    if name == "painleve":
        y = r.outputs(x, r.params(modes, slips))
        _painleve(r.model, t, x, y[r.key("painleve", j)], r.mus[j - 1], j)
    if name == "normal_force":
        modes[j - 1], slips[j - 1] = SEPARATED, None
        return modes, slips, x, 0.0
    if name == "cone":
        y = r.with_mode(x, modes, slips, j, ROLLING)
        p = r.params(modes, slips)
        modes[j - 1], slips[j - 1] = SLIDING, r.onset_slip(r.slip_direction(x, y, j, modes=modes, slips=slips),
                                                          t, x, p, j)
        return modes, slips, x, 0.0
    if name == "onset":  # a slide's onset is over: on along the same slip, Coulomb's direction
        slips[j - 1] = np.asarray(slips[j - 1], dtype=float)[:len(r.slip_keys(j))]
        return modes, slips, x, None
    y = r.with_mode(x, modes, slips, j, ROLLING)
    if name == "slip":
        vt = r.slip_velocity(y, j)
        # the slip turned past 90 degrees (a 3D grasp's: REAIM_ANGLE) from its start's
        # direction, it did not stop: faster than STOP_SPEED there, or it never went along
        # that direction above the witness's arming level (c/watch.c's unarmed event: below
        # minus that level first; at an onset located where it last crossed 0, _last_zero)
        # and is clearly faster than that level across it (twice it; in 2D it is a
        # reversal: a stop)
        if _norm(vt) > (STOP_SPEED if armed else 2 * r.arming(name, j)):
            slips[j - 1] = vt / _norm(vt)
            return modes, slips, x, None
        x2, reset = r.stop_slip(x, y, modes, j)
        modes[j - 1], slips[j - 1] = r.contact_start(t, x2, modes, slips, j)
        return modes, slips, x2, reset
    # an impact
    x2, reset, _, bounced = r.impact(t, x, y, modes, j, slips=slips)
    if bounced:  # restitution: it leaves again
        modes[j - 1], slips[j - 1] = SEPARATED, None
    else:
        modes[j - 1], slips[j - 1] = ROLLING, None
        modes[j - 1], slips[j - 1] = r.contact_start(t, x2, modes, slips, j)
    if r.k == 1:  # no other contact to hit at once
        return modes, slips, x2, reset
    y2 = r.outputs(x2, r.params(modes, slips))
    for i in r.contacts:
        if i != j and modes[i - 1] == SEPARATED and not y2[r.key("gap", i)] > CONTACT_GAP \
                and y2[r.key("normal_speed", i)] < -STOP_SPEED:
            raise ContactModeError(t, x2, f"contacts {j} and {i} hit at once: simultaneous impacts have no "
                                   "answer here (the impulses' order would decide)", r.model.state_names)
    return modes, slips, x2, reset


def _painleve(model, t, x, value, mu, j=1):
    raise PainleveError(t, x, f"contact {j} sliding with mu = {mu:g} has no consistent normal force (or "
                        f"several): the normal row's coefficient {value:.6g} <= 0 (Painleve's paradox); "
                        "the rigid model has no answer here: lower mu, or model the contact's compliance",
                        model.state_names)


def run_many(model, s, X0: np.ndarray, mu, e, us: list | None = None, start_charts: dict | None = None,
             threads: int = 1) -> dict:
    """``simulate_many`` of a model with modes: each run by ``run``, on ``threads`` threads
    (``runtime.pool``; ``mu``, ``e``: None, one value, or one per run; ``us``: each run's
    inputs, None: none; ``start_charts``: name -> each run's chart its ``x0`` is written in,
    None: the start's), within the batch's ``time_limit`` in all; a run that stops by name is
    recorded, the others go on; Ctrl-C is the batch's. Returns the pieces of a
    ``runtime.batch.BatchResult``."""
    n = len(X0)
    mus = _per_run("mu", mu, n)
    es = _per_run("e", e, n)
    dense = not (len(s.t_eval) == 2 and s.t_eval[0] == 0.0)
    m = len(s.t_eval) - (1 if s.drop_first else 0)
    x_final = np.full((n, len(model.state_names)), np.nan)
    X = np.full((n, m, len(model.state_names)), np.nan)
    outs = {k: np.full((n, m), np.nan) for k in model.output_names} if s.outputs else {}
    status = np.zeros(n, dtype=np.int64)
    errors = np.full(n, "", dtype=object)
    events: list = [[] for _ in range(n)]
    run_modes: list = [None] * n
    charts: list = [None] * n
    deadline = None if s.time_limit is None else perf_counter() + s.time_limit  # the whole batch's

    def one(i: int) -> None:
        left = None if deadline is None else deadline - perf_counter()
        if left is not None and left <= 0:
            status[i], errors[i] = c_loops.ERR_INTERRUPT, failures.out_of_time(s.time_limit)
            return
        try:
            res = run(model, s if left is None else dataclasses.replace(s, time_limit=left), X0[i], mus[i], es[i],
                      None if us is None else us[i], charts={k: v[i] for k, v in (start_charts or {}).items()})
        except RunInterruptedError:
            raise  # Ctrl-C: the batch's, not the run's (runtime.pool stops the others)
        except (GraspingSymError, ValueError) as exc:
            status[i], errors[i] = failures.batch_entry(exc, s.time_limit)
            return
        x_final[i] = res.x[-1]
        X[i] = res.x
        for k in outs:
            outs[k][i] = res.outputs[k]
        events[i] = res.events
        run_modes[i] = res.modes
        charts[i] = res.charts if dense else {k: v[-1:] for k, v in res.charts.items()}

    pool.each(n, threads, one)
    return {"x_final": x_final, "x": X if dense else None, "status": status, "errors": errors,
            "outputs": outs if dense else {k: v[:, -1] for k, v in outs.items()},
            "params": {"mu": np.array([_first_or_all(friction_law(model, mu_i, e_i)[0])
                                       for mu_i, e_i in zip(mus, es)]),
                       "e": np.array([friction_law(model, mu_i, e_i)[1] for mu_i, e_i in zip(mus, es)])},
            "events": events, "modes": run_modes, "charts": charts}


def _first_or_all(mus: tuple):
    return mus[0] if len(mus) == 1 else mus


def _per_run(name: str, value, n: int) -> list:
    """None or one value for every run, or an array of ``n``: one per run (``mu``: or of
    ``(n, contacts)``, one per contact of each run)."""
    if value is None or isinstance(value, Coulomb) or np.ndim(value) == 0:
        return [value] * n
    arr = np.asarray(value)
    if name == "mu" and arr.ndim == 2 and arr.shape[0] == n:
        return [tuple(float(v) for v in row) for row in arr]
    if arr.shape != (n,):
        raise RunArgumentError(f"{name} has shape {arr.shape}: give one value, or one per run ({n},)")
    return [float(v) for v in arr]
