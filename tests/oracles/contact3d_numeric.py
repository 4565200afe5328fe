"""Numeric (NumPy) evaluation of Montana's contact kinematics: a test oracle.

The same equations and conventions as ``grasping_sym.derive.contact3d`` (see its docstring:
contact coordinates ``eta = (u_f, v_f, u_o, v_o, psi)``, the relative motion ``(v, w)`` of the
object with respect to the finger in the finger's contact frame), evaluated with
:meth:`ParametricSurface.evaluate` instead of SymPy; plus the classification of the relative
curvature ``K_f + K~_o`` and the world-frame contact checks (contact frames, residuals, the
object pose that puts two bodies in contact, relative twists). Only the tests and the NumPy
oracles use them; the package derives the same rates symbolically
(``contact3d.contact_rates_symbolic``).

The equations are singular exactly where ``K_rel`` is (flat on flat, a cylinder on a plane
along its axis, matched concave on convex): :func:`relative_curvature_report` names the case;
:func:`contact_rates` raises :class:`RelativeCurvatureSingularError` there instead of
returning inf or NaN.
"""
from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from grasping_sym.derive.contact3d import CONTACT_COORDS, MontanaForms, r_psi
from grasping_sym.errors import GraspingSymError
from grasping_sym.geometry.surfaces import ParametricSurface


class RelativeCurvatureSingularError(GraspingSymError, ArithmeticError):
    """The relative curvature ``K_f + K~_o`` is (nearly) singular: the contact rates are undefined.

    Carries the :class:`CurvatureReport` as ``report`` and the contact coordinates ``eta``.
    """

    def __init__(self, report: CurvatureReport, eta: Sequence[float] | None = None):
        self.report = report
        self.eta = None if eta is None else tuple(float(e) for e in eta)
        where = "" if eta is None else " at (" + ", ".join(
            f"{n}={e:.6g}" for n, e in zip(CONTACT_COORDS, self.eta)) + ")"
        super().__init__(
            f"relative curvature K_f + K~_o is singular{where}: {report.name}; smallest eigenvalue "
            f"{report.min_eigenvalue:.3g} 1/m, det {report.det:.3g} 1/m^2 (curvature scale "
            f"{report.scale:.3g} 1/m). The rolling contact kinematics (Montana 1988) are undefined "
            "for these shapes: give one surface a curvature the other does not cancel")


def forms_from_evaluation(values: dict[str, np.ndarray]) -> MontanaForms:
    """The numeric :class:`MontanaForms` from :meth:`ParametricSurface.evaluate` at one point."""
    return MontanaForms(values["M_p"], values["K_p"], np.reshape(values["T_p"], (1, 2)))


# ====================================================================== relative curvature
@dataclass(frozen=True)
class CurvatureReport:
    """The relative curvature ``K_rel = K_f + R_psi K_o R_psi`` at one contact (1/m).

    ``eigenvalues`` ascending, ``min_eigenvalue``, ``det`` (1/m^2), ``scale`` =
    ``max(|K_f|, |K_o|)`` (spectral norms, 1/m), ``singular`` and ``name``: ``'regular'``,
    ``'flat on flat'``, ``'line contact'`` (both surfaces flat along a common tangent
    direction, e.g. a cylinder on a plane along its axis), ``'matched concave on convex'``
    (the curvatures cancel along some direction), or ``'interpenetrating'`` (``K_rel`` has a
    negative eigenvalue: the surfaces cross near the contact; the rates exist but the
    configuration is not a touching contact).
    """

    matrix: np.ndarray
    eigenvalues: np.ndarray
    min_eigenvalue: float
    det: float
    scale: float
    singular: bool
    name: str


def relative_curvature(K_f: np.ndarray, K_o: np.ndarray, psi: float) -> np.ndarray:
    """``K_f + R_psi K_o R_psi`` (1/m), NumPy; both forms in their own surface's frame."""
    Rp = r_psi(float(psi))
    return np.asarray(K_f, float) + Rp @ np.asarray(K_o, float) @ Rp


