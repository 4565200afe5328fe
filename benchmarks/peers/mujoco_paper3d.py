"""paper3d in MuJoCo (soft contact): the same bodies, masses, inertias, gravity, start and
grasp law, for ``benchmarks/soft_contact.py``: ``gs.export.mjcf`` writes the scene
(docs/conventions.md section 12: nested finger bodies with hinges, rod inertias, sphere
fingertips, an ellipsoid geom for the object, finger links with ``gravcomp="1"``) and
``gs.export.paper_law`` applies the paper's 3D grasp law as joint torques before every step:
``tau_i = -c q_i' - J_i^T [(fd / r_ctrl) sum_j (r_i - r_j) + (k_center / N)(r_bar - r_bar0)]``.

Contacts are only fingertip against object, with ``condim=4``: sliding and torsional
friction, and rolling free. MuJoCo's torsional friction is Coulomb-like, not the grasp
model's viscous 2e-5 N m s; ``TORSION`` sets its coefficient.
"""
from __future__ import annotations

import numpy as np

from grasping_sym import export

#: Sliding and torsional friction coefficients of the fingertip contacts (torsional in m).
FRICTION = 1.0
TORSION = 1e-3
#: m, contact margin and gap (contacts found 1 mm apart, acting when they touch).
MARGIN = 0.001


class MujocoGrasp:
    """The MuJoCo model of a grasp scene at the grasp model's start, with the grasp law."""

    def __init__(self, scene, grasp_model, timestep: float = 1e-3, noslip: int = 0):
        import mujoco

        self.mj = mujoco
        self.model = mujoco.MjModel.from_xml_string(export.mjcf(
            grasp_model, timestep=timestep, friction=FRICTION, torsion=TORSION, margin=MARGIN,
            noslip=noslip))
        self.data = mujoco.MjData(self.model)
        mujoco.mj_resetDataKeyframe(self.model, self.data, 0)
        mujoco.mj_forward(self.model, self.data)
        self.body = self.model.body("object").id
        self._law = export.paper_law(grasp_model)

    def law(self) -> None:
        """The grasp law's joint torques at the current state, into ``qfrc_applied``."""
        self._law(self.model, self.data)

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
