"""Provenance: which code and which config slice made an artefact (DESIGN.md, data contracts)."""

from __future__ import annotations

import hashlib
import importlib.metadata
import json
import platform
from collections.abc import Iterable
from pathlib import Path
from typing import Any

import graspstab

_PKG_ROOT = Path(graspstab.__file__).resolve().parent


def stable_hash(obj: Any, length: int = 16) -> str:
    """Hash a JSON-serialisable object independently of key order."""
    blob = json.dumps(obj, sort_keys=True, separators=(",", ":"), default=str).encode()
    return hashlib.sha256(blob).hexdigest()[:length]


def file_sha256(path: str | Path, chunk: int = 1 << 20) -> str:
    """Full SHA-256 of a file's bytes."""
    h = hashlib.sha256()
    with open(path, "rb") as fh:
        while block := fh.read(chunk):
            h.update(block)
    return h.hexdigest()


def installed_versions(names: Iterable[str], missing: str = "not installed") -> dict[str, str]:
    """Installed version of each named distribution (``missing`` where it is absent)."""
    out = {}
    for name in names:
        try:
            out[name] = importlib.metadata.version(name)
        except importlib.metadata.PackageNotFoundError:
            out[name] = missing
    return out


def code_version(*subpackages: str) -> str:
    """Hash of the named sub-packages' source (plus ``common``): changes when their code does."""
    h = hashlib.sha256()
    for name in sorted({"common", *subpackages}):
        root = _PKG_ROOT / name
        if root.is_dir():
            files = sorted(root.rglob("*.py"))
        elif root.with_suffix(".py").is_file():
            files = [root.with_suffix(".py")]
        else:
            raise ValueError(f"no graspstab sub-package or module named {name!r}")
        for f in files:
            h.update(str(f.relative_to(_PKG_ROOT)).encode())
            h.update(f.read_bytes())
    return f"{graspstab.__version__}+{h.hexdigest()[:12]}"


def provenance(stage: str, params: Any) -> dict[str, Any]:
    """The record every artefact carries: stage, its code version, its config slice and its hash."""
    import mujoco
    import numpy
    import trimesh

    return {
        "stage": stage,
        "code_version": code_version(stage),
        "params": params,
        "params_hash": stable_hash(params),
        "python": platform.python_version(),
        "packages": {
            "numpy": numpy.__version__,
            "mujoco": mujoco.__version__,
            "trimesh": trimesh.__version__,
        },
    }
