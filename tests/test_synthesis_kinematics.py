"""Batched torch hand kinematics against MuJoCo's mj_kinematics (HandKinematics), in float64."""

from __future__ import annotations

import json
from pathlib import Path

import mujoco
import numpy as np
import pytest
import torch

from graspstab.hand.kinematics import HandKinematics
from graspstab.synthesis.kinematics import BatchedHandKinematics, HandPose
from graspstab.synthesis.rotation import rot6d_to_matrix

TOL = 1e-9
POSE_FIELDS = (
    "body_pos",
    "body_rot",
    "candidates",
    "candidate_normals",
    "surface_points",
    "capsule_p0",
    "capsule_p1",
    "box_center",
    "box_rot",
    "grasp_focus",
    "palm_normal",
    "wrist_rot",
)


@pytest.fixture(scope="module")
def kin(built_hand_dir: Path) -> BatchedHandKinematics:
    return BatchedHandKinematics(built_hand_dir, dtype=torch.float64)


@pytest.fixture(scope="module")
def ref(built_hand_dir: Path) -> HandKinematics:
    return HandKinematics(built_hand_dir)


def _random_configs(
    kin: BatchedHandKinematics, n: int, seed: int
) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
    """Random wrist positions, unnormalised 6-D rotations and joints uniform within the limits."""
    rng = np.random.default_rng(seed)
    pos = rng.normal(scale=0.2, size=(n, 3))
    r6 = rng.normal(size=(n, 6))
    lower, upper = kin.joint_lower.numpy(), kin.joint_upper.numpy()
    joints = rng.uniform(lower, upper, size=(n, 16))
    return torch.from_numpy(pos), torch.from_numpy(r6), torch.from_numpy(joints)


def _mujoco_quat(rot: np.ndarray) -> np.ndarray:
    quat = np.zeros(4)
    mujoco.mju_mat2Quat(quat, rot.reshape(-1))
    return quat


@pytest.fixture(scope="module")
def batch(
    kin: BatchedHandKinematics,
) -> tuple[tuple[torch.Tensor, torch.Tensor, torch.Tensor], HandPose]:
    inputs = _random_configs(kin, 6, seed=0)
    return inputs, kin.forward(*inputs)


def test_body_poses_match_mujoco(
    kin: BatchedHandKinematics, ref: HandKinematics, batch: tuple
) -> None:
    (pos, r6, joints), pose = batch
    rot = rot6d_to_matrix(r6).numpy()
    for b in range(len(pos)):
        links = ref.link_poses(pos[b].numpy(), _mujoco_quat(rot[b]), joints[b].numpy())
        assert len(links) == kin.nbody - 1
        for name, (p, r) in links.items():
            i = kin.body_index(name)
            assert np.abs(pose.body_pos[b, i].numpy() - p).max() < TOL, name
            assert np.abs(pose.body_rot[b, i].numpy() - r).max() < TOL, name
    # row 0 is the world body
    assert torch.equal(pose.body_pos[:, 0], torch.zeros(len(pos), 3, dtype=torch.float64))
    assert torch.equal(
        pose.body_rot[:, 0], torch.eye(3, dtype=torch.float64).expand(len(pos), 3, 3)
    )


def test_root_pose_is_the_wrist_input(kin: BatchedHandKinematics, batch: tuple) -> None:
    (pos, r6, _), pose = batch
    root = kin.body_index("hand_root")
    assert torch.allclose(pose.body_pos[:, root], pos, atol=0, rtol=0)
    assert torch.allclose(pose.body_rot[:, root], rot6d_to_matrix(r6), atol=1e-15)
    assert torch.allclose(pose.wrist_rot, rot6d_to_matrix(r6), atol=1e-15)


