"""Structured pre-grasps (thesis 3.1.3) on the foam brick: geometry, determinism, no penetration."""

from __future__ import annotations

import json
from pathlib import Path

import igl
import numpy as np
import pytest
import torch
import trimesh
import yaml
from conftest import CONFIG_DIR
from scipy.spatial.transform import Rotation

from graspstab.objects.sdf import SDFGrid
from graspstab.synthesis import pregrasp
from graspstab.synthesis.kinematics import BatchedHandKinematics, HandPose
from graspstab.synthesis.pregrasp import (
    inflate_hull,
    object_centroid,
    palm_facing_rotation,
    sample_pregrasps,
)
from graspstab.synthesis.rotation import quat_to_matrix, rot6d_to_matrix

# the shipped defaults (config/synthesis/default.yaml), so the tests check what users run
PARAMS = yaml.safe_load((CONFIG_DIR / "synthesis" / "default.yaml").read_text())["pregrasp"]
DEFAULT_OPEN_JOINTS = tuple(PARAMS["open_joints"])
N = 64


@pytest.fixture(scope="module")
def mesh(foam_brick_dir: Path) -> trimesh.Trimesh:
    return trimesh.load(foam_brick_dir / "mesh.obj", force="mesh", process=False)


@pytest.fixture(scope="module")
def kin(built_hand_dir: Path) -> BatchedHandKinematics:
    return BatchedHandKinematics(built_hand_dir, dtype=torch.float64)


@pytest.fixture(scope="module")
def sample(mesh: trimesh.Trimesh, kin: BatchedHandKinematics) -> dict[str, np.ndarray]:
    return sample_pregrasps(mesh, kin, N, np.random.default_rng(0), PARAMS)


@pytest.fixture(scope="module")
def posed(sample: dict[str, np.ndarray], kin: BatchedHandKinematics) -> HandPose:
    return kin.forward(*(torch.from_numpy(sample[k]) for k in ("wrist_pos", "rot6d", "joints")))


def _surface_distance(mesh: trimesh.Trimesh, points: np.ndarray) -> np.ndarray:
    sq, _, _ = igl.point_mesh_squared_distance(
        np.ascontiguousarray(points, dtype=np.float64),
        np.asarray(mesh.vertices, dtype=np.float64),
        np.asarray(mesh.faces, dtype=np.int64),
    )
    return np.sqrt(sq)


def _angle_deg(u: np.ndarray, v: np.ndarray) -> np.ndarray:
    return np.degrees(np.arccos(np.clip(np.sum(u * v, axis=1), -1.0, 1.0)))


# ----------------------------------------------------------------------------- inflated hull


def test_inflated_hull_vertices_are_rho_farther(mesh: trimesh.Trimesh) -> None:
    rho = PARAMS["inflation"]
    hull = mesh.convex_hull
    inflated = inflate_hull(mesh, rho)
    c = object_centroid(mesh)
    before = np.linalg.norm(hull.vertices - c, axis=1)
    after = np.linalg.norm(inflated.vertices - c, axis=1)
    assert np.allclose(after - before, rho, atol=1e-12, rtol=0)
    # moved radially: same direction from the centroid
    u0 = (hull.vertices - c) / before[:, None]
    u1 = (inflated.vertices - c) / after[:, None]
    assert np.allclose(u0, u1, atol=1e-12)
    assert np.array_equal(inflated.faces, hull.faces)
    assert inflated.volume > hull.volume


def test_inflate_hull_rejects_nonpositive_rho(mesh: trimesh.Trimesh) -> None:
    with pytest.raises(ValueError, match="rho"):
        inflate_hull(mesh, 0.0)


# ----------------------------------------------------------------------------- samples


def test_output_shapes(sample: dict[str, np.ndarray]) -> None:
    shapes = {
        "wrist_pos": (N, 3),
        "rot6d": (N, 6),
        "quat": (N, 4),
        "joints": (N, 16),
        "anchor": (N, 3),
        "surface_point": (N, 3),
        "direction": (N, 3),
        "direction_raw": (N, 3),
        "standoff": (N,),
        "roll": (N,),
    }
    assert {k: v.shape for k, v in sample.items()} == shapes
    assert all(np.all(np.isfinite(v)) for v in sample.values())


def test_anchors_lie_on_the_inflated_hull(
    mesh: trimesh.Trimesh, sample: dict[str, np.ndarray]
) -> None:
    inflated = inflate_hull(mesh, PARAMS["inflation"])
    assert _surface_distance(inflated, sample["anchor"]).max() < 1e-9
    # spread over the hull, not clustered: anchors on both sides of the object in x and y
    for axis in (0, 1):
        assert sample["anchor"][:, axis].min() < 0 < sample["anchor"][:, axis].max()


def test_surface_points_are_the_nearest_object_points(
    mesh: trimesh.Trimesh, sample: dict[str, np.ndarray]
) -> None:
    s, a = sample["surface_point"], sample["anchor"]
    assert _surface_distance(mesh, s).max() < 1e-9
    # nearest: agrees with trimesh's independent closest-point query
    _, dist, _ = trimesh.proximity.closest_point(mesh, a)
    assert np.allclose(np.linalg.norm(s - a, axis=1), dist, atol=1e-6)
    # the inflated hull lies outside the object: the anchor is well away from the surface
    assert np.linalg.norm(s - a, axis=1).min() > 0.02


