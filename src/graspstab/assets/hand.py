"""Provide the ORCA v2 hand description (v2/, LICENSE) from a local copy or the pinned archive."""

from __future__ import annotations

import json
import logging
import os
import shutil
import tempfile
from datetime import UTC, datetime
from importlib import resources
from pathlib import Path
from typing import Any

from graspstab.assets.download import DEFAULT_TIMEOUT, download, safe_extract
from graspstab.assets.errors import HAND_LOCAL_HINT, AssetError, normalise_sha256
from graspstab.common.io import write_json
from graspstab.common.provenance import file_sha256

log = logging.getLogger(__name__)

HAND_URL_TEMPLATE = "https://github.com/orcahand/orcahand_description/archive/{commit}.tar.gz"
HAND_COMMIT = "9fa90c180c30b593df43c3b0f8499ab5ee866649"
MANIFEST_NAME = "orca_v2_manifest.json"
SOURCE_NAME = "source.json"
RIGHT_MESH_DIR = "v2/models/assets/right"
# Upstream MJCF files: a local copy carries a documented patch of them (the untouched upstream
# files sit beside them as *.upstream, see its SOURCES.md), so they are verified on download only.
UPSTREAM_MJCF = (
    "v2/models/mjcf/orcahand_right.mjcf",
    "v2/models/mjcf/orcahand_right_body.xml",
)
# Upstream meshes a local copy may lack (documented in its SOURCES.md); any other gap is an error.
ABSENT_LOCALLY_OK = frozenset(
    f"{RIGHT_MESH_DIR}/{name}" for name in ("R-Carpals.stl", "P-Assembly.stl", "T-R-Assembly.stl")
)
_TOP_LEVEL_FILES = ("LICENSE",)
_LOCAL_EXTRA_FILES = ("SOURCES.md",)
_MAX_LISTED = 10


def _now() -> str:
    return datetime.now(UTC).isoformat(timespec="seconds")


def load_manifest() -> dict[str, str]:
    """The committed manifest: path under the description root -> sha256 of the upstream file."""
    text = resources.files("graspstab.assets").joinpath(MANIFEST_NAME).read_text()
    return dict(json.loads(text))


def read_manifest(path: str | os.PathLike[str]) -> dict[str, str]:
    """A user's manifest file (config ``assets.hand_manifest``): a JSON object mapping paths under
    the description root to sha256 digests; :class:`AssetError` naming the file otherwise."""
    where = f"ORCA hand manifest {path} (config key assets.hand_manifest)"
    try:
        data = json.loads(Path(path).read_text())
    except FileNotFoundError:
        raise AssetError(f"{where}: no such file; fix the path, or set it to null") from None
    except (OSError, UnicodeDecodeError, json.JSONDecodeError) as exc:
        raise AssetError(f"{where} is not readable JSON ({exc}); fix the file") from None
    if not isinstance(data, dict) or not data:
        raise AssetError(f"{where} must be a non-empty JSON object {{path: sha256}}; fix the file")
    manifest: dict[str, str] = {}
    for rel, sha in data.items():
        manifest[str(rel)] = normalise_sha256(sha, f"{where}, entry {rel}") or ""
    return manifest


def build_manifest(description_dir: str | os.PathLike[str]) -> dict[str, str]:
    """Manifest of a local description copy: every right-hand STL plus the upstream MJCF files.

    For an MJCF file, the sha256 of its ``*.upstream`` twin is used when present (a patched copy).
    """
    root = Path(description_dir)
    manifest = {
        f"{RIGHT_MESH_DIR}/{p.name}": file_sha256(p)
        for p in sorted((root / RIGHT_MESH_DIR).glob("*.stl"))
    }
    for rel in UPSTREAM_MJCF:
        upstream = root / f"{rel}.upstream"
        manifest[rel] = file_sha256(upstream if upstream.is_file() else root / rel)
    return dict(sorted(manifest.items()))


def _stage_local(local_dir: Path, tree: Path) -> dict[str, Any]:
    where = (
        "the local hand directory (config key assets.hand_dir / env var GRASPSTAB_HAND_DIR = "
        f"{local_dir})"
    )
    if not (local_dir / "v2").is_dir():
        raise AssetError(
            f"ORCA hand: no folder {local_dir / 'v2'}; {where} must be an orcahand_description "
            "copy holding v2/ and LICENSE. Fix it, or unset it to download the pinned archive."
        )
    for name in _TOP_LEVEL_FILES:
        if not (local_dir / name).is_file():
            raise AssetError(
                f"ORCA hand: no file {local_dir / name}; {where} must hold the upstream {name} "
                "next to v2/. Fix it, or unset it to download the pinned archive."
            )
    tree.mkdir()
    shutil.copytree(local_dir / "v2", tree / "v2")
    for name in (*_TOP_LEVEL_FILES, *_LOCAL_EXTRA_FILES):
        if (local_dir / name).is_file():
            shutil.copyfile(local_dir / name, tree / name)
    return {"method": "local", "source": str(local_dir.resolve()), "local_dir": str(local_dir)}


def _keep_upstream(name: str) -> str | None:
    if name == "v2" or name.startswith("v2/") or name in _TOP_LEVEL_FILES:
        return name
    return None


