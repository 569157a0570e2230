"""A straightforward one-grasp-at-a-time energy (MuJoCo kinematics, numpy, no culling).

It exists as an independent reference: tests check the batched torch energy against it, and the
synthesis benchmark measures the batched annealer's speed-up over it (docs/design.md, targets).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from graspstab.common.io import read_json
from graspstab.hand.kinematics import HandKinematics
from graspstab.objects.sdf import SDFGrid


def _rot6d_to_matrix(r6: np.ndarray) -> np.ndarray:
    a = r6[:3] / np.linalg.norm(r6[:3])
    b = r6[3:] - a * np.dot(a, r6[3:])
    b = b / np.linalg.norm(b)
    return np.stack([a, b, np.cross(a, b)], axis=1)


def _matrix_to_quat(mat: np.ndarray) -> np.ndarray:
    import mujoco

    quat = np.zeros(4)
    mujoco.mju_mat2Quat(quat, mat.reshape(-1))
    return quat


def _point_segment_distance(q: np.ndarray, a: np.ndarray, b: np.ndarray) -> np.ndarray:
    ab = b - a
    t = np.clip((q - a) @ ab / max(float(ab @ ab), 1e-18), 0.0, 1.0)
    return np.linalg.norm(q - (a + t[:, None] * ab), axis=1)


def _segment_distance(p1: np.ndarray, q1: np.ndarray, p2: np.ndarray, q2: np.ndarray) -> float:
    """Closest distance of two segments (Ericson, Real-Time Collision Detection, 5.1.9)."""
    d1, d2, r = q1 - p1, q2 - p2, p1 - p2
    a, e, f = d1 @ d1, d2 @ d2, d2 @ r
    eps = 1e-18
    if a <= eps and e <= eps:
        return float(np.linalg.norm(r))
    if a <= eps:
        s, t = 0.0, float(np.clip(f / e, 0, 1))
    else:
        c = d1 @ r
        if e <= eps:
            s, t = float(np.clip(-c / a, 0, 1)), 0.0
        else:
            b = d1 @ d2
            denom = a * e - b * b
            s = float(np.clip((b * f - c * e) / denom, 0, 1)) if denom > eps else 0.0
            t = (b * s + f) / e
            if t < 0:
                s, t = float(np.clip(-c / a, 0, 1)), 0.0
            elif t > 1:
                s, t = float(np.clip((b - c) / a, 0, 1)), 1.0
    return float(np.linalg.norm((p1 + d1 * s) - (p2 + d2 * t)))


class ReferenceEnergy:
    """E(g) of eq. 4 (plus E_hpen) for one grasp at a time, written plainly from the equations."""

    def __init__(self, object_dir: str | Path, hand_dir: str | Path, weights: dict) -> None:
        self.kin = HandKinematics(hand_dir)
        self.sdf = SDFGrid.load(Path(object_dir) / "sdf.npz")
        self.hull = np.load(Path(object_dir) / "hull_points.npy").astype(np.float64)
        caps = read_json(Path(hand_dir) / "capsules.json")
        self.capsules = caps["capsules"]
        self.box = caps["palm_box"]
        self.pairs = [tuple(p) for p in caps["pairs"]]
        with np.load(Path(hand_dir) / "surface_points.npz") as npz:
            self.surface_points = np.asarray(npz["points"], dtype=np.float64)
            self.surface_body = [str(b) for b in npz["body"]]
        hand = read_json(Path(hand_dir) / "hand.json")
        self.lower = np.asarray(hand["joint_lower"])
        self.upper = np.asarray(hand["joint_upper"])
        self.weights = dict(weights)

    def terms(self, wrist_pos: np.ndarray, rot6d: np.ndarray, joints: np.ndarray) -> dict:
        """Every unweighted term and the weighted total of one grasp."""
        quat = _matrix_to_quat(_rot6d_to_matrix(np.asarray(rot6d, dtype=np.float64)))
        points = self.kin.candidates_world(wrist_pos, quat, joints)
        poses = {
            self.kin.model.body(i).name: (
                self.kin.data.xpos[i].copy(),
                self.kin.data.xmat[i].reshape(3, 3).copy(),
            )
            for i in range(1, self.kin.model.nbody)
        }
        dist, normal = self.sdf.query(points)
        e_dis = float(np.sum(np.abs(dist)))  # eq. 5
        c = -normal  # inward contact normals, eq. 6
        force = c.sum(axis=0)
        moment = np.cross(points, c).sum(axis=0)  # eq. 7-9
        e_fc = float(force @ force + moment @ moment)  # eq. 10
        ends = []
        hand_sdf = np.full(len(self.hull), np.inf)
        for cap in self.capsules:
            pos, rot = poses[cap["body"]]
            a = pos + rot @ np.asarray(cap["p0"])
            b = pos + rot @ np.asarray(cap["p1"])
            ends.append((a, b))
            d = _point_segment_distance(self.hull, a, b) - cap["radius"]
            hand_sdf = np.minimum(hand_sdf, d)
        pos, rot = poses[self.box["body"]]
        centre = pos + rot @ np.asarray(self.box["center"])
        axes = rot @ np.asarray(self.box["rotation"])
        local = (self.hull - centre) @ axes
        qd = np.abs(local) - np.asarray(self.box["half_extents"])
        box_sdf = np.linalg.norm(np.maximum(qd, 0), axis=1) + np.minimum(qd.max(axis=1), 0)
        hand_sdf = np.minimum(hand_sdf, box_sdf)
        e_pen = float(np.sum(np.maximum(-hand_sdf, 0)))  # eq. 11
        e_spen = 0.0
        for i, j in self.pairs:  # eq. 12-13
            gap = _segment_distance(*ends[i], *ends[j])
            gap -= self.capsules[i]["radius"] + self.capsules[j]["radius"]
            e_spen += max(-gap, 0.0)
        q = np.asarray(joints, dtype=np.float64)
        e_joint = float(
            np.sum(np.maximum(q - self.upper, 0) + np.maximum(self.lower - q, 0))
        )  # eq. 14
        # our addition: hand surface points inside the object (eq. 11 the other way round)
        world = np.array(
            [
                poses[b][0] + poses[b][1] @ x
                for b, x in zip(self.surface_body, self.surface_points, strict=True)
            ]
        )
        e_hpen = float(np.sum(np.maximum(-self.sdf.query(world)[0], 0)))
        out = {
            "dis": e_dis, "fc": e_fc, "pen": e_pen, "spen": e_spen, "joint": e_joint,
            "hpen": e_hpen,
        }  # fmt: skip
        out["total"] = sum(self.weights[k] * out[k] for k in list(out))
        return out

    def __call__(self, wrist_pos: np.ndarray, rot6d: np.ndarray, joints: np.ndarray) -> float:
        """The total energy of one grasp (eq. 4)."""
        return self.terms(wrist_pos, rot6d, joints)["total"]
