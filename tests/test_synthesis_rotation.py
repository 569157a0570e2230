"""Tests of the 6-D wrist rotation (thesis 3.1.1): round trips, MuJoCo agreement, continuity."""

from __future__ import annotations

import math

import mujoco
import numpy as np
import pytest
import torch

from graspstab.synthesis.rotation import (
    matrix_to_quat,
    matrix_to_rot6d,
    quat_to_matrix,
    rot6d_to_matrix,
    rot6d_to_quat,
)


def _random_rotations(n: int, seed: int = 0) -> torch.Tensor:
    """Uniform random rotations (float64) plus the awkward ones: identity and half-turns."""
    rng = np.random.default_rng(seed)
    q = rng.normal(size=(n, 4))
    q /= np.linalg.norm(q, axis=1, keepdims=True)
    special = np.array(
        [
            [1.0, 0.0, 0.0, 0.0],
            [0.0, 1.0, 0.0, 0.0],  # half-turns: w = 0, the branch a naive formula divides by
            [0.0, 0.0, 1.0, 0.0],
            [0.0, 0.0, 0.0, 1.0],
            [0.0, 1.0, 1.0, 0.0],
            [1e-9, 0.0, 1.0, 1.0],
        ]
    )
    q = np.concatenate([q, special / np.linalg.norm(special, axis=1, keepdims=True)])
    return quat_to_matrix(torch.from_numpy(q))


def _orthonormality_error(mat: torch.Tensor) -> float:
    eye = torch.eye(3, dtype=mat.dtype)
    return float((mat.transpose(-1, -2) @ mat - eye).abs().max())


def test_matrix_to_6d_to_matrix_is_exact() -> None:
    mats = _random_rotations(200)
    back = rot6d_to_matrix(matrix_to_rot6d(mats))
    assert torch.allclose(back, mats, atol=1e-13, rtol=0)


def test_6d_to_matrix_to_6d_for_orthonormal_columns() -> None:
    r6 = matrix_to_rot6d(_random_rotations(200, seed=1))
    assert torch.allclose(matrix_to_rot6d(rot6d_to_matrix(r6)), r6, atol=1e-13, rtol=0)


def test_unnormalised_6d_gives_proper_rotations() -> None:
    rng = np.random.default_rng(2)
    r6 = torch.from_numpy(rng.normal(scale=3.0, size=(4, 50, 6)))  # extra leading dims
    mats = rot6d_to_matrix(r6)
    assert mats.shape == (4, 50, 3, 3)
    assert _orthonormality_error(mats) < 1e-12
    assert torch.allclose(torch.linalg.det(mats), torch.ones(4, 50, dtype=torch.float64))
    # the first column keeps the direction of the first 3-vector (Gram-Schmidt)
    first = r6[..., :3] / r6[..., :3].norm(dim=-1, keepdim=True)
    assert torch.allclose(mats[..., :, 0], first, atol=1e-12)


def test_float32_stays_float32() -> None:
    r6 = torch.randn(8, 6, generator=torch.Generator().manual_seed(0))
    mats = rot6d_to_matrix(r6)
    assert mats.dtype == torch.float32
    assert matrix_to_quat(mats).dtype == torch.float32
    assert _orthonormality_error(mats) < 1e-5


def test_quaternion_agrees_with_mujoco() -> None:
    mats = _random_rotations(300, seed=3)
    quats = matrix_to_quat(mats).numpy()
    assert np.all(quats[:, 0] >= 0)
    assert np.allclose(np.linalg.norm(quats, axis=1), 1.0)
    for mat, quat in zip(mats.numpy(), quats, strict=True):
        ref = np.zeros(4)
        mujoco.mju_mat2Quat(ref, mat.reshape(-1))
        # equal up to the sign ambiguity q ~ -q
        assert min(np.abs(ref - quat).max(), np.abs(ref + quat).max()) < 1e-12


def test_quaternion_round_trip() -> None:
    mats = _random_rotations(300, seed=4)
    assert torch.allclose(quat_to_matrix(matrix_to_quat(mats)), mats, atol=1e-13, rtol=0)
    # and quat_to_matrix agrees with MuJoCo's own conversion
    q = matrix_to_quat(mats).numpy()
    ref = np.zeros(9)
    mujoco.mju_quat2Mat(ref, q[7])
    assert np.allclose(ref.reshape(3, 3), mats[7].numpy(), atol=1e-13)


def test_rot6d_to_quat_chain() -> None:
    r6 = torch.randn(20, 6, dtype=torch.float64, generator=torch.Generator().manual_seed(5))
    assert torch.allclose(quat_to_matrix(rot6d_to_quat(r6)), rot6d_to_matrix(r6), atol=1e-13)


@pytest.mark.parametrize("step", [1e-3, 1e-5])
def test_small_6d_change_gives_small_matrix_change(step: float) -> None:
    """Continuity of 3.1.1: |dR| is O(|dr6|), uniformly over random (non-degenerate) inputs."""
    gen = torch.Generator().manual_seed(6)
    r6 = torch.randn(500, 6, dtype=torch.float64, generator=gen)
    # keep away from the degenerate set (tiny or parallel columns), where no map is continuous
    a1, a2 = r6[:, :3], r6[:, 3:]
    cos = (a1 * a2).sum(-1).abs() / (a1.norm(dim=-1) * a2.norm(dim=-1))
    ok = (a1.norm(dim=-1) > 0.3) & (a2.norm(dim=-1) > 0.3) & (cos < 0.95)
    r6 = r6[ok]
    delta = torch.randn(r6.shape, dtype=torch.float64, generator=gen)
    delta = step * delta / delta.norm(dim=-1, keepdim=True)
    change = (rot6d_to_matrix(r6 + delta) - rot6d_to_matrix(r6)).flatten(1).norm(dim=-1)
    # the Gram-Schmidt Lipschitz constant here is bounded by a few / (|a| sin angle)
    assert float(change.max()) < 50 * step
    assert float(change.max()) > 0


def test_quaternion_is_continuous_away_from_w_zero() -> None:
    """With w >= 0 the quaternion only jumps where w = 0; elsewhere a small rotation is small."""
    mats = _random_rotations(300, seed=7)[:300]
    q = matrix_to_quat(mats)
    keep = q[:, 0] > 0.1
    axis = torch.tensor([0.3, -0.5, 0.8], dtype=torch.float64)
    axis = axis / axis.norm()
    angle = 1e-4
    w, xyz = math.cos(angle / 2), math.sin(angle / 2) * axis
    small = quat_to_matrix(torch.cat([torch.tensor([w], dtype=torch.float64), xyz]))
    q2 = matrix_to_quat(mats @ small)
    assert float((q2 - q)[keep].norm(dim=-1).max()) < angle


def test_bad_shapes_raise() -> None:
    with pytest.raises(ValueError, match=r"\(\.\.\., 6\)"):
        rot6d_to_matrix(torch.zeros(3, 5))
    with pytest.raises(ValueError, match=r"\(\.\.\., 3, 3\)"):
        matrix_to_quat(torch.zeros(3, 3, 2))
