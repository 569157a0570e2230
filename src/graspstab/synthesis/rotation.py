"""Continuous 6-D wrist rotation (thesis 3.1.1, eq. 2): 6-D <-> matrix <-> MuJoCo quaternion.

The wrist orientation R in g = (P, R, theta) is the first two columns of the rotation matrix,
``r6 = (R[:, 0], R[:, 1])``; Gram-Schmidt turns any (non-degenerate) 6-vector into a rotation, so
the optimiser works in an unconstrained, continuous space (Zhou et al. 2019). MuJoCo takes the
result as a unit quaternion (w, x, y, z). All functions are torch, dtype-agnostic and batched over
any leading dimensions; no Python loops.
"""

from __future__ import annotations

import torch
from torch import Tensor

# Guards the Gram-Schmidt normalisations against a zero column (a degenerate 6-D vector).
_EPS = 1e-12


def _normalise(v: Tensor) -> Tensor:
    """Unit vectors along the last axis (a zero vector stays finite)."""
    return v / torch.linalg.vector_norm(v, dim=-1, keepdim=True).clamp_min(_EPS)


def rot6d_to_matrix(r6: Tensor) -> Tensor:
    """Rotation matrices (..., 3, 3) from 6-D vectors (..., 6) by Gram-Schmidt (3.1.1).

    ``r6[..., 0:3]`` gives the first column, ``r6[..., 3:6]`` (minus its component along the first)
    the second; the third is their cross product, so the result is a proper rotation.
    """
    if r6.shape[-1] != 6:
        raise ValueError(f"rot6d_to_matrix expects (..., 6), got {tuple(r6.shape)}")
    b1 = _normalise(r6[..., 0:3])
    a2 = r6[..., 3:6]
    b2 = _normalise(a2 - (b1 * a2).sum(dim=-1, keepdim=True) * b1)
    b3 = torch.linalg.cross(b1, b2, dim=-1)
    return torch.stack((b1, b2, b3), dim=-1)


def matrix_to_rot6d(mat: Tensor) -> Tensor:
    """6-D vectors (..., 6): the first two columns of rotations (..., 3, 3), concatenated."""
    if mat.shape[-2:] != (3, 3):
        raise ValueError(f"matrix_to_rot6d expects (..., 3, 3), got {tuple(mat.shape)}")
    return torch.cat((mat[..., :, 0], mat[..., :, 1]), dim=-1)


def _sqrt_positive(x: Tensor) -> Tensor:
    """sqrt(max(x, 0)) with a finite gradient at and below zero."""
    positive = x > 0
    return torch.where(positive, torch.sqrt(torch.where(positive, x, torch.ones_like(x))), 0.0)


def matrix_to_quat(mat: Tensor) -> Tensor:
    """Unit quaternions (..., 4) as MuJoCo's (w, x, y, z) from rotation matrices (..., 3, 3).

    Shepperd's method: all four branches are formed and, per matrix, the one with the largest
    denominator (|w|, |x|, |y| or |z| largest) is kept, so it is accurate for every rotation,
    including half-turns. Canonical sign: w >= 0.
    """
    if mat.shape[-2:] != (3, 3):
        raise ValueError(f"matrix_to_quat expects (..., 3, 3), got {tuple(mat.shape)}")
    m00, m01, m02 = mat[..., 0, 0], mat[..., 0, 1], mat[..., 0, 2]
    m10, m11, m12 = mat[..., 1, 0], mat[..., 1, 1], mat[..., 1, 2]
    m20, m21, m22 = mat[..., 2, 0], mat[..., 2, 1], mat[..., 2, 2]
    # 2|w|, 2|x|, 2|y|, 2|z|
    q_abs = _sqrt_positive(
        torch.stack(
            (
                1.0 + m00 + m11 + m22,
                1.0 + m00 - m11 - m22,
                1.0 - m00 + m11 - m22,
                1.0 - m00 - m11 + m22,
            ),
            dim=-1,
        )
    )
    # Row k = 4 q_k q (for the k-th branch), i.e. the quaternion scaled by 4 q_k.
    by_branch = torch.stack(
        (
            torch.stack((q_abs[..., 0] ** 2, m21 - m12, m02 - m20, m10 - m01), dim=-1),
            torch.stack((m21 - m12, q_abs[..., 1] ** 2, m10 + m01, m02 + m20), dim=-1),
            torch.stack((m02 - m20, m10 + m01, q_abs[..., 2] ** 2, m12 + m21), dim=-1),
            torch.stack((m10 - m01, m20 + m02, m21 + m12, q_abs[..., 3] ** 2), dim=-1),
        ),
        dim=-2,
    )
    # The chosen branch has q_abs >= 1 (2 * max |q_k| >= 1), so the floor only guards the others.
    candidates = by_branch / (2.0 * q_abs[..., None]).clamp_min(0.1)
    best = q_abs.argmax(dim=-1)
    index = best[..., None, None].expand(*best.shape, 1, 4)
    quat = torch.gather(candidates, -2, index).squeeze(-2)
    quat = torch.where(quat[..., :1] < 0, -quat, quat)
    return _normalise(quat)


def quat_to_matrix(quat: Tensor) -> Tensor:
    """Rotation matrices (..., 3, 3) from quaternions (..., 4) in MuJoCo order (w, x, y, z).

    The quaternion is normalised first, so any non-zero 4-vector is accepted.
    """
    if quat.shape[-1] != 4:
        raise ValueError(f"quat_to_matrix expects (..., 4), got {tuple(quat.shape)}")
    w, x, y, z = _normalise(quat).unbind(dim=-1)
    rows = (
        1 - 2 * (y * y + z * z),
        2 * (x * y - w * z),
        2 * (x * z + w * y),
        2 * (x * y + w * z),
        1 - 2 * (x * x + z * z),
        2 * (y * z - w * x),
        2 * (x * z - w * y),
        2 * (y * z + w * x),
        1 - 2 * (x * x + y * y),
    )
    return torch.stack(rows, dim=-1).reshape(*quat.shape[:-1], 3, 3)


def rot6d_to_quat(r6: Tensor) -> Tensor:
    """MuJoCo quaternions (..., 4), w >= 0, from 6-D vectors (..., 6): the chain of 3.1.1."""
    return matrix_to_quat(rot6d_to_matrix(r6))
