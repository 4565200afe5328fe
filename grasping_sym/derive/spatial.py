"""SymPy kinematics and dynamics of spatial finger chains and of a free rigid body (3D model).

Conventions (Arimoto & Yoshida 2011, section 2; docs/conventions.md section 2; ``model.chains``):

Fingers. ``Rot(a, q) = I + sin q [a]x + (1 - cos q) [a]x^2`` (Rodrigues, exact); link frames
``R_k = R_(k-1) F_k Rot(a_k, q_k)`` (``F_k`` the joint's fixed frame, identity unless given) map
link-k coordinates to the inertial frame O-xyz. The fingertip frame is ``Pi_i = R_n tip_rotation``
and its centre ``r_i(q)`` (the paper's ``O_i``). Velocities:

    r_i' = J_i(q) q',        J_i = dr_i/dq^T                       (paper eq 38)
    omega_i = W_i(q) q',     W_i = [R_0 F_1 a_1, ..., R_(n-1) F_n a_n]   (world frame)

``W_i`` is the angular-velocity Jacobian of the fingertip in the inertial frame: the paper's
``W1``, ``W2`` of eq (39), which are ``-W_i`` for the presets (the paper's finger angular
velocity has the sign of its eq (8); see ``model.chains``). Kinetic energy of uniform-rod (or
given-inertia) links

    K = sum_k 1/2 m_k |c_k'|^2 + 1/2 (W_k q')^T R_k I_k R_k^T (W_k q'),    G(q) = d^2K/dq'^2,

and, as in ``derive.planar``, the Coriolis/centrifugal vector

    h(q, q') = (G q')_q q' - dK/dq = d/dt(dK/dq') - dK/dq - G q'' = (G'/2 + S) q',

so the free finger obeys ``G q'' + h + dP/dq = u`` with ``P = -sum_k m_k g . c_k``.

Free object. Pose: the position ``x = (x, y, z)`` of the mass centre Om in O-xyz (m) and a unit
quaternion ``quat = (qw, qx, qy, qz)`` (scalar first, Hamilton product) whose rotation matrix
``Pi0 = R(quat)`` maps object coordinates Om-XYZ to O-xyz. Generalised speeds: the velocity
``v = x'`` (world frame, m/s) and the angular velocity in the *body* frame
``omega = (omegaX, omegaY, omegaZ)`` (rad/s), the paper's bar-omega of eq (5) with
``Pi0' = Pi0 [omega]x`` (eq 6). Equations:

    x' = v,   quat' = 1/2 quat (x) (0, omega) + k (1 - |quat|^2) quat
    M v' = F + M g,    H omega' + omega x H omega = tau      (H, tau in the body frame)

Keeping the quaternion on the unit sphere: the exact flow of ``1/2 quat (x) (0, omega)``
preserves ``|quat|`` (``quat . (quat (x) (0, omega)) = 0``), so only the integrator's error
leaves the sphere. We add the Baumgarte term ``k (1 - |quat|^2) quat``, which vanishes on the
sphere (the true solution is unchanged) and makes it attracting:
``d(|quat|^2 - 1)/dt = -2k |quat|^2 (|quat|^2 - 1)``. We prefer it to dividing by ``|quat|``
in the right-hand side because it keeps the right-hand side polynomial (no square root; cheap
exact Jacobians for the implicit integrators and CasADi), it needs no projection step between
integrator steps (which generic integrators do not offer), and the norm error stays at the
integrator's tolerance instead of random-walking. ``k = BAUMGARTE_RATE = 10 1/s``: slow
against the contact stabilisation gains (~1e3 1/s), so it adds no stiffness, and fast against
runs of seconds, so no drift accumulates. The orthonormality error of ``R(quat)`` is
``~2 |1 - |quat|^2|``.
"""
from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field

import sympy as sp

from grasping_sym.model.chains import FingerChain

#: 1/s, rate of the Baumgarte term that pulls the quaternion back to the unit sphere.
BAUMGARTE_RATE: float = 10.0

