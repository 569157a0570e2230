"""The report's tables of the fixed-task side of chapter 4 (tuning, configurations, parameters,
the 4.3 benchmark, the 4.6 errors and the threshold rules) beside the reference's published
numbers, and the formatting every learning table shares ("undefined" for NaN, never 0)."""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import polars as pl

from graspstab.figures.presentation import (
    METRIC_NAMES,
    METRICS,
    SPLIT_NAMES,
    SPLITS,
    UNDEFINED,
    family_label,
    finite,
    ordered_families,
    rows_by,
)
from graspstab.report import html as H
from graspstab.report import still_now as S

# The reference's numbers (thesis chapter 4), in percent unless stated.
REFERENCE_PARAMETERS = {"cnn": 178_753, "gru": 171_777, "lstm": 25_217}  # table 4.2
REFERENCE_BASELINE = {  # section 4.3: (mean, std) where the text gives one
    ("val", "auprc"): {"gru": (99.25, 0.01), "lstm": (99.24, 0.01), "cnn": (99.06, 0.06)},
    ("val", "f1"): {"gru": (94.49, 0.45), "cnn": (94.16, 0.55), "lstm": (93.80, 0.03)},
    ("test", "auprc"): {"gru": (98.43, 0.05)},
    ("test", "auroc"): {"gru": (97.78, 0.07)},
}
REFERENCE_ERRORS = {  # table 4.3: FP, FN, false-positive rate, miss rate
    "cnn": ("149 ± 31", "1723 ± 165", "2.44 %", "24.46 %"),
    "gru": ("127 ± 4", "1666 ± 32", "2.07 %", "23.64 %"),
    "lstm": ("122 ± 10", "1730 ± 21", "2.00 %", "24.55 %"),
}


# ----------------------------------------------------------------------------- formatting


def pct(mean: Any, std: Any = None, digits: int = 2) -> str:
    """A fraction as 'mean ± std %' in percent; NaN parts render as 'undefined'."""
    if not finite(mean):
        return UNDEFINED
    m = f"{100 * float(mean):.{digits}f}"
    if std is None:
        return f"{m} %"
    s = f"{100 * float(std):.{digits}f}" if finite(std) else UNDEFINED
    return f"{m} ± {s} %"


def num(mean: Any, std: Any = None, digits: int = 3) -> str:
    """A plain number (optionally ± std); NaN renders as 'undefined'."""
    if not finite(mean):
        return UNDEFINED
    m = f"{float(mean):.{digits}f}"
    if std is None:
        return m
    return f"{m} ± {f'{float(std):.{digits}f}' if finite(std) else UNDEFINED}"


def ref_pct(ref: tuple[float, float] | None) -> str:
    """A reference (mean, std) in percent, '—' where the thesis gives none."""
    return f"{ref[0]:.2f} ± {ref[1]:.2f} %" if ref else "—"


def note(text: str) -> str:
    """A highlighted note paragraph (``text`` is HTML)."""
    return f'<p class="note">{text}</p>'


def missing(path: Path | None) -> str:
    """The note standing in for an artefact that is missing (or was not given)."""
    if path is None:
        return note("Not produced in this run: the artefact was not given to the report.")
    return note(f"Not produced in this run: <code>{H.esc(path)}</code> is missing.")


def param(value: Any) -> str:
    """A hyperparameter value as it reads best (floats to 3 significant digits)."""
    if isinstance(value, float):
        return f"{value:.3g}"
    return str(value)


# ------------------------------------------------------------------------------- tables


