"""Multi-seed summaries of the studies (thesis 3.5.4, 4.3-4.5): mean and std across seeds.

Per-seed ``metrics.json`` records become one long table (one row per run and split); the
studies' tables are grouped means and standard deviations of it, the sweep's latency-aware
choice and the split-robustness summary are computed from those.
"""

from __future__ import annotations

import math
from collections import Counter
from collections.abc import Iterable, Mapping, Sequence
from typing import Any

import numpy as np
import polars as pl

METRICS = (
    "loss", "accuracy", "precision", "recall", "f1", "auroc", "auprc",
    "tp", "fp", "tn", "fn", "false_positive_rate", "miss_rate", "threshold",
    "still_auroc", "still_auprc", "still_chance", "still_n", "still_n_unstable",
    "moving_auroc", "moving_auprc", "moving_chance", "moving_n", "moving_n_unstable",
)  # fmt: skip
#: The ranking metrics of a run's still-now and moving-now windows (evaluation.detection), each
#: with its window count and positives: the columns ``still_<key>`` and ``moving_<key>``.
MOTION_KEYS = ("n", "n_unstable", "chance", "auprc", "auroc")


def run_rows(
    records: Iterable[Mapping[str, Any]], keys: Sequence[Mapping[str, Any]]
) -> pl.DataFrame:
    """One row per (run, split in val/test): the run's ``keys`` (e.g. window, assignment), its
    family, seed, best epoch, threshold rule, every metric of ``METRICS`` and the still-now and
    moving-now blocks (``MOTION_KEYS``; NaN for a record written without them)."""
    rows = []
    for record, key in zip(records, keys, strict=True):
        for split in ("val", "test"):
            m = record[split]
            row = {**key, "family": record["family"], "seed": int(record["seed"]),
                   "split": split, "best_epoch": int(record["best_epoch"]),
                   "threshold_rule": record["threshold"]["rule"], "n": int(m["n"]),
                   "n_unstable": int(m["n_unstable"])}  # fmt: skip
            row.update({k: _float(m[k]) for k in METRICS if k in m and k != "threshold"})
            row["threshold"] = float(record["threshold"]["threshold"])
            for part in ("still", "moving"):
                block = record.get(f"{split}_{part}", {})
                row.update({f"{part}_{k}": _float(block.get(k)) for k in MOTION_KEYS})
            rows.append(row)
    return pl.DataFrame(rows, infer_schema_length=None)


def object_rows(
    records: Iterable[Mapping[str, Any]], keys: Sequence[Mapping[str, Any]]
) -> pl.DataFrame:
    """One row per (run, split, object) with the per-object metrics (figure 4.3)."""
    rows = []
    for record, key in zip(records, keys, strict=True):
        for split in ("val", "test"):
            for obj, m in record[f"{split}_objects"].items():
                row = {**key, "family": record["family"], "seed": int(record["seed"]),
                       "split": split, "object": obj}  # fmt: skip
                row.update({k: _float(m[k]) for k in METRICS if k in m})
                rows.append(row)
    return pl.DataFrame(rows, infer_schema_length=None)


def _float(value: Any) -> float:
    return float("nan") if value is None else float(value)


def mean_std(
    frame: pl.DataFrame, by: Sequence[str], metrics: Sequence[str] = METRICS
) -> pl.DataFrame:
    """Mean and sample standard deviation (ddof 1) of each metric across seeds, ignoring NaN
    (an undefined metric), with the number of seeds that defined it."""
    aggs = []
    for m in metrics:
        if m not in frame.columns:
            continue
        col = pl.col(m).fill_nan(None)
        aggs += [col.mean().alias(f"{m}_mean"), col.std(ddof=1).alias(f"{m}_std"),
                 col.count().alias(f"{m}_n")]  # fmt: skip
    return (
        frame.group_by(list(by), maintain_order=True)
        .agg(pl.col("seed").n_unique().alias("seeds"), *aggs)
        .sort(list(by))
    )


