"""Study-level entry points (thesis 4.3-4.7): aggregate per-seed runs, measure latency, score the
friction-ratio proxy, and summarise the replays and the grasp funnel for the report. Each writes
Parquet tables (and a JSON summary) that the report reads."""

from __future__ import annotations

import logging
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np
import polars as pl
import torch

from graspstab.common.io import read_json, read_parquet, write_json, write_parquet
from graspstab.common.logs import setup_logging
from graspstab.evaluation import aggregate
from graspstab.evaluation import crossval as cv
from graspstab.evaluation.detection import (
    ORACLE,
    motion_blocks,
    ranked,
    still_now,
    unstable_share,
)
from graspstab.evaluation.latency import measure_latency
from graspstab.evaluation.proxy import friction_ratio, proxy_metrics
from graspstab.labels.dataset import load_motion
from graspstab.learning.data import load_window_data
from graspstab.learning.models import build_model

log = logging.getLogger("graspstab.learning")


def _records(paths: Sequence[str | Path]) -> list[dict[str, Any]]:
    return [read_json(p) for p in paths]


def aggregate_baseline(
    metrics: Sequence[str | Path], out_dir: str | Path, log_file: str | Path | None = None
) -> dict[str, Any]:
    """Fixed-task benchmark (4.3): per-run table, mean +- std per family and split (as is, and
    with 0/0 metrics undefined for the report), per-object test metrics, the error table
    (table 4.3) and how the runs chose their thresholds (for the report)."""
    setup_logging(log_file)
    out = Path(out_dir)
    records = _records(metrics)
    keys = [{} for _ in records]
    runs = aggregate.run_rows(records, keys)
    summary = aggregate.mean_std(runs, ["family", "split"])
    objects = aggregate.object_rows(records, keys)
    errors = aggregate.error_table(runs)
    write_parquet(out / "runs.parquet", runs)
    write_parquet(out / "summary.parquet", summary)
    write_parquet(out / "objects.parquet", objects)
    write_parquet(out / "errors.parquet", errors)
    # what the report shows: the same mean +- std with 0/0 metrics undefined
    write_parquet(
        out / "summary_defined.parquet", aggregate.seed_summary(runs, ["family", "split"])
    )
    write_json(out / "threshold_rules.json", aggregate.threshold_rules(runs))
    result = {
        "summary": summary.to_dicts(),
        "errors": errors.to_dicts(),
        "parameters": {r["family"]: r["parameters"] for r in records},
    }  # fmt: skip
    write_json(out / "summary.json", result)
    log.info("baseline benchmark over %d runs:\n%s", len(records), summary.select(
        "family", "split", "auprc_mean", "auprc_std", "f1_mean", "f1_std"))  # fmt: skip
    return result


def load_checkpoint(path: str | Path) -> tuple[torch.nn.Module, dict[str, Any]]:
    """A trained model (eval mode) and its checkpoint record."""
    ckpt = torch.load(path, map_location="cpu", weights_only=False)
    model = build_model(ckpt["model"], **ckpt.get("inputs", {}))
    model.load_state_dict(ckpt["state_dict"])
    return model.eval(), ckpt


def measure_latencies(
    checkpoints: Sequence[str | Path],
    keys: Sequence[Mapping[str, Any]],
    out_table: str | Path,
    repeats: int,
    warmup: int,
    threads: int = 1,
    log_file: str | Path | None = None,
) -> pl.DataFrame:
    """CPU batch-1 latency of every checkpoint (4.5); ``keys`` (study, family, window_s) label
    the rows."""
    setup_logging(log_file)
    torch.set_num_threads(max(1, int(threads)))
    rows = []
    for path, key in zip(checkpoints, keys, strict=True):
        model, ckpt = load_checkpoint(path)
        m = measure_latency(model, int(ckpt["window_steps"]), repeats=repeats, warmup=warmup)
        rows.append({**key, "window_steps": int(ckpt["window_steps"]), **m})
        log.info("%s: %.3f +- %.3f ms (median +- std), %.0f windows/s", key, m["median_ms"],
                 m["std_ms"], m["throughput_per_s"])  # fmt: skip
    table = pl.DataFrame(rows, infer_schema_length=None)
    write_parquet(out_table, table)
    return table


