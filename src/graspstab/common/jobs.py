"""How a workflow job ends when it fails: one message, in the job's log (docs/troubleshooting.md).

Every script in ``workflow/scripts/`` runs its work inside :func:`job`:

* a :class:`~graspstab.common.errors.GraspstabError` (a failure the user can fix: a bad input, a
  wrong setting, a corrupt file) ends the job with its message alone, no Python traceback;
* a full disk (``OSError`` ENOSPC anywhere in the exception's chain) ends it with one message
  naming the file being written (or the job's outputs), the free space of its filesystem and the
  fix;
* any other exception is a bug: it ends the job with its full traceback.

The message (or traceback) goes to the job's log file, ``snakemake.log[0]``, as one record in the
log's format; Snakemake's profile (``show-failed-logs``) prints a failed job's log under its
``Error in rule`` block, so the user reads it there once. A job without a log file, or one whose
log cannot be written (a full disk), prints it on stderr instead. Either way the job exits with
status 1, so Snakemake marks it failed and removes its outputs.

:func:`require_free_space` (and :func:`require_job_space` for a job whose outputs the result
cache copies) is the check before a long compute whose output size is known in advance.
"""

from __future__ import annotations

import contextlib
import errno
import logging
import os
import shutil
import sys
import traceback
from collections.abc import Iterator, Mapping
from pathlib import Path
from typing import Any

from graspstab.common.cache import cache_settings
from graspstab.common.errors import DiskSpaceError, GraspstabError
from graspstab.common.logs import append_record

LOGGER = "graspstab.job"
MOVE_HINT = (
    "Free space there, or run the workflow on a disk with more room: its working directory "
    "(snakemake -d <dir>, resources/ and results/ in it) and the result cache (--config "
    "'cache={dir: <dir>}' or GRASPSTAB_CACHE_DIR; deleting .graspstab-cache/ frees its copies)."
)
_MANY = 3  # outputs named in a message before "and <n> more"


def _items(container: Any) -> list[tuple[str, Any]]:
    """(name, value) pairs of a Snakemake ``Namedlist``, a dict or a namespace."""
    if hasattr(container, "items"):
        return list(container.items())
    return list(vars(container).items()) if hasattr(container, "__dict__") else []


def _values(container: Any) -> list[str]:
    """The paths of a Snakemake ``Namedlist`` (every one, named or not), a list or a namespace."""
    if isinstance(container, str):
        return [container]
    if hasattr(container, "__iter__"):
        return [str(v) for v in container]
    return [str(v) for _, v in _items(container)]


def job_name(smk: Any) -> str:
    """``rule (wildcard=value, ...)``: the job as Snakemake's own messages name it."""
    rule = getattr(smk, "rule", None) or "job"
    wildcards = ", ".join(f"{k}={v}" for k, v in _items(getattr(smk, "wildcards", {})))
    return f"{rule} ({wildcards})" if wildcards else rule


def job_log(smk: Any) -> str | None:
    """The job's log file (the first of its ``log:`` entries), if the rule has one."""
    logs = _values(getattr(smk, "log", []))
    return logs[0] if logs else None


def format_bytes(n: float) -> str:
    """A size in decimal units, three significant digits: ``512 B``, ``1.21 GB``."""
    for unit in ("B", "kB", "MB", "GB", "TB"):
        if abs(n) < 1000 or unit == "TB":
            return f"{n:.0f} {unit}" if unit == "B" else f"{n:.3g} {unit}"
        n /= 1000
    raise AssertionError("unreachable")


def _existing_dir(path: str | os.PathLike[str]) -> Path:
    """The nearest existing directory at or above ``path`` (an output not written yet)."""
    p = Path(path).absolute()
    while not p.is_dir() and p != p.parent:
        p = p.parent
    return p


def free_space(path: str | os.PathLike[str]) -> str:
    """``<dir> has <free> free of <total>``, for the filesystem ``path`` is (or will be) on."""
    where = _existing_dir(path)
    try:
        usage = shutil.disk_usage(where)
    except OSError as error:  # reporting a failure must not fail in turn
        return f"the free space of {where} could not be read ({error})"
    return f"{where} has {format_bytes(usage.free)} free of {format_bytes(usage.total)}"


def _filesystems(paths: list[str]) -> dict[Any, list[str]]:
    """``paths`` grouped by the filesystem (device) they are, or will be, on."""
    groups: dict[Any, list[str]] = {}
    for path in paths:
        try:
            device: Any = _existing_dir(path).stat().st_dev
        except OSError:
            device = path
        groups.setdefault(device, []).append(path)
    return groups


def _named(paths: list[str]) -> str:
    shown = ", ".join(paths[:_MANY])
    return shown + (f" and {len(paths) - _MANY} more" if len(paths) > _MANY else "")


