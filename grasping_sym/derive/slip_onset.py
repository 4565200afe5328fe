"""The onset of a slide from rest of the slip (``docs/conventions.md`` section 7), as CasADi
SX: the sliding direction of a contact whose slip starts from the integration's noise.

A slide from rest (at the cone's edge, at a run's start, after a stop) starts with the slip
velocity ``v_t`` at the integration's noise, at any angle; where the rolling force reaches
the cone's edge its speed grows as the square of the time (the slip's acceleration along the
rolling force's direction is 0 there). Coulomb's direction
``v_t/|v_t|`` of that noise jumps from step to step by up to 90 degrees, and a direction held
at ``slip`` until the slip is faster than the noise leaves the slip to grow against ``slip``
where the contact's inverse effective mass is anisotropic (a 3D grasp's fingers chattered).
During the onset (its scale ``s > 0``, a few times that noise; ``runtime.modes``) the
direction is that of ``v_t + ONSET_LEAD s^4 / (|v_t| + s)^3 slip``: continuous in ``v_t``,
``slip`` at ``v_t = 0``, within ``ONSET_LEAD (s/|v_t|)^4`` rad of ``v_t/|v_t|`` beyond, so
that friction turns with the slip as it grows (the consistent solution: the direction turns
at a finite rate from ``slip``). The onset ends where ``onset_left`` reaches 0.
"""
from __future__ import annotations

import casadi as ca

#: The lead toward ``slip``: with 16 it vanishes only where ``v_t`` points against ``slip`` at
#: ~1.3 ``s``, beyond the slip witness's ``-s``, at which a slip that turned back ends the
#: onset first.
ONSET_LEAD = 16.0
#: The onset ends where ``v_t . slip`` reaches this many times ``s``: the direction there is
#: within 1.6e-11 rad of ``v_t/|v_t|``.
ONSET_RELEASE = 1e3
#: Floor (m/s) of the length divided by.
FLOOR = 1e-300


#: ``|v_t|`` in the lead is ``sqrt(v_t . v_t + (SMOOTH s)^2)``: differentiable at ``v_t = 0``
#: (a slide from rest starts there exactly; the generated Jacobian of ``|v_t|`` is 0/0 there).
SMOOTH = 1e-3


def direction(vt: ca.SX, slip: ca.SX, s: ca.SX, otherwise: ca.SX) -> ca.SX:
    """The sliding direction: the onset's where ``s > 0``, else ``otherwise``."""
    speed = ca.sqrt(ca.dot(vt, vt) + (SMOOTH * s) ** 2)
    lead = vt + ONSET_LEAD * s**4 / (speed + s) ** 3 * slip
    return ca.if_else(s > 0, lead / ca.fmax(ca.norm_2(lead), FLOOR), otherwise)


def left(vt: ca.SX, slip: ca.SX, s: ca.SX) -> ca.SX:
    """``ONSET_RELEASE s - v_t . slip``: the onset's witness (0 where it ends)."""
    return ONSET_RELEASE * s - ca.dot(vt, slip)
