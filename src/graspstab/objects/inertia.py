"""Mass and inertia about the centre of mass, as MuJoCo principal moments plus frame quaternion.

The thesis assigns "mass and diagonal inertia". We keep the body frame upright (it is the object
frame every later stage uses), so the body cannot be rotated onto its principal axes. Instead the
full inertia tensor about the COM (uniform density = mass / volume) is diagonalised and we return
the principal moments together with the quaternion of the principal frame relative to the body
frame (MuJoCo w, x, y, z convention, a proper rotation with det +1). ``<inertial pos="0 0 0"
quat=... diaginertia=...>`` therefore reproduces the full tensor exactly.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np
import trimesh
from scipy.spatial.transform import Rotation


@dataclass
class Inertia:
    """Mass properties about the centre of mass, expressed in the body frame."""

    mass: float
    tensor: np.ndarray  # (3, 3) full inertia tensor about the COM [kg m^2]
    principal_moments: np.ndarray  # (3,) ascending eigenvalues [kg m^2]
    principal_axes: np.ndarray  # (3, 3) columns = principal axes in body coordinates, det +1
    quat: np.ndarray  # (4,) MuJoCo (w, x, y, z) of the principal frame in the body frame

    def to_dict(self) -> dict[str, Any]:
        """Plain-JSON form for meta.json."""
        return {
            "mass": self.mass,
            "principal_moments": self.principal_moments.tolist(),
            "quat_wxyz": self.quat.tolist(),
            "tensor": self.tensor.tolist(),
        }


def principal_frame(tensor: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Eigen-decompose a symmetric tensor: (moments ascending, axes with det +1, quat wxyz)."""
    sym = 0.5 * (np.asarray(tensor, dtype=np.float64) + np.asarray(tensor).T)
    moments, axes = np.linalg.eigh(sym)
    if np.linalg.det(axes) < 0:
        axes[:, 2] = -axes[:, 2]
    xyzw = Rotation.from_matrix(axes).as_quat()
    quat = np.array([xyzw[3], xyzw[0], xyzw[1], xyzw[2]])
    if quat[0] < 0:
        quat = -quat
    return moments, axes, quat


def compute_inertia(mesh: trimesh.Trimesh, mass: float) -> Inertia:
    """Inertia of ``mesh`` with total ``mass`` (uniform density) about its centre of mass."""
    if not mass > 0:
        raise ValueError(f"mass must be positive, got {mass!r}")
    if not mesh.is_volume:
        raise ValueError("inertia needs a closed, outward-oriented mesh (run repair first)")
    volume = float(mesh.volume)
    # trimesh reports moment_inertia about the centre of mass, in the mesh frame, for density 1
    tensor = np.asarray(mesh.moment_inertia, dtype=np.float64) * (mass / volume)
    tensor = 0.5 * (tensor + tensor.T)
    moments, axes, quat = principal_frame(tensor)
    return Inertia(
        mass=float(mass), tensor=tensor, principal_moments=moments, principal_axes=axes, quat=quat
    )
