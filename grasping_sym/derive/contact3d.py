"""Kinematics of rolling and sliding contact between two smooth surfaces (Montana 1988).

D. J. Montana, "The kinematics of contact and grasp", Int. J. Robotics Research 7(3), 1988.
This is the formulation regular at rest of docs/conventions.md section 2: the contact is described by
surface coordinates on both bodies and the angle between the two tangent frames, and their
rates are linear in the relative velocity, so they are zero (not 0/0) when the contact stops.

Bodies, frames and coordinates
------------------------------
* The *finger* surface ``S_f`` and the *object* surface ``S_o`` are
  :class:`~grasping_sym.geometry.surfaces.ParametricSurface` patches in their bodies' local
  frames, each with its outward normal (the normal points out of the body's material).
* Contact coordinates ``eta = (u_f, v_f, u_o, v_o, psi)`` (:data:`CONTACT_COORDS`): the
  contact point is ``S_f(u_f, v_f)`` on the finger and ``S_o(u_o, v_o)`` on the object.
* Contact frames: Montana's chart frames ``C_f = [x_f y_f n_f]`` and ``C_o = [x_o y_o n_o]``
  (:attr:`ParametricSurface.frame`, ``x = S_u/|S_u|``, ``y = n x x``), mapped to the world
  by the bodies' rotations. On the constraint manifold

      p_f = p_o                           (the two contact points coincide)
      n_o = -n_f                          (the normals are opposite)
      x_o =  cos(psi) x_f - sin(psi) y_f
      y_o = -sin(psi) x_f - cos(psi) y_f

  i.e. ``C_o = C_f P(psi)`` with ``P(psi) = [[R_psi, 0], [0, -1]]`` and
  ``R_psi = [[cos psi, -sin psi], [-sin psi, -cos psi]]`` (symmetric, ``R_psi^2 = I``):
  ``psi`` is the angle from ``x_o`` to ``x_f`` measured counterclockwise about ``n_f``.
  At ``psi = 0`` the object's frame is the finger's turned by pi about ``x_f``.
* Relative motion ``(v, w)``: the velocity of the *object's* material point at the contact
  and the angular velocity of the object, both *relative to the finger* and given by their
  components in the finger's contact frame ``(x_f, y_f, n_f)`` (m/s, rad/s). Rolling (no
  slip) is ``v_x = v_y = 0``; no spin is ``w_z = 0``; staying in contact requires ``v_z = 0``.

The contact equations in these conventions (:func:`contact_rates_symbolic`)
---------------------------------------------------------------------------
With ``M``, ``K``, ``T`` Montana's metric, curvature form and torsion form
(``K = I/r`` on a sphere with the outward normal), ``K~_o = R_psi K_o R_psi``, the
relative curvature ``K_rel = K_f + K~_o`` and ``alpha_f = (u_f, v_f)``, ``alpha_o = (u_o, v_o)``:

    M_f alpha_f' = K_rel^-1 ([ w_y, -w_x]^T + K~_o [v_x, v_y]^T)
    M_o alpha_o' = R_psi K_rel^-1 ([ w_y, -w_x]^T - K_f [v_x, v_y]^T)
    psi'         = -w_z + T_f M_f alpha_f' + T_o M_o alpha_o'
    v_z          = 0

These are Montana's equations with ``(v, w)`` replaced by ``(-v, -w)``: the form usually
quoted, ``[-w_y, w_x] - K~_o v``, ``[-w_y, w_x] + K_f v`` and ``psi' = w_z + ...``, holds for
the motion of the *finger relative to the object* (in the finger's contact frame). Derivation,
all in the finger's contact frame with the finger at rest and the object at pose ``(R, p)``:
the tangential part of ``d/dt (S_f = R S_o + p)`` gives ``M_f alpha_f' = v + R_psi M_o alpha_o'``
and its normal part ``v_z = 0``; ``d/dt (n_f = -R n_o)`` gives
``K_f M_f alpha_f' = [w_y, -w_x] - R_psi K_o M_o alpha_o'`` (``w x n_f = (w_y, -w_x, 0)``);
and the rate of the angle of ``R x_o`` about ``n_f`` gives the ``psi'`` line. The tests
(``tests/test_contact3d.py``) check every sign against exact rolling answers and against the
contact constraints along integrated motions.

The equations are singular exactly where ``K_rel`` is (flat on flat, a cylinder on a plane
along its axis, matched concave on convex): a property of the shapes, not of the motion.
The numeric evaluation of these equations, the classification of ``K_rel`` and the
world-frame contact checks are test oracles, in ``tests/oracles/contact3d_numeric.py``.
"""
from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
import sympy as sp

