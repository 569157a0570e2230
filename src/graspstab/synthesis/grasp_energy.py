"""The total grasp energy E(g) of eq. 4 (plus our E_hpen) for one object and the hand, batched."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import torch

from graspstab.common.io import load_npy
from graspstab.synthesis import energy as E
from graspstab.synthesis.kinematics import BatchedHandKinematics
from graspstab.synthesis.sdf_torch import TorchSDF

TERMS = E.WEIGHT_KEYS


class GraspEnergy:
    """E(g) = w_dis E_dis + w_fc E_fc + w_pen E_pen + w_spen E_spen + w_joint E_joint (3.1.4),
    plus w_hpen E_hpen (hand surface points inside the object; our addition,
    docs/protocols.md "Annealing energies")."""

    def __init__(
        self,
        kin: BatchedHandKinematics,
        sdf: TorchSDF,
        hull_points: np.ndarray,
        weights: dict[str, float],
        clusters: int = 48,
    ) -> None:
        missing = [k for k in TERMS if k not in weights]
        if missing:
            raise ValueError(f"synthesis.energy.weights lacks {missing}")
        self.kin = kin
        self.sdf = sdf
        self.dtype = kin.dtype
        self.weights = {k: float(weights[k]) for k in TERMS}
        points = torch.as_tensor(np.asarray(hull_points), dtype=self.dtype)
        self.pen_points = E.PenetrationPoints(points, n_clusters=clusters)
        self.radii = kin.capsule_radii
        self.pairs = kin.pairs

    @classmethod
    def load(
        cls,
        object_dir: str | Path,
        hand_dir: str | Path,
        weights: dict[str, float],
        dtype: torch.dtype = torch.float32,
        clusters: int = 48,
    ) -> GraspEnergy:
        """From a preprocessed object directory (sdf.npz, hull_points.npy) and a built hand."""
        object_dir = Path(object_dir)
        kin = BatchedHandKinematics(hand_dir, dtype=dtype)
        sdf = TorchSDF.load(object_dir / "sdf.npz", dtype=dtype)
        hull = load_npy(object_dir / "hull_points.npy")
        return cls(kin, sdf, hull, weights, clusters=clusters)

    def terms(
        self, wrist_pos: torch.Tensor, rot6d: torch.Tensor, joints: torch.Tensor
    ) -> dict[str, torch.Tensor]:
        """Every unweighted term (B,) and the weighted total under ``"total"``."""
        pose = self.kin.forward(wrist_pos, rot6d, joints)
        dist, normal = self.sdf.query(pose.candidates)
        terms = {
            "dis": E.e_dis(dist),
            # the inward contact normal is the reversed outward surface normal (3.1.4)
            "fc": E.e_fc(pose.candidates, -normal),
            "pen": E.e_pen(
                self.pen_points,
                pose.capsule_p0,
                pose.capsule_p1,
                self.radii,
                pose.box_center,
                pose.box_rot,
                self.kin.box_half_extents,
            ),
            "spen": E.e_spen(pose.capsule_p0, pose.capsule_p1, self.radii, self.pairs),
            "joint": E.e_joint(joints, self.kin.joint_lower, self.kin.joint_upper),
            # E_hpen (our addition) = e_hpen(sdf.query(surface points)), fused in one kernel
            "hpen": self.sdf.depth_sum(pose.surface_points),
        }
        terms["total"] = E.total_energy(terms, self.weights)
        return terms

    def __call__(
        self, wrist_pos: torch.Tensor, rot6d: torch.Tensor, joints: torch.Tensor
    ) -> torch.Tensor:
        """The total energy (B,), the annealer's objective."""
        return self.terms(wrist_pos, rot6d, joints)["total"]

    def hand_depths(
        self, wrist_pos: torch.Tensor, rot6d: torch.Tensor, joints: torch.Tensor
    ) -> torch.Tensor:
        """Depth of each hand surface point inside the object, ``-d`` (B, S) [m], < 0 outside."""
        pose = self.kin.forward(wrist_pos, rot6d, joints)
        return -self.sdf.query(pose.surface_points)[0]

    def candidate_distances(
        self, wrist_pos: torch.Tensor, rot6d: torch.Tensor, joints: torch.Tensor
    ) -> torch.Tensor:
        """Signed distance of the 120 contact candidates to the object (B, 120), negative inside."""
        pose = self.kin.forward(wrist_pos, rot6d, joints)
        return self.sdf.query(pose.candidates)[0]
