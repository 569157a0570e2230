"""Convex-hull surface samples for the penetration energy."""

from __future__ import annotations

import numpy as np
from objects_fixtures import mug_like

from graspstab.objects.surface import sample_hull_points


def test_hull_points_on_hull_and_deterministic() -> None:
    cup = mug_like()
    pts = sample_hull_points(cup, count=2000, seed=3)
    assert pts.shape == (2000, 3) and pts.dtype == np.float64
    hull = cup.convex_hull
    # signed distance to the hull's face planes: max over faces is 0 exactly on the surface
    offsets = np.einsum("ij,ij->i", hull.face_normals, hull.triangles[:, 0])
    plane_dist = (pts @ hull.face_normals.T - offsets).max(axis=1)
    assert np.max(np.abs(plane_dist)) < 1e-9
    # on the hull, not the cavity: nothing lies near the axis inside the cup
    radial = np.linalg.norm(pts[:, :2], axis=1)
    assert np.all((radial > 0.0399) | (pts[:, 2] < 1e-6) | (pts[:, 2] > 0.08 - 1e-6))
    assert np.array_equal(pts, sample_hull_points(cup, count=2000, seed=3))
    assert not np.array_equal(pts, sample_hull_points(cup, count=2000, seed=4))
