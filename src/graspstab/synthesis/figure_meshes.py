"""Meshes of the synthesis figures: vertex-clustering decimation and the posed hand meshes.

Apart from the drawing (:mod:`graspstab.synthesis.figure`) because it is geometry only (no
matplotlib): it turns object and hand meshes into the triangles and shading normals drawn.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import trimesh

from graspstab.hand.kinematics import HandKinematics
from graspstab.hand.meshes import body_collision_mesh, collision_geoms

# Decimation of the drawn meshes: clustering cells [m] for the hand's collision meshes (about 23k /
# 12k triangles for the whole ORCA hand) and target triangle counts for an object.
HAND_CELL_DETAIL = 0.002
HAND_CELL_GALLERY = 0.003
OBJECT_FACES_DETAIL = 4000
OBJECT_FACES_GALLERY = 3000


def decimate(
    vertices: np.ndarray, faces: np.ndarray, cell: float, normals: np.ndarray | None = None
) -> tuple[np.ndarray, np.ndarray]:
    """Vertex-clustering decimation on a ``cell``-sized grid that keeps the face winding;
    degenerate and duplicate faces are dropped. With vertex ``normals``, vertices whose normals
    point different ways (dominant axis and sign) never merge, so the two sides of a wall
    thinner than ``cell`` (a mug's rim) stay apart."""
    vertices, faces, _ = _cluster(vertices, faces, cell, normals)
    return vertices, faces


def _cluster(
    vertices: np.ndarray, faces: np.ndarray, cell: float, normals: np.ndarray | None = None
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Decimate as :func:`decimate`, also returning each original vertex's cluster index."""
    keys = np.floor(np.asarray(vertices) / cell).astype(np.int64)
    if normals is not None:
        axis = np.argmax(np.abs(normals), axis=1)
        side = np.take_along_axis(normals, axis[:, None], axis=1)[:, 0] > 0
        keys = np.column_stack([keys, 2 * axis + side])
    _, first, inverse = np.unique(keys, axis=0, return_index=True, return_inverse=True)
    inverse = inverse.reshape(-1)
    new_faces = inverse[np.asarray(faces)]
    ok = (
        (new_faces[:, 0] != new_faces[:, 1])
        & (new_faces[:, 1] != new_faces[:, 2])
        & (new_faces[:, 0] != new_faces[:, 2])
    )
    new_faces = new_faces[ok]
    _, keep = np.unique(np.sort(new_faces, axis=1), axis=0, return_index=True)
    return np.asarray(vertices)[first], new_faces[np.sort(keep)], inverse


def decimate_shaded(
    vertices: np.ndarray, faces: np.ndarray, cell: float, split_sides: bool = False
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Decimated (vertices, faces) plus per-face normals averaged from the ORIGINAL surface's
    vertex normals in each cluster: clustering folds a few small faces over, and shading them by
    their own normal would show dark specks, so the shading follows the undecimated surface.
    ``split_sides`` keeps the two sides of thin walls apart (see :func:`decimate`)."""
    normals = np.asarray(trimesh.Trimesh(vertices, faces, process=False).vertex_normals)
    new_vertices, new_faces, inverse = _cluster(
        vertices, faces, cell, normals if split_sides else None
    )
    cluster_normals = np.zeros((len(new_vertices), 3))
    np.add.at(cluster_normals, inverse, normals)
    face_normals = cluster_normals[new_faces].sum(axis=1)
    face_normals /= np.linalg.norm(face_normals, axis=1, keepdims=True) + 1e-15
    return new_vertices, new_faces, face_normals


Surface = tuple[np.ndarray, np.ndarray]
"""Triangles (m, 3, 3) [m] and their unit outward shading normals (m, 3)."""


def flat_surface(tris: np.ndarray) -> Surface:
    """Triangles with their own (flat) normals."""
    normals = np.cross(tris[:, 1] - tris[:, 0], tris[:, 2] - tris[:, 0])
    normals /= np.linalg.norm(normals, axis=1, keepdims=True) + 1e-15
    return tris, normals


def mesh_surface(mesh: trimesh.Trimesh, max_faces: int) -> Surface:
    """``mesh`` as a :data:`Surface`, decimated to roughly ``max_faces`` if it has more."""
    if len(mesh.faces) <= max_faces:
        tris = np.asarray(mesh.vertices)[np.asarray(mesh.faces)]
        return tris, np.asarray(mesh.face_normals)
    # A clustered surface has about 2 * area / cell^2 triangles.
    cell = math.sqrt(2.0 * float(mesh.area) / max_faces)
    vertices, faces, normals = decimate_shaded(mesh.vertices, mesh.faces, cell, split_sides=True)
    return vertices[faces], normals


class HandMeshes:
    """The hand's collision meshes (hand.xml geoms with contype/conaffinity), decimated once and
    posed by the MuJoCo reference kinematics."""

    def __init__(self, hand_dir: str | Path, cell: float = HAND_CELL_DETAIL) -> None:
        self.kin = HandKinematics(hand_dir)
        model = self.kin.model
        self.bodies: dict[str, tuple[np.ndarray, np.ndarray]] = {}
        for i in range(1, model.nbody):
            body = model.body(i).name
            if collision_geoms(model, body):
                mesh = body_collision_mesh(model, body)
                vertices, faces, normals = decimate_shaded(mesh.vertices, mesh.faces, cell)
                self.bodies[body] = (vertices[faces], normals)

    def surface(self, wrist_pos: np.ndarray, quat: np.ndarray, joints: np.ndarray) -> Surface:
        """World triangles and normals of the hand at one pose g = (P, R, theta)."""
        poses = self.kin.link_poses(
            np.asarray(wrist_pos, dtype=float),
            np.asarray(quat, dtype=float),
            np.asarray(joints, dtype=float),
        )
        tris = [t @ poses[b][1].T + poses[b][0] for b, (t, _) in self.bodies.items()]
        normals = [n @ poses[b][1].T for b, (_, n) in self.bodies.items()]
        return np.concatenate(tris), np.concatenate(normals)
