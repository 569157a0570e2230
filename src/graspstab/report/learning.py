"""The learning section of the report (thesis chapter 4): our study results beside the
reference's published numbers, the threshold-rule warning, and the chapter's figures.

Every table reads one study artefact of the :class:`~graspstab.figures.artefacts.StudyArtefacts`
it is given (no other file; the means and stds over seeds are the aggregation jobs'
``summary_defined.parquet``); a missing artefact gives a note instead of the table. NaN (an
undefined metric, e.g. validation AUPRC when the validation split holds no unstable window)
renders as "undefined". The tables live in :mod:`graspstab.report.learning_tables` and
:mod:`graspstab.report.study_tables`; nothing here imports a plotting module.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from pathlib import Path
from typing import Any

from graspstab.common.io import read_json, read_parquet
from graspstab.figures.artefacts import StudyArtefacts, exists, record, splits_family, table
from graspstab.figures.presentation import LEARNING_FIGURES
from graspstab.report import html as H
from graspstab.report.learning_tables import (
    baseline_still_table,
    baseline_table,
    configurations_table,
    errors_table,
    missing,
    note,
    parameters_table,
    rule_counts,
    rule_warning,
    search_space_table,
    tuning_tables,
)
from graspstab.report.study_tables import (
    choice_text,
    latency_table,
    operating_points_table,
    proxy_still_table,
    proxy_table,
    splits_tables,
    sweep_still_table,
    sweep_table,
)

# Stable ids (and contents entries, where the figure is one of the reference's) of the learning
# figures, one per name of LEARNING_FIGURES (tested).
FIGURE_ANCHORS = {
    "benchmark": ("metrics", "Metrics, mean ± std (fig. 4.1)"),
    "confusion": ("confusion", "Confusion matrices (fig. 4.2)"),
    "objects": ("per-object", "Per-object test metrics (fig. 4.3)"),
    "tuning": ("tuning-history", ""),
    "splits": ("split-robustness-figure", ""),
    "sweep": ("sweep-figure", ""),
    "latency": ("latency-figure", ""),
    "operating_points": ("operating-points-figure", ""),
    "threshold_transfer": ("threshold-transfer", "Threshold transfer (fig. 4.8)"),
    "reliability": ("reliability", "Reliability (fig. 4.9)"),
    "proxy": ("proxy-figure", ""),
}


def _figure(figures: Mapping[str, Path], key: str, caption: str) -> list[str]:
    """The figure ``key`` with its stable id; a slot saying it is missing when it is."""
    anchor, toc = FIGURE_ANCHORS.get(key, (key.replace("_", "-"), ""))
    path = figures.get(key)
    if path is None or not Path(path).exists():
        return [H.missing_figure(anchor, toc, f"Figure '{H.esc(key)}' not produced in this run.")]
    return [H.image(Path(path), key.replace("_", " "), caption, anchor, toc)]


# ------------------------------------------------------------------------------ the section

CAPTIONS = {
    "benchmark": "Fig. 4.1: validation (A, C) and test (B, D) metrics per family at the baseline "
    "window; A/B at the validation-selected threshold, C/D ranking metrics. Mean ± 1 std over "
    "seeds; 'undefined' marks a metric with no defined value.",
    "confusion": "Fig. 4.2: test confusion matrices of the first seed, rows (true class) "
    "normalised, counts in brackets.",
    "objects": "Fig. 4.3: per-object test AUPRC (A) and recall at the validation-selected "
    "threshold (B); mean ± std over seeds (the thesis shows one checkpoint).",
    "tuning": "Optuna optimisation history per family: value of each trial, running best, "
    "pruned and failed trials along the bottom.",
    "sweep": "Fig. 4.5: test accuracy, precision, recall, F1, AUROC and AUPRC (A-F) against "
    "observation-window length; mean ± 1 std over seeds.",
    "operating_points": "Fig. 4.7: validation AUPRC against total decision latency (window + "
    "median forward pass); stars mark each family's best window, the circle the latency-aware "
    "pick.",
    "latency": "Fig. 4.6: CPU batch-1 median forward-pass latency ± std (A) and throughput (B) "
    "at the baseline window.",
    "splits": "Fig. 4.4: test AUPRC per sampled split assignment (mean ± std over seeds); the "
    "fixed split is highlighted, the dashed line marks the mean across assignments.",
    "threshold_transfer": "Fig. 4.8: recall (top) and precision (bottom) against the threshold "
    "on validation and test for the first seed; dotted line: the validation-selected threshold.",
    "reliability": "Fig. 4.9: reliability curves on validation and test for the first seed; the "
    "diagonal is perfect calibration.",
    "proxy": "Fig. 4.10: test AUPRC of the friction-ratio proxy and the models; dashed line: "
    "chance level (the test set's unstable fraction).",
}


def _block(
    title: str,
    path: Path | None,
    reader: Callable[[Path], Any],
    render: Callable[[Any], str | list[str]],
    anchor: str = "",
) -> list[str]:
    """A sub-heading (with a stable id) and the rendering of one artefact (or a note that it is
    missing)."""
    head = H.heading(3, anchor, title) if anchor else f"<h3>{H.esc(title)}</h3>"
    if not exists(path):
        return [head, missing(path)]
    out = render(reader(path))
    return [head, *([out] if isinstance(out, str) else out)]


def _intro(config: Mapping[str, Any]) -> str:
    profile = config.get("profile_name", "?")
    return note(
        f"Profile <b>{H.esc(profile)}</b>. Reference numbers are the thesis's (chapter 4, "
        "'thesis' columns). A quick-profile run trains a few epochs on a handful of grasps: it "
        "checks that every study runs end to end and is not a reproduction of those numbers."
    )


def _tuning_parts(a: StudyArtefacts, figures: Mapping[str, Path], config: Mapping) -> list[str]:
    bests = {f: read_json(p) for f, p in sorted(a.best.items()) if exists(p)}
    # none given or present: name the path pattern (the family's part as <model>)
    f, p = next(iter(sorted(a.best.items())), (None, None))
    absent = Path(*("<model>" if part == f else part for part in Path(p).parts)) if p else None
    return [
        H.heading(3, "tuning", "Tuning: search space and results (table 4.1)"),
        search_space_table(config.get("tune", {})),
        tuning_tables(bests) if bests else missing(absent),
        *_figure(figures, "tuning", CAPTIONS["tuning"]),
    ]


def _baseline_parts(a: StudyArtefacts, figures: Mapping[str, Path], config: Mapping) -> list[str]:
    return [
        H.heading(3, "baseline-configurations", "Baseline configurations (table 4.2)"),
        configurations_table(config),
        *_block("Parameters (table 4.2)", a.baseline_overview, read_json, parameters_table),
        *_block(
            "Fixed-task benchmark (section 4.3)",
            a.baseline_summary_defined,
            read_parquet,
            lambda s: [baseline_table(s), baseline_still_table(s)],
            anchor="baseline-benchmark",
        ),
        *_figure(figures, "benchmark", CAPTIONS["benchmark"]),
        *_figure(figures, "confusion", CAPTIONS["confusion"]),
        *_figure(figures, "objects", CAPTIONS["objects"]),
    ]


def _threshold_parts(a: StudyArtefacts) -> list[str]:
    head = H.heading(3, "threshold-rules", "Threshold rules")
    paths = {"baseline": a.baseline_threshold_rules, "sweep": a.sweep_threshold_rules,
             "splits": a.splits_threshold_rules}  # fmt: skip
    records = {s: read_json(p) for s, p in paths.items() if exists(p)}
    if not records:
        return [head, missing(a.baseline_threshold_rules)]
    table_html, problems = rule_counts(records)
    return [head, rule_warning(problems), table_html]


def _sweep_parts(a: StudyArtefacts, figures: Mapping[str, Path]) -> list[str]:
    overview = record(a.sweep_overview) or {}
    return [
        *_block(
            "Window-length sweep (section 4.5, fig. 4.5)",
            a.sweep_summary_defined,
            read_parquet,
            lambda s: [sweep_table(s), sweep_still_table(s)],
            anchor="sweep",
        ),
        *_figure(figures, "sweep", CAPTIONS["sweep"]),
        *_block(
            "Inference latency (fig. 4.6)",
            a.latency,
            read_parquet,
            latency_table,
            anchor="latency",
        ),
        *_figure(figures, "latency", CAPTIONS["latency"]),
        *_block(
            "AUPRC against decision latency (fig. 4.7)",
            a.sweep_points,
            read_parquet,
            lambda p: [choice_text(overview), operating_points_table(p, overview)],
            anchor="operating-points",
        ),
        *_figure(figures, "operating_points", CAPTIONS["operating_points"]),
    ]


def _splits_parts(a: StudyArtefacts, figures: Mapping[str, Path]) -> list[str]:
    family = splits_family(table(a.splits_runs))
    return [
        *_block(
            "Split robustness (section 4.4)",
            a.splits_overview,
            read_json,
            lambda s: splits_tables(s, family),
            anchor="split-robustness",
        ),
        *_figure(figures, "splits", CAPTIONS["splits"]),
    ]


def _diagnostic_parts(a: StudyArtefacts, figures: Mapping[str, Path]) -> list[str]:
    summary = table(a.baseline_summary)
    return [
        *_block(
            "Errors (section 4.6, table 4.3)",
            a.baseline_errors,
            read_parquet,
            errors_table,
            anchor="errors",
        ),
        H.heading(3, "calibration", "Threshold transfer and calibration (section 4.6)"),
        *_figure(figures, "threshold_transfer", CAPTIONS["threshold_transfer"]),
        *_figure(figures, "reliability", CAPTIONS["reliability"]),
        *_block(
            "Friction-ratio proxy (section 4.7, fig. 4.10)",
            a.proxy,
            read_json,
            lambda p: [proxy_table(p, summary), proxy_still_table(p, summary)],
            anchor="proxy",
        ),
        *_figure(figures, "proxy", CAPTIONS["proxy"]),
    ]


def learning_section(
    artefacts: StudyArtefacts, figures: Mapping[str, Path], config: Mapping[str, Any]
) -> str:
    """The report's chapter-4 section: tables of every study beside the thesis's numbers, the
    threshold-rule warning, and the figures of rule ``plot_learning`` (``figures``: name -> PNG,
    names of :data:`~graspstab.figures.presentation.LEARNING_FIGURES`; an absent one leaves a
    slot saying so). Reads only the paths of ``artefacts`` and ``figures``."""
    unknown = sorted(set(figures) - set(LEARNING_FIGURES))
    if unknown:
        raise ValueError(f"no learning figure is named {unknown}; names: {list(LEARNING_FIGURES)}")
    a = artefacts
    # The reference's order: tuning (table 4.1), baselines (table 4.2), 4.3, 4.4, 4.5, 4.6, 4.7.
    parts = [
        H.heading(2, "learning", "Learning and evaluation (chapter 4)"),
        _intro(config),
        *_threshold_parts(a),
        *_tuning_parts(a, figures, config),
        *_baseline_parts(a, figures, config),
        *_splits_parts(a, figures),
        *_sweep_parts(a, figures),
        *_diagnostic_parts(a, figures),
    ]
    return "\n".join(p for p in parts if p)