def test_candidates_match_mujoco(ref: HandKinematics, batch: tuple) -> None:
    (pos, r6, joints), pose = batch
    rot = rot6d_to_matrix(r6).numpy()
    assert pose.candidates.shape == (len(pos), 120, 3)
    for b in range(len(pos)):
        points, normals = ref.candidates_world(
            pos[b].numpy(), _mujoco_quat(rot[b]), joints[b].numpy(), with_normals=True
        )
        assert np.abs(pose.candidates[b].numpy() - points).max() < TOL
        assert np.abs(pose.candidate_normals[b].numpy() - normals).max() < TOL
    norms = pose.candidate_normals.norm(dim=-1)
    assert torch.allclose(norms, torch.ones_like(norms), atol=1e-9)


def test_surface_points_match_mujoco(
    ref: HandKinematics, built_hand_dir: Path, batch: tuple
) -> None:
    with np.load(built_hand_dir / "surface_points.npz") as npz:
        local, bodies = npz["points"], npz["body"].astype(str)
    (pos, r6, joints), pose = batch
    rot = rot6d_to_matrix(r6).numpy()
    assert pose.surface_points.shape == (len(pos), len(local), 3)
    for b in range(len(pos)):
        links = ref.link_poses(pos[b].numpy(), _mujoco_quat(rot[b]), joints[b].numpy())
        world = [links[n][0] + links[n][1] @ x for n, x in zip(bodies, local, strict=True)]
        assert np.abs(pose.surface_points[b].numpy() - world).max() < TOL


def test_capsules_box_and_palm_points_match_mujoco_poses(
    kin: BatchedHandKinematics, ref: HandKinematics, built_hand_dir: Path, batch: tuple
) -> None:
    caps = json.loads((built_hand_dir / "capsules.json").read_text())
    hand = json.loads((built_hand_dir / "hand.json").read_text())
    (pos, r6, joints), pose = batch
    rot = rot6d_to_matrix(r6).numpy()
    assert pose.capsule_p0.shape == (len(pos), 16, 3)
    for b in range(len(pos)):
        links = ref.link_poses(pos[b].numpy(), _mujoco_quat(rot[b]), joints[b].numpy())
        for k, cap in enumerate(caps["capsules"]):
            p, r = links[cap["body"]]
            assert np.abs(pose.capsule_p0[b, k].numpy() - (p + r @ cap["p0"])).max() < TOL
            assert np.abs(pose.capsule_p1[b, k].numpy() - (p + r @ cap["p1"])).max() < TOL
        box = caps["palm_box"]
        p, r = links[box["body"]]
        assert np.abs(pose.box_center[b].numpy() - (p + r @ box["center"])).max() < TOL
        assert np.abs(pose.box_rot[b].numpy() - r @ np.asarray(box["rotation"])).max() < TOL
        p, r = links[hand["palm_body"]]
        assert np.abs(pose.grasp_focus[b].numpy() - (p + r @ hand["grasp_focus"])).max() < TOL
        normal = np.asarray(hand["palm_normal"]) / np.linalg.norm(hand["palm_normal"])
        assert np.abs(pose.palm_normal[b].numpy() - r @ normal).max() < TOL


def test_batched_equals_one_at_a_time(kin: BatchedHandKinematics, batch: tuple) -> None:
    (pos, r6, joints), pose = batch
    for b in range(len(pos)):
        single = kin.forward(pos[b : b + 1], r6[b : b + 1], joints[b : b + 1])
        for field in POSE_FIELDS:
            assert torch.allclose(
                getattr(single, field)[0], getattr(pose, field)[b], atol=1e-14, rtol=0
            ), field


def test_root_frame_constants(kin: BatchedHandKinematics, ref: HandKinematics) -> None:
    """palm_normal_root / grasp_focus_root: the palm-frame values in hand_root's frame."""
    hand = json.loads((kin.hand_dir / "hand.json").read_text())
    links = ref.link_poses(np.zeros(3), np.array([1.0, 0, 0, 0]), np.zeros(16))
    p, r = links[hand["palm_body"]]
    normal = np.asarray(hand["palm_normal"]) / np.linalg.norm(hand["palm_normal"])
    assert np.allclose(kin.palm_normal_root.numpy(), r @ normal, atol=1e-12)
    assert np.allclose(kin.grasp_focus_root.numpy(), p + r @ hand["grasp_focus"], atol=1e-12)
    # at the identity wrist pose the world values equal the root-frame constants, any joints
    _, _, joints = _random_configs(kin, 3, seed=1)
    identity = torch.tensor([[1.0, 0, 0, 0, 1, 0]], dtype=torch.float64).expand(3, 6)
    pose = kin.forward(torch.zeros(3, 3, dtype=torch.float64), identity, joints)
    assert torch.allclose(pose.palm_normal, kin.palm_normal_root.expand(3, 3), atol=1e-14)
    assert torch.allclose(pose.grasp_focus, kin.grasp_focus_root.expand(3, 3), atol=1e-14)


