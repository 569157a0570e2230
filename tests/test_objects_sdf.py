"""Signed-distance grid: accuracy near the surface, sign, normals, out-of-grid behaviour."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import trimesh

from graspstab.objects.frame import to_upright_com_frame
from graspstab.objects.preprocess_object import load_mesh
from graspstab.objects.repair import repair_mesh
from graspstab.objects.sdf import SDFGrid, exact_signed_distance

SPACING = 0.0015  # the default in DEFAULT_PARAMS


def _near_surface_points(mesh: trimesh.Trimesh, n: int, seed: int = 0) -> np.ndarray:
    rng = np.random.default_rng(seed)
    pts, fi = trimesh.sample.sample_surface(mesh, n, seed=rng)
    return pts + mesh.face_normals[fi] * rng.uniform(-0.01, 0.01, (n, 1))


@pytest.fixture(scope="module")
def sphere() -> trimesh.Trimesh:
    return trimesh.creation.icosphere(subdivisions=5, radius=0.04)


@pytest.fixture(scope="module")
def sphere_grid(sphere: trimesh.Trimesh) -> SDFGrid:
    return SDFGrid.build(sphere, spacing=SPACING, margin=0.02)


def test_sphere_sdf_accuracy_sign_and_normals(
    sphere: trimesh.Trimesh, sphere_grid: SDFGrid
) -> None:
    pts = _near_surface_points(sphere, 500)
    exact = exact_signed_distance(sphere, pts)
    dist, normal = sphere_grid.query(pts)
    sel = np.abs(exact) < 0.01
    assert sel.sum() > 400
    assert np.max(np.abs(dist - exact)[sel]) < 1e-3
    # negative inside, positive outside
    d0, _ = sphere_grid.query(np.zeros((1, 3)))
    assert d0[0] == pytest.approx(-0.04, abs=1e-3)
    radial = pts / np.linalg.norm(pts, axis=1, keepdims=True)
    assert np.all(np.einsum("ij,ij->i", normal, radial) > 0.99)
    assert np.allclose(np.linalg.norm(normal, axis=1), 1.0)


def test_ycb_sdf_accuracy(tmp_path: Path, foam_brick_mesh: Path) -> None:
    mesh, _ = repair_mesh(load_mesh(foam_brick_mesh), object_id="061_foam_brick")
    mesh, _, _ = to_upright_com_frame(mesh)
    grid = SDFGrid.build(mesh, spacing=SPACING, margin=0.05)
    grid.save(tmp_path / "sdf.npz")
    loaded = SDFGrid.load(tmp_path / "sdf.npz")
    assert loaded.values.dtype == np.float32 and loaded.shape == grid.shape
    pts = _near_surface_points(mesh, 600, seed=1)
    exact = exact_signed_distance(mesh, pts)
    # independent reference: trimesh (positive inside, so negate; its search is good to ~10 um)
    ref = -trimesh.proximity.signed_distance(mesh, pts[:100])
    assert np.allclose(exact[:100], ref, atol=1e-5)
    dist, _ = loaded.query(pts)
    sel = np.abs(exact) < 0.01
    assert np.max(np.abs(dist - exact)[sel]) < 1e-3


def test_query_outside_grid_and_saved_fields(sphere_grid: SDFGrid, tmp_path: Path) -> None:
    upper = sphere_grid.upper
    far = np.array([[upper[0] + 0.1, 0.0, 0.0]])
    edge = np.array([[upper[0], 0.0, 0.0]])
    d_far, n_far = sphere_grid.query(far)
    d_edge, _ = sphere_grid.query(edge)
    assert d_far[0] == pytest.approx(d_edge[0] + 0.1)
    assert np.allclose(n_far[0], [1, 0, 0])
    # the estimate lies between the distance to the box and the triangle-inequality bound
    true = np.linalg.norm(far[0]) - 0.04
    assert 0.1 <= d_far[0] and true <= d_far[0] + 1e-3
    sphere_grid.save(tmp_path / "g.npz")
    with np.load(tmp_path / "g.npz") as data:
        assert set(data.files) == {"values", "origin", "spacing", "shape"}


def _reference_query(grid: SDFGrid, p: np.ndarray) -> tuple[float, np.ndarray]:
    """One point the slow way: scipy's trilinear interpolant on the grid nodes and its gradient
    by central differences inside the point's cell (the interpolant is linear along each axis
    there, so the difference is exact); outside the box, the clamped point's value plus the
    distance to it, the normal pointing away from the box."""
    from scipy.interpolate import RegularGridInterpolator

    axes = [grid.origin[i] + grid.spacing * np.arange(n) for i, n in enumerate(grid.shape)]
    interp = RegularGridInterpolator(axes, grid.values.astype(np.float64), method="linear")
    q = np.clip(p, grid.origin, grid.upper)
    offset = p - q
    if np.linalg.norm(offset) > 0:
        return float(interp(q)[0]) + float(np.linalg.norm(offset)), offset / np.linalg.norm(offset)
    h = 1e-4 * grid.spacing
    grad = np.array([(interp(q + h * e)[0] - interp(q - h * e)[0]) / (2 * h) for e in np.eye(3)])
    return float(interp(q)[0]), grad / np.linalg.norm(grad)


def test_query_is_vectorised_for_large_batches(sphere_grid: SDFGrid) -> None:
    """A 100,000-point batch in one call, each point as the one-point reference gives it: inside
    the box (most points) and outside it (beyond the 2 cm margin)."""
    pts = np.random.default_rng(0).uniform(-0.1, 0.1, (100_000, 3))
    dist, normal = sphere_grid.query(pts)
    assert dist.shape == (100_000,) and normal.shape == (100_000, 3)
    assert np.all(np.isfinite(dist)) and np.all(np.isfinite(normal))
    inside = np.all((pts > sphere_grid.origin) & (pts < sphere_grid.upper), axis=1)
    # away from cell faces, so the differences stay in one cell
    u = (pts - sphere_grid.origin) / sphere_grid.spacing
    clear = np.all(np.abs(u - np.round(u)) > 1e-3, axis=1)
    picks = [*np.flatnonzero(inside & clear)[:40], *np.flatnonzero(~inside)[:20]]
    assert len(picks) == 60
    for k in picks:
        ref_dist, ref_normal = _reference_query(sphere_grid, pts[k])
        assert dist[k] == pytest.approx(ref_dist, abs=1e-9), k
        np.testing.assert_allclose(normal[k], ref_normal, atol=1e-6, err_msg=str(k))
        # and alone: no point's answer depends on the rest of the batch
        one_dist, one_normal = sphere_grid.query(pts[k : k + 1])
        assert one_dist[0] == dist[k] and np.array_equal(one_normal[0], normal[k])