from grasping_sym.geometry.surfaces import ParametricSurface, U, V

#: Names of the contact coordinates, in the order of every state vector here.
CONTACT_COORDS = ("u_f", "v_f", "u_o", "v_o", "psi")


# ====================================================================== symbolic
@dataclass(frozen=True)
class MontanaForms:
    """Montana's quantities of one surface at the contact point (SymPy or NumPy).

    Attributes
    ----------
    M
        2x2 metric (m per unit parameter): ``[x.dS, y.dS]^T = M [du, dv]^T``.
    K
        2x2 symmetric curvature form (1/m), ``+I/r`` on a sphere with the outward normal.
    T
        1x2 torsion form (1/m): ``y . dx = T M [du, dv]^T``.
    """

    M: object
    K: object
    T: object

    @staticmethod
    def of(surface: ParametricSurface, u: sp.Expr, v: sp.Expr) -> MontanaForms:
        """The surface's forms as SymPy matrices in the parameters ``u, v`` (any expressions)."""
        sub = {U: u, V: v}
        return MontanaForms(sp.Matrix(surface.montana_metric.xreplace(sub)),
                            sp.Matrix(surface.curvature_form.xreplace(sub)),
                            sp.Matrix(surface.torsion_form.xreplace(sub)))

    def entries(self) -> list:
        """The independent entries ``[M11, M12, M22, K11, K12, K22, T1, T2]``, the order of :meth:`generic`."""
        M, K, T = self.M, self.K, self.T
        return [M[0, 0], M[0, 1], M[1, 1], K[0, 0], K[0, 1], K[1, 1], T[0, 0], T[0, 1]]

    @staticmethod
    def generic(tag: str) -> MontanaForms:
        """Abstract forms of symbols ``M_{tag}11 ...``: ``M`` upper triangular, ``K`` symmetric."""
        s = {k: sp.Symbol(f"{k}_{tag}", real=True) for k in
             ("M11", "M12", "M22", "K11", "K12", "K22", "T1", "T2")}
        return MontanaForms(sp.Matrix([[s["M11"], s["M12"]], [0, s["M22"]]]),
                            sp.Matrix([[s["K11"], s["K12"]], [s["K12"], s["K22"]]]),
                            sp.Matrix([[s["T1"], s["T2"]]]))


@dataclass(frozen=True)
class ContactRates:
    """Rates of the contact coordinates (SymPy column matrices / expressions).

    ``alpha_f_dot = (u_f', v_f')``, ``alpha_o_dot = (u_o', v_o')`` (unit parameter per s),
    ``psi_dot`` (rad/s), ``relative_curvature`` ``K_f + K~_o`` (1/m) and its ``det``.
    """

    alpha_f_dot: sp.Matrix
    alpha_o_dot: sp.Matrix
    psi_dot: sp.Expr
    relative_curvature: sp.Matrix
    det: sp.Expr

    @property
    def vector(self) -> sp.Matrix:
        """The five rates in the order of :data:`CONTACT_COORDS`."""
        return sp.Matrix([*self.alpha_f_dot, *self.alpha_o_dot, self.psi_dot])


def r_psi(psi):
    """``R_psi = [[cos psi, -sin psi], [-sin psi, -cos psi]]`` (SymPy for a SymPy ``psi``, else NumPy)."""
    if isinstance(psi, sp.Basic):
        c, s = sp.cos(psi), sp.sin(psi)
        return sp.Matrix([[c, -s], [-s, -c]])
    c, s = math.cos(psi), math.sin(psi)
    return np.array([[c, -s], [-s, -c]])


