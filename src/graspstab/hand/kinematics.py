"""Reference forward kinematics of the saved hand (MuJoCo mj_kinematics), for figures and tests.

The synthesis stage vectorises its own kinematics; this class is the ground truth it can be checked
against. Poses use the wrist convention of hand.xml: qpos[0:7] = palm position and quaternion.
"""

from __future__ import annotations

from pathlib import Path

import mujoco
import numpy as np

from graspstab.common.io import load_npz
from graspstab.hand import names
from graspstab.hand.model import HAND_XML

CANDIDATES_FILE = "contact_candidates.npz"


class HandKinematics:
    """Forward kinematics of ``hand_dir/hand.xml`` with its contact candidates."""

    def __init__(self, hand_dir: str | Path) -> None:
        self.hand_dir = Path(hand_dir)
        self.model = mujoco.MjModel.from_xml_path(str(self.hand_dir / HAND_XML))
        self.data = mujoco.MjData(self.model)
        wrist = self.model.joint(names.WRIST_JOINT)
        self.wrist_qpos = int(wrist.qposadr[0])
        self.joint_qpos = np.array(
            [int(self.model.joint(j).qposadr[0]) for j in names.FINGER_JOINTS], dtype=int
        )
        self.candidates = load_npz(self.hand_dir / CANDIDATES_FILE)
        self.candidate_body_ids = np.array(
            [self.model.body(str(b)).id for b in self.candidates["body"]], dtype=int
        )

    def set_configuration(
        self, wrist_pos: np.ndarray, wrist_quat: np.ndarray, joints: np.ndarray
    ) -> None:
        """Write g = (P, R as quaternion w-x-y-z, theta in canonical order) and run kinematics."""
        joints = np.asarray(joints, dtype=float)
        if joints.shape != (len(names.FINGER_JOINTS),):
            raise ValueError(f"joints must have shape (16,), got {joints.shape}")
        quat = np.asarray(wrist_quat, dtype=float)
        self.data.qpos[:] = self.model.qpos0
        self.data.qpos[self.wrist_qpos : self.wrist_qpos + 3] = wrist_pos
        self.data.qpos[self.wrist_qpos + 3 : self.wrist_qpos + 7] = quat / np.linalg.norm(quat)
        self.data.qpos[self.joint_qpos] = joints
        mujoco.mj_kinematics(self.model, self.data)

    def link_poses(
        self, wrist_pos: np.ndarray, wrist_quat: np.ndarray, joints: np.ndarray
    ) -> dict[str, tuple[np.ndarray, np.ndarray]]:
        """World pose of every body: name -> (position (3,), rotation matrix (3, 3))."""
        self.set_configuration(wrist_pos, wrist_quat, joints)
        return {
            self.model.body(i).name: (
                self.data.xpos[i].copy(),
                self.data.xmat[i].reshape(3, 3).copy(),
            )
            for i in range(1, self.model.nbody)
        }

    def candidates_world(
        self,
        wrist_pos: np.ndarray,
        wrist_quat: np.ndarray,
        joints: np.ndarray,
        with_normals: bool = False,
    ) -> np.ndarray | tuple[np.ndarray, np.ndarray]:
        """The 120 contact candidates in the world frame (and their outward normals if asked)."""
        self.set_configuration(wrist_pos, wrist_quat, joints)
        rot = self.data.xmat[self.candidate_body_ids].reshape(-1, 3, 3)
        pos = self.data.xpos[self.candidate_body_ids]
        points = pos + np.einsum("nij,nj->ni", rot, self.candidates["points"])
        if not with_normals:
            return points
        return points, np.einsum("nij,nj->ni", rot, self.candidates["normals"])
