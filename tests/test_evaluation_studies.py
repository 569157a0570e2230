"""Split assignments, multi-seed aggregation and latency (thesis 4.3-4.5): the evaluation
package's study statistics against hand-computed values."""

from __future__ import annotations

import numpy as np
import polars as pl
import pytest
import torch
import yaml
from conftest import CONFIG_DIR

from graspstab.evaluation import aggregate
from graspstab.evaluation.latency import measure_latency
from graspstab.evaluation.splits import all_assignments, assignment_key, sample_assignments
from graspstab.learning.models import build_model

W = 20  # timesteps per window
LSTM = {"family": "lstm", "hidden_size": 16, "num_layers": 1, "bidirectional": False,
        "pooling": "mean", "dropout": 0.0, "learning_rate": 1e-2}  # fmt: skip


# -- split assignments ----------------------------------------------------------------------------


def test_sample_assignments_of_reference_split() -> None:
    items = yaml.safe_load((CONFIG_DIR / "objects" / "ycb12.yaml").read_text())["items"]
    fixed = {obj: item["split"] for obj, item in items.items()}
    assert sorted(fixed.values()).count("train") == 8
    picks = sample_assignments(fixed, 30, seed=0)
    assert len(picks) == 30 and picks[0] == fixed
    keys = {
        assignment_key(*([o for o, s in a.items() if s == r] for r in ("val", "test")))
        for a in picks
    }
    assert len(keys) == 30
    for a in picks:
        assert set(a) == set(fixed)
        assert sorted(a.values()) == ["test"] * 2 + ["train"] * 8 + ["val"] * 2
    assert sample_assignments(fixed, 30, seed=0) == picks
    other = sample_assignments(fixed, 30, seed=1)
    assert other[0] == fixed and other != picks
    assert len(all_assignments(list(fixed))) == 2970


# -- aggregation and latency ----------------------------------------------------------------------


def test_mean_std_ignores_nan() -> None:
    values = [0.8, 0.9, float("nan"), 0.7]
    frame = pl.DataFrame({"family": ["lstm"] * 4 + ["cnn"] * 2, "seed": [1, 2, 3, 4, 1, 2],
                          "auprc": values + [0.5, 0.6]})  # fmt: skip
    out = aggregate.mean_std(frame, ["family"], ["auprc"]).row(1, named=True)
    assert out["family"] == "lstm" and out["seeds"] == 4 and out["auprc_n"] == 3
    assert out["auprc_mean"] == pytest.approx(np.nanmean(values))
    assert out["auprc_std"] == pytest.approx(np.std([0.8, 0.9, 0.7], ddof=1))


def test_latency_aware_choice_prefers_faster_within_one_std() -> None:
    table = pl.DataFrame({
        "family": ["gru", "lstm", "cnn", "cnn"],
        "window_s": [0.2, 0.05, 0.01, 0.005],
        "val_auprc_mean": [0.90, 0.87, 0.80, float("nan")],
        "val_auprc_std": [0.05, 0.02, 0.01, float("nan")],
        "total_latency_ms": [300.0, 60.0, 20.0, 6.0],
    })  # fmt: skip
    choice = aggregate.latency_aware_choice(table)
    assert choice["defined"] and choice["cutoff"] == pytest.approx(0.85)
    assert choice["best"]["family"] == "gru"
    assert (choice["pick"]["family"], choice["pick"]["window_s"]) == ("lstm", 0.05)
    # Without a std across seeds only the best itself qualifies.
    single = aggregate.latency_aware_choice(table.with_columns(pl.lit(None).alias("val_auprc_std")))
    assert single["pick"]["family"] == "gru"
    assert not aggregate.latency_aware_choice(table.tail(1))["defined"]


def test_split_summary_statistics() -> None:
    per = {0: [0.80, 0.84], 1: [0.60, 0.70], 2: [0.90, 0.92], 3: [0.50, float("nan")]}
    frame = pl.DataFrame({
        "assignment": [a for a in per for _ in range(2)],
        "val_objects": [f"v{a}" for a in per for _ in range(2)],
        "test_objects": [f"t{a}" for a in per for _ in range(2)],
        "seed": [42, 43] * 4,
        "auprc": [v for vs in per.values() for v in vs],
    })  # fmt: skip
    summary = aggregate.split_summary(frame, hardest=2)
    means = np.array([0.82, 0.65, 0.91, 0.50])
    assert summary["assignments"] == 4 and summary["defined"] == 4
    assert summary["mean"] == pytest.approx(means.mean())
    assert summary["std"] == pytest.approx(means.std(ddof=1))
    assert summary["median"] == pytest.approx(np.median(means))
    assert summary["min"] == pytest.approx(0.50)
    assert summary["fixed_split"] == pytest.approx(0.82)
    assert [h["assignment"] for h in summary["hardest"]] == [3, 1]
    assert summary["per_assignment"][3]["seeds"] == 2
    assert "still" not in summary  # runs written without still-now columns
    # with them: the same statistics of the still-now test AUPRC, per assignment its windows
    still = frame.with_columns((pl.col("auprc") - 0.1).alias("still_auprc"),
                               pl.lit(30).alias("still_n"), pl.lit(6).alias("still_n_unstable"),
                               pl.lit(0.2).alias("still_chance"))  # fmt: skip
    got = aggregate.split_summary(still, hardest=2)
    assert got["still"]["mean"] == pytest.approx((means - 0.1).mean())
    assert got["still"]["fixed_split"] == pytest.approx(0.72)
    assert got["per_assignment"][1]["still_n_unstable"] == 6
    assert got["mean"] == summary["mean"]  # the all-window figures do not move


def test_error_table_rates() -> None:
    frame = pl.DataFrame({
        "family": ["lstm", "lstm", "cnn", "cnn", "lstm"],
        "split": ["test", "test", "test", "test", "val"],
        "seed": [42, 43, 42, 43, 42],
        "fp": [10, 20, 4, 6, 99],
        "fn": [3, 5, 8, 8, 99],
        "n": [200, 200, 200, 200, 50],
        "n_unstable": [40, 40, 40, 40, 10],
    })  # fmt: skip
    table = aggregate.error_table(frame)
    assert table["family"].to_list() == ["cnn", "lstm"]
    lstm = table.row(1, named=True)
    assert (lstm["fp_mean"], lstm["fn_mean"]) == (15.0, 4.0)
    assert lstm["fp_std"] == pytest.approx(np.std([10, 20], ddof=1))
    assert (lstm["stable"], lstm["unstable"]) == (160, 40)
    assert lstm["false_positive_rate"] == pytest.approx(15 / 160)
    assert lstm["miss_rate"] == pytest.approx(4 / 40)


def test_measure_latency() -> None:
    torch.set_num_threads(1)  # the reference's setting (4.5); the report states the count
    m = measure_latency(build_model(LSTM), W, repeats=20, warmup=2)
    assert m["median_ms"] > 0 and m["repeats"] == 20 and m["threads"] == 1
    assert m["throughput_per_s"] == pytest.approx(1000.0 / m["median_ms"])
