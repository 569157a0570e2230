"""Mesh repair: holes, flipped faces and slivers are fixed; unrepairable meshes fail clearly."""

from __future__ import annotations

import numpy as np
import pytest
import trimesh
from objects_fixtures import broken_sphere

from graspstab.objects.repair import MeshRepairError, repair_mesh


def test_repair_fixes_hole_flips_and_slivers() -> None:
    broken = broken_sphere()
    assert not broken.is_watertight
    fixed, report = repair_mesh(broken, sliver_max_faces=16, sliver_max_area_fraction=0.01)
    assert fixed.is_watertight and fixed.is_winding_consistent
    assert report.watertight_before is False and report.watertight_after is True
    assert report.removed_components == 2 and report.removed_component_faces == 4
    assert report.filled_hole_faces >= 1
    # slivers gone: everything lies on the sphere
    assert np.allclose(np.linalg.norm(fixed.vertices, axis=1), 0.05, atol=1e-9)
    # outward normals: positive volume and normals along the radial direction
    assert fixed.volume > 0
    radial = fixed.triangles_center / np.linalg.norm(fixed.triangles_center, axis=1)[:, None]
    assert np.all(np.einsum("ij,ij->i", fixed.face_normals, radial) > 0.9)


def test_repair_inverted_mesh_points_outward() -> None:
    box = trimesh.creation.box([0.1, 0.2, 0.3])
    inv = trimesh.Trimesh(box.vertices, box.faces[:, ::-1], process=False)
    fixed, report = repair_mesh(inv)
    assert report.inverted
    assert fixed.volume == pytest.approx(0.006)


def test_two_large_bodies_refused_with_object_id() -> None:
    a = trimesh.creation.icosphere(subdivisions=2, radius=0.05)
    b = trimesh.creation.icosphere(subdivisions=2, radius=0.04)
    b.apply_translation([0.2, 0, 0])
    both = trimesh.util.concatenate([a, b])
    with pytest.raises(MeshRepairError, match="my_object") as exc:
        repair_mesh(both, object_id="my_object", source="/x/y.obj")
    msg = str(exc.value)
    assert "2 large disconnected components" in msg and "/x/y.obj" in msg and "mesh:" in msg


def test_unclosable_surface_refused() -> None:
    # an open half-sphere: the rim is a large non-planar boundary loop
    s = trimesh.creation.icosphere(subdivisions=3, radius=0.05)
    keep = s.triangles_center[:, 2] > 0.01
    half = trimesh.Trimesh(s.vertices, s.faces[keep], process=False)
    with pytest.raises(MeshRepairError, match="bowl.*not watertight"):
        repair_mesh(half, object_id="bowl")


def test_flat_sheet_refused() -> None:
    sheet = trimesh.Trimesh(
        np.array([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0]], float) * 0.1,
        np.array([[0, 1, 2], [0, 2, 3], [4, 5, 6]]) % 4,
        process=False,
    )
    with pytest.raises(MeshRepairError, match="sheet"):
        repair_mesh(sheet, sliver_max_faces=0, sliver_max_area_fraction=0.0, object_id="sheet")
