"""Numba kernels of the culled penetration energy (eq. 11): cluster tests and point loops.

Kept apart from the torch code (:mod:`graspstab.synthesis.penetration`) because numba compiles
(and caches) this module on its own. Every function works on plain numpy arrays; the tests are in
float64 with a rounding slack (conservative culling), the point formulas in the energy dtype.
"""

from __future__ import annotations

import numba
import numpy as np


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
def e_pen_kernel(
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
    evaluations. The point formulas repeat ``penetration._capsule_distance`` / ``_box_penetration``
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