Scalar = float | int | sp.Expr


def exact(value: Scalar) -> sp.Expr:
    """A number as an exact SymPy rational (via its decimal repr); SymPy input unchanged."""
    if isinstance(value, sp.Basic):
        return value
    return sp.Rational(repr(float(value)))


def exact_vector(values: Sequence[Scalar]) -> sp.Matrix:
    """A column of ``exact`` numbers."""
    return sp.Matrix([exact(v) for v in values])


def skew(v: sp.Matrix) -> sp.Matrix:
    """The cross-product matrix ``[v]x`` with ``[v]x w = v x w``."""
    return sp.Matrix([[0, -v[2], v[1]], [v[2], 0, -v[0]], [-v[1], v[0], 0]])


def unskew(S: sp.Matrix) -> sp.Matrix:
    """The vector of a skew matrix (inverse of ``skew``; the skew part if not exactly skew)."""
    return sp.Matrix([S[2, 1] - S[1, 2], S[0, 2] - S[2, 0], S[1, 0] - S[0, 1]]) / 2


def unit_axis(axis: Sequence[Scalar]) -> sp.Matrix:
    """The exact unit vector along ``axis`` (non-zero)."""
    a = exact_vector(axis)
    return a / sp.sqrt(a.dot(a))


def rodrigues(axis: sp.Matrix, angle: sp.Expr) -> sp.Matrix:
    """Right-handed rotation by ``angle`` (rad) about the unit ``axis``: I + s K + (1 - c) K^2."""
    K = skew(axis)
    return sp.eye(3) + sp.sin(angle) * K + (1 - sp.cos(angle)) * K * K


# --------------------------------------------------------------------------------- fingers


@dataclass(frozen=True, eq=False)
class FingerKinematics:
    """Forward kinematics of one finger chain, all vectors in the inertial frame O-xyz.

    Attributes
    ----------
    chain
        The chain it was derived from.
    q, dq
        n x 1 joint angles ``q{i}{k}`` (rad) and rates ``dq{i}{k}`` (rad/s).
    link_rotations
        ``R_k`` (k = 1..n), link-k frame to inertial frame.
    joint_positions
        m, position of joint k (k = 1..n).
    joint_axes
        Unit axis of joint k in the inertial frame, ``R_(k-1) a_k``.
    com_positions, com_jacobians
        m, centre of mass of link k and its Jacobian ``dc_k/dq^T`` (3 x n).
    link_W
        3 x n angular-velocity Jacobian of link k (inertial frame).
    masses, inertias
        kg, link masses; kg m^2, 3x3 inertia of link k about its centre of mass in its frame.
    Pi
        Fingertip frame (fingertip coordinates to inertial frame), 3 x 3.
    r
        m, fingertip centre (origin of the fingertip frame), 3 x 1.
    J
        m/rad, ``dr/dq^T`` (3 x n).
    W
        Angular-velocity Jacobian of the fingertip (3 x n), ``omega_i = W q'``; the paper's
        ``W_i`` of eq (39) is ``-W`` for the presets.
    params
        Values of the symbols that stand for link lengths and masses (``symbolic=True``).
    """

    chain: FingerChain
    q: sp.Matrix
    dq: sp.Matrix
    link_rotations: tuple[sp.Matrix, ...]
    joint_positions: tuple[sp.Matrix, ...]
    joint_axes: tuple[sp.Matrix, ...]
    com_positions: tuple[sp.Matrix, ...]
    com_jacobians: tuple[sp.Matrix, ...]
    link_W: tuple[sp.Matrix, ...]
    masses: tuple[sp.Expr, ...]
    inertias: tuple[sp.Matrix, ...]
    Pi: sp.Matrix
    r: sp.Matrix
    J: sp.Matrix
    W: sp.Matrix
    params: dict[sp.Symbol, float] = field(default_factory=dict)

    def point_jacobian(self, p_tip: sp.Matrix) -> sp.Matrix:
        """Jacobian (3 x n, m/rad) of the material point at ``p_tip`` (fingertip frame, m).

        Its world position is ``r + Pi p_tip`` and its velocity
        ``J q' + omega x (Pi p_tip) = (J - [Pi p_tip]x W) q'``. The joint torques of a force
        ``f`` (world, N) applied there are ``point_jacobian(p_tip)^T f``.
        """
        return self.J - skew(self.Pi * sp.Matrix(p_tip)) * self.W