def relative_curvature_report(K_f: np.ndarray, K_o: np.ndarray, psi: float, *,
                              rtol: float = 1e-6, atol: float = 1e-9) -> CurvatureReport:
    """Classify the relative curvature; singular when ``|lambda_min| <= atol + rtol * scale``.

    ``atol`` is in 1/m (a radius of relative curvature of 1e9 m by default), ``rtol`` relative
    to the larger of the two surfaces' curvatures, so matched curvatures of any size are caught.
    """
    K_f, K_o = np.asarray(K_f, float), np.asarray(K_o, float)
    Rp = r_psi(float(psi))
    Kot = Rp @ K_o @ Rp
    Krel = K_f + Kot
    Ksym = 0.5 * (Krel + Krel.T)
    lam, vec = np.linalg.eigh(Ksym)
    scale = float(max(np.linalg.norm(K_f, 2), np.linalg.norm(K_o, 2)))
    thresh = atol + rtol * scale
    k = int(np.argmin(np.abs(lam)))
    singular = bool(abs(lam[k]) <= thresh)
    if not singular:
        name = "regular" if lam[0] > 0 else "interpenetrating"
    elif scale <= thresh:
        name = "flat on flat"
    else:
        e = vec[:, k]
        flat_f = abs(e @ K_f @ e) <= thresh
        flat_o = abs(e @ Kot @ e) <= thresh
        name = "line contact" if (flat_f and flat_o) else "matched concave on convex"
    return CurvatureReport(Krel, lam, float(lam[0]), float(np.linalg.det(Krel)), scale, singular, name)


# ====================================================================== numeric rates
def contact_rates(surface_f: ParametricSurface, surface_o: ParametricSurface, eta: Sequence[float],
                  w: Sequence[float], v: Sequence[float] = (0.0, 0.0), *, check: bool = True,
                  rtol: float = 1e-6, atol: float = 1e-9) -> np.ndarray:
    """Numeric rates ``eta' = (u_f', v_f', u_o', v_o', psi')`` of :data:`CONTACT_COORDS`.

    Same equations and conventions as :func:`contact_rates_symbolic`, evaluated with
    :meth:`ParametricSurface.evaluate`. ``w`` (rad/s) and ``v`` (m/s, only ``v_x, v_y``) are
    the object's motion relative to the finger in the finger's contact frame; ``v`` may have
    a third component ``v_z``, which is not used (it is the constraint ``v_z = 0``).

    Raises
    ------
    RelativeCurvatureSingularError
        If ``check`` and the relative curvature is singular (see :func:`relative_curvature_report`).
    """
    uf, vf, uo, vo, psi = (float(e) for e in eta)
    gf, go = surface_f.evaluate(uf, vf), surface_o.evaluate(uo, vo)
    Rp = r_psi(psi)
    Kf, Ko = gf["K_p"], go["K_p"]
    Kot = Rp @ Ko @ Rp
    Krel = Kf + Kot
    if check:
        rep = relative_curvature_report(Kf, Ko, psi, rtol=rtol, atol=atol)
        if rep.singular:
            raise RelativeCurvatureSingularError(rep, (uf, vf, uo, vo, psi))
    vt = np.array([float(v[0]), float(v[1])])
    rot = np.array([float(w[1]), -float(w[0])])
    a = np.linalg.solve(Krel, rot + Kot @ vt)
    b = Rp @ np.linalg.solve(Krel, rot - Kf @ vt)
    psi_dot = -float(w[2]) + gf["T_p"] @ a + go["T_p"] @ b
    return np.concatenate([np.linalg.solve(gf["M_p"], a), np.linalg.solve(go["M_p"], b), [psi_dot]])


# ====================================================================== world frame
@dataclass(frozen=True)
class ContactFrame:
    """A surface's contact point and frame in the world: ``point`` (m), ``normal``, ``frame``.

    ``frame`` is the 3x3 matrix with columns ``(x, y, n)`` (world components), ``normal`` its
    third column.
    """

    point: np.ndarray
    normal: np.ndarray
    frame: np.ndarray


def contact_frame_world(surface: ParametricSurface, R: np.ndarray, p: np.ndarray, u: float, v: float) -> ContactFrame:
    """World contact point and Montana frame of ``surface`` at ``(u, v)`` on a body at pose ``(R, p)``.

    ``R`` (3x3) maps body-local components to world, ``p`` (m) is the body origin in the world:
    a local point ``X`` is at ``R X + p``.
    """
    g = surface.evaluate(float(u), float(v))
    R, p = np.asarray(R, float), np.asarray(p, float)
    C = R @ np.column_stack([g["x"], g["y"], g["normal"]])
    return ContactFrame(R @ g["point"] + p, C[:, 2].copy(), C)


def frame_relation(psi: float) -> np.ndarray:
    """``P(psi)`` with ``C_o = C_f P(psi)`` on the manifold: ``[[R_psi, 0], [0, -1]]`` (3x3)."""
    P = np.zeros((3, 3))
    P[:2, :2] = r_psi(float(psi))
    P[2, 2] = -1.0
    return P


