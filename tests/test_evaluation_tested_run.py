"""Training and testing kept apart (3.5.4): learning.train_model trains and chooses its threshold
on validation and writes no metric; evaluation.tested_run scores the held-out windows it
predicted, pooled and per object, and writes metrics.json."""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import polars as pl
import pytest
from sklearn.metrics import average_precision_score, f1_score

from graspstab.common.io import read_parquet
from graspstab.evaluation.tested_run import split_metrics, train_and_test
from graspstab.learning.train_model import train_model
from tests.test_learning_train import LSTM, TRAIN, write_dataset


@pytest.fixture(scope="module")
def dataset(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return write_dataset(tmp_path_factory.mktemp("ds"), {"train": 20, "val": 20, "test": 20})


def test_training_writes_no_metric_and_the_tested_run_adds_them(dataset, tmp_path) -> None:
    train = {**TRAIN, "max_epochs": 2, "patience": 2}
    run = train_model(dataset, LSTM, train, 0, tmp_path / "trained", checkpoint=False)
    assert not (tmp_path / "trained" / "metrics.json").exists()
    assert not {"val", "test", "val_objects", "test_objects"} & set(run.record)
    assert set(run.predictions["split"].unique()) == {"val", "test"}

    record = train_and_test(dataset, LSTM, train, 0, tmp_path / "tested", checkpoint=False)
    written = json.loads((tmp_path / "tested" / "metrics.json").read_text())
    assert written["test"]["auprc"] == pytest.approx(record["test"]["auprc"])
    # the same training (seeded): the tested run's metrics are those of the trained run's scores
    again = split_metrics(read_parquet(tmp_path / "tested" / "predictions.parquet"),
                          record["threshold"]["threshold"])  # fmt: skip
    assert again["test"] == pytest.approx(record["test"], nan_ok=True)
    assert record["threshold"] == run.record["threshold"]
    # the still-now and moving-now windows (every third window moves, see write_dataset)
    preds = run.predictions.filter(pl.col("split") == "test")
    moving = preds["sample_id"].to_numpy() % 3 == 0
    assert record["test_still"]["n"] + record["test_moving"]["n"] == record["test"]["n"]
    assert record["test_moving"]["n"] == moving.sum()
    y, p = preds["label"].to_numpy(), preds["prob"].to_numpy()
    assert record["test_still"]["auprc"] == pytest.approx(
        average_precision_score(y[~moving], p[~moving]))  # fmt: skip


def test_split_metrics_against_scikit_learn_and_per_object() -> None:
    rng = np.random.default_rng(3)
    n = 200
    split = np.where(np.arange(n) < 80, "val", "test")
    obj = np.where(np.arange(n) % 2 == 0, "a", "b")
    label = (rng.random(n) < 0.4).astype(np.int8)
    logit = rng.normal(label * 1.5, 1.0).astype(np.float32)
    prob = 1.0 / (1.0 + np.exp(-logit.astype(np.float64)))
    frame = pl.DataFrame({"object": obj, "split": split, "label": label, "logit": logit,
                          "prob": prob})  # fmt: skip
    out = split_metrics(frame, 0.5)
    for name in ("val", "test"):
        m = split == name
        assert out[name]["n"] == m.sum() and out[name]["n_unstable"] == label[m].sum()
        assert out[name]["auprc"] == pytest.approx(average_precision_score(label[m], prob[m]))
        assert out[name]["f1"] == pytest.approx(f1_score(label[m], prob[m] >= 0.5))
        for o in ("a", "b"):
            k = m & (obj == o)
            got = out[f"{name}_objects"][o]
            assert got["n"] == k.sum()
            assert got["auprc"] == pytest.approx(average_precision_score(label[k], prob[k]))


def test_a_split_without_windows_has_undefined_metrics() -> None:
    frame = pl.DataFrame({"object": ["a", "a"], "split": ["val", "val"], "label": [0, 1],
                          "logit": [-1.0, 1.0], "prob": [0.27, 0.73]})  # fmt: skip
    out = split_metrics(frame, 0.5)
    assert out["test"]["n"] == 0 and math.isnan(out["test"]["auprc"])
    assert out["test_objects"] == {} and out["val"]["auprc"] == 1.0