def _simplify_rotation(R: sp.Matrix) -> sp.Matrix:
    return R.applyfunc(lambda e: sp.trigsimp(sp.expand(e)))


def finger_kinematics(chain: FingerChain, symbolic: bool = False) -> FingerKinematics:
    """Forward kinematics of ``chain`` by products of Rodrigues rotations (exact SymPy).

    Parameters
    ----------
    chain
        The finger; numbers enter as exact rationals (``exact``).
    symbolic
        If true, the length of every link of positive length becomes the symbol
        ``l{i}{k}`` (along the link's fixed direction) and every positive mass ``m{i}{k}``
        (``i`` the chain name), as the 2D template does; their values are in ``params``.
        Explicit centres of mass and inertias stay numeric; rod defaults follow the symbols.

    Returns
    -------
    FingerKinematics
    """
    name = chain.name
    n = chain.n
    q = sp.Matrix(sp.symbols(" ".join(f"q{name}{k}" for k in range(1, n + 1)), real=True,
                             seq=True))
    dq = sp.Matrix(sp.symbols(" ".join(f"dq{name}{k}" for k in range(1, n + 1)), real=True,
                              seq=True))
    params: dict[sp.Symbol, float] = {}

    R = sp.eye(3)
    p = exact_vector(chain.base)
    rotations, positions, axes, coms, com_jacs, link_ws, masses, inertias = ([] for _ in range(8))
    W = sp.zeros(3, n)
    for k, joint in enumerate(chain.joints, start=1):
        if joint.frame is not None:  # the joint's fixed frame F_k (model.chains)
            R = R * sp.Matrix(3, 3, [exact(x) for row in joint.frame for x in row])
        axis_world = R * unit_axis(joint.axis)
        W = W.copy()
        W[:, k - 1] = axis_world
        R = _simplify_rotation(R * rodrigues(unit_axis(joint.axis), q[k - 1]))
        vector = exact_vector(joint.vector)
        length_value = joint.length
        mass = exact(joint.mass)
        if symbolic and length_value > 0:
            length = sp.Symbol(f"l{name}{k}", positive=True)
            params[length] = length_value
            vector = length * vector / sp.sqrt(vector.dot(vector))
        else:
            length = sp.sqrt(vector.dot(vector))
        if symbolic and joint.mass > 0:
            mass = sp.Symbol(f"m{name}{k}", positive=True)
            params[mass] = joint.mass
        com_local = vector / 2 if joint.com is None else exact_vector(joint.com)
        if joint.inertia is None:
            d = vector / length if length_value > 0 else sp.zeros(3, 1)
            inertia = mass * length**2 / 12 * (sp.eye(3) - d * d.T)
        else:
            inertia = sp.Matrix(3, 3, [exact(x) for row in joint.inertia for x in row])
        com = p + R * com_local
        rotations.append(R)
        positions.append(p)
        axes.append(axis_world)
        coms.append(com)
        com_jacs.append(com.jacobian(q))
        link_ws.append(W)
        masses.append(mass)
        inertias.append(inertia.applyfunc(sp.simplify))
        p = p + R * vector
    r = p + R * exact_vector(chain.tip_offset)
    Pi = R * sp.Matrix(3, 3, [exact(x) for row in chain.tip_rotation for x in row])
    return FingerKinematics(
        chain=chain, q=q, dq=dq, link_rotations=tuple(rotations), joint_positions=tuple(positions),
        joint_axes=tuple(axes), com_positions=tuple(coms), com_jacobians=tuple(com_jacs),
        link_W=tuple(link_ws), masses=tuple(masses), inertias=tuple(inertias), Pi=Pi, r=r,
        J=r.jacobian(q), W=W, params=params,
    )


