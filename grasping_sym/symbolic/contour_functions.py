"""Abstract contour functions whose derivatives follow the Frenet-Serret equations.

The derivation is written for a contour ``c(u)`` of unknown shape through the functions

    X(u), Y(u)          the point (m)
    Tx(u), Ty(u)        the unit tangent
    speed(u)            |c'(u)| (m per unit parameter)
    kappa(u)            signed curvature (x'y'' - x''y')/|c'|^3, 1/m
    dspeed(u), dkappa(u)  their derivatives in u

with ``X' = speed Tx``, ``Y' = speed Ty``, ``T' = speed kappa (-Ty, Tx)``. SymPy's chain rule
then keeps every derivative compact and independent of the shape; the concrete contour is
substituted only when the expressions are translated (``leaf_expressions``). Derivatives of
``dspeed`` and ``dkappa`` are never needed by the 2D model and are refused.
"""
from __future__ import annotations

from dataclasses import dataclass

import sympy as sp

from grasping_sym.geometry.curves import PlanarCurve, T


@dataclass(frozen=True)
class ContourFunctions:
    """The function classes of one contour (``tag`` distinguishes fingertip and object)."""

    tag: str
    X: type
    Y: type
    Tx: type
    Ty: type
    speed: type
    kappa: type
    dspeed: type
    dkappa: type

    def leaves(self) -> tuple[type, ...]:
        return (self.X, self.Y, self.Tx, self.Ty, self.speed, self.kappa, self.dspeed,
                self.dkappa)


class _NoDerivative(sp.Function):
    nargs = 1

    def fdiff(self, argindex=1):
        raise NotImplementedError(
            f"{type(self).__name__}' is not provided: the derivation asked for a derivative "
            "of a contour quantity beyond what contour_functions supplies"
        )


def make_contour_functions(tag: str) -> ContourFunctions:
    """Create the function classes ``X{tag}``, ``Tx{tag}``, ... with Frenet derivatives."""
    fns: dict[str, type] = {}

    def cls(name: str, deriv):
        def fdiff(self, argindex=1):
            return deriv(self.args[0])
        return type(f"{name}{tag}", (sp.Function,), {"nargs": 1, "fdiff": fdiff})

    fns["dspeed"] = type(f"dspeed{tag}", (_NoDerivative,), {})
    fns["dkappa"] = type(f"dkappa{tag}", (_NoDerivative,), {})
    fns["speed"] = cls("speed", lambda u: fns["dspeed"](u))
    fns["kappa"] = cls("kappa", lambda u: fns["dkappa"](u))
    fns["Tx"] = cls("Tx", lambda u: -fns["speed"](u) * fns["kappa"](u) * fns["Ty"](u))
    fns["Ty"] = cls("Ty", lambda u: fns["speed"](u) * fns["kappa"](u) * fns["Tx"](u))
    fns["X"] = cls("X", lambda u: fns["speed"](u) * fns["Tx"](u))
    fns["Y"] = cls("Y", lambda u: fns["speed"](u) * fns["Ty"](u))
    return ContourFunctions(tag=tag, **fns)


def leaf_expressions(fns: ContourFunctions, curve: PlanarCurve) -> dict[type, sp.Expr]:
    """The concrete SymPy expression in ``T`` of each abstract function for ``curve``."""
    speed = curve.speed
    kappa = curve.curvature
    return {
        fns.X: curve.x, fns.Y: curve.y, fns.Tx: curve.tangent[0], fns.Ty: curve.tangent[1],
        fns.speed: speed, fns.kappa: kappa,
        fns.dspeed: sp.diff(speed, T), fns.dkappa: sp.diff(kappa, T),
    }


FINGERTIP = make_contour_functions("0")
OBJECT = make_contour_functions("1")
_EXTRA_FINGERTIPS: dict[int, ContourFunctions] = {}


def fingertip_functions(i: int) -> ContourFunctions:
    """The abstract functions of finger ``i``'s fingertip (``i = 1``: :data:`FINGERTIP`).

    Each finger of a multi-finger scene has its own contour, hence its own functions; the
    object's are :data:`OBJECT` for every contact, applied at each contact's parameter.
    """
    if i == 1:
        return FINGERTIP
    if i not in _EXTRA_FINGERTIPS:
        _EXTRA_FINGERTIPS[i] = make_contour_functions(f"0_{i}")
    return _EXTRA_FINGERTIPS[i]