def test_attributes(kin: BatchedHandKinematics, built_hand_dir: Path) -> None:
    hand = json.loads((built_hand_dir / "hand.json").read_text())
    caps = json.loads((built_hand_dir / "capsules.json").read_text())
    assert kin.joint_names == hand["joint_names"]
    assert np.allclose(kin.joint_lower.numpy(), hand["joint_lower"])
    assert np.allclose(kin.joint_upper.numpy(), hand["joint_upper"])
    assert kin.capsule_radii.shape == (16,)
    assert np.allclose(kin.capsule_radii.numpy(), [c["radius"] for c in caps["capsules"]])
    assert np.allclose(kin.box_half_extents.numpy(), caps["palm_box"]["half_extents"])
    assert kin.pairs.dtype == torch.long
    assert kin.pairs.tolist() == caps["pairs"]
    assert kin.capsule_radii.dtype == torch.float64


def test_float32_follows_input_dtype(kin: BatchedHandKinematics, batch: tuple) -> None:
    (pos, r6, joints), pose = batch
    pose32 = kin.forward(pos.float(), r6.float(), joints.float())
    for field in POSE_FIELDS:
        value = getattr(pose32, field)
        assert value.dtype == torch.float32, field
        assert torch.allclose(value.double(), getattr(pose, field), atol=2e-6), field
    assert BatchedHandKinematics(kin.hand_dir).joint_lower.dtype == torch.float32


def test_gradients_match_finite_differences(kin: BatchedHandKinematics) -> None:
    """Directional derivatives of a random linear functional of the outputs (autograd vs central
    differences), for the wrist position, the 6-D rotation and the joints together."""
    pos, r6, joints = _random_configs(kin, 3, seed=2)
    gen = torch.Generator().manual_seed(0)
    weights = torch.randn(3, 120 + 16, 3, dtype=torch.float64, generator=gen)

    def loss(p: torch.Tensor, r: torch.Tensor, q: torch.Tensor) -> torch.Tensor:
        pose = kin.forward(p, r, q)
        return (torch.cat((pose.candidates, pose.capsule_p1), dim=1) * weights).sum()

    inputs = [x.clone().requires_grad_(True) for x in (pos, r6, joints)]
    grads = torch.autograd.grad(loss(*inputs), inputs)
    for _ in range(3):
        dirs = [torch.randn(x.shape, dtype=torch.float64, generator=gen) for x in inputs]
        h = 1e-6
        plus = loss(*(x.detach() + h * d for x, d in zip(inputs, dirs, strict=True)))
        minus = loss(*(x.detach() - h * d for x, d in zip(inputs, dirs, strict=True)))
        numeric = float((plus - minus) / (2 * h))
        analytic = float(sum((g * d).sum() for g, d in zip(grads, dirs, strict=True)))
        assert abs(numeric - analytic) < 1e-6 * max(1.0, abs(analytic))


def test_bad_input_shapes_raise(kin: BatchedHandKinematics) -> None:
    pos, r6, joints = _random_configs(kin, 2, seed=3)
    with pytest.raises(ValueError, match=r"joints \(B, 16\)"):
        kin.forward(pos, r6, joints[:, :15])
    with pytest.raises(ValueError, match="rot6d"):
        kin.forward(pos, r6[:1], joints)


def test_unknown_body_lists_names(kin: BatchedHandKinematics) -> None:
    with pytest.raises(KeyError, match="hand_root"):
        kin.body_index("no_such_body")
