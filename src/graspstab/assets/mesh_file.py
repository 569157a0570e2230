"""Reading an object's mesh file: a bad one (not OBJ, empty, unreadable, wrong units) is refused
with a message naming the object and the user's own file, before any expensive step runs."""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np
import trimesh

from graspstab.common.errors import GraspstabError

#: A hand-held object's largest bounding-box extent lies between these [m]; outside, the mesh is
#: almost surely in other units (a YCB mesh in millimetres is ~100 "m" across).
MAX_EXTENT_M = 0.5
MIN_EXTENT_M = 0.005
#: A user's mesh thinner than this in its thinnest direction is a sheet, not a solid [m]: thinner
#: than the signed-distance grid's spacing (preprocess.sdf.spacing, 1.5 mm) and that grid's tested
#: error near surfaces (< 1 mm), so no grasp energy or contact could treat it as a body, and
#: preprocessing would fail on it anyway (zero enclosed volume). The thinnest of the 44 YCB meshes
#: (042_adjustable_wrench) is 14 mm thick by the same measure.
MIN_THICKNESS_M = 0.001
#: A closed, consistently wound user mesh enclosing less than this fraction of its bounding box is
#: surfaces that cancel (a sheet folded onto itself, a doubled face): the closed YCB meshes enclose
#: 10 % (043_phillips_screwdriver) to 94 % (036_wood_block) of theirs, a solid 1 mm plate ~100 %.
MIN_VOLUME_FRACTION = 1e-3
OBJ_ONLY = (
    "graspstab reads Wavefront OBJ meshes only (a text .obj file with 'v' vertex and 'f' face "
    "lines, coordinates in metres)"
)


class MeshFileError(ValueError, GraspstabError):
    """A mesh file that is not a readable OBJ of a hand-held object; the message says which
    object, which file, what is wrong and how to fix it."""


def describe(
    object_id: str, path: str | os.PathLike[str], user_file: str | os.PathLike[str] | None = None
) -> str:
    """``object '<id>': mesh <file>``, naming the user's file (and the copy read) when given."""
    who = f"object '{object_id}'" if object_id else "mesh"
    if user_file is None:
        return f"{who}: mesh {path}"
    copy = "" if Path(path) == Path(user_file) else f", read from its copy {path}"
    return f"{who}: your mesh {user_file} ({_mesh_key(object_id)}{copy})"


def _mesh_key(object_id: str) -> str:
    """The config field that names the user's mesh file."""
    if object_id:
        return f"config field objects.items.{object_id}.mesh"
    return "field 'mesh' of the object"


def _fix(user_file: str | os.PathLike[str] | None, verb: str = "fix", object_id: str = "") -> str:
    """How to fix it: the user's file (field 'mesh'), else the file itself."""
    if user_file is not None:
        return f"{verb} {user_file}, or set {_mesh_key(object_id)} to another file"
    return "replace the file"


def read_obj(
    path: str | os.PathLike[str],
    object_id: str = "",
    user_file: str | os.PathLike[str] | None = None,
) -> trimesh.Trimesh:
    """Read ``path`` as one OBJ triangle mesh, unprocessed, ignoring textures and materials.

    Raises :class:`MeshFileError` (naming ``object_id`` and ``user_file``, the file the user
    gave, if any) for a non-.obj name, an empty or unreadable file, no faces, non-finite vertices.
    """
    p = Path(path)
    shown = Path(user_file) if user_file is not None else p
    where = describe(object_id, p, user_file)
    fix = _fix(user_file, object_id=object_id)
    if shown.suffix.lower() != ".obj":
        target = shown.with_suffix(".obj")
        raise MeshFileError(
            f"{where} is not an OBJ file (suffix {shown.suffix or 'none'!r}). {OBJ_ONLY}. Convert "
            f"it, e.g. python -c \"import trimesh; trimesh.load('{shown}').export('{target}')\", "
            "and give the .obj file"
            + (f" in {_mesh_key(object_id)}" if user_file is not None else "")
        )
    try:
        size = p.stat().st_size
    except OSError as exc:
        raise MeshFileError(f"{where} cannot be read ({exc}); {fix}") from exc
    if size == 0:
        raise MeshFileError(f"{where} is empty (0 bytes). {OBJ_ONLY}; {fix}")
    try:
        mesh = trimesh.load(p, file_type="obj", force="mesh", process=False, skip_materials=True)
    except Exception as exc:  # noqa: BLE001 - any parse failure of a bad file, one message
        raise MeshFileError(
            f"{where}: no triangle mesh could be read ({type(exc).__name__}: {exc}). "
            f"{OBJ_ONLY}; {fix}"
        ) from exc
    if not isinstance(mesh, trimesh.Trimesh) or len(mesh.faces) == 0:
        raise MeshFileError(
            f"{where}: no triangle mesh could be read (no 'f' face lines found in {size} bytes; "
            f"is it an OBJ file?). {OBJ_ONLY}; {fix}"
        )
    vertices = np.asarray(mesh.vertices, dtype=np.float64)
    if not np.all(np.isfinite(vertices)):
        raise MeshFileError(f"{where} has non-finite (nan or inf) vertex coordinates; {fix}")
    return trimesh.Trimesh(vertices, mesh.faces, process=False)


