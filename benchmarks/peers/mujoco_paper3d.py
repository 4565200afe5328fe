"""paper3d in MuJoCo (soft contact): the same bodies, masses, inertias, gravity, start and
grasp law, for ``benchmarks/soft_contact.py``.

The MJCF is written from the scene itself:

- each finger chain is nested bodies, one hinge per joint, with the axis in the parent's frame;
  links are uniform rods (the chain's mass, centre and inertia);
- each fingertip is a sphere geom on the last link, at the chain's fingertip centre;
- the object is a free body with an ellipsoid geom, the scene's mass and diagonal inertia,
  placed at the grasp model's start;
- gravity acts on everything, and the finger links carry ``gravcomp="1"``: MuJoCo cancels
  their weight, as the law's ``dP/dq`` term does.

The law is the paper's 3D grasp law, computed from MuJoCo's fingertip sites and Jacobians
before every step and applied as joint torques (``qfrc_applied``):
``tau_i = -c q_i' - J_i^T [(fd / r_ctrl) sum_j (r_i - r_j) + (k_center / N)(r_bar - r_bar0)]``.

Contacts are only fingertip against object, with ``condim=4``: sliding and torsional
friction, and rolling free. MuJoCo's torsional friction is Coulomb-like, not the grasp
model's viscous 2e-5 N m s; ``TORSION`` sets its coefficient.
"""
from __future__ import annotations

import numpy as np

#: Sliding and torsional friction coefficients of the fingertip contacts (torsional in m).
FRICTION = 1.0
TORSION = 1e-3


def _rod_inertia(mass: float, vector) -> list[float]:
    d = np.asarray(vector, float)
    L = float(np.linalg.norm(d))
    # the rod's inertia about its own axis is 0; MuJoCo needs it positive: 1e-10 kg m^2 (no
    # joint of these fingers turns a link about its own axis)
    inertia = mass * L * L / 12.0 * (np.eye(3) - np.outer(d, d) / (L * L)) + 1e-10 * np.eye(3)
    return [inertia[i, j] for i, j in ((0, 0), (1, 1), (2, 2), (0, 1), (0, 2), (1, 2))]


def mjcf(scene, x0: np.ndarray, state_names, timestep: float = 1e-3, noslip: int = 0) -> str:
    """The MJCF of ``scene`` (paper3d's shapes: spherical tips, an ellipsoid) started at the
    grasp model's state ``x0``."""
    from grasping_sym.model.scenes import PAPER3D_SEMI_AXES, PAPER3D_TIP_RADIUS

    tip_radius = PAPER3D_TIP_RADIUS
    idx = {k: i for i, k in enumerate(state_names)}
    g = " ".join(f"{v:.10g}" for v in scene.gravity)
    fingers = []
    for i, f in enumerate(scene.fingers, start=1):
        ch = f.chain
        radius = tip_radius
        xml, close, prev = [], [], (0.0, 0.0, 0.0)
        for k, j in enumerate(ch.joints, start=1):
            pos = ch.base if k == 1 else prev
            head = (f'<body name="f{i}l{k}" pos="{" ".join(f"{v:.10g}" for v in pos)}" gravcomp="1">'
                    f'<joint name="q{i}{k}" type="hinge" axis="{" ".join(f"{v:.10g}" for v in j.axis)}"/>')
            if np.linalg.norm(j.vector) == 0.0:  # a massless joint at the same point as the next
                xml.append(head + '<inertial pos="0 0 0" mass="1e-9" diaginertia="1e-15 1e-15 1e-15"/>')
            else:
                fi = " ".join(f"{v:.10g}" for v in _rod_inertia(j.mass, j.vector))
                com = " ".join(f"{v:.10g}" for v in j.com_local)
                xml.append(head + f'<inertial pos="{com}" mass="{j.mass:.10g}" fullinertia="{fi}"/>'
                           f'<geom type="capsule" fromto="0 0 0 {" ".join(f"{v:.10g}" for v in j.vector)}" '
                           f'size="0.003" contype="0" conaffinity="0" rgba=".4 .4 .4 1"/>')
            close.append("</body>")
            prev = j.vector
        tip = np.asarray(prev, float) + np.asarray(ch.tip_offset, float)
        tp = " ".join(f"{v:.10g}" for v in tip)
        xml.append(f'<geom name="tip{i}" type="sphere" pos="{tp}" size="{radius:.10g}" contype="1" '
                   f'conaffinity="2" condim="4" friction="{FRICTION} {TORSION} 0" margin="0.001" gap="0.001" mass="0"/>'
                   f'<site name="tip{i}" pos="{tp}"/>')
        fingers.append("".join(xml + close[::-1]))
    a, b, c = PAPER3D_SEMI_AXES
    inertia = np.diag(np.asarray(scene.inertia, float))
    pos = " ".join(f"{x0[idx[k]]:.12g}" for k in ("x", "y", "z"))
    quat = " ".join(f"{x0[idx[k]]:.12g}" for k in ("qw", "qx", "qy", "qz"))
    return f"""<mujoco model="{scene.name}_mujoco">
  <option timestep="{timestep}" gravity="{g}" integrator="implicitfast" noslip_iterations="{noslip}"/>
  <worldbody>
    {"".join(fingers)}
    <body name="object" pos="{pos}" quat="{quat}">
      <freejoint name="object"/>
      <inertial pos="0 0 0" mass="{scene.mass:.10g}" diaginertia="{" ".join(f"{v:.10g}" for v in inertia)}"/>
      <geom name="object" type="ellipsoid" size="{a:.10g} {b:.10g} {c:.10g}" contype="2"
            conaffinity="1" condim="4" friction="{FRICTION} {TORSION} 0" margin="0.001" gap="0.001"
            mass="0" rgba=".85 .2 .2 .5"/>
    </body>
  </worldbody>
</mujoco>"""


