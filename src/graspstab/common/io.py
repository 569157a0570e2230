"""Atomic file output, so a killed or failed job never leaves a half-written artefact."""

from __future__ import annotations

import contextlib
import json
import math
import os
import tempfile
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import numpy as np

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


class UnreadableArtefact(RuntimeError):
    """An artefact on disk that cannot be parsed (truncated by a kill, a full disk, a bad copy)."""


def unreadable(path: str | os.PathLike[str], error: BaseException) -> UnreadableArtefact:
    """The one message for a corrupt artefact: which file, and how to recover."""
    return UnreadableArtefact(
        f"{path} is unreadable (truncated?): {type(error).__name__}: {error}. "
        "Delete it and rerun; the workflow rebuilds it."
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