@dataclass(frozen=True, eq=False)
class FingerDynamics:
    """Lagrangian pieces of one finger: ``G(q) q'' + h(q, q') + dP/dq = u``.

    Attributes
    ----------
    kinematics
        The ``FingerKinematics`` it was derived from.
    kinetic_energy
        J, ``K(q, q')``.
    G
        kg m^2, n x n inertia matrix, the Hessian of K in q'.
    h
        N m, Coriolis/centrifugal vector ``(G'/2 + S) q'`` (n x 1).
    gravity
        m/s^2, gravity vector in the inertial frame (zeros if none).
    potential_energy
        J, ``P(q) = -sum_k m_k g . c_k`` (0 without gravity).
    gravity_gradient
        N m, ``dP/dq`` (n x 1); a controller compensates gravity by adding it to ``u``.
    """

    kinematics: FingerKinematics
    kinetic_energy: sp.Expr
    G: sp.Matrix
    h: sp.Matrix
    gravity: sp.Matrix
    potential_energy: sp.Expr
    gravity_gradient: sp.Matrix


def finger_dynamics(kin: FingerKinematics, gravity: Sequence[Scalar] | None = None,
                    simplify: bool = True) -> FingerDynamics:
    """Kinetic energy, inertia matrix, Coriolis vector and gravity terms of a finger.

    Parameters
    ----------
    kin
        The finger's kinematics (``finger_kinematics``).
    gravity
        m/s^2, gravity acceleration in the inertial frame, numbers or symbols, e.g.
        ``(0, -9.81, 0)``; ``None`` for no gravity.
    simplify
        If true, ``G`` is trigsimp'ed entry by entry, its upper triangle mirrored, after
        ``cos^2 = 1 - sin^2`` (the whole derivation of TriFinger's three-joint finger 0.6 s;
        it shrinks G about fourfold and removes the dependence on the first joint angle that
        an unsimplified G only cancels numerically), and ``K = 1/2 q'^T G q'`` and ``h`` are
        rebuilt from the simplified G, which is exact since K is quadratic in q'.
    """
    q, dq = kin.q, kin.dq
    kinetic = sp.Integer(0)
    for m, Jc, Wk, R, I_k in zip(kin.masses, kin.com_jacobians, kin.link_W,
                                 kin.link_rotations, kin.inertias):
        vc = Jc * dq
        wk = R.T * (Wk * dq)  # body-frame angular velocity of link k
        kinetic += m * vc.dot(vc) / 2 + (wk.T * I_k * wk)[0, 0] / 2
    G = sp.hessian(kinetic, dq).applyfunc(sp.expand)
    if simplify:  # G is symmetric: its upper triangle simplified, mirrored (a third less trigsimp)
        n = G.shape[0]
        # cos(q_k)^2 -> 1 - sin(q_k)^2 first (an identity): trigsimp then takes a third of
        # its time on TriFinger's finger (1.05 -> 0.35 s) and returns the same expressions
        square = {sp.cos(x) ** 2: 1 - sp.sin(x) ** 2 for x in q}
        upper = {(i, j): sp.trigsimp(sp.expand(G[i, j].subs(square))) for i in range(n) for j in range(i, n)}
        G = sp.Matrix(n, n, lambda i, j: upper[(min(i, j), max(i, j))])
        kinetic = (dq.T * G * dq)[0, 0] / 2
    Gv = G * dq
    h = Gv.jacobian(q) * dq - sp.Matrix([kinetic]).jacobian(q).T
    g = sp.zeros(3, 1) if gravity is None else exact_vector(gravity)
    potential = sp.Integer(0)
    for m, c in zip(kin.masses, kin.com_positions):
        potential -= m * g.dot(c)
    gradient = sp.Matrix([potential]).jacobian(q).T
    return FingerDynamics(kinematics=kin, kinetic_energy=kinetic, G=G, h=h, gravity=g,
                          potential_energy=potential, gravity_gradient=gradient)


