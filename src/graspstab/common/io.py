"""Atomic file output, so a killed or failed job never leaves a half-written artefact."""

from __future__ import annotations

import contextlib
import hashlib
import json
import math
import os
import tempfile
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import numpy as np

from graspstab.common.errors import GraspstabError

_UMASK = os.umask(0)
os.umask(_UMASK)


@contextlib.contextmanager
def atomic_path(path: str | os.PathLike[str]) -> Iterator[Path]:
    """Yield a temporary path beside ``path``; move it into place only if the block succeeds."""
    target = Path(path)
    target.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(prefix=f".{target.name}.", suffix=".tmp", dir=target.parent)
    os.close(fd)
    os.chmod(tmp, 0o666 & ~_UMASK)  # mkstemp makes 0600; give results the usual permissions
    tmp_path = Path(tmp)
    try:
        yield tmp_path
        os.replace(tmp_path, target)
    finally:
        if tmp_path.exists():
            tmp_path.unlink()


def _json_default(obj: Any) -> Any:
    if isinstance(obj, np.ndarray):
        return obj.tolist()
    if isinstance(obj, np.generic):
        return obj.item()
    if isinstance(obj, Path):
        return str(obj)
    raise TypeError(f"cannot serialise {type(obj).__name__} to JSON")


def _strict(obj: Any) -> Any:
    """``obj`` with numpy values made plain and NaN/inf replaced by None: JSON has no NaN, and
    strict parsers (browsers, jq, other languages) reject the bare ``NaN`` token."""
    if isinstance(obj, dict):
        return {k: _strict(v) for k, v in obj.items()}
    if isinstance(obj, list | tuple):
        return [_strict(v) for v in obj]
    if isinstance(obj, np.ndarray):
        return _strict(obj.tolist())
    if isinstance(obj, np.generic):
        obj = obj.item()
    if isinstance(obj, float) and not math.isfinite(obj):
        return None
    return obj


def write_json(path: str | os.PathLike[str], data: Any) -> None:
    """Write ``data`` as indented, strict JSON atomically: numpy values become plain numbers and
    an undefined value (NaN, inf) becomes null, so readers must treat None as undefined."""
    text = json.dumps(
        _strict(data), indent=2, sort_keys=True, default=_json_default, allow_nan=False
    )
    with atomic_path(path) as tmp:
        tmp.write_text(text + "\n")


class UnreadableArtefact(RuntimeError, GraspstabError):
    """An artefact on disk that cannot be parsed (truncated by a kill, a full disk, a bad copy)."""


# The extended attribute a cache restore leaves on the file it placed: the entry it came from.
CACHE_ORIGIN_ATTR = "user.graspstab.cache_entry"


def mark_restored(path: str | os.PathLike[str], entry: str | os.PathLike[str]) -> None:
    """Note on ``path`` the cache entry it was restored from (skipped where the filesystem keeps
    no extended attributes: the message below then only loses its pointer to the entry)."""
    with contextlib.suppress(OSError):
        os.setxattr(path, CACHE_ORIGIN_ATTR, str(Path(entry).resolve()).encode())


def cache_origin(path: str | os.PathLike[str]) -> Path | None:
    """The cache entry ``path`` was restored from, if it was and the note survived."""
    try:
        return Path(os.getxattr(path, CACHE_ORIGIN_ATTR).decode())
    except (OSError, UnicodeDecodeError):
        return None


def _origin_advice(path: str | os.PathLike[str]) -> str:
    """How to recover a corrupt file that came from a cache entry: delete the entry too when it
    holds the same bytes (a rerun would restore them again), else a rerun restores a good copy."""
    entry = cache_origin(path)
    if entry is None or not entry.is_dir():
        return "Delete it and rerun; the workflow rebuilds it."
    try:
        record = json.loads((entry / "entry.json").read_text())
        recorded = {f["sha256"] for f in record["files"].values()}
        with open(path, "rb") as fh:
            same = hashlib.file_digest(fh, "sha256").hexdigest() in recorded
    except (OSError, ValueError, KeyError, TypeError, AttributeError):
        same = True  # an entry we cannot read is no better than the file
    if same:
        return (
            f"It was restored from cache entry {entry}, which holds the same bytes: delete "
            "that folder and this file, then rerun; the workflow recomputes both."
        )
    return (
        f"It was restored from cache entry {entry} and changed since: delete it and rerun; "
        "the workflow restores the entry's verified copy."
    )


