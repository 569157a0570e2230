"""The penetration energy E_pen (thesis 3.1.4, eq. 11): culled numba evaluation and dense reference.

Apart from the cheap terms (:mod:`graspstab.synthesis.energy`, which re-exports these names) since
it is most of the code and of the cost. Everything is in the object frame.

The penetration term (eq. 11) dominates the cost (B grasps x 2000 hull points x 17 hand
primitives per annealing step), so :func:`e_pen` culls: the hull points are grouped once into a
two-level tree of compact clusters (:class:`PenetrationPoints`, ~48 clusters of ~5 leaves of ~8
points). Every primitive signed distance is 1-Lipschitz, so a cluster whose centre lies at least
its bounding radius outside a primitive cannot penetrate it. A numba kernel walks, per grasp and
primitive, the root sphere, the coarse clusters and their leaves (tests in float64 with a rounding
slack, so culling is conservative) and evaluates only the surviving leaves point by point, keeping
the per-point max over primitives in a ``(B, M)`` array. The per-point arithmetic repeats the
elementwise operations of the brute-force torch :func:`e_pen_dense` in the same dtype and order,
and the final sum over points is the same torch reduction, so both agree to rounding (torch's
vectorised square root is not always correctly rounded; numba's is: 1 ulp per point at most).
"""

from __future__ import annotations

import numpy as np
import torch
from torch import Tensor

from graspstab.synthesis.penetration_kernel import e_pen_kernel
from graspstab.synthesis.penetration_points import PenetrationPoints

__all__ = [
    "PenetrationPoints",
    "e_pen",
    "e_pen_dense",
    "penetration_candidates",
    "penetration_depths",
]


def _capsule_distance(
    qx: Tensor,
    qy: Tensor,
    qz: Tensor,
    ax: Tensor,
    ay: Tensor,
    az: Tensor,
    dx: Tensor,
    dy: Tensor,
    dz: Tensor,
    inv_dd: Tensor,
) -> Tensor:
    """Distance from ``q`` to the segment ``a + t d``, elementwise (broadcast).

    Written as separate IEEE elementwise operations (no fused or reduced kernels), so the value of
    one element does not depend on the shape of the batch it is computed in; the numba kernel of
    :func:`penetration_depths` repeats them (up to the rounding of torch's square root).
    """
    wx = qx - ax
    wy = qy - ay
    wz = qz - az
    t = wx * dx
    tmp = wy * dy
    t.add_(tmp)
    torch.mul(wz, dz, out=tmp)
    t.add_(tmp).mul_(inv_dd).clamp_(0.0, 1.0)
    torch.mul(t, dx, out=tmp)
    wx.sub_(tmp)
    torch.mul(t, dy, out=tmp)
    wy.sub_(tmp)
    torch.mul(t, dz, out=tmp)
    wz.sub_(tmp)
    wx.mul_(wx)
    wy.mul_(wy)
    wz.mul_(wz)
    return wx.add_(wy).add_(wz).sqrt_()


def _box_local(
    qx: Tensor, qy: Tensor, qz: Tensor, cx: Tensor, cy: Tensor, cz: Tensor, rot: Tensor
) -> list[Tensor]:
    """Box-frame coordinates ``l_j = sum_i rot[i][j] (q_i - c_i)`` elementwise (broadcast)."""
    vx = qx - cx
    vy = qy - cy
    vz = qz - cz
    tmp = torch.empty_like(vx)
    local = []
    for j in range(3):
        lj = vx * rot[0][j]
        torch.mul(vy, rot[1][j], out=tmp)
        lj.add_(tmp)
        torch.mul(vz, rot[2][j], out=tmp)
        local.append(lj.add_(tmp))
    return local


def _box_penetration(
    qx: Tensor,
    qy: Tensor,
    qz: Tensor,
    cx: Tensor,
    cy: Tensor,
    cz: Tensor,
    rot: Tensor,
    half: Tensor,
) -> Tensor:
    """``max(-sdf_box(q), 0) = max(min_j (h_j - |l_j|), 0)`` elementwise, ``l = R^T (q - c)``.

    ``rot[i][j]`` is world component ``i`` of box axis ``j`` (each broadcastable). Inside the box
    the box SDF is ``max_j (|l_j| - h_j)`` and outside it is positive, hence this form.
    """
    out: Tensor | None = None
    for j, lj in enumerate(_box_local(qx, qy, qz, cx, cy, cz, rot)):
        lj.abs_().neg_().add_(half[j])
        out = lj if out is None else torch.minimum(out, lj, out=out)
    assert out is not None
    return out.clamp_min_(0.0)


def _capsule_params(p0: Tensor, p1: Tensor, radii: Tensor) -> Tensor:
    """Per-(grasp, capsule) parameters (B, K, 8): a, d = p1 - p0, 1/|d|^2 (0 if degenerate), r."""
    d = p1 - p0
    dd = (d * d).sum(-1)
    pos = dd > 0
    inv_dd = torch.where(pos, 1.0 / torch.where(pos, dd, torch.ones_like(dd)), 0.0)
    r = radii.to(p0.dtype).expand(dd.shape)
    return torch.cat((p0, d, inv_dd[..., None], r[..., None]), dim=-1)


