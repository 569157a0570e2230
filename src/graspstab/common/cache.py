"""Content-addressed results (docs/design.md, caching contract point 3).

An expensive job's outputs are stored under the hash of what determines them: the rule, its params
and wildcards, the *content* of its inputs, the code version of the library stages it runs and the
versions of the numerical packages. A later job with the same key, after a reverted parameter or in
another workflow directory sharing the cache, restores the files instead of recomputing them.

Why our own cache rather than Snakemake's between-workflow cache (``cache: True``): that one needs
``--cache`` and an environment variable on every invocation, supports several outputs only as
``multiext``, and hashes the rule's script file, not the library code the thin scripts call, so a
library change would silently restore stale results.
"""

from __future__ import annotations

import contextlib
import hashlib
import json
import logging
import os
import shutil
import tempfile
import time
from collections.abc import Callable, Iterable, Mapping
from pathlib import Path
from typing import Any

from graspstab.common.io import mark_restored
from graspstab.common.provenance import (
    files_version,
    installed_versions,
    module_closure,
    stable_hash,
)

log = logging.getLogger(__name__)

# Packages whose version can change a numerical result: part of every key.
KEY_PACKAGES = ("numpy", "scipy", "mujoco", "torch", "coacd", "trimesh", "polars", "pyarrow")
ENTRY_FILE = "entry.json"


def content_digest(path: str | os.PathLike[str]) -> str:
    """SHA-256 of a file's bytes, or of a directory's relative paths and file contents."""
    p = Path(path)
    h = hashlib.sha256()
    if p.is_dir():
        for f in sorted(q for q in p.rglob("*") if q.is_file()):
            h.update(str(f.relative_to(p)).encode() + b"\0")
            h.update(content_digest(f).encode())
        return "dir:" + h.hexdigest()
    with open(p, "rb") as fh:
        return hashlib.file_digest(fh, "sha256").hexdigest()


def job_key(
    rule: str,
    stages: Iterable[str],
    params: Any,
    wildcards: Mapping[str, str],
    inputs: Iterable[str | os.PathLike[str]],
) -> tuple[str, dict[str, Any]]:
    """The job's cache key and the record it hashes. Input *paths* are not part of it, only their
    content in order, so another workflow directory with the same inputs finds the same key."""
    material = {
        "rule": rule,
        "code_version": files_version(module_closure(stages)),
        "params": params,
        "wildcards": dict(wildcards),
        "inputs": [content_digest(p) for p in inputs],
        "packages": installed_versions(KEY_PACKAGES, missing="-"),
    }
    return stable_hash(material, length=32), material


class EntryDefect(Exception):
    """Why a stored entry cannot be trusted (a file missing, truncated or changed)."""


