"""Collision-mesh geometry of a body in its own frame, read from the compiled MuJoCo model.

MuJoCo re-centres meshes at compile time, so vertices are taken from the model (mesh frame) and
moved by the geom pose into the body frame; capsules, candidates and figures all use this.
"""

from __future__ import annotations

from dataclasses import dataclass

import mujoco
import numpy as np

from graspstab.hand import names


@dataclass(frozen=True)
class BodyMesh:
    """Triangle mesh in a body frame [m]: vertices (n, 3), faces (m, 3) int."""

    body: str
    vertices: np.ndarray
    faces: np.ndarray


def quat_to_mat(quat: np.ndarray) -> np.ndarray:
    """3x3 rotation matrix of a MuJoCo quaternion (w, x, y, z)."""
    mat = np.zeros(9)
    mujoco.mju_quat2Mat(mat, np.asarray(quat, dtype=float))
    return mat.reshape(3, 3)


def body_id(model: mujoco.MjModel, body: str) -> int:
    """Body id by name, with an error listing the model's bodies."""
    bid = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, body)
    if bid < 0:
        valid = [model.body(i).name for i in range(model.nbody)]
        names.require_name(body, valid, "body", "the hand model")
    return bid


def collision_geoms(model: mujoco.MjModel, body: str) -> list[int]:
    """Ids of the body's colliding mesh geoms (the hard cores; skins are visual only)."""
    bid = body_id(model, body)
    return [
        g
        for g in range(model.ngeom)
        if model.geom_bodyid[g] == bid
        and model.geom_type[g] == mujoco.mjtGeom.mjGEOM_MESH
        and (model.geom_contype[g] or model.geom_conaffinity[g])
    ]


def geom_mesh(model: mujoco.MjModel, geom: int) -> tuple[np.ndarray, np.ndarray]:
    """Vertices (body frame) and faces of one mesh geom."""
    mid = model.geom_dataid[geom]
    v0, nv = model.mesh_vertadr[mid], model.mesh_vertnum[mid]
    f0, nf = model.mesh_faceadr[mid], model.mesh_facenum[mid]
    verts = np.asarray(model.mesh_vert[v0 : v0 + nv], dtype=float)
    faces = np.asarray(model.mesh_face[f0 : f0 + nf], dtype=np.int64)
    rot = quat_to_mat(model.geom_quat[geom])
    return verts @ rot.T + model.geom_pos[geom], faces


def body_collision_mesh(model: mujoco.MjModel, body: str) -> BodyMesh:
    """All collision-mesh triangles of ``body`` merged into one mesh in the body frame."""
    geoms = collision_geoms(model, body)
    if not geoms:
        raise ValueError(f"body {body!r} has no collision mesh geom in the hand model")
    verts, faces, offset = [], [], 0
    for g in geoms:
        v, f = geom_mesh(model, g)
        verts.append(v)
        faces.append(f + offset)
        offset += len(v)
    return BodyMesh(body, np.concatenate(verts), np.concatenate(faces))
