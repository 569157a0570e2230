"""Train one model on one dataset for one seed and choose its threshold on validation.

The training half of the per-seed procedure of 3.5.4: initialise, train with early stopping, keep
the best validation epoch, choose the decision threshold on validation only (3.5.3), and score
the validation and test windows. Writes ``predictions.parquet`` (the validation and test scores,
which the evaluation turns into metrics and the figures into calibration and threshold-transfer
plots) and, when asked, a checkpoint carrying its model arguments, normalisation and config; the
test half (metrics on those scores, ``metrics.json``) is ``graspstab.evaluation.tested_run``.
"""

from __future__ import annotations

import logging
import math
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import polars as pl
import torch

from graspstab.common.io import atomic_path, write_parquet
from graspstab.common.logs import setup_logging
from graspstab.common.provenance import code_version, compute_platform, stable_hash, write_timing
from graspstab.learning.augmentation import attach
from graspstab.learning.data import WindowData, load_window_data
from graspstab.learning.features import window_transform
from graspstab.learning.models import build_model, count_parameters
from graspstab.learning.train import TrainSettings, fit, predict_logits, sigmoid
from graspstab.metrics.classification import (
    UNDEFINED_THRESHOLD,
    ThresholdChoice,
    select_threshold,
    threshold_grid,
)

log = logging.getLogger("graspstab.learning")


def threshold_settings(train: Mapping[str, Any], model: Mapping[str, Any]) -> dict[str, Any]:
    """The threshold rule of a run: the train group's, unless the (tuned) model spec sets
    ``threshold_rule`` or ``min_recall`` (table 4.1 lets Optuna search them)."""
    t = dict(train["threshold"])
    return {
        "grid": list(t["grid"]),
        "rule": model.get("threshold_rule", t.get("rule", "min_recall")),
        "min_recall": float(model.get("min_recall", t["min_recall"])),
    }


def predict_splits(
    model: torch.nn.Module, data: WindowData, threshold: Mapping[str, Any], batch_size: int
) -> tuple[dict[str, Any], pl.DataFrame]:
    """Choose the threshold on validation (3.5.3), and score the validation and test windows:
    the threshold choice and one row per window (an empty split has none)."""
    scores: dict[str, tuple[np.ndarray, np.ndarray, np.ndarray]] = {}
    for split in ("val", "test"):
        rows = data.rows(split)
        scores[split] = (rows, predict_logits(model, data, rows, batch_size), data.labels(rows))
    _, val_logits, val_labels = scores["val"]
    if len(val_labels):
        choice = select_threshold(
            sigmoid(val_logits),
            val_labels,
            threshold_grid(*threshold["grid"]),
            min_recall=threshold["min_recall"],
            rule=threshold["rule"],
        )
    else:
        log.warning("no validation window: the threshold is undefined (0.5 used)")
        choice = ThresholdChoice(UNDEFINED_THRESHOLD, "undefined", math.nan, math.nan, math.nan)
    frames = []
    for split, (rows, logits, labels) in scores.items():
        if len(rows) == 0:
            log.warning("no %s window in this split assignment: its metrics are undefined", split)
            continue
        frames.append(
            pl.DataFrame(
                {
                    "sample_id": data.index["sample_id"].to_numpy()[rows],
                    "object": data.objects(rows),
                    "split": [split] * len(rows),
                    "label": labels.astype(np.int8),
                    "logit": logits,
                    "prob": sigmoid(logits),
                }
            )
        )
    return {**vars(choice), "min_recall": threshold["min_recall"]}, pl.concat(frames)


@dataclass(frozen=True)
class TrainedRun:
    """A trained run: its record (without test metrics) and its validation and test scores."""

    record: dict[str, Any]
    predictions: pl.DataFrame


