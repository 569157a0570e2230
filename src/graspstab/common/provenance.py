"""Provenance: which code, config slice and platform made an artefact (docs/design.md)."""

from __future__ import annotations

import ast
import functools
import hashlib
import importlib.metadata
import json
import os
import platform
from collections.abc import Iterable
from pathlib import Path
from typing import Any

import graspstab
from graspstab.common.io import write_json

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


def _module_file(dotted: str) -> Path | None:
    """The source file of ``graspstab.<...>`` (a package's ``__init__.py``), or None."""
    parts = dotted.split(".")
    if parts[0] != "graspstab":
        return None
    base = _PKG_ROOT.joinpath(*parts[1:])
    for candidate in (base / "__init__.py", base.with_suffix(".py")):
        if candidate.is_file():
            return candidate
    return None


def _imported_modules(path: Path) -> set[str]:
    """Every graspstab module ``path`` imports anywhere (module level or inside functions), as
    dotted names; ``from a import b`` names both ``a`` and ``a.b`` (b may be a module)."""
    package = ".".join(("graspstab", *path.relative_to(_PKG_ROOT).parent.parts))
    out: set[str] = set()
    for node in ast.walk(ast.parse(path.read_text(), filename=str(path))):
        if isinstance(node, ast.Import):
            out.update(a.name for a in node.names)
        elif isinstance(node, ast.ImportFrom):
            if node.level:
                up = package.split(".")[: len(package.split(".")) - (node.level - 1)]
                base = ".".join([*up, *([node.module] if node.module else [])])
            else:
                base = node.module or ""
            out.add(base)
            out.update(f"{base}.{a.name}" for a in node.names)
    return {m for m in out if m == "graspstab" or m.startswith("graspstab.")}


def module_closure(stages: Iterable[str]) -> list[str]:
    """The source files (relative to the package) that a stage's code can run: every module of
    the named sub-packages plus every graspstab module they import, transitively, with the
    ``__init__.py`` of each package on the way. A cache key hashes these files, so a change in
    code a stage uses reaches its key and a change in code it never imports (another stage's
    figure) does not."""
    todo: list[Path] = []
    for name in stages:
        root = _PKG_ROOT / name
        if root.is_dir():
            todo.extend(sorted(root.rglob("*.py")))
        elif root.with_suffix(".py").is_file():
            todo.append(root.with_suffix(".py"))
        else:
            raise ValueError(f"no graspstab sub-package or module named {name!r}")
    seen: set[Path] = set()
    while todo:
        f = todo.pop()
        if f in seen:
            continue
        seen.add(f)
        for parent in f.relative_to(_PKG_ROOT).parents:
            init = _PKG_ROOT / parent / "__init__.py"
            if init.is_file() and init not in seen:
                todo.append(init)
        for dotted in _imported_modules(f):
            target = _module_file(dotted)
            if target is not None and target not in seen:
                todo.append(target)
    return sorted(f.relative_to(_PKG_ROOT).as_posix() for f in seen)


def files_version(files: Iterable[str]) -> str:
    """Hash of the named package files' paths and source (cf. :func:`code_version`)."""
    h = hashlib.sha256()
    for rel in sorted(files):
        h.update(rel.encode())
        h.update((_PKG_ROOT / rel).read_bytes())
    return f"{graspstab.__version__}+{h.hexdigest()[:12]}"


def cpu_model() -> str:
    """The CPU's model name from /proc/cpuinfo (the platform's processor string elsewhere)."""
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                return line.split(":", 1)[1].strip()
    except OSError:
        pass
    return platform.processor() or "unknown"


@functools.cache
def compute_platform() -> dict[str, Any]:
    """The hardware and numerical-library build a result was computed on. Floating-point
    results repeat exactly only on the same CPU family with the same BLAS/MKL build and thread
    count (kernels pick instruction sets and reduction orders at run time), so every artefact
    records them beside the package versions. Only facts that are the same on every run on the
    same machine and settings (no time, no host name), the libraries sorted (threadpoolctl lists
    them in the order the process happened to load them), so that a rerun writes the same bytes."""
    import sys

    from threadpoolctl import threadpool_info

    blas = [
        {k: lib.get(k) for k in ("internal_api", "version", "architecture", "num_threads")}
        for lib in threadpool_info()
    ]
    out: dict[str, Any] = {
        "machine": platform.machine(),
        "cpu": cpu_model(),
        "cpu_count": os.cpu_count(),
        "blas": sorted(blas, key=lambda lib: json.dumps(lib, sort_keys=True, default=str)),
    }
    if "torch" in sys.modules:  # only where the stage uses it; importing torch takes seconds
        torch = sys.modules["torch"]
        out["torch"] = {
            "version": torch.__version__,
            "threads": torch.get_num_threads(),
            "mkl": bool(torch.backends.mkl.is_available()),
            "mkldnn": bool(torch.backends.mkldnn.is_available()),
        }
    return out


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
        "platform": compute_platform(),
    }


def write_timing(path: str | Path | None, record: dict[str, Any]) -> None:
    """Write a job's run-time measurements (wall times, rates) to its timing sidecar ``path``
    (strict JSON; nothing when ``path`` is None). They differ on every run, so they live beside
    the data files, never in them, and a rerun rewrites the data byte for byte (docs/design.md,
    data contracts)."""
    if path is None:
        return
    write_json(path, record)