def disk_full_error(exc: BaseException) -> OSError | None:
    """The ``OSError`` ENOSPC in ``exc``'s chain (causes and contexts), if the disk was full;
    also one that says so only in its text (pyarrow's writers drop the errno)."""
    seen: set[int] = set()
    current: BaseException | None = exc
    while current is not None and id(current) not in seen:
        seen.add(id(current))
        if isinstance(current, OSError) and (
            current.errno == errno.ENOSPC or "No space left on device" in str(current)
        ):
            return current
        current = current.__cause__ or current.__context__
    return None


def _target(filename: str, outputs: list[str]) -> str:
    """The output a written file stands for: an atomic writer's ``.<name>.<random>.tmp`` beside
    an output is that output (graspstab.common.io.atomic_path)."""
    path = Path(filename).absolute()
    for out in outputs:
        o = Path(out).absolute()
        if path == o or (path.parent == o.parent and path.name.startswith(f".{o.name}.")):
            return out
    return filename


def disk_full_message(smk: Any, error: OSError) -> str:
    """The one message of a job that ran out of disk: what it was writing, the free space left
    on that filesystem (each of its outputs' filesystems when the file is not known), the fix."""
    outputs = _values(getattr(smk, "output", []))
    # a copy names its source first and its target second (shutil's sendfile path on ENOSPC)
    name = getattr(error, "filename2", None) or getattr(error, "filename", None)
    if name:
        paths = [_target(str(name), outputs)]
    else:
        paths = outputs
    groups = _filesystems(paths) if paths else {}
    if groups:
        space = "; ".join(free_space(group[0]) for group in groups.values())
        writing = f"writing {_named(paths)}"
    else:
        space, writing = f"{free_space('.')} (the working directory)", "writing its outputs"
    return (
        f"{job_name(smk)} failed: the disk is full ({error.strerror or error}) while {writing}. "
        f"{space}. {MOVE_HINT}"
    )


def require_free_space(
    needs: Mapping[str | os.PathLike[str], int],
    what: str,
    labels: Mapping[str, str] | None = None,
) -> None:
    """Raise :class:`DiskSpaceError` unless each filesystem has the bytes that the paths on it
    need (``needs``: path -> largest size it will take), summed over those paths; ``labels``
    names a path in the message (default: the path itself)."""
    by_path = {str(p): int(n) for p, n in needs.items()}
    for paths in _filesystems(list(by_path)).values():
        need = sum(by_path[p] for p in paths)
        free = shutil.disk_usage(_existing_dir(paths[0])).free
        if free < need:
            named = _named([(labels or {}).get(p, p) for p in paths])
            raise DiskSpaceError(
                f"not enough free disk space for {what}: {named} "
                f"{'needs' if len(paths) == 1 else 'need'} up to {format_bytes(need)}, but "
                f"{free_space(paths[0])}. {MOVE_HINT}"
            )


def require_job_space(smk: Any, needs: Mapping[str | os.PathLike[str], int], what: str) -> None:
    """:func:`require_free_space` for a job's outputs, plus the copy the result cache stores of
    them when it is on (``graspstab.common.cache.run_cached``), counted on the cache's disk."""
    total = {str(p): int(n) for p, n in needs.items()}
    enabled, root = cache_settings(getattr(smk, "config", {}) or {})
    labels = {}
    if enabled:
        cache = str(root)
        total[cache] = total.get(cache, 0) + sum(needs.values())
        labels[cache] = f"{cache} (the result cache's copy)"
    require_free_space(total, what, labels)


def _report(smk: Any, level: int, message: str, exc_info: Any = None) -> None:
    """Write the failure to the job's log, or to stderr when it has none or it cannot be written."""
    log_file = job_log(smk)
    if log_file and append_record(log_file, LOGGER, level, message, exc_info):
        return
    text = message
    if exc_info:
        text += "\n" + "".join(traceback.format_exception(*exc_info)).rstrip()
    print(text, file=sys.stderr, flush=True)


@contextlib.contextmanager
def job(smk: Any) -> Iterator[None]:
    """Run a workflow job's work; on failure report it once (module docstring) and exit 1.

    ``smk`` is the script's ``snakemake`` object (its ``rule``, ``wildcards``, ``output`` and
    ``log`` are used). ``KeyboardInterrupt`` and ``SystemExit`` pass through unchanged, except a
    ``SystemExit`` that is a graspstab error (``learning.storage.StorageError``): an
    ``Exception`` too, it is reported like the others."""
    try:
        yield
    except Exception as exc:  # noqa: BLE001 - every failure of the job, reported once
        full = disk_full_error(exc)
        if isinstance(exc, DiskSpaceError) or (isinstance(exc, GraspstabError) and full is None):
            _report(smk, logging.ERROR, f"{job_name(smk)} failed: {exc}")
        elif full is not None:
            _report(smk, logging.ERROR, disk_full_message(smk, full))
        else:
            _report(
                smk,
                logging.ERROR,
                f"{job_name(smk)} failed on an unexpected error, a bug in graspstab: please "
                "report it with this traceback",
                (type(exc), exc, exc.__traceback__),
            )
        sys.exit(1)