def parameters_table(overview: Mapping[str, Any]) -> str:
    """Our trainable parameter counts beside table 4.2's, with the explanation of the gap."""
    ours = overview.get("parameters", {})
    rows = []
    for f in ordered_families([*ours, *REFERENCE_PARAMETERS]):
        o, r = ours.get(f), REFERENCE_PARAMETERS.get(f)
        diff = f"{r - o:,}" if o is not None and r is not None else "—"
        rows.append(
            [family_label(f), f"{o:,}" if o is not None else "—", f"{r:,}" if r else "—", diff]
        )
    return H.table(
        ["model", "parameters (ours)", "parameters (thesis table 4.2)", "difference"],
        rows,
        caption="Trainable parameters of the baseline configurations (table 4.2)",
    ) + (
        "<p>Our counts are computed for the 10 input features the thesis describes (5 fingertips "
        "× normal and shear force); the reference's counts match the same design with 16 input "
        "features, and each difference is exactly the first layer's weights for the 6 extra "
        "features (CNN 6 × 64 × 5, GRU 6 × 3 × 128, LSTM 6 × 4 × 64).</p>"
    )


def baseline_table(summary: pl.DataFrame) -> str:
    """Validation and test metrics per family (mean ± std in %) beside the reference's."""
    rows = rows_by(summary, ["family", "split"])
    families = ordered_families(summary["family"].to_list())
    body = []
    for split in SPLITS:
        for m in METRICS:
            cells = [SPLIT_NAMES[split], METRIC_NAMES[m]]
            for f in families:
                r = rows.get((f, split), {})
                cells += [
                    pct(r.get(f"{m}_mean"), r.get(f"{m}_std")),
                    ref_pct(REFERENCE_BASELINE.get((split, m), {}).get(f)),
                ]
            body.append(cells)
    head = [
        "split",
        "metric",
        *[h for f in families for h in (family_label(f), f"{family_label(f)} (thesis)")],
    ]
    seeds = sorted({int(s) for s in summary["seeds"].drop_nulls()}) if "seeds" in summary else []
    return H.table(
        head,
        body,
        caption=(
            "Fixed-task benchmark at the baseline window (section 4.3, fig. 4.1): mean ± std over "
            f"{'/'.join(map(str, seeds)) or '?'} seeds; accuracy, precision, recall and F1 at the "
            "validation-selected threshold, undefined where no window is unstable (recall), none "
            "is predicted unstable (precision) or neither (F1), where the stored tables hold 0 by "
            "scikit-learn's convention. '—': the thesis gives no number."
        ),
    )


def motion_headers(split: str = "") -> list[str]:
    """The columns of a still-now table beside its all-windows figures (after the row's keys),
    the metrics' and the count's named after ``split`` when given (e.g. "test")."""
    pre = f"{split} " if split else ""
    return [
        f"{pre}AUPRC: all windows", f"{pre}AUPRC: still now", f"{pre}AUROC: all windows",
        f"{pre}AUROC: still now", f"still-now {pre}windows", "of which unstable",
        "chance AUPRC (still now)",
    ]  # fmt: skip


MOTION_HEADERS = motion_headers()


def motion_cells(row: Mapping[str, Any], split: str, digits: int = 2) -> list[str]:
    """A seed summary row's :data:`MOTION_HEADERS` cells: AUPRC and AUROC (mean ± std over seeds)
    on all windows and on the still-now windows, and the still-now windows' count, positives and
    chance level."""
    return [
        pct(row.get("auprc_mean"), row.get("auprc_std"), digits),
        S.summary_metric(row, "auprc", split, digits=digits),
        pct(row.get("auroc_mean"), row.get("auroc_std"), digits),
        S.summary_metric(row, "auroc", split, digits=digits),
        *S.summary_counts(row, split, digits=digits),
    ]


def baseline_still_table(summary: pl.DataFrame) -> str:
    """The benchmark's ranking metrics on all windows and on the still-now windows per split and
    family (mean ± std over seeds, read from the seed summary); empty for a summary written
    before the still-now metrics."""
    if not S.has_motion(summary.columns):
        return ""
    rows = rows_by(summary, ["family", "split"])
    body = [
        [SPLIT_NAMES[split], family_label(f), *motion_cells(rows[(f, split)], split)]
        for split in SPLITS
        for f in ordered_families(summary["family"].to_list())
        if (f, split) in rows
    ]
    return f"<p>{S.ALL_WINDOWS_TEXT} {S.STILL_NOW_TEXT}</p>" + H.table(
        ["split", "model", *MOTION_HEADERS],
        body,
        caption=(
            "Prediction, not detection at the baseline window: ranking metrics on all windows "
            "and on the still-now windows (the object still over the whole observation "
            "period), mean ± std over seeds; the thesis reports all windows only"
        ),
    )


