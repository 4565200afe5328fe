"""The named quantities of a scene that a control law may use, as CasADi SX.

``planar_quantities`` (2D) and ``grasp3d_quantities`` (3D) make a :class:`Quantities` from a
scene and the symbols ``t, x, p`` of its compiled functions (``p``: the scene's run-time
parameters, then its start's values, then its inputs' coefficients). A law reads:

- ``m.t``: time (s);
- ``m.q[i]``, ``m.dq[i]``: finger ``i``'s joint angles (rad) and rates (rad/s), columns;
- ``m.tip[i]``: finger ``i``'s fingertip centre (m, world), ``m.J[i]`` its Jacobian in the
  joint angles;
- ``m.gravity_torque[i]``: the joint torques that hold finger ``i`` against gravity
  (``dV_i/dq_i``; zero without gravity);
- ``m.param(name)``: a parameter (a run-time input or its folded value; 3D also ``r_ctrl``,
  ``rotation0``: the scene's ``rotation``, ``position0``: a free object's ``position`` as
  given, and ``r_bar0`` when the scene has a centre spring);
- object information (recorded in ``m.uses_object`` when read): 2D ``m.theta``,
  ``m.dtheta``, and for a free object ``m.position``, ``m.velocity`` (its mass centre);
  3D ``m.position``, ``m.velocity``, ``m.rotation`` (body to world), ``m.omega`` (body
  angular velocity), ``m.quaternion``;
- the fixed points: 2D ``m.pivot`` (the pivot Om, a run-time input; for a free object its
  mass centre at the start); 3D pivot scenes ``m.pivot`` (the object's fixed centre).
"""
from __future__ import annotations

import casadi as ca
import numpy as np

from grasping_sym.derive.bodies3d import finger_sx, state_slices
from grasping_sym.derive.planar import has_gravity, parameter_values

__all__ = ["Quantities", "grasp3d_quantities", "planar_quantities"]


class Quantities:
    """What a control law sees (module docstring)."""

    def __init__(self, *, t, q, dq, tip, J, gravity_torque, params: dict, objects: dict,
                 pivot=None):
        self.t = t
        self.q, self.dq = list(q), list(dq)
        self.tip, self.J = list(tip), list(J)
        self.gravity_torque = list(gravity_torque)
        self._params = params
        self._objects = objects
        self._pivot = pivot
        self.uses_object = False

    # --------------------------------------------------------------- parameters and object
    def has_param(self, name: str) -> bool:
        return name in self._params

    def param(self, name: str):
        """Parameter ``name``: its run-time input, or its value folded into the code."""
        if name not in self._params:
            raise KeyError(f"a control law asked for parameter {name!r}; this scene has "
                           f"{sorted(self._params)}")
        return self._params[name]

    @property
    def pivot(self):
        if self._pivot is None:
            raise AttributeError("this scene's object has no fixed pivot (a free object): use its "
                                 "position")
        return self._pivot

    def __getattr__(self, name: str):
        objects = self.__dict__.get("_objects", {})
        if name in objects:
            self.uses_object = True
            return objects[name]
        raise AttributeError(f"a control law asked for {name!r}: a model's quantities are t, q, dq, "
                             f"tip, J, gravity_torque, pivot, param(name) and the object's "
                             f"{sorted(objects)}")

    # --------------------------------------------------------------- shapes
    @property
    def n_joints(self) -> int:
        return sum(dq.numel() for dq in self.dq)

    @property
    def input_style_names(self) -> tuple[str, ...]:
        """``u1, u2, ...``: the joints in order, named as a model's torque inputs."""
        return tuple(f"u{k}" for k in range(1, self.n_joints + 1))

    def column(self, values) -> ca.SX:
        return ca.vertcat(*[ca.SX(v) if not isinstance(v, (ca.SX, ca.MX)) else v for v in values])

    def split(self, torques, who: str) -> list:
        """A law's result as one SX column per finger (it may give one per finger, or one
        column of every joint); named errors for any other shape."""
        sizes = [dq.numel() for dq in self.dq]
        if isinstance(torques, (list, tuple)) and len(torques) == len(sizes) and not all(
                _scalar(v) for v in torques):
            cols = [ca.SX(c) if not isinstance(c, ca.SX) else c for c in torques]
            cols = [c if c.numel() > 1 or s == 1 else ca.repmat(c, s, 1) for c, s in zip(cols, sizes)]
        else:
            whole = ca.SX(torques) if not isinstance(torques, ca.SX) else torques
            if whole.numel() != sum(sizes):
                raise ValueError(f"controller {who!r} gave {whole.numel()} torques; this model has "
                                 f"{sum(sizes)} joints ({sizes} per finger): return one column "
                                 "per finger or one of every joint")
            whole = ca.reshape(whole, whole.numel(), 1)
            cols, k = [], 0
            for s in sizes:
                cols.append(whole[k:k + s])
                k += s
        for i, (c, s) in enumerate(zip(cols, sizes), start=1):
            if c.shape != (s, 1):
                raise ValueError(f"controller {who!r} gave finger {i} torques of shape {c.shape}; "
                                 f"it has {s} joints: return a column of {s}")
        return cols


