"""Rule ``plot_learning``'s entry point: read the study artefacts it is given, draw every chapter-4
figure (or a placeholder naming what is missing) and write each PNG atomically."""

from __future__ import annotations

import logging
from collections.abc import Callable, Mapping
from pathlib import Path
from typing import Any

import polars as pl

from graspstab.figures.artefacts import StudyArtefacts, record, splits_family, table
from graspstab.figures.baseline import plot_benchmark, plot_confusion, plot_objects
from graspstab.figures.common import placeholder
from graspstab.figures.presentation import (
    FIGURES,
    LEARNING_FIGURES,
    defined_summary,
    ordered_families,
)
from graspstab.figures.proxy import plot_proxy
from graspstab.figures.splits import plot_splits
from graspstab.figures.sweep import plot_latency, plot_operating_points, plot_sweep
from graspstab.figures.thresholds import plot_reliability, plot_threshold_transfer
from graspstab.figures.tuning import plot_tuning

log = logging.getLogger("graspstab.learning")


def load_predictions(artefacts: StudyArtefacts) -> dict[str, tuple[pl.DataFrame, dict]]:
    """family -> (predictions, threshold record) of the given first-seed baseline runs (those
    whose predictions and metrics.json are both present)."""
    out = {}
    for fam in ordered_families(artefacts.predictions):
        predictions, metrics = artefacts.predictions[fam], artefacts.metrics.get(fam)
        if Path(predictions).exists() and metrics is not None and Path(metrics).exists():
            out[fam] = (table(predictions), record(metrics).get("threshold", {}))
    return out


def load_tuning(artefacts: StudyArtefacts) -> dict[str, tuple[pl.DataFrame, dict | None]]:
    """family -> (trials table, best.json or None) of every family with a given trials table."""
    out = {}
    for fam in ordered_families(artefacts.trials):
        trials = table(artefacts.trials[fam])
        if trials is not None:
            out[fam] = (trials, record(artefacts.best.get(fam), warn=True))
    return out


def _study_inputs(a: StudyArtefacts) -> dict[str, Any]:
    return {
        "summary": table(a.baseline_summary, warn=True),
        "runs": table(a.baseline_runs, warn=True),
        "objects": table(a.baseline_objects, warn=True),
        "splits": record(a.splits_overview, warn=True),
        "splits_family": splits_family(table(a.splits_runs, warn=True)),
        "sweep": table(a.sweep_summary, warn=True),
        "sweep_runs": table(a.sweep_runs, warn=True),
        "points": table(a.sweep_points, warn=True),
        "sweep_json": record(a.sweep_overview, warn=True),
        "latency": table(a.latency, warn=True),
        "proxy": record(a.proxy, warn=True),
        "predictions": load_predictions(a) or None,
        "tuning": load_tuning(a) or None,
    }


def _outputs(out: Path | Mapping[str, Path]) -> dict[str, Path]:
    """Figure name -> output path, from a folder or an explicit mapping of every name."""
    if isinstance(out, Mapping):
        if set(out) != set(LEARNING_FIGURES):
            raise ValueError(
                f"plot_learning writes exactly {list(LEARNING_FIGURES)}; got outputs {sorted(out)}"
            )
        return {name: Path(out[name]) for name in LEARNING_FIGURES}
    return {name: Path(out) / file for name, file in FIGURES.items()}


def plot_learning(
    artefacts: StudyArtefacts,
    out: Path | Mapping[str, Path],
    dpi: int,
    first_seed: int,
) -> dict[str, Path]:
    """Write every chapter-4 figure from the given ``artefacts`` (and no other file): into the
    folder ``out`` (file names :data:`FIGURES`) or to ``out``'s path per figure name (exactly
    the names of :data:`LEARNING_FIGURES`). A figure whose inputs are missing becomes a
    placeholder that says which. Returns name -> path."""
    d = _study_inputs(artefacts)
    if d["runs"] is not None:
        d["summary_defined"] = defined_summary(d["runs"], ["family", "split"])
    else:
        d["summary_defined"] = d["summary"]
    if d["sweep_runs"] is not None:
        d["sweep"] = defined_summary(d["sweep_runs"], ["family", "window_s", "split"])
    out = _outputs(out)
    jobs: dict[str, tuple[tuple[str, ...], Callable[[], Path]]] = {
        "benchmark": (
            ("summary_defined",),
            lambda: plot_benchmark(d["summary_defined"], out["benchmark"], dpi),
        ),
        "confusion": (
            ("runs",),
            lambda: plot_confusion(d["runs"], first_seed, out["confusion"], dpi),
        ),
        "objects": (("objects",), lambda: plot_objects(d["objects"], out["objects"], dpi)),
        "splits": (
            ("splits",),
            lambda: plot_splits(d["splits"], d["splits_family"], out["splits"], dpi),
        ),
        "sweep": (("sweep",), lambda: plot_sweep(d["sweep"], out["sweep"], dpi)),
        "latency": (("latency",), lambda: plot_latency(d["latency"], out["latency"], dpi)),
        "operating_points": (
            ("points", "sweep_json"),
            lambda: plot_operating_points(
                d["points"], d["sweep_json"], out["operating_points"], dpi
            ),
        ),
        "threshold_transfer": (
            ("predictions",),
            lambda: plot_threshold_transfer(d["predictions"], out["threshold_transfer"], dpi),
        ),
        "reliability": (
            ("predictions",),
            lambda: plot_reliability(d["predictions"], out["reliability"], dpi),
        ),
        "proxy": (
            ("proxy", "summary"),
            lambda: plot_proxy(d["proxy"], d["summary"], out["proxy"], dpi),
        ),
        "tuning": (("tuning",), lambda: plot_tuning(d["tuning"], out["tuning"], dpi)),
    }
    for name, (needs, draw) in jobs.items():
        missing = [k for k in needs if d[k] is None]
        if missing:
            placeholder(
                out[name],
                f"{name}: not drawn",
                f"missing study artefact(s): {', '.join(missing)}",
                dpi,
            )
        else:
            draw()
        log.info("wrote %s", out[name])
    return out
