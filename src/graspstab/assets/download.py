"""Streaming download and safe archive extraction, so a failed fetch leaves no partial file."""

from __future__ import annotations

import http.client
import logging
import os
import shutil
import tarfile
import tempfile
import urllib.error
import urllib.request
from collections.abc import Callable
from pathlib import Path, PurePosixPath

from graspstab.assets.errors import AssetError

log = logging.getLogger(__name__)

DEFAULT_TIMEOUT = 120.0
_CHUNK = 1 << 20
_GENERIC_HINT = (
    "To use local copies instead, set config key assets.ycb_dir / env var GRASPSTAB_YCB_DIR "
    "(YCB meshes) or assets.hand_dir / GRASPSTAB_HAND_DIR (hand description)."
)


def download(
    url: str,
    dest: str | os.PathLike[str],
    timeout: float = DEFAULT_TIMEOUT,
    *,
    hint: str = _GENERIC_HINT,
) -> Path:
    """Stream ``url`` to a temp file beside ``dest`` and rename it into place only when complete."""
    target = Path(dest)
    target.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp_name = tempfile.mkstemp(prefix=f".{target.name}.", suffix=".part", dir=target.parent)
    tmp = Path(tmp_name)
    log.info("downloading %s", url)
    try:
        request = urllib.request.Request(url, headers={"User-Agent": "graspstab-assets/1"})
        with os.fdopen(fd, "wb") as out, urllib.request.urlopen(request, timeout=timeout) as resp:
            expected = resp.headers.get("Content-Length")
            shutil.copyfileobj(resp, out, _CHUNK)
            written = out.tell()
        if expected is not None and expected.isdigit() and int(expected) != written:
            raise AssetError(
                f"download of {url} was cut short ({written} of {expected} bytes); "
                f"retry, or fetch it another way. {hint}"
            )
        os.replace(tmp, target)
    except urllib.error.HTTPError as exc:
        raise AssetError(
            f"download of {url} failed: HTTP {exc.code} {exc.reason}. Check the URL (and the id or "
            f"commit in it). {hint}"
        ) from exc
    except urllib.error.URLError as exc:
        raise AssetError(
            f"download of {url} failed: {exc.reason}. No network access, or the host is "
            f"unreachable. {hint}"
        ) from exc
    except (TimeoutError, OSError, http.client.HTTPException) as exc:
        raise AssetError(f"download of {url} failed: {exc}. {hint}") from exc
    finally:
        if tmp.exists():
            tmp.unlink()
    log.info("downloaded %s (%d bytes)", url, target.stat().st_size)
    return target


def _safe_relpath(name: str) -> str | None:
    """Normalise a member path; None when it is absolute or climbs out of the extraction folder."""
    path = PurePosixPath(name)
    parts = [p for p in path.parts if p not in ("", ".")]
    if path.is_absolute() or ".." in parts or not parts:
        return None
    return "/".join(parts)


def _top_folder(members: list[tarfile.TarInfo], url: str, hint: str) -> str:
    """The single top-level folder of an archive (GitHub archives have one)."""
    tops = {
        rel.split("/", 1)[0]
        for m in members
        if (rel := _safe_relpath(m.name)) is not None and "/" in rel
    }
    if len(tops) != 1:
        raise AssetError(
            f"archive from {url} does not have a single top-level folder (found "
            f"{sorted(tops)[:5]}); is the URL right? {hint}"
        )
    return tops.pop()


def safe_extract(
    archive: str | os.PathLike[str],
    dest_dir: str | os.PathLike[str],
    select: Callable[[str], str | None],
    *,
    url: str,
    hint: str = _GENERIC_HINT,
    strip_top: bool = False,
) -> list[str]:
    """Extract only the members ``select`` maps to a relative output path (regular files, dirs).

    ``select`` gets each member's normalised path (without its top folder when ``strip_top``) and
    returns the path to write it to under ``dest_dir``, or None to skip it. Members with absolute
    or ``..`` paths are refused, and extraction uses tarfile's ``data`` filter as a second guard.
    Returns the relative paths of the regular files written.
    """
    out = Path(dest_dir)
    out.mkdir(parents=True, exist_ok=True)
    try:
        with tarfile.open(archive, "r:*") as tf:
            members = tf.getmembers()
            top = _top_folder(members, url, hint) if strip_top else None
            chosen: list[tarfile.TarInfo] = []
            for member in members:
                rel = _safe_relpath(member.name)
                if rel is None:
                    raise AssetError(
                        f"archive from {url} has an unsafe member path {member.name!r}; refusing "
                        f"to extract it. {hint}"
                    )
                if top is not None:
                    if not rel.startswith(top + "/"):
                        continue
                    rel = rel[len(top) + 1 :]
                new = select(rel)
                if new is None:
                    continue
                safe_new = _safe_relpath(new)
                if safe_new is None:
                    raise AssetError(f"refusing to extract {member.name!r} to unsafe path {new!r}")
                if not (member.isfile() or member.isdir()):
                    log.warning("skipping %s in %s: not a regular file or folder", member.name, url)
                    continue
                chosen.append(member.replace(name=safe_new, deep=False))
            tf.extractall(out, members=chosen, filter="data")
    except (tarfile.TarError, EOFError) as exc:
        raise AssetError(
            f"archive from {url} could not be read or extracted ({exc}); the download may be "
            f"corrupt, retry. {hint}"
        ) from exc
    return sorted(m.name for m in chosen if m.isfile())
