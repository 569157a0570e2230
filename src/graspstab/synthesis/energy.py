"""Energy terms of the grasp-synthesis objective (thesis 3.1.4, eqs. 4-14), batched over grasps.

Every term takes tensors with a leading grasp dimension ``B`` and returns a ``(B,)`` tensor in the
inputs' dtype. Frames: everything is in the object frame, which is the world frame with the object's
centre of mass at the origin (so moments are taken about the centre of mass).

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

from collections.abc import Mapping

import numba
import numpy as np
import torch
from torch import Tensor

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


# --------------------------------------------------------------------------------------------
# E_pen (eq. 11)


class PenetrationPoints:
    """Object hull samples ``S_o`` (eq. 11) in a two-level cluster tree for culled queries.

    ``n_clusters`` coarse clusters come from balanced median splits along the longest box axis;
    each is split the same way into ``fan`` leaves of about ``leaf_size`` points. Leaves are padded
    to a common size by repeating their first member (harmless under the per-point max). ``rho``
    and ``leaf_rho`` bound every member's distance to its cluster centre (computed from the
    coordinates as stored, rounded up). ``dtype`` defaults to the dtype of a floating tensor
    ``points``, else float32.
    """

    points: Tensor  # (M, 3) hull samples, object frame [m]
    centers: Tensor  # (C, 3) coarse cluster centres [m]
    rho: Tensor  # (C,) bounding radius of each coarse cluster [m]
    fan: int  # leaves per coarse cluster; leaf c * fan + f belongs to coarse cluster c
    # slot-major layouts: the gathered index runs along the last, contiguous axis, which keeps
    # the broadcast elementwise kernels vectorised
    leaf_xyz: Tensor  # (3 * fan, C) centre of leaf f of coarse cluster c, rows x..., y..., z...
    leaf_rho: Tensor  # (fan, C) bounding radius of that leaf [m]
    members: Tensor  # (S, C * fan) long, indices into points (padded)
    member_xyz: Tensor  # (3 * S, C * fan) member coordinates, rows x..., y..., z... [m]

    def __init__(
        self,
        points: np.ndarray | Tensor,
        n_clusters: int = 32,
        dtype: torch.dtype | None = None,
        leaf_size: int = 8,
    ) -> None:
        if dtype is None:
            is_float = isinstance(points, Tensor) and points.is_floating_point()
            dtype = points.dtype if is_float else torch.float32  # type: ignore[union-attr]
        if isinstance(points, Tensor):
            points = points.detach().cpu().numpy()
        pts = np.asarray(points, dtype=np.float64)
        if pts.ndim != 2 or pts.shape[1] != 3 or len(pts) == 0:
            raise ValueError(
                f"penetration points must be a non-empty (M, 3) array, not {pts.shape}"
            )
        n_clusters = max(1, min(int(n_clusters), len(pts)))
        groups = _balanced_split(pts, np.arange(len(pts)), n_clusters)
        fan = max(1, min(round(len(pts) / (n_clusters * max(1, leaf_size))), min(map(len, groups))))
        self._source = pts
        self._leaf_size = leaf_size
        self._groups = groups
        self._leaves = [leaf for g in groups for leaf in _balanced_split(pts, g, fan)]
        self.fan = fan
        self._converted: dict[torch.dtype, PenetrationPoints] = {}
        self._set_dtype(dtype)

    def _set_dtype(self, dtype: torch.dtype) -> None:
        # round to dtype first, so the radii bound the coordinates that are actually evaluated
        pts_t = torch.as_tensor(self._source).to(dtype)
        pts_r = pts_t.double().numpy()
        self.points = pts_t
        self.centers, self.rho = _bounding_spheres(pts_r, self._groups, dtype)
        leaf_centers, leaf_rho = _bounding_spheres(pts_r, self._leaves, dtype)
        n_c, fan = len(self._groups), self.fan
        self.leaf_xyz = leaf_centers.view(n_c, fan, 3).permute(2, 1, 0).reshape(3 * fan, n_c)
        self.leaf_rho = leaf_rho.view(n_c, fan).T.contiguous()
        size = max(len(g) for g in self._leaves)
        padded = [np.concatenate([g, np.full(size - len(g), g[0])]) for g in self._leaves]
        self.members = torch.as_tensor(np.stack(padded, axis=1), dtype=torch.long)  # (S, L)
        self.member_xyz = pts_t[self.members].permute(2, 0, 1).reshape(3 * size, -1)
        # the same tree as plain arrays for the numba kernel of e_pen: points in leaf order (CSR,
        # no padding), sphere centres and radii widened to float64 (exactly) for the culling tests
        order = np.concatenate(self._leaves).astype(np.int64)
        ptr = np.concatenate([[0], np.cumsum([len(g) for g in self._leaves])]).astype(np.int64)
        self._kernel_tree = (
            np.ascontiguousarray(pts_t.numpy()[order]),
            order,
            ptr,
            np.ascontiguousarray(torch.cat((self.centers.T, self.rho[None])).double().numpy()),
            np.ascontiguousarray(torch.cat((leaf_centers.T, leaf_rho[None])).double().numpy()),
        )

    @property
    def dtype(self) -> torch.dtype:
        """Floating dtype of the stored coordinates."""
        return self.points.dtype

    @property
    def n_points(self) -> int:
        """Number of hull samples M."""
        return int(self.points.shape[0])

    @property
    def n_clusters(self) -> int:
        """Number of coarse clusters C."""
        return int(self.centers.shape[0])

    @property
    def leaf_members(self) -> int:
        """Padded number of points per leaf S."""
        return int(self.members.shape[0])

    def to(self, dtype: torch.dtype) -> PenetrationPoints:
        """The same samples and clusters in another dtype (built once, then cached)."""
        if dtype == self.dtype:
            return self
        if dtype not in self._converted:
            self._converted[dtype] = PenetrationPoints(
                self._source, self.n_clusters, dtype, self._leaf_size
            )
        return self._converted[dtype]


def _balanced_split(pts: np.ndarray, idx: np.ndarray, k: int) -> list[np.ndarray]:
    """Recursive median split of ``pts[idx]`` into ``k`` groups of near-equal size."""
    if k == 1:
        return [idx]
    k1 = k // 2
    n1 = int(round(len(idx) * k1 / k))
    sub = pts[idx]
    axis = int(np.argmax(sub.max(0) - sub.min(0)))
    order = np.argsort(sub[:, axis], kind="stable")
    return _balanced_split(pts, idx[order[:n1]], k1) + _balanced_split(pts, idx[order[n1:]], k - k1)


def _bounding_spheres(
    pts: np.ndarray, groups: list[np.ndarray], dtype: torch.dtype
) -> tuple[Tensor, Tensor]:
    """Box-centre spheres ``(G, 3), (G,)`` of the groups, radii rounded up in ``dtype``."""
    lo = np.stack([pts[g].min(0) for g in groups])
    hi = np.stack([pts[g].max(0) for g in groups])
    centers = torch.as_tensor(0.5 * (lo + hi)).to(dtype)
    c = centers.double().numpy()
    rho = torch.as_tensor(
        [np.linalg.norm(pts[g] - c[i], axis=1).max() for i, g in enumerate(groups)]
    )
    rho = rho.to(dtype)
    return centers, torch.nextafter(rho, torch.full_like(rho, float("inf")))


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


def _box_sdf(
    qx: Tensor,
    qy: Tensor,
    qz: Tensor,
    cx: Tensor,
    cy: Tensor,
    cz: Tensor,
    rot: Tensor,
    half: Tensor,
) -> Tensor:
    """Full signed distance to the box elementwise (used for culling, where outside matters)."""
    k = [lj.abs_().sub_(half[j]) for j, lj in enumerate(_box_local(qx, qy, qz, cx, cy, cz, rot))]
    inside = torch.maximum(torch.maximum(k[0], k[1]), k[2]).clamp_max_(0.0)
    outside = sum(kj.clamp_min(0.0).square_() for kj in k)
    return inside.add_(outside.sqrt_())  # type: ignore[union-attr]


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


@numba.njit(cache=True)
def _segment_near(
    cx: np.ndarray,
    cy: np.ndarray,
    cz: np.ndarray,
    rho: np.ndarray,
    reach: float,
    a: np.ndarray,
    d: np.ndarray,
    inv_dd: float,
    near: np.ndarray,
) -> None:
    """``near[c] = dist(centre c, segment a + t d) < rho[c] + reach`` in float64, for every c.

    Branch-free over structure-of-arrays centres, so LLVM vectorises it.
    """
    a0, a1, a2 = a[0], a[1], a[2]
    d0, d1, d2 = d[0], d[1], d[2]
    for c in range(cx.shape[0]):
        wx = cx[c] - a0
        wy = cy[c] - a1
        wz = cz[c] - a2
        t = min(max((wx * d0 + wy * d1 + wz * d2) * inv_dd, 0.0), 1.0)
        ex = wx - t * d0
        ey = wy - t * d1
        ez = wz - t * d2
        rr = rho[c] + reach
        near[c] = ex * ex + ey * ey + ez * ez < rr * rr


@numba.njit(cache=True)
def _box_near(
    cx: np.ndarray,
    cy: np.ndarray,
    cz: np.ndarray,
    rho: np.ndarray,
    slack: float,
    center: np.ndarray,
    rot: np.ndarray,
    col_norm: np.ndarray,
    half: np.ndarray,
    near: np.ndarray,
) -> None:
    """``near[c]`` unless no point within ``rho[c]`` of centre c can lie inside the box, i.e.
    unless ``|l_j(c)| - h_j >= |R e_j| rho[c] + slack`` for some axis j (``l_j`` is
    ``|R e_j|``-Lipschitz, so R need not be exactly orthonormal). Float64, branch-free."""
    for c in range(cx.shape[0]):
        vx = cx[c] - center[0]
        vy = cy[c] - center[1]
        vz = cz[c] - center[2]
        gap = -np.inf
        for j in range(3):
            lj = vx * rot[0, j] + vy * rot[1, j] + vz * rot[2, j]
            gap = max(gap, abs(lj) - half[j] - col_norm[j] * rho[c])
        near[c] = gap < slack


@numba.njit(cache=True)
def _e_pen_kernel(
    pts: np.ndarray,
    order: np.ndarray,
    ptr: np.ndarray,
    spheres: np.ndarray,
    leaf_spheres: np.ndarray,
    cap: np.ndarray,
    box_center: np.ndarray,
    box_rot: np.ndarray,
    half: np.ndarray,
    slack: float,
    unit: np.ndarray,
    pen: np.ndarray,
    counts: np.ndarray,
) -> None:
    """``pen[b, q] = max over primitives of max(-sdf(q), 0)`` for every point q not culled.

    ``pts`` (M, 3) are the hull points in leaf order (leaf l holds ``pts[ptr[l]:ptr[l + 1]]``,
    originally ``order[...]``), in the energy dtype like ``cap`` (B, K, 8: a, d, 1/|d|^2, r),
    ``box_center`` (B, 3), ``box_rot`` (B, 3, 3), ``half`` (3,) and ``pen`` (B, M, zeros).
    ``spheres`` (4, C) and ``leaf_spheres`` (4, C * fan) hold the float64 centres (x, y, z rows)
    and radii of the coarse clusters and their leaves (leaf ``c * fan + f`` in cluster c);
    ``unit`` is ``[1]`` in the dtype. ``counts`` receives coarse/leaf candidates and point
    evaluations. The point formulas repeat :func:`_capsule_distance` / :func:`_box_penetration`
    operation by operation in the dtype (no fastmath, so no fused or reordered arithmetic).
    """
    n_b, n_k = cap.shape[0], cap.shape[1]
    n_c = spheres.shape[1]
    fan = leaf_spheres.shape[1] // n_c
    cx, cy, cz, rho = spheres[0], spheres[1], spheres[2], spheres[3]
    lx, ly, lz, lrho = leaf_spheres[0], leaf_spheres[1], leaf_spheres[2], leaf_spheres[3]
    near = np.empty(n_c, dtype=np.bool_)
    leaf_near = np.empty(fan, dtype=np.bool_)
    a64 = np.empty(3)
    d64 = np.empty(3)
    c64 = np.empty(3)
    r64 = np.empty((3, 3))
    col_norm = np.empty(3)
    h64 = np.empty(3)
    for j in range(3):
        h64[j] = half[j]
    one = unit[0]
    zero = one - one
    for b in range(n_b):
        # capsules (eq. 11: max(-(|q - segment| - r), 0))
        for k in range(n_k):
            for j in range(3):
                a64[j] = cap[b, k, j]
                d64[j] = cap[b, k, 3 + j]
            dd = d64[0] * d64[0] + d64[1] * d64[1] + d64[2] * d64[2]
            inv64 = 1.0 / dd if dd > 0.0 else 0.0
            reach = float(cap[b, k, 7]) + slack
            _segment_near(cx, cy, cz, rho, reach, a64, d64, inv64, near)
            ax, ay, az = cap[b, k, 0], cap[b, k, 1], cap[b, k, 2]
            dx, dy, dz = cap[b, k, 3], cap[b, k, 4], cap[b, k, 5]
            inv_dd, r = cap[b, k, 6], cap[b, k, 7]
            for c in range(n_c):
                if not near[c]:
                    continue
                counts[0] += 1
                lo = c * fan
                hi = lo + fan
                _segment_near(
                    lx[lo:hi], ly[lo:hi], lz[lo:hi], lrho[lo:hi], reach, a64, d64, inv64, leaf_near
                )
                for f in range(fan):
                    if not leaf_near[f]:
                        continue
                    leaf = lo + f
                    counts[1] += 1
                    counts[4] += ptr[leaf + 1] - ptr[leaf]
                    for i in range(ptr[leaf], ptr[leaf + 1]):
                        wx = pts[i, 0] - ax
                        wy = pts[i, 1] - ay
                        wz = pts[i, 2] - az
                        t = wx * dx
                        t = t + wy * dy
                        t = t + wz * dz
                        t = t * inv_dd
                        t = min(max(t, zero), one)
                        wx = wx - t * dx
                        wy = wy - t * dy
                        wz = wz - t * dz
                        s = wx * wx + wy * wy
                        s = s + wz * wz
                        value = r - np.sqrt(s)
                        q = order[i]
                        if value > pen[b, q]:
                            pen[b, q] = value
        # palm box: max(min_j (h_j - |l_j|), 0)
        for j in range(3):
            c64[j] = box_center[b, j]
            for i in range(3):
                r64[i, j] = box_rot[b, i, j]
        for j in range(3):
            col_norm[j] = np.sqrt(r64[0, j] ** 2 + r64[1, j] ** 2 + r64[2, j] ** 2)
        _box_near(cx, cy, cz, rho, slack, c64, r64, col_norm, h64, near)
        bx, by, bz = box_center[b, 0], box_center[b, 1], box_center[b, 2]
        rot = box_rot[b]
        for c in range(n_c):
            if not near[c]:
                continue
            counts[2] += 1
            lo = c * fan
            hi = lo + fan
            _box_near(
                lx[lo:hi], ly[lo:hi], lz[lo:hi], lrho[lo:hi], slack, c64, r64, col_norm, h64,
                leaf_near,
            )  # fmt: skip
            for f in range(fan):
                if not leaf_near[f]:
                    continue
                leaf = lo + f
                counts[3] += 1
                counts[4] += ptr[leaf + 1] - ptr[leaf]
                for i in range(ptr[leaf], ptr[leaf + 1]):
                    vx = pts[i, 0] - bx
                    vy = pts[i, 1] - by
                    vz = pts[i, 2] - bz
                    value = zero
                    for j in range(3):
                        lj = vx * rot[0, j]
                        lj = lj + vy * rot[1, j]
                        lj = lj + vz * rot[2, j]
                        mj = half[j] - abs(lj)
                        value = mj if j == 0 else min(value, mj)
                    q = order[i]
                    if value > pen[b, q]:
                        pen[b, q] = value


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
    _e_pen_kernel(
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