def _scalar(v) -> bool:
    return isinstance(v, (int, float)) or (hasattr(v, "numel") and v.numel() == 1)


def planar_quantities(scene, t: ca.SX, x: ca.SX, p: ca.SX, p_names: tuple[str, ...]) -> Quantities:
    """A 2D scene's quantities (two-link fingers of uniform rods, ``model.planar``)."""

    names = scene.state_names
    values = {k: v for k, v in parameter_values(scene).items() if not k.startswith("tau_")}
    params = {k: p[p_names.index(k)] if k in p_names else ca.SX(v) for k, v in values.items()}
    gravity = has_gravity(scene)
    one = scene.n_fingers == 1
    q, dq, tip, J, grav = [], [], [], [], []
    for i in range(1, scene.n_fingers + 1):
        jn = ("q1", "q2") if one else (f"q{i}1", f"q{i}2")
        qi = ca.vertcat(*[x[names.index(k)] for k in jn])
        dqi = ca.vertcat(*[x[names.index("d" + k)] for k in jn])
        l1, l2, m1, m2 = (params[f"{k}{i}{j}"] for k, j in (("l", 1), ("l", 2), ("m", 1), ("m", 2)))
        base = ca.vertcat(params[f"xb{i}"], params[f"yb{i}"]) if i > 1 else ca.SX.zeros(2, 1)
        d1 = ca.vertcat(ca.sin(qi[0]), ca.cos(qi[0]))
        d12 = ca.vertcat(ca.sin(qi[0] + qi[1]), ca.cos(qi[0] + qi[1]))
        centre = base + l1 * d1 + l2 * d12
        V = ca.SX(0)
        if gravity:
            g = ca.vertcat(params["gx"], params["gy"])
            V = -(m1 * ca.dot(g, base + l1 / 2 * d1) + m2 * ca.dot(g, base + l1 * d1 + l2 / 2 * d12))
        q.append(qi)
        dq.append(dqi)
        tip.append(centre)
        J.append(ca.jacobian(centre, qi))
        grav.append(ca.jacobian(V, qi).T if gravity else ca.SX.zeros(2, 1))
    objects = {"theta": x[names.index("theta")], "dtheta": x[names.index("dtheta")]}
    if scene.free:
        objects.update({"position": ca.vertcat(x[names.index("x")], x[names.index("y")]),
                        "velocity": ca.vertcat(x[names.index("dx")], x[names.index("dy")])})
    return Quantities(t=t, q=q, dq=dq, tip=tip, J=J, gravity_torque=grav, params=params,
                      objects=objects,
                      pivot=ca.vertcat(params["xm"], params["ym"]))


def grasp3d_quantities(scene, t: ca.SX, x: ca.SX, p: ca.SX, p_names: tuple[str, ...]) -> Quantities:
    """A 3D scene's quantities (its chains, ``derive.bodies3d.finger_sx``)."""

    sl = state_slices(scene)
    g = None if scene.gravity is None else tuple(float(v) for v in scene.gravity)
    params = {k: p[p_names.index(k)] if k in p_names else ca.SX(v) for k, v in scene.params.items()}
    params["r_ctrl"] = ca.SX(float(scene.r_ctrl))
    params["rotation0"] = ca.SX(ca.DM(np.asarray(scene.rotation, dtype=float)))
    if scene.free:  # the point one finger presses a free object toward (controllers.paper3d)
        params["position0"] = ca.SX(ca.DM(np.asarray(scene.position, dtype=float)))
    if scene.start_param_names:
        params["r_bar0"] = ca.vertcat(*[p[p_names.index(k)] for k in scene.start_param_names])
    q, dq, tip, J, grav = [], [], [], [], []
    off = 0
    for f in scene.fingers:
        n = f.chain.n
        qi, dqi = x[sl["q"]][off:off + n], x[sl["dq"]][off:off + n]
        fin = finger_sx(f.chain, g, qi, dqi)
        q.append(qi)
        dq.append(dqi)
        tip.append(fin["r"])
        J.append(fin["J"])
        grav.append(fin["dP"] if g is not None else ca.SX.zeros(n, 1))
        off += n
    quat = x[sl["quat"]]
    w, v_ = quat[0], quat[1:4]
    R = (w * w - ca.dot(v_, v_)) * ca.SX.eye(3) + 2 * v_ @ v_.T + 2 * w * ca.skew(v_)
    objects = {"quaternion": quat, "rotation": R, "omega": x[sl["om"]]}
    pivot = None
    if scene.free:
        objects.update({"position": x[sl["pos"]], "velocity": x[sl["vel"]]})
    else:
        pivot = ca.SX(ca.DM(scene.position))
    return Quantities(t=t, q=q, dq=dq, tip=tip, J=J, gravity_torque=grav, params=params,
                      objects=objects, pivot=pivot)


def body_quantities(scene, t: ca.SX, x: ca.SX, p: ca.SX, p_names: tuple[str, ...]) -> Quantities:
    """A body on a plane (``model.body``): no joints, nothing for a law to drive."""
    return Quantities(t=t, q=[], dq=[], tip=[], J=[], gravity_torque=[], params={}, objects={})