def contact_residuals(surface_f: ParametricSurface, pose_f: tuple[np.ndarray, np.ndarray],
                      surface_o: ParametricSurface, pose_o: tuple[np.ndarray, np.ndarray],
                      eta: Sequence[float]) -> dict[str, float]:
    """How far the bodies are from the contact manifold at coordinates ``eta``.

    Returns ``point`` = ``|p_f - p_o|`` (m), ``normal`` = ``|n_f + n_o|``, ``frame`` =
    ``max |C_o - C_f P(psi)|`` (dimensionless; covers the normals and the angle ``psi``),
    ``angle`` = the signed error of ``psi`` (rad, from the tangent axes) and ``max`` of the
    dimensionless ones and ``point``.
    """
    uf, vf, uo, vo, psi = (float(e) for e in eta)
    cf = contact_frame_world(surface_f, *pose_f, uf, vf)
    co = contact_frame_world(surface_o, *pose_o, uo, vo)
    xo = co.frame[:, 0]
    psi_meas = math.atan2(-(xo @ cf.frame[:, 1]), xo @ cf.frame[:, 0])
    out = {"point": float(np.linalg.norm(cf.point - co.point)),
           "normal": float(np.linalg.norm(cf.normal + co.normal)),
           "frame": float(np.max(np.abs(co.frame - cf.frame @ frame_relation(psi)))),
           "angle": float(math.remainder(psi_meas - psi, 2 * math.pi))}
    out["max"] = max(out["point"], out["normal"], out["frame"], abs(out["angle"]))
    return out


def object_pose_from_contact(surface_f: ParametricSurface, pose_f: tuple[np.ndarray, np.ndarray],
                             surface_o: ParametricSurface, eta: Sequence[float]) -> tuple[np.ndarray, np.ndarray]:
    """The object pose ``(R_o, p_o)`` that puts the bodies in contact at coordinates ``eta``.

    ``R_o = C_f P(psi) C_o_local^T`` and ``p_o = p_f_contact - R_o S_o(u_o, v_o)``: a start on
    the constraint manifold for a given finger pose.
    """
    uf, vf, uo, vo, psi = (float(e) for e in eta)
    cf = contact_frame_world(surface_f, *pose_f, uf, vf)
    go = surface_o.evaluate(uo, vo)
    Co = np.column_stack([go["x"], go["y"], go["normal"]])
    R_o = cf.frame @ frame_relation(psi) @ Co.T
    return R_o, cf.point - R_o @ go["point"]


def relative_motion(frame_f: np.ndarray, point: np.ndarray,
                    twist_f: tuple[np.ndarray, np.ndarray, np.ndarray],
                    twist_o: tuple[np.ndarray, np.ndarray, np.ndarray]) -> tuple[np.ndarray, np.ndarray]:
    """``(v, w)`` of the contact equations from the two bodies' world twists.

    Parameters
    ----------
    frame_f
        The finger's contact frame ``C_f`` (columns ``x_f, y_f, n_f``, world).
    point
        The contact point (world, m).
    twist_f, twist_o
        ``(omega, p_dot, p)`` of each body: world angular velocity (rad/s), velocity of the
        body origin (m/s) and the origin's position (m).

    Returns
    -------
    v, w
        Velocity of the object's material point at the contact minus the finger's, and
        ``omega_o - omega_f``, both as components in ``C_f`` (3-vectors; ``v[2]`` must be 0).
    """
    wf, pdf, pf = (np.asarray(a, float) for a in twist_f)
    wo, pdo, po = (np.asarray(a, float) for a in twist_o)
    c = np.asarray(point, float)
    vel = (pdo + np.cross(wo, c - po)) - (pdf + np.cross(wf, c - pf))
    C = np.asarray(frame_f, float)
    return C.T @ vel, C.T @ (wo - wf)


def object_twist(frame_f: np.ndarray, point: np.ndarray, p_o: np.ndarray, w: Sequence[float],
                 v: Sequence[float] = (0.0, 0.0, 0.0)) -> tuple[np.ndarray, np.ndarray]:
    """Inverse of :func:`relative_motion` for a fixed finger: ``(omega_o, p_o_dot)`` in the world.

    ``w``, ``v`` are contact-frame components (rad/s, m/s); ``point`` the contact, ``p_o`` the
    object's origin (world, m). ``omega_o = C_f w``, ``p_o_dot = C_f v - omega_o x (point - p_o)``.
    """
    C = np.asarray(frame_f, float)
    omega = C @ np.asarray(w, float)
    vel = C @ np.asarray(v, float)
    return omega, vel - np.cross(omega, np.asarray(point, float) - np.asarray(p_o, float))
