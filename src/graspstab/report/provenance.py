"""Run provenance for the report: config hash, package versions, git commit, stage wall times."""

from __future__ import annotations

import csv
import importlib.metadata
import subprocess
from pathlib import Path
from typing import Any

PACKAGES = (
    "graspstab",
    "snakemake",
    "mujoco",
    "trimesh",
    "coacd",
    "numpy",
    "scipy",
    "torch",
    "hydra-core",
    "matplotlib",
)


def package_versions() -> dict[str, str]:
    """Installed versions of the packages the pipeline depends on."""
    out = {}
    for name in PACKAGES:
        try:
            out[name] = importlib.metadata.version(name)
        except importlib.metadata.PackageNotFoundError:
            out[name] = "not installed"
    return out


def git_commit(repo_dir: Path) -> str:
    """The commit of the workflow checkout (or 'unknown' outside git), marked dirty if modified."""
    try:
        sha = subprocess.run(
            ["git", "rev-parse", "HEAD"],
            cwd=repo_dir,
            capture_output=True,
            text=True,
            check=True,
            timeout=10,
        ).stdout.strip()
        dirty = subprocess.run(
            ["git", "status", "--porcelain", "--untracked-files=no"],
            cwd=repo_dir,
            capture_output=True,
            text=True,
            timeout=10,
        ).stdout
        return sha + ("-dirty" if dirty.strip() else "")
    except (OSError, subprocess.SubprocessError):
        return "unknown"


def read_benchmark(path: Path) -> dict[str, Any]:
    """One Snakemake benchmark TSV (first row): wall seconds and peak memory."""
    with open(path) as fh:
        row = next(csv.DictReader(fh, delimiter="\t"))
    return {"s": float(row["s"]), "max_rss_mb": _float(row.get("max_rss"))}


def _float(value: Any) -> float | None:
    try:
        return float(value)
    except (TypeError, ValueError):
        return None
