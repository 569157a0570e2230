"""Signed-distance grid: accuracy near the surface, sign, normals, out-of-grid behaviour."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import trimesh
from objects_fixtures import FOAM_BRICK

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


def test_ycb_sdf_accuracy(tmp_path: Path) -> None:
    mesh, _ = repair_mesh(load_mesh(FOAM_BRICK), object_id="061_foam_brick")
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


def test_query_is_vectorised_for_large_batches(sphere_grid: SDFGrid) -> None:
    pts = np.random.default_rng(0).uniform(-0.1, 0.1, (100_000, 3))
    dist, normal = sphere_grid.query(pts)
    assert dist.shape == (100_000,) and normal.shape == (100_000, 3)
    assert np.all(np.isfinite(dist)) and np.all(np.isfinite(normal))