# ------------------------------------------------------------------------------ free body


def quaternion_product(a: sp.Matrix, b: sp.Matrix) -> sp.Matrix:
    """Hamilton product ``a (x) b`` of quaternions given scalar first ``(w, x, y, z)``."""
    aw, av = a[0], sp.Matrix(a[1:4])
    bw, bv = b[0], sp.Matrix(b[1:4])
    return sp.Matrix([aw * bw - av.dot(bv), *(aw * bv + bw * av + av.cross(bv))])


def quaternion_to_matrix(quat: sp.Matrix, unit: bool = True) -> sp.Matrix:
    """Rotation matrix (body to world) of the quaternion ``(w, x, y, z)``: ``R v = q v q*``.

    With ``unit=True`` the polynomial form valid for ``|quat| = 1`` (orthonormality error
    ``~2 |1 - |quat|^2|``); with ``unit=False`` the homogeneous form divided by ``|quat|^2``,
    an exact rotation for any non-zero quaternion.
    """
    w, x, y, z = quat
    if unit:
        return sp.Matrix([
            [1 - 2 * (y**2 + z**2), 2 * (x * y - w * z), 2 * (x * z + w * y)],
            [2 * (x * y + w * z), 1 - 2 * (x**2 + z**2), 2 * (y * z - w * x)],
            [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x**2 + y**2)],
        ])
    n2 = w**2 + x**2 + y**2 + z**2
    return sp.Matrix([
        [w**2 + x**2 - y**2 - z**2, 2 * (x * y - w * z), 2 * (x * z + w * y)],
        [2 * (x * y + w * z), w**2 - x**2 + y**2 - z**2, 2 * (y * z - w * x)],
        [2 * (x * z - w * y), 2 * (y * z + w * x), w**2 - x**2 - y**2 + z**2],
    ]) / n2


def quaternion_rate_matrix(quat: sp.Matrix) -> sp.Matrix:
    """The 4 x 3 matrix E with ``1/2 quat (x) (0, omega) = E omega`` (omega in the body frame)."""
    w, x, y, z = quat
    return sp.Matrix([[-x, -y, -z], [w, -z, y], [z, w, -x], [-y, x, w]]) / 2


def quaternion_rate(quat: sp.Matrix, omega_body: sp.Matrix,
                    baumgarte: Scalar = BAUMGARTE_RATE) -> sp.Matrix:
    """``quat' = 1/2 quat (x) (0, omega) + k (1 - |quat|^2) quat`` (k = ``baumgarte``, 1/s)."""
    n2 = quat.dot(quat)
    return quaternion_rate_matrix(quat) * omega_body + exact(baumgarte) * (1 - n2) * quat