def errors_table(errors: pl.DataFrame) -> str:
    """Table 4.3: test false positives / negatives and their rates beside the reference."""
    body = []
    for r in sorted(
        errors.iter_rows(named=True),
        key=lambda r: ordered_families(errors["family"].to_list()).index(r["family"]),
    ):
        ref = REFERENCE_ERRORS.get(r["family"], ("—",) * 4)
        body.append(
            [
                family_label(r["family"]),
                num(r["fp_mean"], r["fp_std"], 1),
                ref[0],
                num(r["fn_mean"], r["fn_std"], 1),
                ref[1],
                pct(r["false_positive_rate"]),
                ref[2],
                pct(r["miss_rate"]),
                ref[3],
                r["stable"],
                r["unstable"],
            ]
        )
    return H.table(
        [
            "model",
            "false positives",
            "thesis",
            "false negatives",
            "thesis",
            "false-positive rate",
            "thesis",
            "miss rate",
            "thesis",
            "stable test windows",
            "unstable test windows",
        ],
        body,
        caption=(
            "Table 4.3: aggregate test errors at the baseline window, mean ± std over "
            "seeds. The rates divide by our test set's stable / unstable windows; the "
            "thesis divides by 6113 stable and 7045 unstable windows of its same-end "
            "reference set."
        ),
    )


def rule_counts(records: Mapping[str, Mapping[str, Any]]) -> tuple[str, list[str]]:
    """A table of threshold rules per study (one count per run) and the problems found: runs
    whose rule is 'undefined' and validation ranking metrics that are NaN. ``records``: study ->
    its ``threshold_rules.json`` (:func:`graspstab.evaluation.aggregate.threshold_rules`, written
    by the study's aggregation job)."""
    rules = ("min_recall", "best_f1", UNDEFINED)
    body, problems = [], []
    for study, record in records.items():
        counts = dict(record["rules"])
        runs = record["runs"]
        body.append(
            [
                study,
                runs,
                *[counts.get(r, 0) for r in rules],
                ", ".join(f"{k} {v}" for k, v in counts.items() if k not in rules) or "—",
            ]
        )
        undefined = record["undefined_validation_metrics"]
        if counts.get(UNDEFINED) or undefined:
            problems.append(
                f"{study}: {counts.get(UNDEFINED, 0)} of {runs} runs with rule 'undefined', "
                f"{undefined} with undefined validation AUROC/AUPRC ({record['no_unstable']} "
                "whose validation split held no unstable window, "
                f"{record['no_stable']} whose validation split held no stable window)"
            )
    table = H.table(
        ["study", "runs", *rules, "other"],
        body,
        caption=(
            "Decision-threshold rule chosen on validation per run (sections 3.5.3, 4.2): "
            "min_recall = most precise threshold with validation recall ≥ the target; "
            "best_f1 = the fallback; "
            "undefined = no unstable validation window, threshold 0.5"
        ),
    )
    return table, problems


def rule_warning(problems: Sequence[str]) -> str:
    """The visible warning when a threshold or validation metric is undefined."""
    if not problems:
        return ""
    items = "".join(f"<li>{H.esc(p)}</li>" for p in problems)
    return note(
        "<b>Warning: undefined validation metrics.</b> In some runs the validation split held no "
        "unstable window (or no stable one), so validation AUROC and AUPRC are undefined, "
        "checkpoint selection could not use them, and the precision-at-minimum-recall rule could "
        "not choose a threshold: rule 'undefined' falls back to 0.5. The test metrics at that "
        "threshold are not the thesis's operating point. This is expected of a toy-scale run "
        f"whose validation objects never slip; a full run should not show it.<ul>{items}</ul>"
    )


