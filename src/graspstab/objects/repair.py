"""Mesh repair, so every object is one closed, outward-oriented body before mass properties."""

from __future__ import annotations

import logging
from dataclasses import asdict, dataclass, field
from typing import Any

import numpy as np
import trimesh

from graspstab.common.errors import GraspstabError

log = logging.getLogger(__name__)


class MeshRepairError(RuntimeError, GraspstabError):
    """The mesh cannot be turned into a single closed body automatically."""


@dataclass
class RepairReport:
    """What :func:`repair_mesh` found and changed."""

    watertight_before: bool
    watertight_after: bool = False
    vertices_before: int = 0
    faces_before: int = 0
    vertices_after: int = 0
    faces_after: int = 0
    merged_vertices: int = 0
    removed_degenerate_faces: int = 0
    removed_duplicate_faces: int = 0
    removed_components: int = 0
    removed_component_faces: int = 0
    removed_component_sizes: list[int] = field(default_factory=list)
    winding_fixed: bool = False
    inverted: bool = False
    filled_hole_faces: int = 0
    volume: float = 0.0

    def to_dict(self) -> dict[str, Any]:
        """Plain-JSON form for meta.json."""
        return asdict(self)


def _where(object_id: str | None, source: str | None) -> str:
    parts = []
    if object_id:
        parts.append(f"object {object_id!r}")
    if source:
        parts.append(f"mesh file {source}")
    return " / ".join(parts) if parts else "mesh"


def _hint() -> str:
    return (
        "Fix the mesh (e.g. in MeshLab or Blender) and point the object config entry at it with "
        "'mesh: <path>' (optionally 'sha256: null'), or adjust preprocess 'repair' parameters."
    )


def repair_mesh(
    mesh: trimesh.Trimesh,
    sliver_max_faces: int = 16,
    sliver_max_area_fraction: float = 0.01,
    object_id: str | None = None,
    source: str | None = None,
) -> tuple[trimesh.Trimesh, RepairReport]:
    """Return a watertight, outward-oriented single-body copy of ``mesh`` and a report.

    Steps: merge duplicate vertices (ignoring UVs/normals), drop degenerate and duplicate faces,
    drop small disconnected components other than the largest (at most ``sliver_max_faces``
    faces or under ``sliver_max_area_fraction`` of the total area), make winding consistent and
    outward, and fill simple holes. Raises :class:`MeshRepairError` naming ``object_id`` and
    ``source`` when the result is not one closed body with positive volume.
    """
    where = _where(object_id, source)
    m = trimesh.Trimesh(
        vertices=np.asarray(mesh.vertices, dtype=np.float64).copy(),
        faces=np.asarray(mesh.faces, dtype=np.int64).copy(),
        process=False,
        validate=False,
    )
    report = RepairReport(
        watertight_before=False, vertices_before=len(m.vertices), faces_before=len(m.faces)
    )
    if len(m.faces) == 0:
        raise MeshRepairError(f"{where}: the mesh has no faces. {_hint()}")
    if not np.all(np.isfinite(m.vertices)):
        raise MeshRepairError(f"{where}: the mesh has non-finite vertex coordinates. {_hint()}")

    m.merge_vertices(merge_tex=True, merge_norm=True)
    report.merged_vertices = report.vertices_before - len(m.vertices)
    report.watertight_before = bool(m.is_watertight)

    keep = m.nondegenerate_faces()
    report.removed_degenerate_faces = int((~keep).sum())
    m.update_faces(keep)
    uniq = m.unique_faces()
    report.removed_duplicate_faces = int((~uniq).sum())
    m.update_faces(uniq)
    m.remove_unreferenced_vertices()

    labels = trimesh.graph.connected_component_labels(m.face_adjacency, node_count=len(m.faces))
    n_comp = int(labels.max()) + 1 if len(labels) else 0
    sizes = np.bincount(labels, minlength=n_comp)
    areas = np.bincount(labels, weights=m.area_faces, minlength=n_comp)
    total_area = float(areas.sum())
    small = (sizes <= sliver_max_faces) | (areas < sliver_max_area_fraction * total_area)
    small[int(np.argmax(areas))] = False  # the largest component is the body, however coarse
    large = np.flatnonzero(~small)
    if len(large) > 1:
        raise MeshRepairError(
            f"{where}: {len(large)} large disconnected components (faces "
            f"{sizes[large].tolist()}, area fractions "
            f"{np.round(areas[large] / total_area, 3).tolist()}); expected a single body. "
            f"{_hint()}"
        )
    drop = np.flatnonzero(small)
    report.removed_components = len(drop)
    report.removed_component_faces = int(sizes[drop].sum())
    report.removed_component_sizes = sizes[drop].tolist()
    if len(drop):
        m.update_faces(labels == large[0])
        m.remove_unreferenced_vertices()

    was_consistent = bool(m.is_winding_consistent)
    trimesh.repair.fix_winding(m)
    n_faces = len(m.faces)
    trimesh.repair.fill_holes(m)
    report.filled_hole_faces = len(m.faces) - n_faces
    trimesh.repair.fix_winding(m)  # the new hole faces join the consistent winding
    report.winding_fixed = not was_consistent
    if m.is_watertight and m.volume < 0:  # consistently wound but inside-out: point normals out
        m.invert()
        report.inverted = True

    report.watertight_after = bool(m.is_watertight and m.is_winding_consistent)
    report.vertices_after = len(m.vertices)
    report.faces_after = len(m.faces)
    if not report.watertight_after:
        n_open = int(len(trimesh.grouping.group_rows(m.edges_sorted, require_count=1)))
        raise MeshRepairError(
            f"{where}: not watertight after repair ({n_open} boundary edges remain, winding "
            f"consistent: {m.is_winding_consistent}); holes could not be filled automatically. "
            f"{_hint()}"
        )
    volume = float(m.volume)
    report.volume = volume
    if not volume > 0:
        raise MeshRepairError(
            f"{where}: enclosed volume after repair is {volume:.3g} m^3 (must be > 0). {_hint()}"
        )
    log.info(
        "repair %s: watertight %s -> %s, dropped %d components (%d faces), filled %d faces",
        object_id or "mesh",
        report.watertight_before,
        report.watertight_after,
        report.removed_components,
        report.removed_component_faces,
        report.filled_hole_faces,
    )
    return m, report