def unreadable(path: str | os.PathLike[str], error: BaseException) -> UnreadableArtefact:
    """The one message for a corrupt artefact: which file, and how to recover (naming the cache
    entry it came from, if it did)."""
    return UnreadableArtefact(
        f"{path} is unreadable (truncated?): {type(error).__name__}: {error}. "
        + _origin_advice(path)
    )


@contextlib.contextmanager
def reading(path: str | os.PathLike[str]) -> Iterator[None]:
    """Turn any parse error raised while reading ``path`` into :class:`UnreadableArtefact`
    (a missing file stays a FileNotFoundError: that is a different fix)."""
    try:
        yield
    except (FileNotFoundError, UnreadableArtefact):
        raise
    except Exception as error:  # noqa: BLE001 - every reader's parse errors, one message
        raise unreadable(path, error) from error


def read_json(path: str | os.PathLike[str]) -> Any:
    """Read a JSON file."""
    with reading(path):
        return json.loads(Path(path).read_text())


def read_parquet(path: str | os.PathLike[str], **kwargs: Any) -> Any:
    """Read a Parquet table as a polars DataFrame; a corrupt file names its path."""
    import polars as pl

    with reading(path):
        return pl.read_parquet(path, **kwargs)


def load_npz(path: str | os.PathLike[str]) -> dict[str, np.ndarray]:
    """Every array of a ``.npz`` file, loaded eagerly so a truncated member fails here, named."""
    with reading(path), np.load(path, allow_pickle=False) as data:
        return {key: data[key] for key in data.files}


def load_npy(path: str | os.PathLike[str], mmap_mode: str | None = None) -> np.ndarray:
    """One ``.npy`` array (memory-mapped if asked); a corrupt file names its path."""
    with reading(path):
        return np.load(path, mmap_mode=mmap_mode, allow_pickle=False)


def write_text(path: str | os.PathLike[str], text: str) -> None:
    """Write text atomically."""
    with atomic_path(path) as tmp:
        tmp.write_text(text)


def save_figure(path: str | os.PathLike[str], fig: Any, **kwargs: Any) -> None:
    """Save a matplotlib figure atomically (the format comes from ``path``'s suffix)."""
    fmt = kwargs.pop("format", Path(path).suffix.lstrip(".") or "png")
    with atomic_path(path) as tmp:
        fig.savefig(tmp, format=fmt, **kwargs)


def save_npz(path: str | os.PathLike[str], **arrays: Any) -> None:
    """Save compressed arrays atomically (numpy appends no suffix because we pass a file object)."""
    with atomic_path(path) as tmp, open(tmp, "wb") as fh:
        np.savez_compressed(fh, **arrays)


def save_npy(path: str | os.PathLike[str], array: np.ndarray) -> None:
    """Save one array atomically as ``.npy`` (memory-mappable)."""
    with atomic_path(path) as tmp, open(tmp, "wb") as fh:
        np.save(fh, array)


def write_parquet(
    path: str | os.PathLike[str], frame: Any, metadata: dict[str, Any] | None = None
) -> None:
    """Write a polars DataFrame as Parquet atomically; ``metadata`` goes in as JSON under
    the schema key ``graspstab`` (e.g. the provenance of the table)."""
    import pyarrow.parquet as pq

    table = frame.to_arrow()
    if metadata is not None:
        extra = {b"graspstab": json.dumps(metadata, sort_keys=True, default=_json_default).encode()}
        table = table.replace_schema_metadata({**(table.schema.metadata or {}), **extra})
    with atomic_path(path) as tmp:
        pq.write_table(table, tmp, compression="zstd")


def read_parquet_metadata(path: str | os.PathLike[str]) -> dict[str, Any]:
    """The ``graspstab`` JSON metadata written by :func:`write_parquet` (empty if none)."""
    import pyarrow.parquet as pq

    with reading(path):
        schema = pq.read_schema(path)
    raw = (schema.metadata or {}).get(b"graspstab")
    return json.loads(raw) if raw else {}
