"""Upright reference frame: optional configured rotation, then the centre of mass at the origin."""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
import trimesh
from scipy.spatial.transform import Rotation


def rotation_matrix(rotation_deg: Sequence[float] | None) -> np.ndarray:
    """3x3 rotation for extrinsic x-y-z Euler angles in degrees (``None``: identity)."""
    if rotation_deg is None:
        return np.eye(3)
    angles = np.asarray(rotation_deg, dtype=np.float64)
    if angles.shape != (3,):
        raise ValueError(f"rotation_deg must be three Euler angles [x, y, z], got {rotation_deg!r}")
    return Rotation.from_euler("xyz", angles, degrees=True).as_matrix()


def to_upright_com_frame(
    mesh: trimesh.Trimesh, rotation_deg: Sequence[float] | None = None
) -> tuple[trimesh.Trimesh, np.ndarray, np.ndarray]:
    """Rotate (optional) and translate ``mesh`` so its uniform-density COM is the origin.

    YCB google_16k meshes already rest upright with +z up, so the default is no rotation. The
    centre of mass is that of the closed volume (uniform density), so the mesh must be
    watertight. Returns the new mesh, the applied 3x3 rotation and the translation that was
    added after rotating (``new = R @ old + t``; ``-t`` is the COM in the rotated input frame).
    """
    rot = rotation_matrix(rotation_deg)
    out = mesh.copy()
    if rotation_deg is not None:
        tf = np.eye(4)
        tf[:3, :3] = rot
        out.apply_transform(tf)
    if not out.is_volume:
        raise ValueError("centre of mass needs a closed, outward-oriented mesh (run repair first)")
    com = np.asarray(out.center_mass, dtype=np.float64)
    out.apply_translation(-com)
    return out, rot, -com