class ResultCache:
    """A directory of entries ``<root>/<rule>/<key>/``, each holding a job's output files by
    name plus ``entry.json``, which records every file's size and SHA-256. Entries appear
    atomically (built aside, then renamed); a restore verifies them first, and an entry that does
    not verify is removed, so the job recomputes and stores a complete one."""

    def __init__(self, root: str | os.PathLike[str]):
        self.root = Path(root).absolute()  # messages name entries by a path that works anywhere
        self.damage: str | None = None  # the last restore's warning, if it refused an entry

    def entry(self, rule: str, key: str) -> Path:
        return self.root / rule / key

    def verify(self, entry: Path, names: Iterable[str] | Mapping[str, Any]) -> None:
        """Raise :class:`EntryDefect` unless ``entry`` holds each of ``names`` with the size and
        SHA-256 its record gives (and no record means no trust: an entry from before records).
        ``names`` may map each to the output it restores, which the message then names."""
        try:
            record = json.loads((entry / ENTRY_FILE).read_text())
            files = record["files"]
        except (OSError, ValueError, KeyError, TypeError) as error:
            raise EntryDefect(
                f"its {ENTRY_FILE} is unreadable or lists no files ({error})"
            ) from None
        for name in names:
            path, want = entry / name, files.get(name) if isinstance(files, dict) else None
            # the entry's file by name, and the output it stands for when the caller gave them
            what = f"{name} (for {names[name]})" if isinstance(names, Mapping) else name
            if want is None:
                raise EntryDefect(f"its record lists no file {what}")
            if not path.is_file():
                raise EntryDefect(f"file {what} is missing")
            size = path.stat().st_size
            if size != want.get("size"):
                raise EntryDefect(f"file {what} has {size} bytes, recorded {want.get('size')}")
            if content_digest(path) != want.get("sha256"):
                raise EntryDefect(f"file {what} does not match its recorded SHA-256")

    def discard(self, entry: Path) -> None:
        """Remove ``entry``: renamed aside first, so no reader ever sees it half deleted."""
        trash = entry.with_name(f".{entry.name}.{os.getpid()}.discard")
        try:
            os.rename(entry, trash)
        except FileNotFoundError:  # another job discarded it first
            return
        shutil.rmtree(trash, ignore_errors=True)

    def restore(self, rule: str, key: str, outputs: Mapping[str, str | os.PathLike[str]]) -> bool:
        """Put a stored entry's files at ``outputs``; False (nothing written) if there is none or
        it does not verify (then it is removed, with a warning naming it and what was wrong)."""
        entry = self.entry(rule, key)
        if not entry.is_dir():
            return False
        try:
            self.verify(entry, outputs)
        except EntryDefect as defect:
            self.damage = f"cache entry {entry} is damaged: {defect}; removing it and recomputing"
            log.warning(self.damage)
            self.discard(entry)
            return False
        now = time.time()
        for name, target in outputs.items():
            _place(entry / name, Path(target))
            # The job has just produced this file: mtime now, or Snakemake would see it as older
            # than its inputs and schedule it again.
            os.utime(target, (now, now))
            mark_restored(target, entry)
        return True

    def store(
        self,
        rule: str,
        key: str,
        outputs: Mapping[str, str | os.PathLike[str]],
        material: Mapping[str, Any],
    ) -> Path:
        """Add the job's outputs as the entry of ``key``. A concurrent identical entry that
        verifies wins; one that does not (a file lost or changed since) is replaced."""
        entry = self.entry(rule, key)
        if self._sound(entry, outputs):
            return entry
        entry.parent.mkdir(parents=True, exist_ok=True)
        tmp = Path(tempfile.mkdtemp(prefix=f".{key}.", dir=entry.parent))
        try:
            files = {}
            for name, source in outputs.items():
                _place(Path(source), tmp / name)
                files[name] = {"size": (tmp / name).stat().st_size,
                               "sha256": content_digest(tmp / name)}  # fmt: skip
            record = {"key": key, "created": time.strftime("%Y-%m-%dT%H:%M:%S%z"),
                      "files": files, **material}  # fmt: skip
            (tmp / ENTRY_FILE).write_text(json.dumps(record, indent=1, sort_keys=True, default=str))
            if entry.is_dir():  # there, but damaged: replace it
                log.warning("cache entry %s is damaged; replacing it", entry)
                self.discard(entry)
            try:
                os.rename(tmp, entry)
            except OSError:  # another job stored the same key first: keep theirs if it is sound
                if not self._sound(entry, outputs):
                    raise
        finally:
            if tmp.exists():
                shutil.rmtree(tmp)
        return entry

    def _sound(self, entry: Path, names: Iterable[str]) -> bool:
        try:
            self.verify(entry, names)
        except EntryDefect:
            return False
        return True


def _place(source: Path, target: Path) -> None:
    """Copy ``source`` to ``target`` atomically. A copy, not a hard link: a writer that opens an
    output in place (outside Snakemake, which deletes outputs first) would otherwise rewrite the
    cache entry through the shared inode. The price is disk: the cached outputs are stored twice."""
    target.parent.mkdir(parents=True, exist_ok=True)
    tmp = target.with_name(f".{target.name}.{os.getpid()}.cache.tmp")
    try:
        shutil.copyfile(source, tmp)
        os.replace(tmp, target)
    finally:
        with contextlib.suppress(FileNotFoundError):
            tmp.unlink()


def cache_settings(config: Mapping[str, Any]) -> tuple[bool, Path]:
    """Whether the cache is on, and its root, from the resolved config's ``cache`` group."""
    group = config.get("cache") or {}
    return bool(group.get("enabled", False)), Path(group.get("dir") or ".graspstab-cache")


def run_cached(smk: Any, stages: Iterable[str], compute: Callable[[], None]) -> bool:
    """Run a Snakemake job's ``compute`` unless its outputs are in the cache; store them after.

    ``smk`` is the ``snakemake`` object of a script job; ``stages`` are the graspstab
    sub-packages whose code the job runs. Returns True when the outputs were restored."""
    enabled, root = cache_settings(smk.config)
    if not enabled:
        compute()
        return False
    # Outputs by position (the rule fixes their order); params by name plus every value in order,
    # so unnamed ones count too. Only list behaviour and items() of Snakemake's containers are used.
    outputs = {str(i): path for i, path in enumerate(smk.output)}
    params = {"named": dict(smk.params.items()), "values": list(smk.params)}
    key, material = job_key(smk.rule, stages, params, dict(smk.wildcards.items()), list(smk.input))
    cache = ResultCache(root)
    if cache.restore(smk.rule, key, outputs):
        message = f"restored from cache entry {cache.entry(smk.rule, key)} (key {key})"
        for log_path in list(smk.log)[:1]:
            Path(log_path).parent.mkdir(parents=True, exist_ok=True)
            with open(log_path, "w") as fh:  # this job's log: it restored, it did not compute
                fh.write(f"graspstab cache: {message}\n")
        log.info(message)
        return True
    compute()
    entry = cache.store(smk.rule, key, outputs, material)
    if cache.damage:  # after the compute, whose logging set-up starts the job's log afresh
        for log_path in list(smk.log)[:1]:
            Path(log_path).parent.mkdir(parents=True, exist_ok=True)
            with open(log_path, "a") as fh:
                fh.write(f"graspstab cache: {cache.damage}; stored a whole entry at {entry}\n")
    return False
