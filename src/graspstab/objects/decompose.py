"""CoACD approximate convex decomposition: the object's collision geometry in MuJoCo."""

from __future__ import annotations

import logging
from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np
import trimesh

log = logging.getLogger(__name__)

# keyword arguments of coacd.run_coacd (coacd 1.0.14) that may be set from the config
COACD_KEYS = frozenset(
    {
        "threshold",
        "max_convex_hull",
        "preprocess_mode",
        "preprocess_resolution",
        "resolution",
        "mcts_nodes",
        "mcts_iterations",
        "mcts_max_depth",
        "pca",
        "merge",
        "decimate",
        "max_ch_vertex",
        "extrude",
        "extrude_margin",
        "apx_mode",
        "seed",
    }
)


def convex_decomposition(
    mesh: trimesh.Trimesh, params: Mapping[str, Any] | None = None
) -> list[trimesh.Trimesh]:
    """Split ``mesh`` into convex parts with CoACD; ``params`` are run_coacd keyword arguments.

    CoACD cuts along concave regions, so cavities (the mug) stay empty. Each returned part is the
    convex hull of a CoACD piece (watertight, outward normals).
    """
    import coacd

    params = dict(params or {})
    unknown = set(params) - COACD_KEYS
    if unknown:
        raise ValueError(
            f"unknown CoACD parameters {sorted(unknown)}; allowed: {sorted(COACD_KEYS)}"
        )
    coacd.set_log_level("error")
    cmesh = coacd.Mesh(
        np.ascontiguousarray(mesh.vertices, dtype=np.float64),
        np.ascontiguousarray(mesh.faces, dtype=np.int32),
    )
    raw = coacd.run_coacd(cmesh, **params)
    parts = []
    for verts, faces in raw:
        part = trimesh.Trimesh(np.asarray(verts, dtype=np.float64), np.asarray(faces), process=True)
        parts.append(part.convex_hull)
    log.info("CoACD produced %d convex parts", len(parts))
    return parts


def inside_any_part(
    parts: Sequence[trimesh.Trimesh], points: np.ndarray, tol: float = 0.0
) -> np.ndarray:
    """Boolean mask of ``points`` (N, 3) inside (or within ``tol`` of) at least one convex part."""
    pts = np.atleast_2d(np.asarray(points, dtype=np.float64))
    inside = np.zeros(len(pts), dtype=bool)
    for part in parts:
        normals = part.face_normals
        offsets = np.einsum("ij,ij->i", normals, part.triangles[:, 0])
        inside |= np.all(pts @ normals.T - offsets <= tol, axis=1)
    return inside
