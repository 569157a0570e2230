"""Torch twin of the object's signed-distance grid, so annealing queries run batched (3.1.4).

:class:`TorchSDF` answers exactly what :meth:`graspstab.objects.sdf.SDFGrid.query` answers
(trilinear interpolation, the normalised analytic gradient of the interpolant as the outward
normal, and the outside-the-box extension ``d(c) + |p - c|``), but on tensors of any leading shape
and in the dtype it was built with. The per-point work runs in a numba kernel (one pass, eight
flat grid values per point): torch's gathers and dozens of elementwise passes over
``B x 120`` points cost several times more per annealing step (3.1.4).
"""

from __future__ import annotations

import os
from dataclasses import dataclass
from functools import cached_property
from pathlib import Path

import numba
import numpy as np
import torch
from torch import Tensor

from graspstab.objects.sdf import SDFGrid


@dataclass(frozen=True)
class TorchSDF:
    """A regular signed-distance grid (negative inside) held as torch tensors."""

    flat_values: Tensor  # (nx * ny * nz,) grid values, C order (x slowest)
    origin: Tensor  # (3,) position of node (0, 0, 0) [m]
    upper: Tensor  # (3,) position of the last node [m]
    spacing: float  # node spacing [m]
    shape: tuple[int, int, int]  # nodes along x, y, z

    @classmethod
    def from_grid(cls, grid: SDFGrid, dtype: torch.dtype = torch.float32) -> TorchSDF:
        """Copy an :class:`SDFGrid` into tensors of ``dtype`` (float64 reproduces it exactly)."""
        shape = grid.shape
        if min(shape) < 2:
            raise ValueError(f"SDF grid needs at least 2 nodes per axis, got shape {shape}")
        values = torch.as_tensor(grid.values.reshape(-1)).to(dtype).contiguous()
        return cls(
            flat_values=values,
            origin=torch.as_tensor(grid.origin, dtype=torch.float64).to(dtype),
            upper=torch.as_tensor(grid.upper, dtype=torch.float64).to(dtype),
            spacing=float(grid.spacing),
            shape=shape,
        )

    @classmethod
    def load(
        cls, path: str | os.PathLike[str] | Path, dtype: torch.dtype = torch.float32
    ) -> TorchSDF:
        """Read an ``sdf.npz`` written by :meth:`SDFGrid.save`."""
        return cls.from_grid(SDFGrid.load(path), dtype=dtype)

    @property
    def dtype(self) -> torch.dtype:
        """The floating dtype of the grid values."""
        return self.flat_values.dtype

    def query(self, points: Tensor) -> tuple[Tensor, Tensor]:
        """Signed distance ``(...)`` and unit outward normal ``(..., 3)`` at ``points (..., 3)``.

        Same semantics as :meth:`SDFGrid.query`; the points are cast to the grid's dtype and the
        arithmetic runs in it (a numba kernel, no gradients).
        """
        lead = points.shape[:-1]
        dtype = self.dtype
        pts = points.detach().to(device="cpu", dtype=dtype).reshape(-1, 3).contiguous().numpy()
        np_dtype = pts.dtype
        dist = np.empty(len(pts), dtype=np_dtype)
        normal = np.empty((len(pts), 3), dtype=np_dtype)
        _query_kernel(
            pts,
            self.flat_values.numpy(),
            self.origin.numpy(),
            self.upper.numpy(),
            # spacing, 1 and the last cell index per axis, in the dtype
            np.array([self.spacing, 1.0, *(n - 2 for n in self.shape)], dtype=np_dtype),
            np.asarray(self.shape, dtype=np.int64),
            dist,
            normal,
        )
        device = points.device
        return (
            torch.from_numpy(dist).reshape(lead).to(device),
            torch.from_numpy(normal).reshape(*lead, 3).to(device),
        )

    @cached_property
    def block_min(self) -> np.ndarray:
        """Smallest node value of each block of ``BLOCK^3`` cells (the nodes its cells touch)."""
        values = self.flat_values.numpy().reshape(self.shape)
        cells = [n - 1 for n in self.shape]
        blocks = [-(-c // BLOCK) for c in cells]
        out = np.empty(blocks, dtype=values.dtype)
        for i in range(blocks[0]):
            for j in range(blocks[1]):
                sub = values[
                    i * BLOCK : i * BLOCK + BLOCK + 1, j * BLOCK : j * BLOCK + BLOCK + 1
                ]
                for k in range(blocks[2]):
                    out[i, j, k] = sub[:, :, k * BLOCK : k * BLOCK + BLOCK + 1].min()
        return out

    def depth_sum(self, points: Tensor) -> Tensor:
        """``sum max(-d, 0)`` over the last-but-one axis of ``points (B, S, 3)``, ``(B,)``.

        The same signed distance as :meth:`query` (same formulas in the same order) without the
        normals, summed in float64 inside the kernel: E_hpen's hot path. A point whose cell lies
        in a block with no negative node (:attr:`block_min`) is skipped: its trilinear value is a
        convex combination of non-negative nodes and the outside extension only adds, so it
        contributes exactly 0.
        """
        if points.ndim != 3 or points.shape[-1] != 3:
            raise ValueError(f"depth_sum expects points (B, S, 3), got {tuple(points.shape)}")
        dtype = self.dtype
        pts = points.detach().to(device="cpu", dtype=dtype).contiguous().numpy()
        out = np.zeros(pts.shape[0], dtype=np.float64)
        _depth_sum_kernel(
            pts,
            self.block_min,
            self.flat_values.numpy(),
            self.origin.numpy(),
            self.upper.numpy(),
            np.array([self.spacing, 1.0, *(n - 2 for n in self.shape)], dtype=pts.dtype),
            np.asarray(self.shape, dtype=np.int64),
            out,
        )
        return torch.from_numpy(out).to(device=points.device, dtype=dtype)


#: Cells per block edge of :attr:`TorchSDF.block_min` (6 mm blocks on the 1.5 mm grid).
BLOCK = 4


@numba.njit(inline="always")
def _cell(px, py, pz, lo, hi, constants):  # type: ignore[no-untyped-def]
    """Cell ``(ix, iy, iz)``, fractions ``(tx, ty, tz)`` and outside offset of a point.

    The point is clamped into the grid box (the remainder is the offset); ``constants`` holds
    the spacing, 1 and the last cell index per axis in the grid dtype.
    """
    spacing = constants[0]
    zero = constants[1] - constants[1]
    cx = min(max(px, lo[0]), hi[0])
    cy = min(max(py, lo[1]), hi[1])
    cz = min(max(pz, lo[2]), hi[2])
    u = (cx - lo[0]) / spacing
    i0 = min(max(np.floor(u), zero), constants[2])
    tx = u - i0
    ix = int(i0)
    u = (cy - lo[1]) / spacing
    i0 = min(max(np.floor(u), zero), constants[3])
    ty = u - i0
    iy = int(i0)
    u = (cz - lo[2]) / spacing
    i0 = min(max(np.floor(u), zero), constants[4])
    tz = u - i0
    iz = int(i0)
    return ix, iy, iz, tx, ty, tz, px - cx, py - cy, pz - cz


@numba.njit(inline="always")
def _corners(values, base, sx, sy):  # type: ignore[no-untyped-def]
    """The cell's eight node values, c000 ... c111 (two adjacent pairs per (x, y) column:
    measured faster than a table of 8 corners per cell, which is 8x larger)."""
    return (
        values[base],
        values[base + 1],
        values[base + sy],
        values[base + sy + 1],
        values[base + sx],
        values[base + sx + 1],
        values[base + sx + sy],
        values[base + sx + sy + 1],
    )


@numba.njit(inline="always")
def _interpolate(corners, tx, ty, tz):  # type: ignore[no-untyped-def]
    """Trilinear interpolation along z first (the order of SDFGrid.query); the intermediate
    values too, which the gradient needs."""
    c000, c001, c010, c011, c100, c101, c110, c111 = corners
    c00 = c000 + (c001 - c000) * tz
    c01 = c010 + (c011 - c010) * tz
    c10 = c100 + (c101 - c100) * tz
    c11 = c110 + (c111 - c110) * tz
    c0 = c00 + (c01 - c00) * ty
    c1 = c10 + (c11 - c10) * ty
    return c00, c01, c10, c11, c0, c1, c0 + (c1 - c0) * tx


@numba.njit(cache=True)
def _depth_sum_kernel(
    pts: np.ndarray,
    block_min: np.ndarray,
    values: np.ndarray,
    lo: np.ndarray,
    hi: np.ndarray,
    constants: np.ndarray,
    shape: np.ndarray,
    out: np.ndarray,
) -> None:
    """``out[b] = sum_s max(-d(pts[b, s]), 0)``; ``d`` exactly as in :func:`_query_kernel`."""
    zero = constants[1] - constants[1]
    sx = shape[1] * shape[2]
    sy = shape[2]
    for b in range(pts.shape[0]):
        total = 0.0
        for n in range(pts.shape[1]):
            ix, iy, iz, tx, ty, tz, ox, oy, oz = _cell(
                pts[b, n, 0], pts[b, n, 1], pts[b, n, 2], lo, hi, constants
            )
            if block_min[ix // BLOCK, iy // BLOCK, iz // BLOCK] >= zero:
                continue  # every corner >= 0, so d >= 0 (see TorchSDF.depth_sum)
            corners = _corners(values, ix * sx + iy * sy + iz, sx, sy)
            d = _interpolate(corners, tx, ty, tz)[6]
            out_sq = ox * ox + oy * oy + oz * oz
            if out_sq > zero:
                d = d + np.sqrt(out_sq)
            if d < zero:
                total -= d
        out[b] = total


@numba.njit(cache=True)
def _query_kernel(
    pts: np.ndarray,
    values: np.ndarray,
    lo: np.ndarray,
    hi: np.ndarray,
    constants: np.ndarray,
    shape: np.ndarray,
    dist: np.ndarray,
    normal: np.ndarray,
) -> None:
    """Fill ``dist (N,)`` and ``normal (N, 3)`` for ``pts (N, 3)``, all in the grid dtype.

    ``values`` are the flat grid values (C order, x slowest); ``constants`` holds the
    node spacing, 1 and the last cell index along x, y, z in the dtype (typed constants keep all
    arithmetic in the dtype). Formulas and their order are those of :meth:`SDFGrid.query`.
    """
    one = constants[1]
    zero = one - one
    sx = shape[1] * shape[2]  # node strides
    sy = shape[2]
    for n in range(pts.shape[0]):
        # clamp into the grid box; the remainder is the outside offset
        ix, iy, iz, tx, ty, tz, ox, oy, oz = _cell(
            pts[n, 0], pts[n, 1], pts[n, 2], lo, hi, constants
        )
        corners = _corners(values, ix * sx + iy * sy + iz, sx, sy)
        c000, c001, c010, c011, c100, c101, c110, c111 = corners
        c00, c01, c10, c11, c0, c1, d = _interpolate(corners, tx, ty, tz)
        gx = c1 - c0
        gy = (one - tx) * (c01 - c00) + tx * (c11 - c10)
        dz0 = (one - ty) * (c001 - c000) + ty * (c011 - c010)
        dz1 = (one - ty) * (c101 - c100) + ty * (c111 - c110)
        gz = (one - tx) * dz0 + tx * dz1
        # normalised gradient (per cell unit; only the direction matters), zero where it vanishes
        sq = gx * gx + gy * gy + gz * gz
        inv = one / np.sqrt(sq) if sq > zero else zero
        nx, ny, nz = gx * inv, gy * inv, gz * inv
        # outside the box: d(c) + |p - c| along (p - c) / |p - c|
        out_sq = ox * ox + oy * oy + oz * oz
        if out_sq > zero:
            out_dist = np.sqrt(out_sq)
            d = d + out_dist
            inv_out = one / out_dist
            nx, ny, nz = ox * inv_out, oy * inv_out, oz * inv_out
        dist[n] = d
        normal[n, 0] = nx
        normal[n, 1] = ny
        normal[n, 2] = nz