def aggregate_sweep(
    metrics: Sequence[str | Path],
    latency_table: str | Path,
    out_dir: str | Path,
    log_file: str | Path | None = None,
) -> dict[str, Any]:
    """Window-length sweep (4.5): metrics per family and window (mean +- std over seeds; also with
    0/0 metrics undefined, for the report), total decision latency, each family's best window,
    the latency-aware operating point and how the runs chose their thresholds (for the report)."""
    setup_logging(log_file)
    out = Path(out_dir)
    records = _records(metrics)
    runs = aggregate.run_rows(records, [{"window_s": r["window_s"]} for r in records])
    summary = aggregate.mean_std(runs, ["family", "window_s", "split"])
    latency = read_parquet(latency_table).filter(pl.col("study") == "sweep")
    val = (
        summary.filter(pl.col("split") == "val")
        .select("family", "window_s", "auprc_mean", "auprc_std")
        .rename({"auprc_mean": "val_auprc_mean", "auprc_std": "val_auprc_std"})
        .join(latency.select("family", "window_s", pl.col("median_ms").alias("latency_ms"),
                             pl.col("std_ms").alias("latency_std_ms")),
              on=["family", "window_s"], how="left")
        .with_columns((pl.col("window_s") * 1e3 + pl.col("latency_ms")).alias("total_latency_ms"))
    )  # fmt: skip
    choice = aggregate.latency_aware_choice(val)
    best = aggregate.best_windows(val)
    write_parquet(out / "runs.parquet", runs)
    write_parquet(out / "summary.parquet", summary)
    write_parquet(out / "operating_points.parquet", val)
    write_parquet(
        out / "summary_defined.parquet",
        aggregate.seed_summary(runs, ["family", "window_s", "split"]),
    )
    write_json(out / "threshold_rules.json", aggregate.threshold_rules(runs))
    result = {"choice": choice, "best_windows": best.to_dicts()}
    write_json(out / "summary.json", result)
    log.info("sweep operating points:\n%s\nchoice: %s", val, choice)
    return result


def aggregate_splits(
    metrics: Sequence[str | Path],
    assignments: Sequence[Mapping[str, str]],
    out_dir: str | Path,
    log_file: str | Path | None = None,
) -> dict[str, Any]:
    """Split robustness (4.4): test AUPRC per sampled assignment and its distribution, and how
    the runs chose their thresholds (for the report)."""
    setup_logging(log_file)
    out = Path(out_dir)
    records = _records(metrics)
    keys = []
    for record in records:
        k = int(record["assignment_index"])
        a = assignments[k]
        keys.append(
            {"assignment": k, **{f"{split}_objects": ", ".join(sorted(o for o, s in a.items()
                                                                     if s == split))
                                 for split in ("val", "test")}}
        )  # fmt: skip
    runs = aggregate.run_rows(records, keys)
    summary = aggregate.split_summary(runs.filter(pl.col("split") == "test"))
    write_parquet(out / "runs.parquet", runs)
    write_json(out / "summary.json", summary)
    write_json(out / "threshold_rules.json", aggregate.threshold_rules(runs))
    log.info("split robustness: mean %.4f std %.4f median %.4f min %.4f fixed %.4f",
             summary["mean"], summary["std"], summary["median"], summary["min"],
             summary["fixed_split"])  # fmt: skip
    return summary


