"""Energy terms of the grasp-synthesis objective (thesis 3.1.4, eqs. 4-14), batched over grasps.

Every term takes tensors with a leading grasp dimension ``B`` and returns a ``(B,)`` tensor in the
inputs' dtype. Frames: everything is in the object frame, which is the world frame with the object's
centre of mass at the origin (so moments are taken about the centre of mass).

The penetration term (eq. 11) lives in :mod:`graspstab.synthesis.penetration` (torch side and
wrappers), :mod:`~graspstab.synthesis.penetration_points` (the cluster tree of the hull samples)
and :mod:`~graspstab.synthesis.penetration_kernel` (numba); its public names are re-exported here.
"""

from __future__ import annotations

from collections.abc import Mapping

import torch
from torch import Tensor

from graspstab.synthesis.penetration import (
    PenetrationPoints,
    e_pen,
    e_pen_dense,
    penetration_candidates,
    penetration_depths,
)

__all__ = [
    "WEIGHT_KEYS",
    "PenetrationPoints",
    "e_dis",
    "e_fc",
    "e_hpen",
    "e_joint",
    "e_pen",
    "e_pen_dense",
    "e_spen",
    "penetration_candidates",
    "penetration_depths",
    "point_segment_distance",
    "segment_segment_distance",
    "total_energy",
]

WEIGHT_KEYS: tuple[str, ...] = ("dis", "fc", "pen", "spen", "joint", "hpen")
"""Names of the energy terms: eq. (4)'s order (weights of eq. 16), then our hand-penetration term
``hpen`` (:func:`e_hpen`, a documented deviation; weight 0 gives the reference's energy)."""


# --------------------------------------------------------------------------------------------
# E_dis, E_fc, E_joint, total energy (eqs. 4-10, 14)


def e_dis(dist: Tensor) -> Tensor:
    """Distance energy (eq. 5): ``sum_i |d(p_i)|`` over the N candidates, ``(B, N) -> (B,)``."""
    return dist.abs().sum(-1)


def e_fc(points: Tensor, inward_normals: Tensor) -> Tensor:
    """Force-closure energy (eqs. 6-10): ``||G c||^2`` for points and inward normals ``(B, N, 3)``.

    ``G c`` stacks the net force ``sum_i c_i`` and the net moment ``sum_i p_i x c_i`` about the
    object-frame origin (the centre of mass); ``G`` (eq. 7) is never built.
    """
    force = inward_normals.sum(-2)
    moment = torch.linalg.cross(points, inward_normals, dim=-1).sum(-2)
    return (force * force).sum(-1) + (moment * moment).sum(-1)


def e_joint(theta: Tensor, lower: Tensor, upper: Tensor) -> Tensor:
    """Joint-limit energy (eq. 14): linear violation of the limits, (B, 16) -> (B,)."""
    return ((theta - upper).clamp_min(0) + (lower - theta).clamp_min(0)).sum(-1)


def e_hpen(hand_dist: Tensor) -> Tensor:
    """Hand-in-object penetration: ``sum_x max(-d(x), 0)`` over hand surface points, ``(B, S)``.

    ``hand_dist`` is the object's signed distance (negative inside) at the points covering the
    hand's collision hulls, so each summand is how deep one point lies inside the object. Not in
    the reference: eq. (11)'s other direction (:mod:`graspstab.hand.surface_points` says why).
    """
    return (-hand_dist).clamp_min(0).sum(-1)


def total_energy(terms: Mapping[str, Tensor], weights: Mapping[str, float]) -> Tensor:
    """Weighted sum of eq. (4) plus ``w_hpen E_hpen``, keyed by :data:`WEIGHT_KEYS`.

    The thesis weights (100, 1, 10, 100, 1000) of eq. (16) live in the config, not here.
    """
    for name, given in (("terms", terms), ("weights", weights)):
        missing = [k for k in WEIGHT_KEYS if k not in given]
        unknown = [k for k in given if k not in WEIGHT_KEYS]
        if missing or unknown:
            raise KeyError(
                f"energy {name}: missing {missing}, unknown {unknown}; "
                f"expected exactly {WEIGHT_KEYS}"
            )
    total = weights[WEIGHT_KEYS[0]] * terms[WEIGHT_KEYS[0]]
    for k in WEIGHT_KEYS[1:]:
        total = total + weights[k] * terms[k]
    return total