def check_extent(
    mesh: trimesh.Trimesh,
    object_id: str = "",
    path: str | os.PathLike[str] = "",
    user_file: str | os.PathLike[str] | None = None,
) -> None:
    """Refuse a mesh whose largest extent is not that of a hand-held object (5 mm to 0.5 m):
    almost surely a unit mistake, which would otherwise ask for an absurd signed-distance grid."""
    extents = np.asarray(mesh.extents, dtype=np.float64)
    largest = float(extents.max())
    if MIN_EXTENT_M <= largest <= MAX_EXTENT_M:
        return
    where = describe(object_id, path, user_file)
    box = " x ".join(f"{e:.4g}" for e in extents)
    if largest > MAX_EXTENT_M:
        guesses = [
            f"is it in {unit}? Then it is {largest * factor * 100:.3g} cm across: scale it by "
            f"{factor:g}."
            for unit, factor in (("millimetres", 1e-3), ("centimetres", 1e-2))
            if MIN_EXTENT_M <= largest * factor <= MAX_EXTENT_M
        ]
        guess = " Or ".join(guesses) if guesses else "is it in millimetres?"
        raise MeshFileError(
            f"{where} is {largest:.4g} m across (bounding box {box} m), more than the "
            f"{MAX_EXTENT_M:g} m a hand-held object can be: {guess} Mesh coordinates are read as "
            f"metres; rescale it and {_fix(user_file, 'save it as', object_id)}"
        )
    raise MeshFileError(
        f"{where} is only {largest * 1e3:.3g} mm across (bounding box {box} m), less than the "
        f"{MIN_EXTENT_M * 1e3:g} mm a graspable object needs: is it in metres? Mesh coordinates "
        "are read as metres (a mesh scaled by 0.001 twice, or exported in kilometres, looks like "
        f"this); rescale it and {_fix(user_file, 'save it as', object_id)}"
    )


def _widths(mesh: trimesh.Trimesh) -> tuple[float, float]:
    """(thickness [m], box volume [m^3]) of the mesh's used vertices: thickness is the smallest
    width along the coordinate axes and the principal axes (exactly 0 for a planar mesh in any
    orientation); the box is the tighter of the axis-aligned and the principal-axes boxes."""
    used = np.asarray(mesh.vertices, dtype=np.float64)[np.unique(mesh.faces)]
    centred = used - used.mean(axis=0)
    _, _, axes = np.linalg.svd(centred, full_matrices=False)
    spans = []
    for frame in (np.eye(3), axes):
        proj = centred @ frame.T
        spans.append(proj.max(axis=0) - proj.min(axis=0))
    return float(min(s.min() for s in spans)), float(min(np.prod(s) for s in spans))


def check_solid(
    mesh: trimesh.Trimesh,
    object_id: str = "",
    path: str | os.PathLike[str] = "",
    user_file: str | os.PathLike[str] | None = None,
) -> None:
    """Refuse a flat or zero-volume mesh: thinner than :data:`MIN_THICKNESS_M` in its thinnest
    direction, or closed (watertight, consistently wound) yet enclosing less than
    :data:`MIN_VOLUME_FRACTION` of its bounding box. An open mesh is not refused for being open
    (preprocessing fills simple holes); its volume is not defined, so only its thickness is."""
    where = describe(object_id, path, user_file)
    fix = _fix(user_file, "save it as", object_id)
    box = " x ".join(f"{e:.4g}" for e in np.asarray(mesh.extents, dtype=np.float64))
    thickness, box_volume = _widths(mesh)
    if thickness < MIN_THICKNESS_M:
        raise MeshFileError(
            f"{where} is flat: {thickness * 1e3:.2f} mm thick in its thinnest direction "
            f"(bounding box {box} m), less than the {MIN_THICKNESS_M * 1e3:g} mm a solid object "
            "needs; a single sheet (e.g. a square of two triangles, or a box of zero height) "
            "encloses no volume, and the simulation needs a closed body with volume. Give it "
            f"thickness (e.g. Blender's Solidify modifier) and {fix}"
        )
    closed = mesh.copy()
    closed.merge_vertices(merge_tex=True, merge_norm=True)  # OBJ splits vertices at UV seams
    if not (closed.is_watertight and closed.is_winding_consistent):
        return
    with np.errstate(invalid="ignore", divide="ignore"):  # trimesh's centre of mass at volume 0
        volume = abs(float(closed.volume))
    if volume < MIN_VOLUME_FRACTION * box_volume:
        raise MeshFileError(
            f"{where} encloses almost no volume: {volume:.3g} m^3, "
            f"{100 * volume / box_volume:.2g} % of its bounding box ({box} m, "
            f"{thickness * 1e3:.2f} mm thick in its thinnest direction), less than the "
            f"{100 * MIN_VOLUME_FRACTION:g} % a solid object encloses; its faces cancel (a sheet "
            f"folded onto itself, or a surface given twice). Make it one closed solid and {fix}"
        )


def load_object_mesh(
    path: str | os.PathLike[str],
    object_id: str = "",
    user_file: str | os.PathLike[str] | None = None,
) -> trimesh.Trimesh:
    """:func:`read_obj` then :func:`check_extent`: the mesh of one object, or a clear error."""
    mesh = read_obj(path, object_id, user_file)
    check_extent(mesh, object_id, path, user_file)
    return mesh
