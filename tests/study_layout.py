"""The workflow's layout of the study artefacts below a results folder, as the StudyArtefacts the
rules hand their scripts (workflow/rules/train.smk, STUDY_ARTEFACTS and FIRST_SEED_ARTEFACTS), so
tests can build a synthetic tree anywhere and give the library its paths."""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

from graspstab.figures.artefacts import StudyArtefacts

FAMILIES = ("cnn", "gru", "lstm")


def study_artefacts(
    results: Path, families: Sequence[str] = FAMILIES, first_seed: int = 42
) -> StudyArtefacts:
    """Every artefact path of the workflow's layout below ``results`` (present or not)."""
    s, r = Path(results) / "studies", Path(results)
    run = {f: r / "train" / "baseline" / f / f"seed{first_seed}" for f in families}
    return StudyArtefacts(
        baseline_runs=s / "baseline" / "runs.parquet",
        baseline_summary=s / "baseline" / "summary.parquet",
        baseline_objects=s / "baseline" / "objects.parquet",
        baseline_errors=s / "baseline" / "errors.parquet",
        baseline_overview=s / "baseline" / "summary.json",
        baseline_summary_defined=s / "baseline" / "summary_defined.parquet",
        baseline_threshold_rules=s / "baseline" / "threshold_rules.json",
        sweep_runs=s / "sweep" / "runs.parquet",
        sweep_summary=s / "sweep" / "summary.parquet",
        sweep_points=s / "sweep" / "operating_points.parquet",
        sweep_overview=s / "sweep" / "summary.json",
        sweep_summary_defined=s / "sweep" / "summary_defined.parquet",
        sweep_threshold_rules=s / "sweep" / "threshold_rules.json",
        splits_runs=s / "splits" / "runs.parquet",
        splits_overview=s / "splits" / "summary.json",
        splits_threshold_rules=s / "splits" / "threshold_rules.json",
        latency=s / "latency.parquet",
        proxy=s / "proxy.json",
        predictions={f: run[f] / "predictions.parquet" for f in families},
        metrics={f: run[f] / "metrics.json" for f in families},
        trials={f: r / "tune" / f / "trials.parquet" for f in families},
        best={f: r / "tune" / f / "best.json" for f in families},
    )
