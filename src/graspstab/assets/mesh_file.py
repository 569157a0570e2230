"""Reading an object's mesh file: a bad one (not OBJ, empty, unreadable, wrong units) is refused
with a message naming the object and the user's own file, before any expensive step runs."""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np
import trimesh

#: A hand-held object's largest bounding-box extent lies between these [m]; outside, the mesh is
#: almost surely in other units (a YCB mesh in millimetres is ~100 "m" across).
MAX_EXTENT_M = 0.5
MIN_EXTENT_M = 0.005
OBJ_ONLY = (
    "graspstab reads Wavefront OBJ meshes only (a text .obj file with 'v' vertex and 'f' face "
    "lines, coordinates in metres)"
)


class MeshFileError(ValueError):
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
    return f"{who}: your mesh {user_file} (field 'mesh' of the object{copy})"


def _fix(user_file: str | os.PathLike[str] | None, verb: str = "fix") -> str:
    """How to fix it: the user's file (field 'mesh'), else the file itself."""
    if user_file is not None:
        return f"{verb} {user_file}, or set field 'mesh' of the object to another file"
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
    if shown.suffix.lower() != ".obj":
        target = shown.with_suffix(".obj")
        raise MeshFileError(
            f"{where} is not an OBJ file (suffix {shown.suffix or 'none'!r}). {OBJ_ONLY}. Convert "
            f"it, e.g. python -c \"import trimesh; trimesh.load('{shown}').export('{target}')\", "
            "and give the .obj file"
            + (" in field 'mesh' of the object" if user_file is not None else "")
        )
    try:
        size = p.stat().st_size
    except OSError as exc:
        raise MeshFileError(f"{where} cannot be read ({exc}); {_fix(user_file)}") from exc
    if size == 0:
        raise MeshFileError(f"{where} is empty (0 bytes). {OBJ_ONLY}; {_fix(user_file)}")
    try:
        mesh = trimesh.load(p, file_type="obj", force="mesh", process=False, skip_materials=True)
    except Exception as exc:  # noqa: BLE001 - any parse failure of a bad file, one message
        raise MeshFileError(
            f"{where}: no triangle mesh could be read ({type(exc).__name__}: {exc}). "
            f"{OBJ_ONLY}; {_fix(user_file)}"
        ) from exc
    if not isinstance(mesh, trimesh.Trimesh) or len(mesh.faces) == 0:
        raise MeshFileError(
            f"{where}: no triangle mesh could be read (no 'f' face lines found in {size} bytes; "
            f"is it an OBJ file?). {OBJ_ONLY}; {_fix(user_file)}"
        )
    vertices = np.asarray(mesh.vertices, dtype=np.float64)
    if not np.all(np.isfinite(vertices)):
        raise MeshFileError(
            f"{where} has non-finite (nan or inf) vertex coordinates; {_fix(user_file)}"
        )
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
            f"metres; rescale it and {_fix(user_file, 'save it as')}"
        )
    raise MeshFileError(
        f"{where} is only {largest * 1e3:.3g} mm across (bounding box {box} m), less than the "
        f"{MIN_EXTENT_M * 1e3:g} mm a graspable object needs: is it in metres? Mesh coordinates "
        "are read as metres (a mesh scaled by 0.001 twice, or exported in kilometres, looks like "
        f"this); rescale it and {_fix(user_file, 'save it as')}"
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
