"""The learning section of the report (thesis chapter 4): our study results beside the
reference's published numbers, the threshold-rule warning, and the chapter's figures.

Every table reads one study artefact; a missing artefact gives a note instead of the table. NaN
(an undefined metric, e.g. validation AUPRC when the validation split holds no unstable window)
renders as "undefined".
"""

from __future__ import annotations

import math
from collections import Counter
from collections.abc import Callable, Mapping, Sequence
from pathlib import Path
from typing import Any

import polars as pl

from graspstab.common.io import read_json
from graspstab.learning.figures import FAMILY_LABELS, defined_summary, ordered_families
from graspstab.report import html as H

UNDEFINED = "undefined"
SPLITS = ("val", "test")
SPLIT_NAMES = {"val": "validation", "test": "test"}
METRICS = ("accuracy", "precision", "recall", "f1", "auroc", "auprc")
METRIC_NAMES = {
    "accuracy": "accuracy",
    "precision": "precision",
    "recall": "recall",
    "f1": "F1",
    "auroc": "AUROC",
    "auprc": "AUPRC",
}

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
REFERENCE_LATENCY = {  # section 4.5: median ± std [ms], throughput [windows/s] (approximate)
    "cnn": ("0.625 ± 0.032", "≈ 1600"),
    "lstm": ("2.407 ± 0.048", "≈ 415"),
    "gru": ("5.634 ± 0.118", "≈ 178"),
}
REFERENCE_SPLITS = {  # section 4.4, 0.01 s tuned LSTM, 30 assignments x 3 seeds
    "assignments": "30",
    "mean ± std": "97.14 ± 2.49 %",
    "median": "98.13 %",
    "minimum": "above 90 % (every assignment)",
    "fixed split": "97.90 %",
}
REFERENCE_PROXY = {"proxy": "96.27 %", "cnn": "98.03 %", "gru": "98.34 %", "lstm": "98.41 %"}
REFERENCE_SWEEP_F1 = {"cnn": "84.2-86.1 %", "gru": "85.4-85.9 %", "lstm": "85.0-85.4 %"}


# ----------------------------------------------------------------------------- formatting


def finite(value: Any) -> bool:
    """True for a real, finite number: None (strict JSON's undefined) and NaN are not."""
    try:
        return value is not None and math.isfinite(float(value))
    except (TypeError, ValueError):
        return False


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
    return f"{ref[0]:.2f} ± {ref[1]:.2f} %" if ref else "—"


def fam(family: str) -> str:
    return FAMILY_LABELS.get(family, str(family).upper())


def note(text: str) -> str:
    return f'<p class="note">{text}</p>'


def missing(path: Path) -> str:
    return note(f"Not produced in this run: <code>{H.esc(path)}</code> is missing.")


def _read(path: Path, reader: Callable[[Path], Any]) -> Any:
    return reader(path) if path.exists() else None


# Stable ids (and contents entries, where the figure is one of the reference's) of the figures.
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


def _rows_by(frame: pl.DataFrame, keys: Sequence[str]) -> dict[tuple, dict[str, Any]]:
    return {tuple(r[k] for k in keys): r for r in frame.iter_rows(named=True)}


# ------------------------------------------------------------------------------- sections


def parameters_table(overview: Mapping[str, Any]) -> str:
    """Our trainable parameter counts beside table 4.2's, with the explanation of the gap."""
    ours = overview.get("parameters", {})
    rows = []
    for f in ordered_families([*ours, *REFERENCE_PARAMETERS]):
        o, r = ours.get(f), REFERENCE_PARAMETERS.get(f)
        diff = f"{r - o:,}" if o is not None and r is not None else "—"
        rows.append([fam(f), f"{o:,}" if o is not None else "—", f"{r:,}" if r else "—", diff])
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
    rows = _rows_by(summary, ["family", "split"])
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
    head = ["split", "metric", *[h for f in families for h in (fam(f), f"{fam(f)} (thesis)")]]
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
                fam(r["family"]),
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