@dataclass(frozen=True, eq=False)
class FreeBody:
    """A free rigid body: Newton-Euler equations with a body-frame angular velocity.

    Attributes
    ----------
    position
        m, ``(x, y, z)``: mass centre Om in O-xyz.
    quaternion
        ``(qw, qx, qy, qz)``: unit quaternion, scalar first, object frame to O-xyz.
    velocity
        m/s, ``(vx, vy, vz)`` = x', inertial frame.
    omega
        rad/s, ``(omegaX, omegaY, omegaZ)``: angular velocity in the object frame Om-XYZ.
    mass, inertia
        kg; kg m^2, 3x3 about Om in the object frame (the paper's H).
    gravity
        m/s^2, inertial frame.
    force, torque
        N, external force in the inertial frame; N m, torque about Om in the object frame.
    rotation
        ``Pi0 = R(quaternion)`` (object frame to O-xyz).
    coordinate_rates
        7 x 1, ``(x', quat')`` with the Baumgarte term.
    mass_matrix, bias
        6 x 6 ``diag(M I, H)`` and 6 x 1 ``(-M g, omega x H omega)``: with the generalised
        forces ``(F, tau)`` the speeds obey ``mass_matrix (v', omega') + bias = (F, tau)``.
    speed_rates
        6 x 1, ``(v', omega')`` solved from the above.
    kinetic_energy, potential_energy
        J; ``1/2 M |v|^2 + 1/2 omega^T H omega`` and ``-M g . x``.
    angular_momentum
        kg m^2/s, about Om in the inertial frame, ``Pi0 H omega``.
    """

    position: sp.Matrix
    quaternion: sp.Matrix
    velocity: sp.Matrix
    omega: sp.Matrix
    mass: sp.Expr
    inertia: sp.Matrix
    gravity: sp.Matrix
    force: sp.Matrix
    torque: sp.Matrix
    rotation: sp.Matrix
    coordinate_rates: sp.Matrix
    mass_matrix: sp.Matrix
    bias: sp.Matrix
    speed_rates: sp.Matrix
    kinetic_energy: sp.Expr
    potential_energy: sp.Expr
    angular_momentum: sp.Matrix

    @property
    def state(self) -> sp.Matrix:
        """13 x 1 ``(x, quat, v, omega)``."""
        return sp.Matrix([*self.position, *self.quaternion, *self.velocity, *self.omega])

    @property
    def rhs(self) -> sp.Matrix:
        """13 x 1 time derivative of ``state``."""
        return sp.Matrix([*self.coordinate_rates, *self.speed_rates])


def free_body(
    mass: Scalar,
    inertia: Sequence[Sequence[Scalar]] | sp.Matrix,
    *,
    gravity: Sequence[Scalar] | None = None,
    force: Sequence[Scalar] | None = None,
    torque: Sequence[Scalar] | None = None,
    baumgarte: Scalar = BAUMGARTE_RATE,
) -> FreeBody:
    """Equations of a free rigid body (state ``x, quat, v, omega``; see the module docstring).

    Parameters
    ----------
    mass
        kg, number or symbol.
    inertia
        kg m^2, 3x3 about the mass centre in the body frame (numbers or symbols).
    gravity
        m/s^2, inertial frame; ``None`` for none.
    force
        N, inertial frame, expressions allowed (e.g. contact forces); ``None`` for zero.
    torque
        N m, about the mass centre in the body frame; ``None`` for zero.
    baumgarte
        1/s, rate k of the term keeping ``|quat| = 1``.
    """
    position = sp.Matrix(sp.symbols("x y z", real=True))
    quat = sp.Matrix(sp.symbols("qw qx qy qz", real=True))
    velocity = sp.Matrix(sp.symbols("vx vy vz", real=True))
    omega = sp.Matrix(sp.symbols("omegaX omegaY omegaZ", real=True))
    M = exact(mass)
    H = sp.Matrix(3, 3, [exact(x) for x in sp.Matrix(inertia)])
    g = sp.zeros(3, 1) if gravity is None else exact_vector(gravity)
    F = sp.zeros(3, 1) if force is None else sp.Matrix([exact(f) for f in force])
    tau = sp.zeros(3, 1) if torque is None else sp.Matrix([exact(t) for t in torque])
    R = quaternion_to_matrix(quat)
    Hw = H * omega
    mass_matrix = sp.diag(M * sp.eye(3), H)
    bias = sp.Matrix([*(-M * g), *omega.cross(Hw)])
    rates = sp.Matrix([*(F / M + g), *H.LUsolve(tau - omega.cross(Hw))])
    return FreeBody(
        position=position, quaternion=quat, velocity=velocity, omega=omega, mass=M, inertia=H,
        gravity=g, force=F, torque=tau, rotation=R,
        coordinate_rates=sp.Matrix([*velocity, *quaternion_rate(quat, omega, baumgarte)]),
        mass_matrix=mass_matrix, bias=bias, speed_rates=rates,
        kinetic_energy=M * velocity.dot(velocity) / 2 + (omega.T * Hw)[0, 0] / 2,
        potential_energy=-M * g.dot(position), angular_momentum=R * Hw,
    )