def test_directions(sample: dict[str, np.ndarray]) -> None:
    raw, direction = sample["direction_raw"], sample["direction"]
    delta = sample["surface_point"] - sample["anchor"]
    assert np.allclose(raw, delta / np.linalg.norm(delta, axis=1, keepdims=True), atol=1e-12)
    assert np.allclose(np.linalg.norm(direction, axis=1), 1.0, atol=1e-12)
    assert _angle_deg(direction, raw).max() <= PARAMS["cone_half_angle_deg"] + 1e-9
    assert _angle_deg(direction, raw).max() > 5.0  # jittered at all
    assert np.all(direction[:, 2] <= 0.0)  # reject_upward


def test_palm_faces_the_direction_and_focus_is_backed_off(
    sample: dict[str, np.ndarray], posed: HandPose
) -> None:
    assert np.allclose(posed.palm_normal.numpy(), sample["direction"], atol=1e-12)
    focus = sample["surface_point"] - sample["standoff"][:, None] * sample["direction"]
    assert np.allclose(posed.grasp_focus.numpy(), focus, atol=1e-12)
    lo, hi = PARAMS["standoff"]
    assert np.all((sample["standoff"] >= lo) & (sample["standoff"] <= hi))
    # with d ~ rho the focus lands near the anchor (3.1.3), within ~ d + rho in the worst case
    near = np.linalg.norm(posed.grasp_focus.numpy() - sample["anchor"], axis=1)
    assert np.median(near) < 0.05


def test_rotation_outputs_agree(sample: dict[str, np.ndarray]) -> None:
    rot = rot6d_to_matrix(torch.from_numpy(sample["rot6d"]))
    assert torch.allclose(quat_to_matrix(torch.from_numpy(sample["quat"])), rot, atol=1e-12)
    assert np.all(sample["quat"][:, 0] >= 0)
    assert np.allclose(np.linalg.norm(sample["rot6d"][:, :3], axis=1), 1.0)
    assert np.all((sample["roll"] >= 0) & (sample["roll"] < 2 * np.pi))


def test_roll_is_a_rotation_about_the_direction(kin: BatchedHandKinematics) -> None:
    """R(d, r2) = Rot(d, r2 - r1) R(d, r1): the roll turns the hand about the approach axis."""
    rng = np.random.default_rng(3)
    d = rng.normal(size=(50, 3))
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    r1, r2 = rng.uniform(0, 2 * np.pi, size=(2, 50))
    normal = kin.palm_normal_root.numpy()
    rot1 = palm_facing_rotation(d, r1, normal)
    rot2 = palm_facing_rotation(d, r2, normal)
    assert np.allclose(rot1 @ normal, d, atol=1e-12)
    assert np.allclose(rot1.transpose(0, 2, 1) @ rot1, np.eye(3), atol=1e-12)
    assert np.allclose(np.linalg.det(rot1), 1.0)
    turn = [Rotation.from_rotvec(a * v).as_matrix() for a, v in zip(r2 - r1, d, strict=True)]
    assert np.allclose(np.asarray(turn) @ rot1, rot2, atol=1e-12)


def test_joints_are_the_fixed_open_configuration(sample: dict[str, np.ndarray]) -> None:
    assert np.array_equal(sample["joints"], np.tile(PARAMS["open_joints"], (N, 1)))


def test_same_seed_same_output(
    mesh: trimesh.Trimesh, kin: BatchedHandKinematics, sample: dict[str, np.ndarray]
) -> None:
    again = sample_pregrasps(mesh, kin, N, np.random.default_rng(0), PARAMS)
    assert all(np.array_equal(again[k], sample[k]) for k in sample)
    other = sample_pregrasps(mesh, kin, N, np.random.default_rng(1), PARAMS)
    assert not np.allclose(other["anchor"], sample["anchor"])


def test_no_deep_penetration(
    foam_brick_dir: Path, kin: BatchedHandKinematics, posed: HandPose
) -> None:
    """Measured on the foam brick: every candidate is outside (min 15 mm at seed 0, n = 256);
    across the twelve objects at most 1 candidate in 30 000 was inside, by <= 4 mm."""
    sdf = SDFGrid.load(foam_brick_dir / "sdf.npz")
    dist, _ = sdf.query(posed.candidates.reshape(-1, 3).numpy())
    assert np.mean(dist > 0) >= 0.99
    assert dist.min() > -0.005
    # capsule surfaces too (points along each axis, minus the radius)
    t = torch.linspace(0, 1, 11, dtype=torch.float64)[None, None, :, None]
    axis = posed.capsule_p0[:, :, None] + (posed.capsule_p1 - posed.capsule_p0)[:, :, None] * t
    d_axis, _ = sdf.query(axis.reshape(-1, 3).numpy())
    clearance = d_axis.reshape(N, 16, 11) - kin.capsule_radii.numpy()[None, :, None]
    assert np.mean(clearance > 0) >= 0.99


