"""Provide one YCB mesh (<dest>/textured.obj + source.json) from a local copy or the archive."""

from __future__ import annotations

import contextlib
import functools
import logging
import os
import shutil
import tempfile
from datetime import UTC, datetime
from pathlib import Path
from typing import Any

from graspstab.assets.download import DEFAULT_TIMEOUT, download, safe_extract
from graspstab.assets.errors import YCB_LOCAL_HINT, AssetError, normalise_sha256
from graspstab.assets.local_ycb import MESH_NAME, missing_local_meshes_message
from graspstab.common.io import write_json
from graspstab.common.provenance import file_sha256

log = logging.getLogger(__name__)

YCB_URL_TEMPLATE = (
    "http://ycb-benchmarks.s3-website-us-east-1.amazonaws.com/data/google/{id}_google_16k.tgz"
)
SOURCE_NAME = "source.json"


def archive_member(object_id: str) -> str:
    """Path of the mesh inside the official google_16k archive."""
    return f"{object_id}/google_16k/{MESH_NAME}"


def _now() -> str:
    return datetime.now(UTC).isoformat(timespec="seconds")


@functools.cache
def _content_sha256(path: str) -> str:
    return file_sha256(path)


def user_mesh_sha256(mesh: str | os.PathLike[str] | None) -> str | None:
    """The sha256 of the user's own mesh file (config field objects.items.<id>.mesh), for the
    fetch rule's params: Snakemake reruns a job whose params changed, so editing the file in
    place reruns its copy even where the edit kept the old mtime (``cp -p``, ``rsync -a``, an
    unpacked archive), which the mtime trigger misses. Hashed once per file per process (one
    workflow load), cached by resolved path. None without a mesh (a YCB object: its copy or
    download is checked against its pinned sha256 in the job) or for a missing file (the config
    check and the job report that)."""
    if not mesh:
        return None
    path = Path(mesh).resolve()
    if not path.is_file():
        return None
    return _content_sha256(str(path))


def _stage_local(object_id: str, local_dir: Path, staged: Path) -> dict[str, Any]:
    src = local_dir / object_id / MESH_NAME
    if not src.is_file():
        raise AssetError(missing_local_meshes_message([object_id], local_dir))
    shutil.copyfile(src, staged)
    return {"method": "local", "source": str(src.resolve()), "local_dir": str(local_dir)}


def _stage_override(object_id: str, mesh: Path, staged: Path) -> dict[str, Any]:
    if not mesh.is_file():
        raise AssetError(
            f"object '{object_id}', field 'mesh': no such file {mesh}; "
            "fix the path in the object set"
        )
    check_user_mesh(object_id, mesh)
    shutil.copyfile(mesh, staged)
    return {"method": "mesh_override", "source": str(mesh.resolve())}


def check_user_mesh(object_id: str, mesh: str | os.PathLike[str]) -> None:
    """Refuse the user's own mesh (field ``mesh``) here, at the first job, unless it is a readable
    OBJ of a hand-held size with a thickness and a volume (not flat): :class:`AssetError` naming
    the object, the config field and the file."""
    # imported here: trimesh is not needed to load the workflow (the catalogue imports this package)
    from graspstab.assets.mesh_file import MeshFileError, check_solid, load_object_mesh

    try:
        loaded = load_object_mesh(mesh, object_id, user_file=mesh)
        check_solid(loaded, object_id, mesh, user_file=mesh)
    except MeshFileError as exc:
        raise AssetError(str(exc)) from None  # the same message: one traceback, not two


def _stage_download(
    object_id: str, url_template: str, work: Path, staged: Path, timeout: float
) -> dict[str, Any]:
    url = url_template.format(id=object_id)
    member = archive_member(object_id)
    hint = f"(YCB object '{object_id}') {YCB_LOCAL_HINT}"
    archive = download(url, work / "archive.tgz", timeout, hint=hint)
    got = safe_extract(
        archive,
        work / "extract",
        lambda name: MESH_NAME if name == member else None,
        url=url,
        hint=hint,
    )
    if MESH_NAME not in got:
        raise AssetError(
            f"YCB object '{object_id}': the archive {url} has no file {member}; check the object "
            f"id and assets.ycb_url. {YCB_LOCAL_HINT}"
        )
    os.replace(work / "extract" / MESH_NAME, staged)
    archive.unlink()
    return {"method": "download", "source": url, "url": url, "archive_member": member}