def _check_hand(
    p0: Tensor, p1: Tensor, radii: Tensor, box_center: Tensor, box_rotation: Tensor
) -> None:
    b, k = p0.shape[:2]
    if p0.shape != (b, k, 3) or p1.shape != (b, k, 3) or radii.shape != (k,):
        raise ValueError(
            f"capsules: need p0, p1 (B, K, 3) and radii (K,), got {tuple(p0.shape)}, "
            f"{tuple(p1.shape)}, {tuple(radii.shape)}"
        )
    if box_center.shape != (b, 3) or box_rotation.shape != (b, 3, 3):
        raise ValueError(
            f"palm box: need centre (B, 3) and rotation (B, 3, 3) with B={b}, got "
            f"{tuple(box_center.shape)}, {tuple(box_rotation.shape)}"
        )


def _coarse_masks(
    points: PenetrationPoints,
    p0: Tensor,
    p1: Tensor,
    radii: Tensor,
    box_center: Tensor,
    box_rotation: Tensor,
    box_half_extents: Tensor,
) -> tuple[Tensor, Tensor, float]:
    """Coarse candidate masks ``(C, B * K)``, ``(C, B)`` and the rounding slack [m] for finer tests.

    Uses the 1-Lipschitz bound ``sdf(q) >= sdf(centre) - rho``. The capsule distances to all
    centres come from two small matmuls (``|c - a - t d|^2`` expanded), the box from one; their
    rounding is covered by a generous slack, so the masks are conservative.
    """
    _check_hand(p0, p1, radii, box_center, box_rotation)
    dtype = p0.dtype
    eps = torch.finfo(dtype).eps
    bsz, k = p0.shape[:2]
    centers, rho = points.centers, points.rho
    cc = (centers * centers).sum(-1)[:, None]  # (C, 1)
    a = p0.reshape(bsz * k, 3)
    d = (p1 - p0).reshape(bsz * k, 3)
    dd = (d * d).sum(-1)  # (BK,)
    aa = (a * a).sum(-1)
    ad = (a * d).sum(-1)
    pos = dd > 0
    inv_dd = torch.where(pos, 1.0 / torch.where(pos, dd, torch.ones_like(dd)), 0.0)
    w = torch.matmul(centers, d.T).sub_(ad)  # (c - a) . d, (C, BK)
    ca = torch.matmul(centers, a.T)
    t = (w * inv_dd).clamp_(0.0, 1.0)
    # |c - a - t d|^2 = |c|^2 - 2 c.a + |a|^2 - t (2 w - t |d|^2)
    d2 = (t * dd).neg_().add_(w, alpha=2.0).mul_(t)
    d2 = ca.mul_(-2.0).add_(cc).add_(aa).sub_(d2)
    reach = (rho[:, None] + radii).repeat(1, bsz)  # (C, BK), capsule index fastest
    scale = max(
        float(cc.max()) ** 0.5 + float(aa.max()) ** 0.5 + float(dd.max()) ** 0.5,
        float(box_center.abs().max()) + float(box_half_extents.abs().max()),
        float(reach.max()),
        1.0,
    )
    capsule_mask = d2 < reach.square_().add_(256.0 * eps * scale * scale)

    # (B, C, 3) box-frame centres; broadcast multiply-sum, since CPU bmm of many 3x3 is slow
    offset = centers[None, :, :, None] - box_center[:, None, :, None]  # (B, C, 3, 1)
    local = (offset * box_rotation[:, None]).sum(-2)
    q = local.abs() - box_half_extents
    box_sdf = (q.clamp_min(0).norm(dim=-1) + q.amax(-1).clamp_max(0)).T  # (C, B)
    slack = 256.0 * eps * scale
    box_mask = box_sdf < rho[:, None] + slack
    return capsule_mask, box_mask, slack


def penetration_candidates(
    points: PenetrationPoints,
    p0: Tensor,
    p1: Tensor,
    radii: Tensor,
    box_center: Tensor,
    box_rotation: Tensor,
    box_half_extents: Tensor,
) -> tuple[Tensor, Tensor]:
    """Coarse masks of the (grasp, capsule, cluster) ``(B, K, C)`` and (grasp, cluster) ``(B, C)``
    pairs whose points may lie inside the capsule / palm box (conservative, see ``e_pen``)."""
    dtype = p0.dtype
    points = points.to(dtype)
    half = box_half_extents.to(dtype)
    cap, box, _ = _coarse_masks(points, p0, p1, radii.to(dtype), box_center, box_rotation, half)
    bsz, k = p0.shape[:2]
    return cap.T.reshape(bsz, k, -1), box.T