def rule_counts(runs: Mapping[str, pl.DataFrame]) -> tuple[str, list[str]]:
    """A table of threshold rules per study (one count per run) and the problems found: runs
    whose rule is 'undefined' and validation ranking metrics that are NaN."""
    rules = ("min_recall", "best_f1", UNDEFINED)
    body, problems = [], []
    for study, frame in runs.items():
        val = frame.filter(pl.col("split") == "val")
        counts = Counter(val["threshold_rule"].to_list())
        body.append(
            [
                study,
                len(val),
                *[counts.get(r, 0) for r in rules],
                ", ".join(f"{k} {v}" for k, v in counts.items() if k not in rules) or "—",
            ]
        )
        nan = val.filter(pl.col("auprc").is_nan() | pl.col("auroc").is_nan())
        if counts.get(UNDEFINED) or nan.height:
            no_pos = int((nan["n_unstable"] == 0).sum())
            no_neg = int((nan["n_unstable"] == nan["n"]).sum())
            problems.append(
                f"{study}: {counts.get(UNDEFINED, 0)} of {len(val)} runs with rule 'undefined', "
                f"{nan.height} with undefined validation AUROC/AUPRC ({no_pos} whose validation "
                f"split held no unstable window, {no_neg} whose validation split held no stable "
                "window)"
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
            fam(f),
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
                _param(tuning[f].get("spec", {}).get(p))
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
        ["parameter", *[fam(f) for f in families]],
        best,
        caption="Best parameters per family ('—': not searched for that family)",
    )


def _param(value: Any) -> str:
    if isinstance(value, float):
        return f"{value:.3g}"
    return str(value)


def operating_points_table(points: pl.DataFrame, overview: Mapping[str, Any]) -> str:
    """Fig. 4.7's points: validation AUPRC and latency per family and window, best and pick."""
    choice = overview.get("choice", {})
    pick = choice.get("pick", {}) if choice.get("defined") else {}
    stars = {(b["family"], b["window_s"]) for b in overview.get("best_windows", [])}
    body = []
    for r in points.sort(["family", "window_s"]).iter_rows(named=True):
        key = (r["family"], r["window_s"])
        mark = " ".join(
            m
            for m, on in (
                ("★ best of family", key in stars),
                ("◎ latency-aware pick", key == (pick.get("family"), pick.get("window_s"))),
            )
            if on
        )
        body.append(
            [
                fam(r["family"]),
                f"{r['window_s'] * 1000:g}",
                pct(r["val_auprc_mean"], r["val_auprc_std"], 3),
                num(r["latency_ms"], r["latency_std_ms"], 3),
                num(r["total_latency_ms"], None, 2),
                mark or "",
            ]
        )
    return H.table(
        [
            "model",
            "window [ms]",
            "validation AUPRC",
            "forward pass [ms]",
            "total decision latency [ms]",
            "",
        ],
        body,
        caption="Sweep operating points (section 4.5, fig. 4.7): mean ± std over seeds; "
        "total latency = window duration + median forward pass",
    )


def choice_text(overview: Mapping[str, Any]) -> str:
    """The latency-aware choice, its rule and the reference's."""
    c = overview.get("choice", {})
    rule = H.esc(c.get("rule", "?"))
    ref = (
        "The thesis: best mean validation AUPRC GRU at 0.10 s (98.762 ± 0.034 %, 106.10 ms); "
        "latency-aware pick LSTM at 0.01 s (98.747 ± 0.022 %, 10.17 ms)."
    )
    if not c.get("defined"):
        return note(
            f"Latency-aware choice undefined ({H.esc(c.get('reason', '?'))}). Rule: {rule}. {ref}"
        )

    def cfg(p: Mapping[str, Any]) -> str:
        auprc = pct(p.get("val_auprc_mean"), p.get("val_auprc_std"), 3)
        total = num(p.get("total_latency_ms"), None, 2)
        return f"{fam(p['family'])} at {p['window_s']:g} s ({auprc}, {total} ms)"

    return (
        f"<p>Latency-aware rule: <i>{rule}</i>. Best configuration: {H.esc(cfg(c['best']))}; "
        f"cut-off {H.esc(pct(c.get('cutoff'), None, 3))}; <b>pick: "
        f"{H.esc(cfg(c['pick']))}</b>. {ref}</p>"
    )