# --------------------------------------------------------------------------------------------
# E_spen (eqs. 12-13)


Vec = tuple[Tensor, Tensor, Tensor]


def _sub(a: Vec, b: Vec) -> Vec:
    return (a[0] - b[0], a[1] - b[1], a[2] - b[2])


def _dot(a: Vec, b: Vec) -> Tensor:
    # component-wise: reductions over a size-3 axis are slow in torch on CPU
    return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]


def _norm(a: Vec) -> Tensor:
    return _dot(a, a).sqrt()


def _safe_ratio(num: Tensor, den: Tensor) -> Tensor:
    """``num / den`` clamped to [0, 1], 0 where ``den <= 0``."""
    pos = den > 0
    return torch.where(pos, num / torch.where(pos, den, 1.0), 0.0).clamp_(0.0, 1.0)


def _point_segment(q: Vec, a: Vec, d: Vec, dd: Tensor) -> Tensor:
    w = _sub(q, a)
    t = _safe_ratio(_dot(w, d), dd)
    return _norm((w[0] - t * d[0], w[1] - t * d[1], w[2] - t * d[2]))


def point_segment_distance(q: Tensor, a: Tensor, b: Tensor) -> Tensor:
    """Distance from points ``q (..., 3)`` to segments ``a-b (..., 3)`` (a = b allowed)."""
    qv, av, bv = q.unbind(-1), a.unbind(-1), b.unbind(-1)
    d = _sub(bv, av)
    return _point_segment(qv, av, d, _dot(d, d))


def segment_segment_distance(a0: Tensor, a1: Tensor, b0: Tensor, b1: Tensor) -> Tensor:
    """Shortest distance between segments ``a0-a1`` and ``b0-b1`` (``(..., 3)``, broadcast).

    The minimum of the convex squared distance over ``[0, 1]^2`` lies either where the two lines
    are closest (an interior candidate, used when its parameters are in range) or on an edge of the
    square, i.e. from an endpoint to the other segment. Each candidate is the distance of an actual
    pair of points, so the minimum never underestimates; parallel and zero-length segments fall
    back to the endpoint candidates and need no special case.
    """
    a0v, a1v, b0v, b1v = a0.unbind(-1), a1.unbind(-1), b0.unbind(-1), b1.unbind(-1)
    d1 = _sub(a1v, a0v)
    d2 = _sub(b1v, b0v)
    r = _sub(a0v, b0v)
    a = _dot(d1, d1)
    e = _dot(d2, d2)
    b = _dot(d1, d2)
    c = _dot(d1, r)
    f = _dot(d2, r)
    # closest points of the two lines: s from the 2x2 normal equations, then t given s
    s = _safe_ratio(b * f - c * e, a * e - b * b)
    t = _safe_ratio(b * s + f, e)
    best = _norm(tuple(r[i] + s * d1[i] - t * d2[i] for i in range(3)))  # type: ignore[arg-type]
    for q, base, d, dd in (
        (a0v, b0v, d2, e),
        (a1v, b0v, d2, e),
        (b0v, a0v, d1, a),
        (b1v, a0v, d1, a),
    ):
        best = torch.minimum(best, _point_segment(q, base, d, dd))
    return best


def e_spen(p0: Tensor, p1: Tensor, radii: Tensor, pairs: Tensor) -> Tensor:
    """Self-penetration energy (eqs. 12-13) of capsules ``p0-p1 (B, K, 3)``, ``radii (K,)``.

    ``pairs (P, 2)`` lists the capsule index pairs checked;
    returns ``sum_pairs max(-(s_ij - r_i - r_j), 0)``.
    """
    i, j = pairs[:, 0], pairs[:, 1]
    s = segment_segment_distance(p0[:, i], p1[:, i], p0[:, j], p1[:, j])
    gap = s - radii[i] - radii[j]
    return (-gap).clamp_min(0).sum(-1)