def _stage_download(url: str, work: Path, tree: Path, timeout: float) -> dict[str, Any]:
    archive = download(url, work / "archive.tar.gz", timeout, hint=HAND_LOCAL_HINT)
    safe_extract(archive, tree, _keep_upstream, url=url, hint=HAND_LOCAL_HINT, strip_top=True)
    archive.unlink()
    missing = [n for n in ("v2", *_TOP_LEVEL_FILES) if not (tree / n).exists()]
    if missing:
        raise AssetError(
            f"ORCA hand: the archive {url} has no {', '.join(missing)} under its top folder; check "
            f"assets.hand_url and assets.hand_commit. {HAND_LOCAL_HINT}"
        )
    return {"method": "download", "source": url, "url": url}


def _verify(
    tree: Path, manifest: dict[str, str], method: str, source: str, commit: str
) -> dict[str, Any]:
    """Check every manifest entry that applies to this path; raise listing all failures."""
    verified: list[str] = []
    skipped: list[str] = []
    absent: list[str] = []
    missing: list[str] = []
    bad: list[str] = []
    for rel, expected in sorted(manifest.items()):
        if method == "local" and rel in UPSTREAM_MJCF:
            skipped.append(rel)
            continue
        path = tree / rel
        if not path.is_file():
            if method == "local" and rel in ABSENT_LOCALLY_OK:
                absent.append(rel)
            else:
                missing.append(rel)
            continue
        actual = file_sha256(path)
        if actual != expected:
            bad.append(f"  - {rel}: expected sha256 {expected}, got {actual}")
        else:
            verified.append(rel)
    if missing or bad:
        lines = [f"  - {rel}: missing" for rel in missing] + bad
        more = len(lines) - _MAX_LISTED
        listed = "\n".join(lines[:_MAX_LISTED]) + (f"\n  ... and {more} more" if more > 0 else "")
        if method == "local":
            fix = (
                f"The local copy differs from upstream commit {commit}; restore these files from "
                "the upstream repository, or unset assets.hand_dir / GRASPSTAB_HAND_DIR to "
                "download the pinned archive."
            )
        else:
            fix = (
                "Retry (the download may be corrupt), and check that assets.hand_commit is the "
                f"commit the manifest pins (graspstab/assets/{MANIFEST_NAME}). {HAND_LOCAL_HINT}"
            )
        raise AssetError(
            f"ORCA hand description from {source}: checksum check failed for "
            f"{len(missing) + len(bad)} file(s):\n{listed}\n{fix}"
        )
    return {
        "entries": len(manifest),
        "verified": len(verified),
        "not_verified_local_patch": skipped,
        "absent_locally": absent,
    }


def _tree_hashes(tree: Path) -> dict[str, str]:
    return {
        p.relative_to(tree).as_posix(): file_sha256(p)
        for p in sorted(tree.rglob("*"))
        if p.is_file()
    }


def _swap_into_place(tree: Path, dest: Path, work: Path) -> None:
    """Rename the finished tree onto ``dest``; an old ``dest`` moves into ``work`` (deleted)."""
    old = work / "old"
    had_old = dest.exists() or dest.is_symlink()
    if had_old:
        os.rename(dest, old)
    try:
        os.rename(tree, dest)
    except BaseException:
        if had_old:
            os.rename(old, dest)
        raise


def fetch_hand_description(
    dest_dir: str | os.PathLike[str],
    *,
    local_dir: str | os.PathLike[str] | None = None,
    url_template: str = HAND_URL_TEMPLATE,
    commit: str = HAND_COMMIT,
    manifest: dict[str, str] | None = None,
    timeout: float = DEFAULT_TIMEOUT,
) -> dict[str, Any]:
    """Write the description tree to ``dest_dir`` (with ``source.json``); return the source record.

    From ``local_dir`` (v2/, LICENSE and SOURCES.md copied) if given, else from the upstream archive
    at ``commit`` (v2/ and LICENSE only). Files are checked against ``manifest`` (default: the
    committed one). The tree is built in a temp folder beside ``dest_dir`` and renamed into place
    only once verified; on failure the temp folder is removed and ``dest_dir`` is left as it was.
    """
    entries = load_manifest() if manifest is None else dict(manifest)
    for rel, sha in entries.items():
        entries[rel] = normalise_sha256(sha, f"ORCA hand manifest entry {rel}") or ""
    if manifest is None and commit != HAND_COMMIT:
        log.warning(
            "ORCA hand: commit %s is not the one the committed manifest pins (%s); "
            "the checksum check will probably fail",
            commit,
            HAND_COMMIT,
        )
    dest = Path(dest_dir).absolute()
    local = Path(local_dir) if local_dir not in (None, "") else None
    if local is not None and local.resolve() == dest.resolve():
        raise AssetError(
            f"ORCA hand: the destination {dest} is the local hand directory itself "
            "(assets.hand_dir / GRASPSTAB_HAND_DIR); choose another destination"
        )
    dest.parent.mkdir(parents=True, exist_ok=True)
    work = Path(tempfile.mkdtemp(prefix=f".{dest.name}.tmp-", dir=dest.parent))
    tree = work / "tree"
    try:
        if local is not None:
            record = _stage_local(local, tree)
        else:
            record = _stage_download(url_template.format(commit=commit), work, tree, timeout)
        summary = _verify(tree, entries, record["method"], record["source"], commit)
        record = {
            "asset": "orcahand_description",
            **record,
            "upstream_commit": commit,
            "manifest": summary,
            "files": _tree_hashes(tree),
            "fetched_at": _now(),
        }
        write_json(tree / SOURCE_NAME, record)
        _swap_into_place(tree, dest, work)
    finally:
        shutil.rmtree(work, ignore_errors=True)
    log.info(
        "ORCA hand description in %s via %s (%d of %d manifest files verified)",
        dest,
        record["method"],
        summary["verified"],
        summary["entries"],
    )
    return record