def tuning_tables(tuning: Mapping[str, Mapping[str, Any]]) -> str:
    """Trials by state and the best parameters per family (Optuna, table 4.1)."""
    families = ordered_families(tuning)
    states = sorted({s for b in tuning.values() for s in b.get("trials", {})})
    body = [
        [
            family_label(f),
            tuning[f].get("objective", "?"),
            num(tuning[f].get("best_value"), None, 4),
            tuning[f].get("best_trial", "?"),
            *[tuning[f].get("trials", {}).get(s, 0) for s in states],
        ]
        for f in families
    ]
    params = sorted({p for b in tuning.values() for p in b.get("searched", [])})
    best = [
        [
            p,
            *[
                param(tuning[f].get("spec", {}).get(p))
                if p in tuning[f].get("searched", [])
                else "—"
                for f in families
            ],
        ]
        for p in params
    ]
    return H.table(
        ["model", "objective", "best value", "best trial", *[f"trials {s}" for s in states]],
        body,
        caption="Optuna studies (4.1.2, table 4.1): trials by state and the best value "
        "(−validation loss when the objective is loss)",
    ) + H.table(
        ["parameter", *[family_label(f) for f in families]],
        best,
        caption="Best parameters per family ('—': not searched for that family)",
    )


def search_space_table(tune: Mapping[str, Any]) -> str:
    """Table 4.1 as this run searched it: every parameter's group, values or range."""
    space = tune.get("space", {})
    groups = {"common": "all families", "cnn": "CNN", "recurrent": "GRU and LSTM"}
    rows = []
    for group, params in space.items():
        for name, spec in (params or {}).items():
            if isinstance(spec, Mapping):
                scale = ", log scale" if spec.get("log") else ""
                values = f"[{param(spec.get('low'))}, {param(spec.get('high'))}]{scale}"
            else:
                values = ", ".join(param(v) for v in spec)
            rows.append([groups.get(group, group), name, values])
    if not rows:
        return note("No tuning search space in this run's configuration.")
    return H.table(
        ["searched for", "parameter", "values (list) or range"],
        rows,
        caption=f"Optuna search space (table 4.1; the thesis names the groups, not the ranges): "
        f"{tune.get('trials', '?')} trials per family at a {tune.get('window_s', '?')} s window, "
        f"objective validation {tune.get('objective', '?')}",
        cls="text",
    )


ARCHITECTURE_KEYS = {
    "cnn": ("base_channels", "kernel_sizes"),
    "gru": ("hidden_size", "num_layers", "bidirectional", "pooling"),
    "lstm": ("hidden_size", "num_layers", "bidirectional", "pooling"),
}
REFERENCE_CONFIGS = {  # table 4.2, architecture settings
    "cnn": "base channels 64",
    "gru": "hidden 128, 2 layers, unidirectional, mean pooling",
    "lstm": "hidden 64, 1 layer, unidirectional, mean pooling",
}


def configurations_table(config: Mapping[str, Any]) -> str:
    """Table 4.2's settings as configured in this run, beside the reference's."""
    models, train = config.get("model", {}), config.get("train", {})
    rows = []
    for f in ordered_families(models):
        spec = models[f]
        arch = ", ".join(f"{k} {spec[k]}" for k in ARCHITECTURE_KEYS.get(f, ()) if k in spec)
        rows.append([
            family_label(f), arch, REFERENCE_CONFIGS.get(f, "—"),
            f"dropout {spec.get('dropout', '?')}, learning rate {spec.get('learning_rate', '?')}",
        ])  # fmt: skip
    if not rows:
        return note("No model configuration in this run's configuration.")
    shared = ", ".join(
        f"{k.replace('_', ' ')} {train[k]}"
        for k in ("batch_size", "weight_decay", "patience", "max_epochs")
        if k in train
    )
    return H.table(
        ["model", "architecture (ours)", "architecture (thesis)", "training (ours)"],
        rows,
        caption=f"Baseline configurations (table 4.2); shared training settings: {shared}. "
        "The thesis trains every baseline with dropout 0.2, batch 256, weight decay 1e-4, "
        "patience 10 and learning rate 1e-3 (LSTM 5e-4).",
        cls="text",
    )