def test_upward_directions_appear_without_rejection(
    mesh: trimesh.Trimesh, kin: BatchedHandKinematics
) -> None:
    params = {**PARAMS, "reject_upward": False}
    out = sample_pregrasps(mesh, kin, 2000, np.random.default_rng(2), params)
    assert np.any(out["direction"][:, 2] > 0.1)
    # jitter is uniform on the spherical cap: 1 - cos(angle) is uniform on [0, 1 - cos(alpha)]
    cos_alpha = np.cos(np.radians(PARAMS["cone_half_angle_deg"]))
    u = (1.0 - np.sum(out["direction"] * out["direction_raw"], axis=1)) / (1.0 - cos_alpha)
    assert u.min() >= -1e-9 and u.max() <= 1.0 + 1e-9
    assert abs(u.mean() - 0.5) < 0.02  # 3 sigma of the mean of 2000 U(0, 1) is 0.019
    assert abs(np.mean(u < 0.25) - 0.25) < 0.03


def test_impossible_rejection_raises(
    mesh: trimesh.Trimesh, kin: BatchedHandKinematics, monkeypatch: pytest.MonkeyPatch
) -> None:
    def always_up(n: np.ndarray, half_angle: float, rng: np.random.Generator) -> np.ndarray:
        return np.tile([0.0, 0.0, 1.0], (len(n), 1))

    monkeypatch.setattr(pregrasp, "jitter_in_cone", always_up)
    monkeypatch.setattr(pregrasp, "MAX_ROUNDS", 5)
    with pytest.raises(RuntimeError, match="upward component after 5 rounds"):
        sample_pregrasps(mesh, kin, 4, np.random.default_rng(0), PARAMS)


def test_bad_params_raise(mesh: trimesh.Trimesh, kin: BatchedHandKinematics) -> None:
    rng = np.random.default_rng(0)
    with pytest.raises(KeyError, match="standoff"):
        sample_pregrasps(mesh, kin, 2, rng, {k: v for k, v in PARAMS.items() if k != "standoff"})
    joints = list(DEFAULT_OPEN_JOINTS)
    joints[5] = 3.0
    with pytest.raises(ValueError, match="right_i-mcp"):
        sample_pregrasps(mesh, kin, 2, rng, {**PARAMS, "open_joints": joints})
    with pytest.raises(ValueError, match="16 angles"):
        sample_pregrasps(mesh, kin, 2, rng, {**PARAMS, "open_joints": joints[:15]})


# ----------------------------------------------------------------------------- open joints


def _segment_distance_brute(
    p0: np.ndarray, p1: np.ndarray, q0: np.ndarray, q1: np.ndarray, steps: int = 200
) -> np.ndarray:
    """Lower bound of the distance between segments (P, 3) pairs by dense sampling: the sampled
    minimum minus the largest gap a sample can leave (half a step along each segment)."""
    t = np.linspace(0.0, 1.0, steps + 1)[None, :, None]
    a = p0[:, None] + (p1 - p0)[:, None] * t
    b = q0[:, None] + (q1 - q0)[:, None] * t
    sampled = np.linalg.norm(a[:, :, None] - b[:, None, :], axis=-1).min(axis=(1, 2))
    slack = 0.5 * (np.linalg.norm(p1 - p0, axis=1) + np.linalg.norm(q1 - q0, axis=1)) / steps
    return sampled - slack


def test_default_open_joints_are_open_and_collision_free(kin: BatchedHandKinematics) -> None:
    q = torch.tensor([DEFAULT_OPEN_JOINTS], dtype=torch.float64)
    assert torch.all(q >= kin.joint_lower) and torch.all(q <= kin.joint_upper)
    identity = torch.tensor([[1.0, 0, 0, 0, 1, 0]], dtype=torch.float64)
    pose = kin.forward(torch.zeros(1, 3, dtype=torch.float64), identity, q)
    p0, p1 = pose.capsule_p0[0].numpy(), pose.capsule_p1[0].numpy()
    i, j = kin.pairs[:, 0].numpy(), kin.pairs[:, 1].numpy()
    gap = _segment_distance_brute(p0[i], p1[i], p0[j], p1[j])
    radii = kin.capsule_radii.numpy()
    assert np.all(gap > radii[i] + radii[j])  # no interpenetrating capsule pair
    # the cavity: the thumb tip stands in front of the palm, away from the index fingertip
    tip = {name: kin.body_index(body) for name, body in _fingertips(kin).items()}
    thumb, index = pose.body_pos[0, tip["thumb"]], pose.body_pos[0, tip["index"]]
    normal = kin.palm_normal_root
    assert float((thumb - index) @ normal) > 0.04
    assert float(torch.linalg.vector_norm(thumb - index)) > 0.08


def _fingertips(kin: BatchedHandKinematics) -> dict[str, str]:
    return json.loads((kin.hand_dir / "hand.json").read_text())["fingertips"]