def _as_array(x: Tensor, dtype: torch.dtype) -> np.ndarray:
    """A C-contiguous numpy view (or copy) of ``x`` in ``dtype`` on the CPU."""
    return x.detach().to(device="cpu", dtype=dtype).contiguous().numpy()


def penetration_depths(
    points: PenetrationPoints,
    p0: Tensor,
    p1: Tensor,
    radii: Tensor,
    box_center: Tensor,
    box_rotation: Tensor,
    box_half_extents: Tensor,
    stats: dict[str, int] | None = None,
) -> Tensor:
    """Per grasp and hull point ``(B, M)``: ``max(-d_H(q), 0)``, the summand of eq. (11).

    Arguments as in :func:`e_pen`; points in the order of ``points.points``. Culled exactly (see
    the module docstring), computed by a numba kernel in the dtype of ``p0`` (no gradients).
    """
    _check_hand(p0, p1, radii, box_center, box_rotation)
    dtype = p0.dtype
    points = points.to(dtype)
    with torch.no_grad():
        cap = _as_array(_capsule_params(p0, p1, radii.to(dtype)), dtype)
    center = _as_array(box_center, dtype)
    rot = _as_array(box_rotation, dtype)
    half = _as_array(box_half_extents, dtype)
    pts, order, ptr, spheres, leaf_spheres = points._kernel_tree
    # rounding slack of the culling tests [m]: far above both the float64 error of the tests and
    # the dtype error of the point formulas, whose magnitudes are bounded by ``scale``
    scale = 1.0
    for arr in (pts, spheres[3], cap[..., :6], center, half, cap[..., 7]):
        if arr.size:
            scale += float(np.abs(arr).max())
    slack = 256.0 * float(torch.finfo(dtype).eps) * scale
    pen = np.zeros((p0.shape[0], points.n_points), dtype=pts.dtype)
    counts = np.zeros(5, dtype=np.int64)
    unit = np.ones(1, dtype=pts.dtype)
    e_pen_kernel(
        pts, order, ptr, spheres, leaf_spheres, cap, center, rot, half, slack, unit, pen, counts
    )
    if stats is not None:
        keys = ("coarse_capsule", "leaf_capsule", "coarse_box", "leaf_box", "point_evaluations")
        stats.update({key: int(n) for key, n in zip(keys, counts, strict=True)})
    return torch.from_numpy(pen).to(p0.device)


def e_pen(
    points: PenetrationPoints,
    p0: Tensor,
    p1: Tensor,
    radii: Tensor,
    box_center: Tensor,
    box_rotation: Tensor,
    box_half_extents: Tensor,
    stats: dict[str, int] | None = None,
) -> Tensor:
    """Penetration energy (eq. 11) with two-level cluster culling; equals :func:`e_pen_dense`
    up to rounding (torch's square root is not always correctly rounded, numba's is).

    ``d_H`` is the minimum of the capsule SDFs (segments ``p0-p1 (B, K, 3)``, ``radii (K,)``) and
    the palm-box SDF (``box_center (B, 3)``, ``box_rotation (B, 3, 3)`` whose columns are the box
    axes in the object frame, ``box_half_extents (3,)``).
    Returns ``sum_q max(-d_H(q), 0)``, ``(B,)``, in the dtype of ``p0`` (not differentiable: the
    annealer needs no gradients). If ``stats`` is given, it receives the numbers of coarse and
    leaf candidates and of point evaluations.
    """
    depths = penetration_depths(
        points, p0, p1, radii, box_center, box_rotation, box_half_extents, stats
    )
    return depths.sum(-1)  # the reduction of e_pen_dense


def e_pen_dense(
    points: PenetrationPoints | Tensor,
    p0: Tensor,
    p1: Tensor,
    radii: Tensor,
    box_center: Tensor,
    box_rotation: Tensor,
    box_half_extents: Tensor,
) -> Tensor:
    """Brute-force eq. (11) over every point and primitive (reference for :func:`e_pen`)."""
    _check_hand(p0, p1, radii, box_center, box_rotation)
    dtype = p0.dtype
    pts = points.to(dtype).points if isinstance(points, PenetrationPoints) else points.to(dtype)
    qx, qy, qz = pts.unbind(-1)  # (M,)
    cols = _capsule_params(p0, p1, radii).permute(2, 0, 1)[..., None]  # (8, B, K, 1)
    per_capsule = _capsule_distance(qx, qy, qz, *cols[:7].unbind(0))  # (B, K, M)
    per_capsule.neg_().add_(cols[7]).clamp_min_(0.0)
    ctr = box_center.T[..., None]  # (3, B, 1)
    rot = box_rotation.permute(1, 2, 0)[..., None]  # (3, 3, B, 1)
    half = box_half_extents.to(dtype)
    per_box = _box_penetration(qx, qy, qz, ctr[0], ctr[1], ctr[2], rot, half)  # (B, M)
    return torch.maximum(per_capsule.amax(1), per_box).sum(-1)
