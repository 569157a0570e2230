"""The per-seed procedure of 3.5.4 as one job: train (``learning.train_model``, which chooses the
best epoch and the threshold on validation only), then test once: the validation and test
metrics, pooled and per object, at that threshold, and the ranking metrics of the still-now and
moving-now windows (``evaluation.detection``), written as the run's ``metrics.json``."""

from __future__ import annotations

import logging
import math
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import numpy as np
import polars as pl

from graspstab.common.io import write_json
from graspstab.evaluation.detection import motion_blocks, still_now
from graspstab.labels.dataset import load_motion
from graspstab.learning.train_model import train_model
from graspstab.metrics.classification import METRIC_KEYS, binary_metrics, per_object_metrics

log = logging.getLogger("graspstab.evaluation")

SPLITS = ("val", "test")


def split_metrics(
    predictions: pl.DataFrame, threshold: float, still: np.ndarray | None = None
) -> dict[str, Any]:
    """Metrics of each held-out split's windows (``<split>``) and of each of its objects
    (``<split>_objects``) at ``threshold``; a split without windows has undefined metrics. With
    ``still`` (per sample id: the object still over the observation period), also the ranking
    metrics of its still-now and moving-now windows (``<split>_still``, ``<split>_moving``)."""
    out: dict[str, Any] = {}
    for split in SPLITS:
        rows = predictions.filter(pl.col("split") == split)
        if still is not None:
            ids = rows["sample_id"].to_numpy()
            out.update(motion_blocks(rows["prob"].to_numpy(), rows["label"].to_numpy(),
                                     still[ids], split))  # fmt: skip
        if rows.height == 0:
            out[split] = {k: math.nan for k in METRIC_KEYS} | {"n": 0, "n_unstable": 0}
            out[f"{split}_objects"] = {}
            continue
        probs, labels = rows["prob"].to_numpy(), rows["label"].to_numpy()
        logits, objects = rows["logit"].to_numpy(), rows["object"].to_numpy()
        out[split] = binary_metrics(probs, labels, threshold, logits=logits)
        out[f"{split}_objects"] = per_object_metrics(
            probs, labels, objects, threshold, logits=logits
        )
    return out


def train_and_test(
    dataset_dir: str | Path,
    model_spec: Mapping[str, Any],
    train: Mapping[str, Any],
    seed: int,
    out_dir: str | Path,
    **options: Any,
) -> dict[str, Any]:
    """Train one model x dataset x seed (``options``: those of ``learning.train_model``), score
    its held-out windows, write ``metrics.json`` beside its predictions and return the record."""
    run = train_model(dataset_dir, model_spec, train, seed, out_dir, **options)
    still = still_now(load_motion(dataset_dir))
    metrics = split_metrics(run.predictions, run.record["threshold"]["threshold"], still)
    record = {**run.record, **metrics}
    log.info("val AUPRC %.4f, test AUPRC %.4f (still now: %.4f of %d windows, %d unstable), "
             "test F1 %.4f", record["val"]["auprc"], record["test"]["auprc"],
             record["test_still"]["auprc"], record["test_still"]["n"],
             record["test_still"]["n_unstable"], record["test"]["f1"])  # fmt: skip
    write_json(Path(out_dir) / "metrics.json", record)
    return record

