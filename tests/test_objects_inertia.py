"""Centre of mass, upright frame and inertia against analytic values."""

from __future__ import annotations

import numpy as np
import pytest
import trimesh
from scipy.spatial.transform import Rotation

from graspstab.objects.frame import to_upright_com_frame
from graspstab.objects.inertia import compute_inertia


def _tensor_from_quat(quat_wxyz: np.ndarray, moments: np.ndarray) -> np.ndarray:
    w, x, y, z = quat_wxyz
    rot = Rotation.from_quat([x, y, z, w]).as_matrix()
    return rot @ np.diag(moments) @ rot.T


def test_box_offset_com_and_inertia() -> None:
    a, b, c, m = 0.04, 0.06, 0.1, 0.3
    box = trimesh.creation.box([a, b, c])
    box.apply_translation([0.1, -0.2, 0.05])
    centred, rot, t = to_upright_com_frame(box)
    assert np.allclose(rot, np.eye(3))
    assert np.allclose(t, [-0.1, 0.2, -0.05])
    assert np.allclose(centred.center_mass, 0, atol=1e-12)
    inertia = compute_inertia(centred, m)
    expected = m / 12 * np.array([b**2 + c**2, a**2 + c**2, a**2 + b**2])
    assert np.allclose(np.diag(inertia.tensor), expected, rtol=1e-9)
    assert np.allclose(inertia.tensor - np.diag(np.diag(inertia.tensor)), 0, atol=1e-12)
    assert np.allclose(inertia.principal_moments, np.sort(expected), rtol=1e-9)


def test_cylinder_inertia() -> None:
    r, h, m = 0.03, 0.12, 0.5
    cyl = trimesh.creation.cylinder(radius=r, height=h, sections=256)
    cyl.apply_translation([0.0, 0.0, 0.3])
    centred, _, _ = to_upright_com_frame(cyl)
    assert np.allclose(centred.center_mass, 0, atol=1e-12)
    inertia = compute_inertia(centred, m)
    ixx = m * (3 * r**2 + h**2) / 12
    izz = m * r**2 / 2
    assert np.diag(inertia.tensor) == pytest.approx([ixx, ixx, izz], rel=1e-3)


def test_rotated_box_principal_frame() -> None:
    a, b, c, m = 0.02, 0.05, 0.09, 0.2
    box = trimesh.creation.box([a, b, c])
    rot = Rotation.from_euler("xyz", [20, -35, 50], degrees=True).as_matrix()
    tf = np.eye(4)
    tf[:3, :3] = rot
    tf[:3, 3] = [0.3, 0.1, -0.2]
    box.apply_transform(tf)
    centred, _, _ = to_upright_com_frame(box)
    inertia = compute_inertia(centred, m)
    expected = np.sort(m / 12 * np.array([b**2 + c**2, a**2 + c**2, a**2 + b**2]))
    assert np.allclose(inertia.principal_moments, expected, rtol=1e-9)
    assert np.linalg.det(inertia.principal_axes) == pytest.approx(1.0)
    assert np.linalg.norm(inertia.quat) == pytest.approx(1.0)
    full = _tensor_from_quat(inertia.quat, inertia.principal_moments)
    assert np.allclose(full, inertia.tensor, atol=1e-12 * m)
    # the full tensor is the rotated body-frame tensor
    body = np.diag(m / 12 * np.array([b**2 + c**2, a**2 + c**2, a**2 + b**2]))
    assert np.allclose(inertia.tensor, rot @ body @ rot.T, atol=1e-12)


def test_configured_rotation_applied_before_centring() -> None:
    box = trimesh.creation.box([0.02, 0.04, 0.08])
    box.apply_translation([0.0, 0.0, 0.04])
    lying, rot, t = to_upright_com_frame(box, rotation_deg=[90, 0, 0])
    assert np.allclose(lying.extents, [0.02, 0.08, 0.04])
    assert np.allclose(lying.center_mass, 0, atol=1e-12)
    # the COM in the input frame is recovered from the stored transform
    assert np.allclose(rot.T @ -t, [0, 0, 0.04])


def test_mass_must_be_positive() -> None:
    with pytest.raises(ValueError, match="mass"):
        compute_inertia(trimesh.creation.box([0.1, 0.1, 0.1]), 0.0)