class MujocoGrasp:
    """The MuJoCo model of a grasp scene at the grasp model's start, with the grasp law."""

    def __init__(self, scene, grasp_model, timestep: float = 1e-3, noslip: int = 0):
        import mujoco

        self.mj = mujoco
        x0 = grasp_model.initial_state()
        names = grasp_model.state_names
        self.model = mujoco.MjModel.from_xml_string(mjcf(scene, x0, names, timestep, noslip))
        self.data = mujoco.MjData(self.model)
        m, d = self.model, self.data
        joints = [f"q{i}{k}" for i, f in enumerate(scene.fingers, start=1)
                  for k in range(1, len(f.chain.joints) + 1)]
        self.dofs = np.array([m.joint(j).dofadr[0] for j in joints])
        for j in joints:
            d.qpos[m.joint(j).qposadr[0]] = x0[names.index(j)]
        mujoco.mj_forward(m, d)
        self.sites = [m.site(f"tip{i}").id for i in range(1, len(scene.fingers) + 1)]
        self.split = np.cumsum([len(f.chain.joints) for f in scene.fingers])[:-1]
        sp = dict(grasp_model.start_params)
        self.fd, self.c = scene.params["fd"], scene.params["c"]
        self.r_ctrl, self.k_center = scene.r_ctrl, scene.params["k_center"]
        self.r_bar0 = np.array([sp["r_bar0_x"], sp["r_bar0_y"], sp["r_bar0_z"]])
        self.body = m.body("object").id
        self.jac = np.zeros((3, m.nv))

    def law(self) -> None:
        """The grasp law's joint torques at the current state, into ``qfrc_applied``."""
        m, d, mj = self.model, self.data, self.mj
        r = [d.site_xpos[s].copy() for s in self.sites]
        N = len(r)
        r_bar = sum(r) / N
        tau = np.zeros(m.nv)
        for i, s in enumerate(self.sites):
            mj.mj_jacSite(m, d, self.jac, None, s)
            pull = (self.fd / self.r_ctrl) * sum((r[i] - r[j] for j in range(N) if j != i), np.zeros(3))
            pull = pull + (self.k_center / N) * (r_bar - self.r_bar0)
            tau -= self.jac.T @ pull
        tau[self.dofs] -= self.c * d.qvel[self.dofs]
        d.qfrc_applied[:] = 0.0
        d.qfrc_applied[self.dofs] = tau[self.dofs]

    def run(self, t_final: float, every: float = 0.01) -> dict:
        """Step to ``t_final``: the object's centre every ``every`` s, the largest |distance|
        between the surfaces at a contact over the run (0 for rigid contact), the wall time."""
        import time

        m, d, mj = self.model, self.data, self.mj
        n = int(round(t_final / m.opt.timestep))
        stride = max(1, int(round(every / m.opt.timestep)))
        t, pos, quat, depth = [], [], [], 0.0
        start = time.perf_counter()
        for k in range(n + 1):
            if k % stride == 0:
                t.append(d.time)
                pos.append(d.xpos[self.body].copy())
                quat.append(d.xquat[self.body].copy())
                for c in d.contact[:d.ncon]:
                    depth = max(depth, abs(float(c.dist)))
            if k < n:
                self.law()
                mj.mj_step(m, d)
        wall = time.perf_counter() - start
        return {"t": np.array(t), "pos": np.array(pos), "quat": np.array(quat), "depth": depth,
                "wall": wall, "ncon": int(d.ncon)}