def undefined_as_nan(frame: pl.DataFrame) -> pl.DataFrame:
    """Precision, recall and F1 as NaN where scikit-learn's zero_division=0 stored 0 for 0/0:
    recall with no unstable window, precision with none predicted unstable, F1 with neither.
    ``frame`` needs tp, fp, fn and the three metrics (runs or objects table)."""
    pos = pl.col("tp") + pl.col("fn")
    pred = pl.col("tp") + pl.col("fp")
    nan = pl.lit(float("nan"))
    return frame.with_columns(
        pl.when(pos == 0).then(nan).otherwise(pl.col("recall")).alias("recall"),
        pl.when(pred == 0).then(nan).otherwise(pl.col("precision")).alias("precision"),
        pl.when(pos + pred == 0).then(nan).otherwise(pl.col("f1")).alias("f1"),
    )


def seed_summary(runs: pl.DataFrame, by: Sequence[str]) -> pl.DataFrame:
    """What the report shows of a study's runs: :func:`mean_std` with 0/0 metrics undefined
    (:func:`undefined_as_nan`), plus per group ``no_unstable`` / ``no_stable``: whether every run's
    split held no unstable (no stable) window, the reason a ranking metric is undefined."""
    summary = mean_std(undefined_as_nan(runs), by)
    classes = runs.group_by(list(by)).agg(
        (pl.col("n_unstable") == 0).all().alias("no_unstable"),
        (pl.col("n_unstable") == pl.col("n")).all().alias("no_stable"),
    )
    return summary.join(classes, on=list(by), how="left").sort(list(by))


def threshold_rules(runs: pl.DataFrame) -> dict[str, Any]:
    """How a study's runs chose their decision threshold on validation (3.5.3): the validation
    runs, each rule with its count (``rules``: [rule, runs] in order of first use), and the runs
    with an undefined validation AUROC or AUPRC, of which how many had no unstable and no stable
    validation window."""
    val = runs.filter(pl.col("split") == "val")
    counts = Counter(val["threshold_rule"].to_list())
    nan = val.filter(pl.col("auprc").is_nan() | pl.col("auroc").is_nan())
    return {
        "runs": val.height,
        "rules": [[rule, n] for rule, n in counts.items()],
        "undefined_validation_metrics": nan.height,
        "no_unstable": int((nan["n_unstable"] == 0).sum()),
        "no_stable": int((nan["n_unstable"] == nan["n"]).sum()),
    }


def error_table(frame: pl.DataFrame) -> pl.DataFrame:
    """Table 4.3: test false positives and false negatives per family (mean, std) with the
    false-positive rate (over stable windows) and miss rate (over unstable windows)."""
    test = frame.filter(pl.col("split") == "test")
    return test.group_by("family", maintain_order=True).agg(
        pl.col("fp").mean().alias("fp_mean"), pl.col("fp").std(ddof=1).alias("fp_std"),
        pl.col("fn").mean().alias("fn_mean"), pl.col("fn").std(ddof=1).alias("fn_std"),
        (pl.col("n") - pl.col("n_unstable")).first().alias("stable"),
        pl.col("n_unstable").first().alias("unstable"),
    ).with_columns(
        (pl.col("fp_mean") / pl.col("stable")).alias("false_positive_rate"),
        (pl.col("fn_mean") / pl.col("unstable")).alias("miss_rate"),
    ).sort("family")  # fmt: skip


def latency_aware_choice(table: pl.DataFrame) -> dict[str, Any]:
    """The sweep's operating point (4.5), stated precisely: among all (family, window)
    configurations, those whose mean validation AUPRC is at least the best configuration's mean
    minus that configuration's standard deviation across seeds; of those, the one with the
    lowest total decision latency (window duration + median inference latency).

    ``table`` needs family, window_s, val_auprc_mean, val_auprc_std, total_latency_ms."""
    valid = table.filter(pl.col("val_auprc_mean").fill_nan(None).is_not_null())
    if valid.is_empty():
        return {"rule": LATENCY_RULE, "defined": False,
                "reason": "no configuration has a defined validation AUPRC"}  # fmt: skip
    ranked = valid.sort(["val_auprc_mean", "total_latency_ms"], descending=[True, False])
    best = ranked.row(0, named=True)
    std = best["val_auprc_std"]
    std = 0.0 if std is None or math.isnan(std) else float(std)
    cutoff = best["val_auprc_mean"] - std
    pick = (
        valid.filter(pl.col("val_auprc_mean") >= cutoff)
        .sort(["total_latency_ms", "val_auprc_mean"], descending=[False, True], nulls_last=True)
        .row(0, named=True)
    )
    return {"rule": LATENCY_RULE, "defined": True, "cutoff": cutoff, "best": _pick(best),
            "pick": _pick(pick)}  # fmt: skip