def _inv2(A: sp.Matrix) -> tuple[sp.Matrix, sp.Expr]:
    det = A[0, 0] * A[1, 1] - A[0, 1] * A[1, 0]
    return sp.Matrix([[A[1, 1], -A[0, 1]], [-A[1, 0], A[0, 0]]]) / det, det


def contact_rates_symbolic(forms_f: MontanaForms, forms_o: MontanaForms, psi: sp.Expr,
                           w: Sequence[sp.Expr], v: Sequence[sp.Expr] = (0, 0)) -> ContactRates:
    """Montana's contact equations, SymPy, in this module's conventions (see the module docstring).

    Parameters
    ----------
    forms_f, forms_o
        The finger's and the object's :class:`MontanaForms` at the contact coordinates
        (e.g. ``MontanaForms.of(surface, u_f, v_f)`` or ``MontanaForms.generic('f')``).
    psi
        Angle from ``x_o`` to ``x_f`` about ``n_f`` (rad).
    w
        ``(w_x, w_y, w_z)``: angular velocity of the object relative to the finger, components
        in the finger's contact frame (rad/s).
    v
        ``(v_x, v_y)``: velocity of the object's material point at the contact relative to the
        finger, finger contact frame (m/s); ``(0, 0)`` for rolling. A third component ``v_z`` is
        not used: ``v_z = 0`` is the normal-velocity constraint, enforced by the dynamics.

    Returns
    -------
    ContactRates
        Built with the explicit 2x2 inverses (no ``simplify``); divides by ``det``.
    """
    Rp = r_psi(sp.sympify(psi))
    Kf, Ko = sp.Matrix(forms_f.K), sp.Matrix(forms_o.K)
    Kot = Rp * Ko * Rp
    Krel = Kf + Kot
    Kinv, det = _inv2(Krel)
    wx, wy, wz = (sp.sympify(c) for c in w)
    vt = sp.Matrix([sp.sympify(v[0]), sp.sympify(v[1])])
    rot = sp.Matrix([wy, -wx])
    a = Kinv * (rot + Kot * vt)          # M_f alpha_f'  (finger frame components, m/s)
    b = Rp * Kinv * (rot - Kf * vt)      # M_o alpha_o'  (object frame components, m/s)
    Mf_inv, _ = _inv2(sp.Matrix(forms_f.M))
    Mo_inv, _ = _inv2(sp.Matrix(forms_o.M))
    psi_dot = -wz + (sp.Matrix(forms_f.T) * a)[0] + (sp.Matrix(forms_o.T) * b)[0]
    return ContactRates(Mf_inv * a, Mo_inv * b, psi_dot, Krel, det)


@dataclass(frozen=True)
class ContactEquations:
    """The contact equations of two given surfaces, as SymPy expressions in named symbols.

    ``coords`` are the symbols of :data:`CONTACT_COORDS`, ``w = (w_x, w_y, w_z)`` and
    ``v = (v_x, v_y)`` the relative motion symbols, ``rates`` the :class:`ContactRates`.
    """

    coords: tuple[sp.Symbol, ...]
    w: tuple[sp.Symbol, sp.Symbol, sp.Symbol]
    v: tuple[sp.Symbol, sp.Symbol]
    rates: ContactRates


def contact_equations(surface_f: ParametricSurface, surface_o: ParametricSurface, *,
                      sliding: bool = False) -> ContactEquations:
    """Contact equations of ``surface_f`` (finger) against ``surface_o`` (object), SymPy.

    With ``sliding=False`` the rolling equations (``v_x = v_y = 0``) are returned and the
    ``v`` symbols do not appear.
    """
    coords = sp.symbols(" ".join(CONTACT_COORDS), real=True)
    w = sp.symbols("w_x w_y w_z", real=True)
    v = sp.symbols("v_x v_y", real=True)
    uf, vf, uo, vo, psi = coords
    rates = contact_rates_symbolic(MontanaForms.of(surface_f, uf, vf), MontanaForms.of(surface_o, uo, vo),
                                   psi, w, v if sliding else (0, 0))
    return ContactEquations(tuple(coords), tuple(w), tuple(v), rates)