def sweep_table(summary: pl.DataFrame) -> str:
    """Test F1 and AUPRC per window and family (fig. 4.5 D and F)."""
    test = summary.filter(pl.col("split") == "test")
    rows = _rows_by(test, ["family", "window_s"])
    families = ordered_families(test["family"].to_list())
    body = []
    for w in sorted(test["window_s"].unique().to_list()):
        cells = [f"{w * 1000:g}"]
        for f in families:
            r = rows.get((f, w), {})
            cells += [
                pct(r.get("f1_mean"), r.get("f1_std"), 1),
                pct(r.get("auprc_mean"), r.get("auprc_std"), 1),
            ]
        body.append(cells)
    head = ["window [ms]", *[h for f in families for h in (f"{fam(f)} F1", f"{fam(f)} AUPRC")]]
    ref = ", ".join(f"{fam(f)} {v}" for f, v in REFERENCE_SWEEP_F1.items())
    return H.table(
        head,
        body,
        caption=(
            f"Test metrics across the sweep (fig. 4.5D, F), mean ± std over seeds. The thesis's "
            f"mean test F1 ranges over its windows: {ref}."
        ),
    )


def latency_table(latency: pl.DataFrame) -> str:
    """Baseline forward-pass latency and throughput beside the reference's (fig. 4.6)."""
    base = latency.filter(pl.col("study") == "baseline")
    body = []
    for f in ordered_families(base["family"].to_list()):
        r = base.filter(pl.col("family") == f).row(0, named=True)
        ref = REFERENCE_LATENCY.get(f, ("—", "—"))
        body.append(
            [
                fam(f),
                f"{r['window_s']:g}",
                num(r["median_ms"], r["std_ms"], 3),
                ref[0],
                num(r["throughput_per_s"], None, 0),
                ref[1],
            ]
        )
    return H.table(
        [
            "model",
            "window [s]",
            "median ± std [ms]",
            "thesis [ms]",
            "throughput [windows/s]",
            "thesis [windows/s]",
        ],
        body,
        caption="CPU batch-1 forward-pass latency of the baseline checkpoints (first seed; "
        "fig. 4.6). Different machines: compare the ordering, not the absolute times.",
    )


def splits_tables(summary: Mapping[str, Any], family: str | None) -> str:
    """Split-robustness statistics beside the reference's, and the hardest pairings."""
    s = summary
    ours = {
        "assignments": f"{s.get('assignments', '?')} ({s.get('defined', '?')} defined)",
        "mean ± std": pct(s.get("mean"), s.get("std")),
        "median": pct(s.get("median")),
        "minimum": pct(s.get("min")),
        "fixed split": pct(s.get("fixed_split")),
    }
    stats = H.table(
        ["test AUPRC across assignments", "ours", "thesis"],
        [[k, v, REFERENCE_SPLITS[k]] for k, v in ours.items()],
        caption=f"Split robustness (section 4.4, fig. 4.4), "
        f"{fam(family) if family else 'model'} of the split study",
    )
    hard = [
        [
            r["assignment"],
            r["val_objects"],
            r["test_objects"],
            pct(r.get("auprc"), r.get("auprc_std")),
            r.get("seeds"),
        ]
        for r in s.get("hardest", [])
    ]
    return stats + H.table(
        ["assignment", "validation objects", "test objects", "test AUPRC", "seeds"],
        hard,
        caption="Hardest sampled assignments (lowest mean test AUPRC). The thesis's hardest "
        "pairings repeatedly involve foam_brick, especially with lemon or sponge.",
    )