def evaluate_proxy(
    dataset_dir: str | Path, out_json: str | Path, log_file: str | Path | None = None
) -> dict[str, Any]:
    """Friction-ratio proxy (4.7) on the raw (un-normalised) windows of validation and test, on
    all windows and on the still-now and moving-now ones (``evaluation.detection``), and beside it
    the persistence oracle (``persistence``: the observation period's unstable share, a reference
    line that reads object motion)."""
    setup_logging(log_file)
    data = load_window_data(dataset_dir)
    motion = load_motion(dataset_dir)
    result: dict[str, Any] = {}
    oracle: dict[str, Any] = {}
    for split in ("val", "test"):
        rows = data.rows(split)
        scores = friction_ratio(data.windows[rows]) if len(rows) else np.zeros(0)
        labels = data.labels(rows)
        ranking = proxy_metrics(scores, labels) if len(rows) else {"auprc": np.nan, "auroc": np.nan}
        result[split] = {**ranking, "n": int(len(rows)), "n_unstable": int(labels.sum())}
        result[f"{split}_objects"] = {
            obj: proxy_metrics(scores[mask], labels[mask])
            for obj in sorted(set(data.objects(rows)))
            for mask in [data.objects(rows) == obj]
        }
        observed = np.asarray(motion[rows])
        still = still_now(observed)
        result.update(motion_blocks(scores, labels, still, split))
        share = unstable_share(observed)
        oracle[split] = ranked(share, labels)
        oracle.update(motion_blocks(share, labels, still, split))
    result[ORACLE] = oracle
    write_json(out_json, result)
    log.info("friction-ratio proxy: val AUPRC %.4f, test AUPRC %.4f; on the %d still-now test "
             "windows (%d unstable) %.4f; persistence oracle test AUPRC %.4f",
             result["val"]["auprc"], result["test"]["auprc"], result["test_still"]["n"],
             result["test_still"]["n_unstable"], result["test_still"]["auprc"],
             oracle["test"]["auprc"])  # fmt: skip
    return result


def aggregate_inputs(
    metrics: Sequence[str | Path],
    input_sets: Sequence[str],
    out_dir: str | Path,
    log_file: str | Path | None = None,
) -> dict[str, Any]:
    """Input audit: test and validation AUPRC (mean +- std over seeds) per input set and family,
    with each configuration's inputs per timestep and trainable parameters (table 4.2)."""
    setup_logging(log_file)
    out = Path(out_dir)
    records = _records(metrics)
    keys = [{"input_set": s} for s in input_sets]
    runs = aggregate.run_rows(records, keys)
    summary = aggregate.mean_std(runs, ["input_set", "family", "split"])
    shapes = {
        (s, r["family"]): {"inputs": r["inputs"]["fingertips"] * r["inputs"]["channels"],
                           "parameters": int(r["parameters"])}
        for s, r in zip(input_sets, records, strict=True)
    }  # fmt: skip
    write_parquet(out / "runs.parquet", runs)
    result = {
        "summary": summary.to_dicts(),
        "shapes": [{"input_set": s, "family": f, **v} for (s, f), v in shapes.items()],
    }
    write_json(out / "summary.json", result)
    log.info("input audit:\n%s", summary.filter(pl.col("split") == "test").select(
        "input_set", "family", "auprc_mean", "auprc_std"))  # fmt: skip
    return result


def _with_chance(table: pl.DataFrame) -> pl.DataFrame:
    """A pooled table with the chance level of AUPRC (the unstable share of its windows)."""
    if table.is_empty():
        return table
    return table.with_columns((pl.col("unstable") / pl.col("windows")).alias("chance"))


