"""Contact that can change: a run of a model with contact modes, switching at located events.

A model with modes (a body on a plane, ``model.body``; the manifest's ``modes``) is compiled
once with its mode a run-time parameter (0 rolling, 1 sliding, 2 separated) and the slip
direction at the start of a slide (``slip_x``, ``slip_y``, ``slip_z``). A run integrates one
segment per mode by the run's C loop (``METHODS``: radau, dopri5, dop853); along each segment
the mode's witnesses are watched at the output samples and the first sign change is located
between the samples by integrating again (``runtime.events``), where the run switches
(``docs/conventions.md`` section 7):

- rolling: ``mu f - |F_t|`` reaching 0 -> sliding, the slip starting where the sliding
  equations accelerate it (the fixed point of ``d -> a_t(d)/|a_t(d)|`` from
  ``-F_t/|F_t|``); ``f`` reaching 0 -> separated;
- sliding: ``f`` reaching 0 -> separated; the slip velocity along its direction ``d`` at the
  slide's start, ``v_t . d``, reaching 0 -> the slip stopped if ``|v_t| <= STOP_SPEED`` there
  (else it turned past 90 degrees: the slide goes on along the new ``v_t``, no switch): the contact velocity is set to
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
    PainleveError,
    RunArgumentError,
)
from grasping_sym.runtime import events, failures, integrators
from grasping_sym.runtime import outputs as outputs_
from grasping_sym.runtime.result import SimulationResult

ROLLING, SLIDING, SEPARATED = 0, 1, 2
#: The methods a run with modes takes: the adaptive loops in C (implicit and explicit).
METHODS = ("radau", "dopri5", "dop853")
NAMES = ("rolling", "sliding", "separated")
#: Gap (m) within which a start counts as in contact.
CONTACT_GAP = 1e-9
#: Slip speed (m/s) at or below which a contact counts as at rest of the slip (rolling if
#: consistent): the round-off of a contact velocity that a reset set to 0.
SLIP_SPEED = 1e-10
#: Slip speed (m/s) at the located zero of ``v_t . slip`` above which the slip did not stop but
#: turned past 90 degrees from ``slip``: the slide goes on, re-aimed (no switch, no reset).
STOP_SPEED = 1e-6
#: Most switches within ``SWITCH_WINDOW`` seconds before a run stops as chattering.
MAX_SWITCHES = 50
SWITCH_WINDOW = 1e-3
#: An impact slower than this (m/s, normal approach) is plastic whatever ``e``: the bounces
#: of a body coming to rest would otherwise accumulate (Zeno).
REST_SPEED = 1e-3


def friction_law(model, mu, e=None) -> tuple[float, float]:
    """``(mu, e)`` of a run: ``mu`` (a number or a ``Coulomb``) else the model's law, ``e``
    (a number in [0, 1]) else the law's; no law at all: ``mu = inf`` (the contact never
    slides), ``e = 0``."""
    law = model.friction if mu is None else mu
    if law is None:
        mu_, e_law = math.inf, 0.0
    elif isinstance(law, Coulomb):
        mu_, e_law = float(law.per_contact(1)[0]), float(law.e)
    else:
        if isinstance(law, (bool, np.bool_)) or not isinstance(law, (int, float, np.floating, np.integer)):
            raise RunArgumentError(f"mu = {law!r:.40} must be a number >= 0 or gs.contact.coulomb(mu, e)")
        mu_ = float(law)
        if not mu_ >= 0:
            raise RunArgumentError(f"mu = {law!r} must be a number >= 0 (math.inf: never slides)")
        e_law = float(model.friction.e) if isinstance(model.friction, Coulomb) else 0.0
    if e is None:
        return mu_, e_law
    if isinstance(e, (bool, np.bool_)) or not isinstance(e, (int, float, np.floating, np.integer)) \
            or not 0 <= float(e) <= 1:
        raise RunArgumentError(f"e = {e!r:.40} must be a number in [0, 1] (Newton's restitution)")
    return mu_, float(e)


class _Run:
    """One run's state: the model, its settings, the parameters per mode; what every kind of
    model with modes shares (a subclass per kind gives its contact's geometry)."""

    def __init__(self, model, s, mu: float, e: float):
        self.model, self.s, self.mu, self.e = model, s, mu, e
        names = model.p_names
        self.p = np.array(model.default_params, dtype=float)
        self.i_mode, self.i_mu = names.index("mode"), names.index("mu")
        self.p[self.i_mu] = min(mu, 1e300)
        self.events: list[dict] = []
        #: ``switch_time``: seconds spent locating the switches and making them
        self.stats = {"n_steps": 0, "n_rhs": 0, "segments": 0, "switch_time": 0.0}

    def params(self, mode: int, slip=None) -> np.ndarray:
        p = self.p.copy()
        p[self.i_mode] = float(mode)
        if slip is not None:
            p[self.i_slip:self.i_slip + len(slip)] = slip
        return p

    def outputs(self, x: np.ndarray, p: np.ndarray) -> dict[str, float]:
        return outputs_.at(self.model, x, p)

    def contact_start(self, t: float, x: np.ndarray, y: dict) -> tuple[int, np.ndarray | None]:
        """The mode of a state in contact (gap and normal speed 0; ``y`` its outputs with the
        rolling parameters) and its slip direction: a slipping contact slides if its sliding
        normal force is > 0; one at rest of the slip rolls if rolling is consistent
        (``f > 0``, ``|F_t| <= mu f``), else slides where the sliding equations take it if
        that is consistent; a contact that can do neither separates if its free normal
        acceleration is >= 0. Otherwise there is no consistent mode: a named error."""
        vt = self.slip_velocity(y)
        f, ft = y["rolling_normal_force"], y["rolling_tangential_force"]
        if np.linalg.norm(vt) > SLIP_SPEED:
            return self._slide_or_leave(t, x, y, vt / np.linalg.norm(vt))
        if f > 0 and (ft < self.mu * f or self.mu == math.inf):
            return ROLLING, None
        if f > 0:
            return self._slide_or_leave(t, x, y, self.slip_direction(x, y))
        return self._slide_or_leave(t, x, y, None)

    def _slide_or_leave(self, t, x, y, d):
        if d is not None:
            ys = self.outputs(x, self.params(SLIDING, d))
            if not ys["painleve"] > 0:
                _painleve(self.model, t, x, ys, self.mu)
            if ys["normal_force"] > 0:
                return SLIDING, d
        if self.free_normal_acceleration(y) >= 0:
            return SEPARATED, None
        raise ContactModeError(t, x, "no contact mode is consistent: rolling needs f = "
                               f"{y['rolling_normal_force']:.6g} N <= 0 or more friction than mu = "
                               f"{self.mu:g}, sliding a normal force <= 0, and the free bodies would "
                               "accelerate into each other; the rigid model has no answer here",
                               self.model.state_names)

    def witnesses(self, mode: int, slip):
        """``(name, function of the outputs)`` of the events of ``mode``, elementwise (one
        state's outputs or every sample's) (``slip``: the slide's direction parameter: the
        stop is where ``v_t . slip`` reaches 0)."""
        if mode == ROLLING:
            lift = [("normal_force", lambda y: y["normal_force"])]
            if self.mu == math.inf:  # no friction limit: no cone to leave
                return lift
            return [("cone", lambda y: self.mu * y["normal_force"] - y["tangential_force"]), *lift]
        if mode == SLIDING:
            return [("normal_force", lambda y: y["normal_force"]),
                    ("slip", self.slip_witness(np.asarray(slip, dtype=float))),
                    ("painleve", lambda y: y["painleve"])]
        return [("gap", lambda y: y["gap"])]


class _BodyRun(_Run):
    """A body on a plane (``model.body``): the contact's quantities in the world frame."""

    def __init__(self, model, s, mu: float, e: float):
        super().__init__(model, s, mu, e)
        self.i_slip = model.p_names.index("slip_x")
        info = model.manifest["body"]
        self.m = float(info["mass"])
        self.H = np.array(info["inertia"], dtype=float)
        self.Hinv = np.linalg.inv(self.H)
        self.n = np.array(info["plane_normal"], dtype=float)
        self.gain = float(info["gain"])

    def contact(self, y: dict) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """From one state's outputs: the contact's inverse effective mass ``K`` (1/kg), its
        velocity relative to the plane ``v_c``, its point from the centre ``r_c`` (world) and
        the rolling solution's force ``F_roll``."""
        K = np.array([[y[f"K_{i}{j}"] for j in range(3)] for i in range(3)])
        vc = np.array([y[f"vc_{c}"] for c in "xyz"])
        rc = np.array([y[f"rc_{c}"] for c in "xyz"])
        F_roll = y["rolling_normal_force"] * self.n + np.array([y[f"rolling_Ft_{c}"] for c in "xyz"])
        return K, vc, rc, F_roll

    def slip_velocity(self, y: dict) -> np.ndarray:
        return np.array([y[f"vt_{c}"] for c in "xyz"])

    def slip_witness(self, d: np.ndarray):
        return lambda y: d[0] * y["vt_x"] + d[1] * y["vt_y"] + d[2] * y["vt_z"]

    def apart(self, x: np.ndarray) -> np.ndarray:
        """A body apart from the plane: its support point is the model's to keep."""
        return np.asarray(x, dtype=float)

    # ------------------------------------------------------------------ what a mode is
    def slip_direction(self, x: np.ndarray, y: dict) -> np.ndarray:
        """The direction a slide starts in from rest of the slip (module docstring)."""
        n = self.n
        K, _, _, F_roll = self.contact(y)
        ft = F_roll - np.dot(F_roll, n) * n
        d = -ft / np.linalg.norm(ft) if np.linalg.norm(ft) > 0 else np.cross(n, [1.0, 0.0, 0.0])
        target = np.zeros(3)  # at v_c = 0 and gap = 0 the rolling acceleration is 0
        for _ in range(50):
            dirn = n - self.mu * d
            f = np.dot(n, K @ F_roll) / np.dot(n, K @ dirn)
            a = K @ (f * dirn - F_roll) + target
            a_t = a - np.dot(a, n) * n
            if not np.linalg.norm(a_t) > 1e-12 * max(np.linalg.norm(a), 1.0):
                break  # on the cone's edge: no slip acceleration, keep the direction
            nd = a_t / np.linalg.norm(a_t)
            if np.linalg.norm(nd - d) < 1e-15:
                break
            d = nd
        return d

    def free_normal_acceleration(self, y: dict) -> float:
        """The contact's normal acceleration with no contact force (m/s^2)."""
        n = self.n
        K, vc, _, F_roll = self.contact(y)
        target = -2 * self.gain * vc - self.gain**2 * y["gap"] * n
        return float(np.dot(n, target - K @ F_roll))

    # ------------------------------------------------------------------ the maps at a switch
    def _apply(self, x: np.ndarray, P: np.ndarray, rc: np.ndarray) -> np.ndarray:
        """``x`` after the impulse ``P`` (N s, world) at the contact point ``rc`` (world,
        from the centre)."""
        x = x.copy()
        q = x[3:7]
        R = rotation(q)
        x[7:10] += P / self.m
        x[10:13] += self.Hinv @ np.cross(R.T @ rc, R.T @ P)
        return x

    def stop_slip(self, x: np.ndarray, y: dict) -> tuple[np.ndarray, float]:
        """The contact velocity set to 0 (the impulse that does it); the largest change."""
        K, vc, rc, _ = self.contact(y)
        P = np.linalg.solve(K, -vc)
        return self._apply(x, P, rc), float(np.max(np.abs(vc)))

    def impact(self, t: float, x: np.ndarray, y: dict) -> tuple[np.ndarray, float, bool, bool]:
        """Newton's restitution and Coulomb friction on the impulse (module docstring):
        ``(x after, largest speed change, stuck, bounced)``: a bounce when ``e > 0`` and the
        approach is faster than ``REST_SPEED``."""
        n, mu = self.n, self.mu
        K, vc, rc, _ = self.contact(y)
        vn = float(np.dot(n, vc))
        e = self.e if -vn > REST_SPEED else 0.0
        target = -e * vn * n
        P = np.linalg.solve(K, target - vc)
        Pn = float(np.dot(P, n))
        Pt = P - Pn * n
        vt = vc - vn * n
        stuck = bool(np.linalg.norm(Pt) <= mu * Pn)
        if not stuck:  # on the cone's edge, against the slip
            if np.linalg.norm(vt) > SLIP_SPEED:
                d = vt / np.linalg.norm(vt)
            else:  # no incoming slip: the slip the frictionless impulse would make
                after0 = vc + K @ n * (-(1 + e) * vn / float(n @ K @ n))
                a_t = after0 - np.dot(after0, n) * n
                d = a_t / np.linalg.norm(a_t) if np.linalg.norm(a_t) > 0 else -Pt / np.linalg.norm(Pt)
            denominator = float(np.dot(n, K @ (n - mu * d)))
            if not denominator > 0:
                raise PainleveError(t, x, f"an impact with mu = {mu:g} has no consistent impulse: "
                                    f"n . K (n - mu d) = {denominator:.6g} 1/kg <= 0 (Painleve's "
                                    "paradox at an impact); the rigid model has no answer here",
                                    self.model.state_names)
            Pn = -(1 + e) * vn / denominator
            P = Pn * (n - mu * d)
        after = self._apply(x, P, rc)
        return after, float(np.max(np.abs(K @ P))), bool(stuck), e > 0


class _PlanarRun(_Run):
    """A planar finger (``model.planar_modes``): the contact's quantities in its own frame,
    the normal row ``gQ`` (``gQ . v``: the rate of ``Q``, minus the gap's) and the tangent row
    ``gR`` (``v_t = gR . v``), ``W = [gQ; gR] M^-1 [gQ; gR]^T`` (``docs/conventions.md``
    section 8). A contact impulse ``(P_n, P_t)`` changes the speeds by
    ``-M^-1 (P_n gQ + P_t gR)``."""

    def __init__(self, model, s, mu: float, e: float):
        super().__init__(model, s, mu, e)
        self.i_slip = model.p_names.index("slip")
        self.n_speeds = 3

    def slip_velocity(self, y: dict) -> np.ndarray:
        return np.array([y["vt"]])

    def apart(self, x: np.ndarray) -> np.ndarray:
        """``x`` with its contact parameters on the contours' common normal (``R = 0`` and
        ``delta = 0``, Newton's method on ``(u0, u1)``): a start apart need not give them."""
        x = np.array(x, dtype=float)
        p = self.params(SEPARATED)

        def G(u):
            y = self.outputs(np.concatenate([x[:6], u]), p)
            return np.array([y["R"], y["tangency_defect"]])

        u = x[6:8].copy()
        for _ in range(50):
            g = G(u)
            if np.max(np.abs(g)) < 1e-14:
                break
            h = 1e-7 * np.maximum(1.0, np.abs(u))
            J = np.column_stack([(G(u + h[k] * np.eye(2)[k]) - g) / h[k] for k in range(2)])
            u = u - np.linalg.solve(J, g)
        if not np.max(np.abs(G(u))) < 1e-12:
            raise RunArgumentError(f"x0 is apart, but no pair of points on a common normal was found "
                                   f"near u0, u1 = {tuple(x[6:8])} (R, delta = {tuple(G(u))}): give "
                                   "u0, u1 near the closest points of the contours")
        x[6:8] = u
        return x

    def slip_witness(self, d: np.ndarray):
        return lambda y: d[0] * y["vt"]

    def slip_direction(self, x: np.ndarray, y: dict) -> np.ndarray:
        """A slide from rest of the slip starts along the rolling solution's tangential force
        (the friction it needs and the cone cannot give)."""
        return np.array([1.0 if y["rolling_lam"] >= 0 else -1.0])

    def free_normal_acceleration(self, y: dict) -> float:
        return float(y["free_normal_acceleration"])

    def _W(self, y: dict) -> np.ndarray:
        return np.array([[y["W_nn"], y["W_nt"]], [y["W_nt"], y["W_tt"]]])

    def _apply(self, x: np.ndarray, y: dict, P: np.ndarray) -> np.ndarray:
        x = x.copy()
        x[3:6] -= P[0] * np.array([y[f"Minv_gQ_{i}"] for i in range(3)]) \
            + P[1] * np.array([y[f"Minv_gR_{i}"] for i in range(3)])
        return x

    def _sliding_impulse(self, t, x, W, vn: float, vt: float, e: float, s0: float) -> np.ndarray:
        """The impulse on the cone's edge, ``P_t = mu s P_n``, whose slip after the impact
        ``v_t+`` has the sign ``s`` (friction opposes the slip it leaves; Moreau's law), tried
        along the stick impulse's sign ``s0`` first."""
        mu = self.mu
        for s in (s0, -s0):
            denominator = float(W[0, 0] + mu * s * W[0, 1])
            if not denominator > 0:
                continue
            Pn = (1 + e) * vn / denominator
            vt_after = vt - Pn * (W[1, 0] + mu * s * W[1, 1])
            if Pn >= 0 and vt_after * s >= 0:
                return np.array([Pn, mu * s * Pn])
        raise PainleveError(t, x, f"an impact with mu = {mu:g} has no consistent impulse: no impulse "
                            "on the cone's edge leaves a slip it opposes with a positive normal "
                            "row's coefficient (Painleve's paradox at an impact); the rigid model "
                            "has no answer here", self.model.state_names)

    def stop_slip(self, x: np.ndarray, y: dict) -> tuple[np.ndarray, float]:
        """The contact's normal and slip speeds set to 0 (the impulse that does it)."""
        Jv = np.array([y["vn_fixed"], y["vt"]])
        return self._apply(x, y, np.linalg.solve(self._W(y), Jv)), float(np.max(np.abs(Jv)))

    def impact(self, t: float, x: np.ndarray, y: dict) -> tuple[np.ndarray, float, bool, bool]:
        """Newton's restitution and Coulomb friction on the impulse (``_BodyRun.impact``, in
        the contact's frame); the kinetic energy must not grow (a named error otherwise)."""
        mu, W = self.mu, self._W(y)
        vn, vt = float(y["vn_fixed"]), float(y["vt"])
        e = self.e if vn > REST_SPEED else 0.0
        P = np.linalg.solve(W, np.array([(1 + e) * vn, vt]))
        stuck = bool(abs(P[1]) <= mu * P[0])
        if not stuck:  # on the cone's edge, against the slip after the impact (Moreau)
            P = self._sliding_impulse(t, x, W, vn, vt, e, math.copysign(1.0, P[1]))
        after = self._apply(x, y, P)
        before_k = float(y["kinetic_energy"])
        after_k = float(self.outputs(after, self.params(ROLLING))["kinetic_energy"])
        if after_k > before_k * (1 + 1e-9) + 1e-15:
            raise ContactModeError(t, x, f"the impact with mu = {mu:g}, e = {e:g} would raise the kinetic "
                                   f"energy from {before_k:.9g} J to {after_k:.9g} J (Newton's "
                                   "restitution with friction can when e > 0); the rigid model has no "
                                   "answer here: give e = 0", self.model.state_names)
        return after, float(np.max(np.abs(W @ P))), stuck, e > 0


#: the kind of a model with modes (its manifest's ``kind``) -> how its contact is run
_RUNS = {"body": _BodyRun, "planar_modes": _PlanarRun}


def refuse_unused(*, params, u, slip) -> None:
    """Refuse by name what a run with modes does not read (it would be ignored silently)."""
    given = [k for k, v in (("params", params), ("u", u)) if v is not None]
    if slip != "stop":
        given.append("slip")
    if given:
        raise RunArgumentError(f"{', '.join(given)} given, but a model with contact modes takes none: "
                               "its mode and slip direction are its own, its friction is mu= and e= "
                               "(or the scene's law), and it has no inputs")


def rotation(q: np.ndarray) -> np.ndarray:
    """The rotation of a (not necessarily unit) quaternion ``(w, x, y, z)``, in the homogeneous
    form the compiled model uses (``derive.bodies3d.object_rotation``)."""
    w, v = q[0], q[1:4]
    s = float(np.dot(q, q))
    return ((w * w - v @ v) * np.eye(3) + 2 * np.outer(v, v) + 2 * w * np.array(
        [[0, -v[2], v[1]], [v[2], 0, -v[0]], [-v[1], v[0], 0]])) / s


def run(model, s, x0: np.ndarray, mu_arg=None, e_arg=None) -> SimulationResult:
    """``Model.simulate`` of a model with modes (module docstring)."""
    start = perf_counter()
    if s.method not in METHODS:
        raise RunArgumentError(f"method {s.method!r}: a model with contact modes runs one of {METHODS} "
                               "(the loops in C, with which its switches are located by integrating "
                               "again)")
    mu, e = friction_law(model, mu_arg, e_arg)
    r = _RUNS[model.manifest.get("kind", "body")](model, s, mu, e)
    t_eval = s.t_eval
    y = r.outputs(x0, r.params(ROLLING))
    if y["gap"] > CONTACT_GAP:
        x0 = r.apart(x0)
        y = r.outputs(x0, r.params(ROLLING))
    if abs(y["gap"]) <= CONTACT_GAP and y["normal_speed"] > STOP_SPEED:  # leaving at once
        mode, slip = SEPARATED, None
    elif abs(y["gap"]) <= CONTACT_GAP and y["normal_speed"] < -STOP_SPEED:  # an impact at once
        mode, slip, x0, reset = _switch(r, SEPARATED, "gap", 0.0, np.asarray(x0, dtype=float))
        r.events.append({"t": 0.0, "contact": 1, "from": NAMES[SEPARATED], "to": NAMES[mode],
                         "witness": "gap", "value": float(y["gap"]), "reset": reset})
    elif abs(y["gap"]) <= CONTACT_GAP:
        mode, slip = r.contact_start(0.0, x0, y)
    elif y["gap"] > 0:
        mode, slip = SEPARATED, None
    else:
        raise RunArgumentError(f"x0 penetrates the contact: gap = {y['gap']:.6g} m < 0; start in "
                               "contact (a body: start='contact'; a finger: the scene's start) or apart")
    rows_t, rows_x, rows_mode, rows_p = [], [], [], []
    t_now, x_now = 0.0, np.asarray(x0, dtype=float)
    last_t = -math.inf
    recent: list[float] = []
    while True:
        p = r.params(mode, slip)
        if mode == SLIDING and r.outputs(x_now, p)["painleve"] <= 0:
            _painleve(model, t_now, x_now, r.outputs(x_now, p), mu)
        grid = np.concatenate([[t_now], t_eval[t_eval > t_now + 1e-15]])
        if len(grid) < 2:
            break
        try:
            t, X, st = integrators.c_loop(model, s.method, x_now, grid, p, rtol=s.rtol, atol=s.atol,
                                          max_steps=s.max_steps, h=s.h, time_limit=s.time_limit)
        except IntegratorError as exc:  # named as simulate names it (a contact off its chart)
            raise failures.classify(model, exc) from None
        r.stats["n_steps"] += int(st.get("n_steps", 0))
        r.stats["n_rhs"] += int(st.get("n_rhs", 0))
        r.stats["segments"] += 1
        Y = outputs_.at_rows(model, X, p)
        t_look = perf_counter()
        found = _first_event(r, mode, slip, t, X, Y, p)
        keep = len(t) if found is None else found[0]
        on_grid = np.isin(t[:keep], t_eval) & (t[:keep] > last_t)
        rows_t.append(t[:keep][on_grid])
        rows_x.append(X[:keep][on_grid])
        rows_mode.append(np.full(int(on_grid.sum()), mode))
        rows_p.append(np.tile(p, (int(on_grid.sum()), 1)))
        if on_grid.any():
            last_t = float(t[:keep][on_grid][-1])
        if found is None:
            break
        _, t_ev, x_ev, name, value = found
        recent = [tt for tt in recent if tt > t_ev - SWITCH_WINDOW] + [t_ev]
        if len(recent) > MAX_SWITCHES:
            raise ChatteringError(t_ev, x_ev, f"{len(recent)} switches of contact modes within "
                                  f"{SWITCH_WINDOW:g} s up to t = {t_ev:.9g} s (a Zeno run): the "
                                  "contact chatters; give a plastic impact (e = 0) or a larger "
                                  "friction coefficient", model.state_names)
        mode_before = mode
        mode, slip, x_now, reset = _switch(r, mode, name, t_ev, x_ev)
        r.stats["switch_time"] += perf_counter() - t_look
        if reset is not None:  # None: a slide re-aimed, no switch
            r.events.append({"t": t_ev, "contact": 1, "from": NAMES[mode_before], "to": NAMES[mode],
                             "witness": name, "value": value, "reset": reset})
        t_now = t_ev
    t_all = np.concatenate(rows_t)
    X_all = np.concatenate(rows_x)
    modes_all = np.concatenate(rows_mode)
    outs = {}
    if s.outputs:
        P_all = np.concatenate(rows_p)
        Y = np.array([outputs_.row(model, x, pp) for x, pp in zip(X_all, P_all)]) if len(X_all) \
            else np.zeros((0, len(model.columns)))
        outs = {k: Y[:, i].copy() for i, k in enumerate(model.columns) if k in model.output_names}
    if s.drop_first and len(t_all) and t_all[0] == 0.0:
        t_all, X_all, modes_all = t_all[1:], X_all[1:], modes_all[1:]
        outs = {k: v[1:] for k, v in outs.items()}
    stats = {**r.stats, "n_events": len(r.events), "wall_time": perf_counter() - start}
    pdict = {"mu": mu, "e": e}
    return SimulationResult(t=t_all, x=X_all, state_names=model.state_names, outputs=outs,
                            method=s.method, stats=stats, params=pdict, scene=model.scene,
                            events=r.events, modes=np.array([NAMES[m] for m in modes_all]))


def _first_event(r: _Run, mode: int, slip, t, X, Y, p):
    """``(samples to keep, t, x, witness, value)`` of the first event along the segment's
    samples, located; None if none."""
    cols = {k: i for i, k in enumerate(r.model.columns)}
    values = {k: Y[k] for k in r.model.columns}
    if mode == SEPARATED:
        gap = values["gap"]
        bad = np.flatnonzero(~(gap > 0) & (values["normal_speed"] < 0))
        bad = bad[bad > 0]
        cands = [("gap", int(bad[0]))] if bad.size else []
    else:  # the witnesses on every sample at once (they are elementwise in the outputs)
        cands = []
        for name, w in r.witnesses(mode, slip):
            W = np.asarray(w(values), dtype=float)
            cross = np.flatnonzero((W[:-1] > 0) & ~(W[1:] > 0))
            if cross.size:
                cands.append((name, int(cross[0]) + 1))
    if not cands:
        return None
    i = min(k for _, k in cands)
    y0 = {k: float(values[k][i - 1]) for k in cols}
    t0, x0 = float(t[i - 1]), X[i - 1]
    if mode == SEPARATED and not y0["gap"] > CONTACT_GAP:  # just left the contact: from the apex
        apex = events.locate(r.model, r.s, None, p, t0, x0, float(t[i]), lambda y: y["normal_speed"]) \
            if y0["normal_speed"] > 0 else None
        if apex is None or not r.outputs(apex[1], p)["gap"] > 0:
            raise EventLocationError(float(t[i]), X[i], f"the contact left at {t0:.9g} s returns before "
                                     f"{t[i]:.9g} s, but no time apart is found between: give a denser "
                                     "t_eval or tighter tolerances", r.model.state_names)
        t0, x0 = apex
    best = None
    for name, w in r.witnesses(mode, slip):
        if mode != SEPARATED and not (w(y0) > 0 and not w({k: float(values[k][i]) for k in cols}) > 0):
            continue
        found = events.locate(r.model, r.s, None, p, t0, x0, float(t[i]), w)
        if found is None:
            raise EventLocationError(float(t[i]), X[i], f"the {name} witness changes sign between the "
                                     f"outputs at {t[i - 1]:.9g} and {t[i]:.9g} s, but integrating "
                                     "again does not find where: give a denser t_eval or tighter "
                                     "tolerances", r.model.state_names)
        tc, xc = found
        if best is None or tc < best[1]:
            best = (i, tc, xc, name, float(w(r.outputs(xc, p))))
    return best


def _switch(r: _Run, mode: int, name: str, t: float, x: np.ndarray):
    """``(new mode, slip direction, state after, reset)`` at an event of ``mode``."""
    if name == "painleve":
        _painleve(r.model, t, x, r.outputs(x, r.params(SLIDING)), r.mu)
    if name == "normal_force":
        return SEPARATED, None, x, 0.0
    if name == "cone":
        y = r.outputs(x, r.params(ROLLING))
        return SLIDING, r.slip_direction(x, y), x, 0.0
    if name == "slip":
        y = r.outputs(x, r.params(ROLLING))
        vt = r.slip_velocity(y)
        if np.linalg.norm(vt) > STOP_SPEED:  # the slip turned past 90 degrees, it did not stop
            return SLIDING, vt / np.linalg.norm(vt), x, None
        x2, reset = r.stop_slip(x, y)
        y2 = r.outputs(x2, r.params(ROLLING))
        new, slip = r.contact_start(t, x2, y2)
        return new, slip, x2, reset
    # an impact
    y = r.outputs(x, r.params(ROLLING))
    x2, reset, _, bounced = r.impact(t, x, y)
    y2 = r.outputs(x2, r.params(ROLLING))
    if bounced:  # restitution: it leaves the plane again
        return SEPARATED, None, x2, reset
    new, slip = r.contact_start(t, x2, y2)
    return new, slip, x2, reset


def _painleve(model, t, x, y, mu):
    raise PainleveError(t, x, f"sliding with mu = {mu:g} has no consistent normal force (or several): "
                        f"the normal row's coefficient n . K (n - mu d) = {y['painleve']:.6g} 1/kg <= 0 "
                        "(Painleve's paradox); the rigid model has no answer here: lower mu, or "
                        "model the contact's compliance", model.state_names)


def run_many(model, s, X0: np.ndarray, mu, e) -> dict:
    """``simulate_many`` of a model with modes: each run by ``run`` in turn (``mu``, ``e``:
    None, one value, or one per run); a run that stops by name is recorded, the others go on.
    Returns the pieces of a ``runtime.batch.BatchResult``."""
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
    for i in range(n):
        try:
            res = run(model, s, X0[i], mus[i], es[i])
        except (GraspingSymError, ValueError) as exc:
            status[i] = -11 if isinstance(exc, ContactModeError) else \
                -2 if isinstance(exc, ContactLeftContourError) else \
                -10 if isinstance(exc, ValueError) else -3
            errors[i] = f"{type(exc).__name__}: {exc}"
            continue
        x_final[i] = res.x[-1]
        X[i] = res.x
        for k in outs:
            outs[k][i] = res.outputs[k]
        events[i] = res.events
    return {"x_final": x_final, "x": X if dense else None, "status": status, "errors": errors,
            "outputs": outs if dense else {k: v[:, -1] for k, v in outs.items()},
            "params": {"mu": np.array([friction_law(model, mu_i, e_i)[0] for mu_i, e_i in zip(mus, es)]),
                       "e": np.array([friction_law(model, mu_i, e_i)[1] for mu_i, e_i in zip(mus, es)])},
            "events": events}


def _per_run(name: str, value, n: int) -> list:
    """None or one value for every run, or an array of ``n``: one per run."""
    if value is None or isinstance(value, Coulomb) or np.ndim(value) == 0:
        return [value] * n
    arr = np.asarray(value)
    if arr.shape != (n,):
        raise RunArgumentError(f"{name} has shape {arr.shape}: give one value, or one per run ({n},)")
    return [float(v) for v in arr]