LATENCY_RULE = (
    "lowest total decision latency among configurations whose mean validation AUPRC is within "
    "one standard deviation (across seeds) of the best configuration's mean"
)


def _pick(row: Mapping[str, Any]) -> dict[str, Any]:
    keys = ("family", "window_s", "val_auprc_mean", "val_auprc_std", "total_latency_ms",
            "latency_ms")  # fmt: skip
    return {k: row[k] for k in keys if k in row}


def best_windows(table: pl.DataFrame) -> pl.DataFrame:
    """Each family's window with the highest mean validation AUPRC (the stars of fig. 4.7)."""
    return (
        table.filter(pl.col("val_auprc_mean").is_not_nan())
        .sort(["family", "val_auprc_mean"], descending=[False, True])
        .group_by("family", maintain_order=True)
        .first()
    )


def _spread(per: pl.DataFrame, column: str) -> dict[str, Any]:
    """Mean, std, median and minimum of a per-assignment column across assignments, and the
    fixed split's (assignment 0) value; undefined (NaN) where no assignment defines it."""
    values = per[column].drop_nulls().to_numpy()
    fixed = per.filter(pl.col("assignment") == 0)[column]
    return {
        "assignments": int(len(per)),
        "defined": int(len(values)),
        "mean": float(np.mean(values)) if len(values) else float("nan"),
        "std": float(np.std(values, ddof=1)) if len(values) > 1 else float("nan"),
        "median": float(np.median(values)) if len(values) else float("nan"),
        "min": float(np.min(values)) if len(values) else float("nan"),
        "fixed_split": float(fixed[0]) if len(fixed) and fixed[0] is not None else float("nan"),
    }


def split_summary(frame: pl.DataFrame, hardest: int = 5) -> dict[str, Any]:
    """Split robustness (4.4): test AUPRC per assignment (mean over seeds), then its mean, std,
    median and minimum across assignments, the fixed split's value and the hardest pairings;
    with the runs' still-now columns, the same of the still-now test AUPRC (``still``) and each
    assignment's still-now windows, positives and chance.

    ``frame``: rows of split "test" with assignment (int, 0 = fixed split), val_objects,
    test_objects, seed, auprc (and still_auprc, still_n, still_n_unstable, still_chance)."""
    still = "still_auprc" in frame.columns
    aggs = [pl.col("auprc").fill_nan(None).mean().alias("auprc"),
            pl.col("auprc").fill_nan(None).std(ddof=1).alias("auprc_std"),
            pl.col("seed").n_unique().alias("seeds")]  # fmt: skip
    if still:
        aggs += [pl.col("still_auprc").fill_nan(None).mean().alias("still_auprc"),
                 pl.col("still_auprc").fill_nan(None).std(ddof=1).alias("still_auprc_std"),
                 *(pl.col(f"still_{k}").first().alias(f"still_{k}")
                   for k in ("n", "n_unstable", "chance"))]  # fmt: skip
    per = (
        frame.group_by(["assignment", "val_objects", "test_objects"], maintain_order=True)
        .agg(*aggs)
        .sort("assignment")
    )
    out = {
        **_spread(per, "auprc"),
        "hardest": per.drop_nulls("auprc").sort("auprc").head(hardest).to_dicts(),
        "per_assignment": per.to_dicts(),
    }
    if still:
        out["still"] = _spread(per, "still_auprc")
    return out
