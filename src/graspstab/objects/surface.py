"""Convex-hull surface samples of the object, used by the penetration energy (thesis 3.1.4)."""

from __future__ import annotations

import numpy as np
import trimesh


def sample_hull_points(mesh: trimesh.Trimesh, count: int = 2000, seed: int = 0) -> np.ndarray:
    """``count`` points (float64, (count, 3)) uniform by area on the convex hull of ``mesh``."""
    if count <= 0:
        raise ValueError(f"count must be positive, got {count}")
    hull = mesh.convex_hull
    points, _ = trimesh.sample.sample_surface(hull, int(count), seed=np.random.default_rng(seed))
    return np.ascontiguousarray(points, dtype=np.float64)