def proxy_table(proxy: Mapping[str, Any], summary: pl.DataFrame | None) -> str:
    """Friction-ratio proxy vs the models' mean test AUPRC (fig. 4.10)."""
    test = proxy.get("test", {})
    body = [
        [
            "friction-ratio proxy",
            pct(test.get("auprc")),
            pct(test.get("auroc")),
            REFERENCE_PROXY["proxy"],
        ]
    ]
    if summary is not None:
        rows = _rows_by(summary.filter(pl.col("split") == "test"), ["family"])
        for f in ordered_families(f for (f,) in rows):
            r = rows[(f,)]
            body.append(
                [
                    f"{fam(f)} (mean ± std over seeds)",
                    pct(r["auprc_mean"], r["auprc_std"]),
                    pct(r["auroc_mean"], r["auroc_std"]),
                    REFERENCE_PROXY.get(f, "—"),
                ]
            )
    n, pos = test.get("n", 0), test.get("n_unstable", 0)
    body.append(
        [
            "chance level (test unstable fraction)",
            pct(pos / n if n else None),
            "50.00 %",
            "59.2 % (8632 / 14587)",
        ]
    )
    return H.table(
        ["score", "test AUPRC", "test AUROC", "thesis test AUPRC"],
        body,
        caption=f"Friction-ratio proxy (section 4.7) on the unseen-object test split "
        f"({pos} unstable of {n} windows)",
    )


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
    path: Path,
    reader: Callable[[Path], Any],
    render: Callable[[Any], str | list[str]],
    anchor: str = "",
) -> list[str]:
    """A sub-heading (with a stable id) and the rendering of one artefact (or a note that it is
    missing)."""
    head = H.heading(3, anchor, title) if anchor else f"<h3>{H.esc(title)}</h3>"
    data = _read(path, reader)
    if data is None:
        return [head, missing(path)]
    out = render(data)
    return [head, *([out] if isinstance(out, str) else out)]


def _runs(studies: Path) -> dict[str, pl.DataFrame]:
    paths = {s: studies / s / "runs.parquet" for s in ("baseline", "sweep", "splits")}
    return {s: pl.read_parquet(p) for s, p in paths.items() if p.exists()}


