"""Run provenance for the report: config hash, package versions, git commit, and per-stage wall
times and peak memory from the Snakemake benchmark files of every rule."""

from __future__ import annotations

import csv
import subprocess
from collections.abc import Iterable, Mapping, Sequence
from pathlib import Path
from typing import Any

from graspstab.common.provenance import installed_versions

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
    return installed_versions(PACKAGES)


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
    """One Snakemake benchmark TSV (first row): wall seconds and peak memory [MB] (None when
    Snakemake could not measure it, e.g. "NA" for a job shorter than its sampling interval)."""
    with open(path) as fh:
        row = next(csv.DictReader(fh, delimiter="\t"))
    return {"s": float(row["s"]), "max_rss_mb": _float(row.get("max_rss"))}


def stage_times(
    benchmarks: Mapping[str, Sequence[Path]],
    job_counts: Mapping[str, int] | None = None,
    order: Iterable[str] | None = None,
) -> list[dict[str, Any]]:
    """Per rule: benchmarked jobs, total job-seconds, share of all job-seconds, the longest job
    and the peak RSS over its jobs. Rules in ``job_counts`` (the DAG's jobs per rule) without a
    benchmark get a row saying so; ``order`` (e.g. topological) sorts the rows."""
    rows = {}
    for rule, paths in benchmarks.items():
        found = [(Path(p), read_benchmark(p)) for p in paths if Path(p).exists()]
        longest = max(found, key=lambda f: f[1]["s"], default=None)
        rss = [b["max_rss_mb"] for _, b in found if b["max_rss_mb"] is not None]
        rows[rule] = {
            "rule": rule,
            "jobs": len(found),
            "missing": len(paths) - len(found),
            "dag_jobs": (job_counts or {}).get(rule),
            "job_s": sum(b["s"] for _, b in found) if found else None,
            "max_s": longest[1]["s"] if longest else None,
            "max_job": longest[0].stem if longest else None,
            "peak_rss_mb": max(rss) if rss else None,
        }
    for rule, n in (job_counts or {}).items():
        rows.setdefault(rule, {"rule": rule, "jobs": 0, "missing": 0, "dag_jobs": n,
                               "job_s": None, "max_s": None, "max_job": None,
                               "peak_rss_mb": None})  # fmt: skip
    total = sum(r["job_s"] or 0.0 for r in rows.values())
    for r in rows.values():
        r["share"] = r["job_s"] / total if r["job_s"] is not None and total > 0 else None
    rank = {rule: i for i, rule in enumerate(order or [])}
    return sorted(rows.values(), key=lambda r: (rank.get(r["rule"], len(rank)), r["rule"]))


def _float(value: Any) -> float | None:
    try:
        return float(value)
    except (TypeError, ValueError):
        return None