def _mismatch_message(object_id: str, record: dict[str, Any], expected: str, actual: str) -> str:
    method = record["method"]
    head = (
        f"YCB object '{object_id}': checksum mismatch for {MESH_NAME} from {record['source']}: "
        f"expected sha256 {expected}, got {actual}. "
    )
    if method == "local":
        fix = (
            "The local file is not the official google_16k mesh; replace it with the official "
            "file, or, to use your own mesh on purpose, set field 'mesh' of the object and update "
            "its field 'sha256' (null skips the check)."
        )
    elif method == "mesh_override":
        fix = (
            "Field 'sha256' of the object must be the sha256 of the file in field 'mesh'; update "
            "it (or set it to null to skip the check)."
        )
    else:
        fix = (
            "The downloaded file differs from the pinned one: retry (it may have been corrupted "
            f"in transit), check field 'sha256' of the object and assets.ycb_url. {YCB_LOCAL_HINT}"
        )
    return head + fix


def fetch_ycb_object(
    object_id: str,
    dest_dir: str | os.PathLike[str],
    *,
    local_dir: str | os.PathLike[str] | None = None,
    url_template: str = YCB_URL_TEMPLATE,
    sha256: str | None = None,
    mesh_override: str | os.PathLike[str] | None = None,
    timeout: float = DEFAULT_TIMEOUT,
) -> dict[str, Any]:
    """Write ``<dest_dir>/textured.obj`` and ``source.json``; return the source record.

    The mesh comes from ``mesh_override`` (the user's own file, which must be a readable OBJ of a
    hand-held size: :func:`check_user_mesh`) if given, else from ``<local_dir>/<id>/textured.obj``
    (copied), else from the official google_16k archive. It is verified against ``sha256`` when
    one is given. On failure nothing new is left in ``dest_dir`` (nor the folders made for it):
    staging happens in a temp folder inside it, removed in every case.
    """
    expected = normalise_sha256(sha256, f"YCB object '{object_id}'")
    dest = Path(dest_dir)
    created = [d for d in (dest, *dest.parents) if not d.exists()]  # innermost first
    dest.mkdir(parents=True, exist_ok=True)
    work = Path(tempfile.mkdtemp(prefix=".fetch-", dir=dest))
    mesh_placed = False
    try:
        staged = work / MESH_NAME
        if mesh_override is not None:
            record = _stage_override(object_id, Path(mesh_override), staged)
        elif local_dir not in (None, ""):
            record = _stage_local(object_id, Path(local_dir), staged)
        else:
            record = _stage_download(object_id, url_template, work, staged, timeout)
        actual = file_sha256(staged)
        if expected is not None and actual != expected:
            raise AssetError(_mismatch_message(object_id, record, expected, actual))
        if expected is None:
            log.warning(
                "YCB object '%s': no sha256 configured, %s is NOT verified (its sha256 is %s); "
                "add field 'sha256' to the object to pin it",
                object_id,
                MESH_NAME,
                actual,
            )
        record = {
            "asset": "ycb",
            "object_id": object_id,
            **record,
            "file": MESH_NAME,
            "sha256": actual,
            "expected_sha256": expected,
            "verified": expected is not None,
            "fetched_at": _now(),
        }
        write_json(work / SOURCE_NAME, record)
        os.replace(staged, dest / MESH_NAME)
        mesh_placed = True
        os.replace(work / SOURCE_NAME, dest / SOURCE_NAME)
    except BaseException:
        shutil.rmtree(work, ignore_errors=True)
        if mesh_placed:
            (dest / MESH_NAME).unlink(missing_ok=True)
        for folder in created:  # the folders this call made, if still empty
            with contextlib.suppress(OSError):
                folder.rmdir()
        raise
    shutil.rmtree(work, ignore_errors=True)
    log.info("YCB object '%s': %s via %s (%s)", object_id, MESH_NAME, record["method"], actual)
    return record