def _intro(config: Mapping[str, Any]) -> str:
    profile = config.get("profile_name", "?")
    return note(
        f"Profile <b>{H.esc(profile)}</b>. Reference numbers are the thesis's (chapter 4, "
        "'thesis' columns). A quick-profile run trains a few epochs on a handful of grasps: it "
        "checks that every study runs end to end and is not a reproduction of those numbers."
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
                values = f"[{_param(spec.get('low'))}, {_param(spec.get('high'))}]{scale}"
            else:
                values = ", ".join(_param(v) for v in spec)
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
            fam(f), arch, REFERENCE_CONFIGS.get(f, "—"),
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


def _tuning_parts(results: Path, figures: Mapping[str, Path], config: Mapping) -> list[str]:
    tune = results / "tune"
    bests = {p.parent.name: read_json(p) for p in sorted(tune.glob("*/best.json"))}
    return [
        H.heading(3, "tuning", "Tuning: search space and results (table 4.1)"),
        search_space_table(config.get("tune", {})),
        tuning_tables(bests) if bests else missing(tune / "<model>" / "best.json"),
        *_figure(figures, "tuning", CAPTIONS["tuning"]),
    ]


def _baseline_parts(studies: Path, figures: Mapping[str, Path], config: Mapping) -> list[str]:
    base = studies / "baseline"
    overview = base / "summary.json"
    if not overview.exists() and (base / "overview.json").exists():
        overview = base / "overview.json"
    return [
        H.heading(3, "baseline-configurations", "Baseline configurations (table 4.2)"),
        configurations_table(config),
        *_block("Parameters (table 4.2)", overview, read_json, parameters_table),
        *_block(
            "Fixed-task benchmark (section 4.3)",
            base / "runs.parquet",
            lambda p: defined_summary(pl.read_parquet(p), ["family", "split"]),
            lambda s: [baseline_table(s)],
            anchor="baseline-benchmark",
        ),
        *_figure(figures, "benchmark", CAPTIONS["benchmark"]),
        *_figure(figures, "confusion", CAPTIONS["confusion"]),
        *_figure(figures, "objects", CAPTIONS["objects"]),
    ]


def _threshold_parts(studies: Path) -> list[str]:
    head = H.heading(3, "threshold-rules", "Threshold rules")
    runs = _runs(studies)
    if not runs:
        return [head, missing(studies / "baseline" / "runs.parquet")]
    table, problems = rule_counts(runs)
    return [head, rule_warning(problems), table]


def _sweep_parts(studies: Path, figures: Mapping[str, Path]) -> list[str]:
    sweep = studies / "sweep"
    overview = _read(sweep / "summary.json", read_json) or {}
    return [
        *_block(
            "Window-length sweep (section 4.5, fig. 4.5)",
            sweep / "runs.parquet",
            lambda p: defined_summary(pl.read_parquet(p), ["family", "window_s", "split"]),
            sweep_table,
            anchor="sweep",
        ),
        *_figure(figures, "sweep", CAPTIONS["sweep"]),
        *_block(
            "Inference latency (fig. 4.6)",
            studies / "latency.parquet",
            pl.read_parquet,
            latency_table,
            anchor="latency",
        ),
        *_figure(figures, "latency", CAPTIONS["latency"]),
        *_block(
            "AUPRC against decision latency (fig. 4.7)",
            sweep / "operating_points.parquet",
            pl.read_parquet,
            lambda p: [choice_text(overview), operating_points_table(p, overview)],
            anchor="operating-points",
        ),
        *_figure(figures, "operating_points", CAPTIONS["operating_points"]),
    ]


def _splits_parts(studies: Path, figures: Mapping[str, Path]) -> list[str]:
    runs = _read(studies / "splits" / "runs.parquet", pl.read_parquet)
    family = runs["family"][0] if runs is not None and runs.height else None
    return [
        *_block(
            "Split robustness (section 4.4)",
            studies / "splits" / "summary.json",
            read_json,
            lambda s: splits_tables(s, family),
            anchor="split-robustness",
        ),
        *_figure(figures, "splits", CAPTIONS["splits"]),
    ]


def _diagnostic_parts(studies: Path, figures: Mapping[str, Path]) -> list[str]:
    summary = _read(studies / "baseline" / "summary.parquet", pl.read_parquet)
    return [
        *_block(
            "Errors (section 4.6, table 4.3)",
            studies / "baseline" / "errors.parquet",
            pl.read_parquet,
            errors_table,
            anchor="errors",
        ),
        H.heading(3, "calibration", "Threshold transfer and calibration (section 4.6)"),
        *_figure(figures, "threshold_transfer", CAPTIONS["threshold_transfer"]),
        *_figure(figures, "reliability", CAPTIONS["reliability"]),
        *_block(
            "Friction-ratio proxy (section 4.7, fig. 4.10)",
            studies / "proxy.json",
            read_json,
            lambda p: proxy_table(p, summary),
            anchor="proxy",
        ),
        *_figure(figures, "proxy", CAPTIONS["proxy"]),
    ]


def learning_section(results_dir: Path, figures: dict[str, Path], config: dict) -> str:
    """The report's chapter-4 section: tables of every study beside the thesis's numbers, the
    threshold-rule warning, and the figures of :func:`graspstab.learning.figures.plot_learning`
    (``figures``: name -> PNG; absent names are skipped)."""
    results = Path(results_dir)
    studies = results / "studies"
    # The reference's order: tuning (table 4.1), baselines (table 4.2), 4.3, 4.4, 4.5, 4.6, 4.7.
    parts = [
        H.heading(2, "learning", "Learning and evaluation (chapter 4)"),
        _intro(config),
        *_threshold_parts(studies),
        *_tuning_parts(results, figures, config),
        *_baseline_parts(studies, figures, config),
        *_splits_parts(studies, figures),
        *_sweep_parts(studies, figures),
        *_diagnostic_parts(studies, figures),
    ]
    return "\n".join(p for p in parts if p)
