"""Contact laws as data: what a scene says about friction at its contacts (``gs.contact``).

>>> scene = gs.scenes.paper2d(friction=gs.contact.coulomb(mu=0.3))

``Coulomb(mu, e)``: Coulomb's friction coefficient, one for every contact or one per contact
(in the scene's contact order), and Newton's coefficient of restitution ``e`` for impacts.
The model reads it at run time (``Model.simulate(mu=...)`` overrides it run by run, and
``simulate_many`` takes one per run), so changing it never rebuilds anything. The
conventions are in ``docs/conventions.md`` ("Friction"): the normal force ``f`` and the
tangential force ``F_t`` are the contact multipliers of the rolling model; the contact stays
inside the cone while ``|F_t| <= mu f``.

This module sits on the ground floor with ``errors`` and ``names``: the scenes (``model``)
hold a law and the runtime reads it, and neither may import the other.
"""
from __future__ import annotations

import math
import numbers
from dataclasses import dataclass

from grasping_sym.errors import InvalidSceneError

__all__ = ["Coulomb", "coulomb", "friction_problems"]


def _number(v) -> bool:
    return isinstance(v, numbers.Real) and not isinstance(v, bool)


@dataclass(frozen=True)
class Coulomb:
    """Coulomb friction (and Newton restitution) at a scene's contacts.

    Attributes
    ----------
    mu
        Friction coefficient (>= 0; ``math.inf``: the contact never slips): one number for
        every contact, or a tuple with one per contact.
    e
        Newton's coefficient of restitution at an impact, in [0, 1] (0: plastic, the default).
    """

    mu: float | tuple[float, ...]
    e: float = 0.0

    def __post_init__(self):
        problems = []
        mus = self.mu if isinstance(self.mu, tuple) else (self.mu,)
        if isinstance(self.mu, list):
            problems.append("mu is a list: give one number, or a tuple with one per contact")
        elif not mus:
            problems.append("mu is an empty tuple: give one number, or one per contact")
        for k, m in enumerate(mus):
            if not (_number(m) and (math.isfinite(m) or m == math.inf) and m >= 0):
                where = f"mu[{k}]" if isinstance(self.mu, tuple) else "mu"
                problems.append(f"{where} = {m!r} must be a number >= 0 (math.inf: no slip ever)")
        if not (_number(self.e) and 0 <= self.e <= 1):
            problems.append(f"e = {self.e!r} must be a number in [0, 1] (Newton's restitution; 0: "
                            "plastic impact)")
        if problems:
            raise InvalidSceneError(problems)

    def per_contact(self, n: int) -> tuple[float, ...]:
        """``mu`` for each of ``n`` contacts; a tuple of another length is refused by name."""
        if not isinstance(self.mu, tuple):
            return (float(self.mu),) * n
        if len(self.mu) != n:
            raise InvalidSceneError([f"mu has {len(self.mu)} entries for {n} contact(s): give one "
                                     "number for all, or one per contact"])
        return tuple(float(m) for m in self.mu)


def coulomb(mu: float | tuple[float, ...], e: float = 0.0) -> Coulomb:
    """Coulomb friction with coefficient ``mu`` (one, or one per contact) and restitution ``e``."""
    if isinstance(mu, list):
        mu = tuple(mu)
    return Coulomb(mu=mu, e=e)


def friction_problems(friction, n_contacts: int) -> list[str]:
    """A scene's ``friction`` checked: None or a ``Coulomb`` with one ``mu`` or one per contact."""
    if friction is None:
        return []
    if not isinstance(friction, Coulomb):
        return [f"friction = {friction!r:.60} is {type(friction).__name__}: give "
                "gs.contact.coulomb(mu) or None (no friction limit)"]
    if isinstance(friction.mu, tuple) and len(friction.mu) != n_contacts:
        return [f"friction.mu has {len(friction.mu)} entries for {n_contacts} contact(s): give one "
                "number for all, or one per contact"]
    return []