def train_model(
    dataset_dir: str | Path,
    model_spec: Mapping[str, Any],
    train: Mapping[str, Any],
    seed: int,
    out_dir: str | Path,
    *,
    assignment: Mapping[str, str] | None = None,
    threads: int = 1,
    checkpoint: bool = True,
    extra: Mapping[str, Any] | None = None,
    augment: Mapping[str, Any] | None = None,
    features: Mapping[str, Any] | None = None,
    log_file: str | Path | None = None,
    timing_path: str | Path | None = None,
) -> TrainedRun:
    """Train, choose the threshold and score the held-out windows; write the predictions (and
    checkpoint) into ``out_dir`` and return the run's record without its test metrics, which
    ``graspstab.evaluation.tested_run`` adds (``extra`` keys, e.g. the split assignment's
    number, are stored with them). The run's
    timings (training seconds, per epoch) differ on every run: they go to the timing sidecar
    ``timing_path`` (when given) and the log, never into ``metrics.json``. ``augment``
    (sensing, trace_paths, trace_keys, dt) trains through the sensing group's sensors
    (graspstab.learning.augmentation); validation and test stay clean."""
    setup_logging(log_file)
    torch.set_num_threads(max(1, int(threads)))
    out = Path(out_dir)
    params = {"model": dict(model_spec), "train": dict(train), "seed": int(seed),
              "assignment": dict(assignment) if assignment else None}  # fmt: skip
    if features:
        params["features"] = dict(features)  # only then, so earlier runs keep their hash
    data = load_window_data(dataset_dir, assignment, transform=window_transform(features))
    if augment is not None:
        params["augment"] = {k: augment[k] for k in ("sensing", "dt")}
        attach(data, augment["sensing"], augment["trace_paths"], augment["trace_keys"],
               float(augment["dt"]), int(seed))  # fmt: skip
    counts = {s: dict(zip(("stable", "unstable"), data.class_counts(s), strict=True))
              for s in ("train", "val", "test")}  # fmt: skip
    log.info("dataset %s: W=%d, %s", dataset_dir, data.window_steps, counts)
    settings = TrainSettings.from_config(train, model_spec)
    torch.manual_seed(seed)
    # the dataset's input layout: 5 fingertips x 2 channels, or an input set's 1 x F
    inputs = {"fingertips": int(data.windows.shape[2]), "channels": data.channels}
    model = build_model(model_spec, **inputs)
    n_params = count_parameters(model)
    log.info("%s: %d trainable parameters, %s", model_spec["family"], n_params, settings)
    result = fit(model, data, settings, seed)
    threshold, predictions = predict_splits(
        model, data, threshold_settings(train, model_spec), settings.eval_batch_size
    )
    record = {
        "family": model_spec["family"],
        "seed": int(seed),
        "parameters": n_params,
        "inputs": inputs,
        "window_steps": data.window_steps,
        "dataset": str(dataset_dir),
        "counts": counts,
        "best_epoch": result.best_epoch,
        "epochs_run": len(result.history),
        "stopped_early": result.stopped_early,
        "selection_metric": result.selection_metric,
        "placement": result.placement,
        "history": [{k: v for k, v in row.items() if k != "seconds"} for row in result.history],
        "threshold": threshold,
        **dict(extra or {}),
        "code_version": code_version("learning", "labels"),
        "platform": compute_platform(),
        "params": params,
        "params_hash": stable_hash(params),
    }
    log.info("best epoch %d (%s); threshold %.3f (%s)", result.best_epoch,
             result.selection_metric, threshold["threshold"], threshold["rule"])  # fmt: skip
    write_parquet(out / "predictions.parquet", predictions)
    if checkpoint:
        # through a file object: given a path, torch names the archive's folder after the file,
        # here the temporary one (a random name), and no two saves would be the same bytes
        with atomic_path(out / "model.pt") as tmp, open(tmp, "wb") as fh:
            torch.save(
                {
                    "state_dict": result.state_dict,
                    "model": dict(model_spec),
                    "window_steps": data.window_steps,
                    "inputs": inputs,
                    "mean": data.mean.tolist(),
                    "std": data.std.tolist(),
                    "threshold": threshold["threshold"],
                    "params": params,
                },
                fh,
            )
    write_timing(timing_path, {
        "train_seconds": result.seconds,
        "seconds_per_epoch": result.seconds / max(len(result.history), 1),
        "epoch_seconds": [row["seconds"] for row in result.history],
    })  # fmt: skip
    return TrainedRun(record, predictions)
