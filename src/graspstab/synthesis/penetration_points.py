"""The object's hull samples for E_pen (eq. 11), grouped once into a two-level cluster tree.

Kept apart from the penetration kernels (:mod:`graspstab.synthesis.penetration`) because the tree
is built once per object, while the kernels run at every annealing step. ``n_clusters`` compact
coarse clusters of ``fan`` leaves of about ``leaf_size`` points each; every cluster and leaf has a
bounding sphere, which lets the kernels skip a whole cluster that no hand primitive can reach.
"""

from __future__ import annotations

import numpy as np
import torch
from torch import Tensor


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