def aggregate_crossval(
    predictions: Sequence[str | Path],
    metrics: Sequence[str | Path],
    run_keys: Sequence[Mapping[str, Any]],
    dataset_dir: str | Path,
    properties: Mapping[str, Mapping[str, Any]],
    protocol: str,
    bootstrap: Mapping[str, Any],
    out_dir: str | Path,
    log_file: str | Path | None = None,
) -> dict[str, Any]:
    """Object-level k-fold study of one protocol (graspstab.evaluation.crossval): per-object,
    pooled and per-fold test metrics of every learned scorer and the friction-ratio proxy, and
    the paired learned-against-proxy comparisons over objects; what each fairness variant
    changes against its plain family; every scorer's thresholded test metrics. ``metrics``: each
    run's metrics.json (its threshold), in ``predictions``' order. ``properties``: object ->
    mass, size, shape (the figure's axes)."""
    setup_logging(log_file)
    out = Path(out_dir)
    root = Path(dataset_dir)
    index = read_parquet(root / "index.parquet")
    windows = load_window_data(root).windows
    proxy = pl.DataFrame({"sample_id": index["sample_id"], "score": friction_ratio(windows)})
    triples = zip(run_keys, predictions, metrics, strict=True)
    runs = [{**k, "predictions": read_parquet(p), "metrics": read_json(m)} for k, p, m in triples]
    scored = cv.scored_windows(runs, index, proxy)
    b = {"resamples": int(bootstrap["resamples"]), "seed": int(bootstrap["seed"]),
         "level": float(bootstrap["level"])}  # fmt: skip
    per_object = cv.per_object_table(scored, **b)
    props = pl.DataFrame([{"object": o, **dict(v)} for o, v in properties.items()])
    per_object = per_object.join(props, on="object", how="left")
    pooled = cv.pooled_table(scored, **b)
    folds = cv.fold_table(scored)
    paired = cv.paired_table(per_object, **b)
    # prediction, not detection (evaluation.detection): the same on the still-now windows, with
    # the persistence oracle beside the scorers (it reads object motion: a reference line)
    motion = load_motion(root)
    state = pl.DataFrame({"sample_id": index["sample_id"], "still": still_now(motion),
                          "oracle": unstable_share(motion)})  # fmt: skip
    oracle = (
        scored.filter(pl.col("scorer") == cv.PROXY)
        .join(state, on="sample_id")
        .with_columns(pl.lit(ORACLE).alias("scorer"), pl.col("oracle").alias("score"))
        .select(scored.columns)
    )
    still_ids = state.filter(pl.col("still")).select("sample_id")
    still = pl.concat([scored, oracle]).join(still_ids, on="sample_id")
    pooled_still = _with_chance(cv.pooled_table(still, **b))
    pooled_oracle = _with_chance(cv.pooled_table(oracle, **b))
    per_object_still = cv.per_object_table(still.filter(pl.col("scorer") != ORACLE), **b)
    paired_still = cv.paired_table(per_object_still, **b)
    # how far each scorer is from the oracle's recognition of motion, paired over objects
    oracle_still = still.filter(pl.col("scorer") == ORACLE)
    paired_oracle = pl.DataFrame()
    if oracle_still.height and per_object_still.height:
        both = pl.concat([per_object_still, cv.per_object_table(oracle_still, **b)],
                         how="diagonal_relaxed")  # fmt: skip
        paired_oracle = cv.paired_table(both, proxy=ORACLE, **b)
    variants = cv.variant_table(per_object, **b)
    learned = sorted(set(scored["scorer"].to_list()) - {cv.PROXY})
    plain = [s for s in learned if "+" not in s]
    tested = sorted(set(scored["object"].to_list()))
    summary = {
        "protocol": protocol,
        "objects": len(properties),
        "tested_objects": tested,
        "untested_objects": sorted(set(properties) - set(tested)),
        "folds": int(folds["fold"].n_unique()),
        "scorers": learned + [cv.PROXY],
        "bootstrap": b,
        "pooled": {r["scorer"]: r for r in pooled.iter_rows(named=True)},
        "pooled_still": {r["scorer"]: r for r in pooled_still.iter_rows(named=True)},
        "oracle": pooled_oracle.row(0, named=True) if pooled_oracle.height else None,
        "paired_still": paired_still.to_dicts(),
        "paired_still_oracle": paired_oracle.to_dicts(),
        "fold_mean": {
            s: {m: float(np.nanmean(g[m].to_numpy())) for m in cv.METRICS}
            | {f"{m}_std": float(np.nanstd(g[m].to_numpy(), ddof=1)) for m in cv.METRICS}
            for (s,), g in folds.group_by(["scorer"])
        },
        "paired": paired.to_dicts(),
        "variants": variants.to_dicts(),
        "thresholds": cv.threshold_table(runs).to_dicts(),
        "answer": cv.answer(paired, protocol.replace("_", "-"), plain, b["level"]),
        "answer_variants": cv.answer(paired, protocol.replace("_", "-"), learned, b["level"]),
        "answer_still": cv.answer(paired_still, protocol.replace("_", "-"), plain, b["level"],
                                  still=True),
    }
    write_parquet(out / "per_object.parquet", per_object)
    write_parquet(out / "pooled.parquet", pooled)
    write_parquet(out / "folds.parquet", folds)
    write_parquet(out / "paired.parquet", paired)
    write_parquet(out / "pooled_still.parquet", pooled_still)
    write_parquet(out / "per_object_still.parquet", per_object_still)
    write_json(out / "summary.json", summary)
    log.info("%s", summary["answer"])
    return summary
