"""The study artefacts a reader of the learning results is given, as explicit paths.

Rule ``plot_learning`` and rule ``report`` declare these files as named inputs; their scripts hand
them over as a :class:`StudyArtefacts` (:meth:`StudyArtefacts.from_inputs`), and the figures and
the report read those paths and nothing else (never a walk of ``results/``). No plotting here.
"""

from __future__ import annotations

import dataclasses
import logging
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import polars as pl

from graspstab.common.io import read_json, read_parquet

log = logging.getLogger("graspstab.learning")

#: Per-family artefacts: named input ``<kind>_<family>`` -> field ``<kind>`` (family -> path).
PER_FAMILY = ("predictions", "metrics", "trials", "best")


@dataclass(frozen=True)
class StudyArtefacts:
    """Paths of the studies' tables and records (None: not given). Field names are the named
    inputs of the rules; per-family ones are named ``<kind>_<family>`` (e.g. ``best_gru``)."""

    baseline_runs: Path | None = None  # studies/baseline/runs.parquet
    baseline_summary: Path | None = None  # studies/baseline/summary.parquet
    baseline_objects: Path | None = None  # studies/baseline/objects.parquet
    baseline_errors: Path | None = None  # studies/baseline/errors.parquet
    baseline_overview: Path | None = None  # studies/baseline/summary.json
    sweep_runs: Path | None = None  # studies/sweep/runs.parquet
    sweep_summary: Path | None = None  # studies/sweep/summary.parquet
    sweep_points: Path | None = None  # studies/sweep/operating_points.parquet
    sweep_overview: Path | None = None  # studies/sweep/summary.json
    # mean ± std over seeds with 0/0 metrics undefined (evaluation.aggregate.seed_summary): what
    # the report shows of the baseline and sweep studies
    baseline_summary_defined: Path | None = None  # studies/baseline/summary_defined.parquet
    sweep_summary_defined: Path | None = None  # studies/sweep/summary_defined.parquet
    # each study's threshold rules per run, counted (evaluation.aggregate.threshold_rules)
    baseline_threshold_rules: Path | None = None  # studies/baseline/threshold_rules.json
    sweep_threshold_rules: Path | None = None  # studies/sweep/threshold_rules.json
    splits_threshold_rules: Path | None = None  # studies/splits/threshold_rules.json
    splits_runs: Path | None = None  # studies/splits/runs.parquet
    splits_overview: Path | None = None  # studies/splits/summary.json
    latency: Path | None = None  # studies/latency.parquet
    proxy: Path | None = None  # studies/proxy.json
    # family -> path
    predictions: Mapping[str, Path] = field(default_factory=dict)  # first-seed baseline run's
    metrics: Mapping[str, Path] = field(default_factory=dict)  # that run's metrics.json
    trials: Mapping[str, Path] = field(default_factory=dict)  # tune/<family>/trials.parquet
    best: Mapping[str, Path] = field(default_factory=dict)  # tune/<family>/best.json

    @classmethod
    def from_inputs(cls, named: Mapping[str, Any], prefix: str = "") -> StudyArtefacts:
        """The artefacts among a rule's named inputs (Snakemake's ``input.items()``): every name
        starting with ``prefix``, which is stripped; any other name is left alone. A name that
        is neither a field nor ``<kind>_<family>`` of :data:`PER_FAMILY` is an error."""
        scalars = {f.name for f in dataclasses.fields(cls)} - set(PER_FAMILY)
        values: dict[str, Any] = {kind: {} for kind in PER_FAMILY}
        for key, value in named.items():
            if not key.startswith(prefix):
                continue
            name = key[len(prefix) :]
            path = _one_path(key, value)
            kind, _, family = name.partition("_")
            if name in scalars:
                values[name] = path
            elif kind in PER_FAMILY and family:
                values[kind][family] = path
            else:
                raise ValueError(f"named input {key!r} is no study artefact of StudyArtefacts")
        return cls(**values)


def _one_path(key: str, value: Any) -> Path:
    if isinstance(value, str | Path):
        return Path(value)
    files = list(value)
    if len(files) != 1:
        raise ValueError(f"named input {key!r} must be one file, got {len(files)}")
    return Path(files[0])


def exists(path: Path | None) -> bool:
    """True when ``path`` was given and is on disk."""
    return path is not None and Path(path).exists()


def table(path: Path | None, warn: bool = False) -> pl.DataFrame | None:
    """A Parquet artefact, or None when it was not given or is missing (``warn``: say so)."""
    if not exists(path):
        if warn:
            log.warning("learning results: %s is missing", path or "an artefact not given")
        return None
    return read_parquet(path)


def record(path: Path | None, warn: bool = False) -> Any:
    """A JSON artefact, or None when it was not given or is missing (``warn``: say so)."""
    if not exists(path):
        if warn:
            log.warning("learning results: %s is missing", path or "an artefact not given")
        return None
    return read_json(path)


def splits_family(runs: pl.DataFrame | None) -> str | None:
    """The family of the split-robustness study (the runs table's first row), if any."""
    return runs["family"][0] if runs is not None and runs.height else None
