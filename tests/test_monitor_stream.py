"""The streaming monitor: batch parity per family, stride and debounce, checkpoint loading."""

from __future__ import annotations

import json
import math
from pathlib import Path
from typing import Any

import numpy as np
import polars as pl
import pytest
import torch
from torch import nn

from graspstab.evaluation.tested_run import train_and_test
from graspstab.learning.data import WindowData
from graspstab.learning.models import build_model
from graspstab.learning.train import sigmoid
from graspstab.monitor.checkpoint import load_monitor, read_trained
from graspstab.monitor.constants import MonitorConstants, MonitorError
from graspstab.monitor.scoring import TorchScorer
from graspstab.monitor.stream import StreamingMonitor, debounced, score_trace, scored_frames
from tests.test_learning_train import LSTM, TRAIN, W, write_dataset

STEPS = 12  # window of the parity models [frames]
# The real architecture classes, small; dropout high so a monitor left in train mode would differ.
SPECS: dict[str, dict[str, Any]] = {
    "cnn": {"family": "cnn", "base_channels": 4, "kernel_sizes": [5, 5, 3], "dropout": 0.5},
    "gru": {"family": "gru", "hidden_size": 8, "num_layers": 2, "bidirectional": True,
            "pooling": "last", "dropout": 0.5},
    "lstm": {"family": "lstm", "hidden_size": 8, "num_layers": 1, "bidirectional": False,
             "pooling": "mean", "dropout": 0.5},
}  # fmt: skip


@pytest.fixture(autouse=True)
def _one_thread() -> None:
    torch.set_num_threads(1)


def _stats(seed: int = 0) -> tuple[np.ndarray, np.ndarray]:
    """Training-like mean/std (5, 2): normal loads of a few newtons, shear a fraction of it."""
    rng = np.random.default_rng(seed)
    mean = np.stack([rng.uniform(1.0, 4.0, 5), rng.uniform(0.1, 1.0, 5)], axis=-1)
    return mean, np.stack([rng.uniform(0.2, 1.0, 5), rng.uniform(0.05, 0.3, 5)], axis=-1)


def _trace(frames: int, mean: np.ndarray, std: np.ndarray, seed: int = 1) -> np.ndarray:
    """A raw (T, 5, 2) force trace around the statistics, with a slow drift."""
    rng = np.random.default_rng(seed)
    drift = np.linspace(-2.0, 2.0, frames)[:, None, None]
    return (mean + std * (rng.normal(size=(frames, 5, 2)) + drift)).astype(np.float32)


def _batch_reference(model: nn.Module, trace: np.ndarray, mean: Any, std: Any) -> np.ndarray:
    """Every full window of ``trace`` scored in one batch, normalised by ``WindowData.batch``."""
    windows = np.stack([trace[t - STEPS + 1 : t + 1] for t in range(STEPS - 1, len(trace))])
    data = WindowData(windows=windows, index=pl.DataFrame(), mean=np.asarray(mean),
                      std=np.asarray(std), source=Path("."))  # fmt: skip
    model.eval()
    with torch.inference_mode():
        logits = model(data.batch(np.arange(len(windows)))).double().numpy()
    return sigmoid(logits)


@pytest.mark.parametrize("family", list(SPECS))
def test_frame_by_frame_matches_batch_scoring(family: str) -> None:
    torch.manual_seed(0)
    model = build_model(SPECS[family]).train()  # the monitor must switch it to eval
    mean, std = _stats()
    trace = _trace(4 * STEPS + 5, mean, std)  # the ring wraps several times
    monitor = StreamingMonitor(model, mean, std, 0.5, STEPS)
    got = [monitor.push(frame).prob for frame in trace]
    assert got[: STEPS - 1] == [None] * (STEPS - 1)
    reference = _batch_reference(model, trace, mean, std)
    np.testing.assert_allclose(np.array(got[STEPS - 1 :], dtype=float), reference,
                               rtol=0, atol=1e-6)  # fmt: skip
    assert reference.std() > 1e-4  # a trace that moves the score, so the check bites
    # run() from a reset gives the same, NaN before the buffer is full
    again = monitor.run(trace)
    assert np.isnan(again.prob[: STEPS - 1]).all()
    np.testing.assert_allclose(again.prob[STEPS - 1 :], reference, rtol=0, atol=1e-6)


def test_stride_scores_every_kth_frame_from_the_first_full_window() -> None:
    torch.manual_seed(0)
    model = build_model(SPECS["lstm"])
    mean, std = _stats()
    trace = _trace(3 * STEPS, mean, std)
    out = StreamingMonitor(model, mean, std, 0.5, STEPS, stride=5).run(trace)
    scored = np.flatnonzero(~np.isnan(out.prob))
    np.testing.assert_array_equal(scored, np.arange(STEPS - 1, len(trace), 5))
    reference = _batch_reference(model, trace, mean, std)
    np.testing.assert_allclose(out.prob[scored], reference[scored - (STEPS - 1)], atol=1e-6)


@pytest.mark.parametrize("family", list(SPECS))
@pytest.mark.parametrize(("stride", "debounce"), [(1, 1), (3, 1), (4, 3)])
def test_batched_trace_scoring_equals_the_frame_by_frame_monitor(
    family: str, stride: int, debounce: int
) -> None:
    torch.manual_seed(1)
    model = build_model(SPECS[family])
    mean, std = _stats()
    trace = _trace(5 * STEPS + 3, mean, std, seed=2)
    probs = StreamingMonitor(model, mean, std, 0.5, STEPS, stride=stride).run(trace).prob
    # a threshold between two neighbouring scores near the median: about half the scores are
    # unstable and none sits within float noise of the threshold
    ranked = np.sort(probs[np.isfinite(probs)])
    gaps = np.diff(ranked)
    mid = len(ranked) // 2
    i = mid + int(np.argmax(gaps[mid:] > 1e-5))
    threshold = float(ranked[i] + gaps[i] / 2)
    streamed = StreamingMonitor(model, mean, std, threshold, STEPS, stride=stride,
                                debounce=debounce).run(trace)  # fmt: skip
    scorer = TorchScorer(model, MonitorConstants(mean, std, threshold, STEPS))
    # batches of 7 windows: the chunking must not matter
    batched = score_trace(scorer, trace, stride=stride, debounce=debounce, batch_size=7)
    np.testing.assert_array_equal(np.isnan(batched.prob), np.isnan(streamed.prob))
    np.testing.assert_allclose(batched.prob, streamed.prob, rtol=0, atol=1e-6, equal_nan=True)
    np.testing.assert_array_equal(batched.warning, streamed.warning)
    assert streamed.warning.any() and not streamed.warning.all()  # the rule is exercised


def test_batched_scoring_of_a_trace_shorter_than_the_window_scores_nothing() -> None:
    scorer = TorchScorer(LastValue(), MonitorConstants(np.zeros((5, 2)), np.ones((5, 2)), 0.5, 5))
    out = score_trace(scorer, np.ones((4, 5, 2)))
    assert np.isnan(out.prob).all() and not out.warning.any()
    assert scored_frames(4, 5, 1).size == 0
    np.testing.assert_array_equal(scored_frames(12, 5, 3), [4, 7, 10])


def test_debounced_counts_consecutive_unstable_scores() -> None:
    flags = np.array([1, 1, 0, 1, 1, 1, 0, 1], dtype=bool)
    assert debounced(flags, 1).tolist() == flags.tolist()
    assert debounced(flags, 2).tolist() == [0, 1, 0, 0, 1, 1, 0, 0]
    assert debounced(flags, 3).tolist() == [0, 0, 0, 0, 0, 1, 0, 0]
    assert debounced(np.zeros(0, dtype=bool), 2).size == 0


class LastValue(nn.Module):
    """Stub classifier: the logit is the last frame's first fingertip's normal force."""

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        return x[:, -1, 0, 0]


def _stub_monitor(logits: list[float], **kwargs: Any) -> tuple[np.ndarray, np.ndarray]:
    """Per-frame (prob, warning) of a 3-frame-window stub monitor whose frame t scores
    sigmoid(logits[t]) (mean 0, std 1: raw equals normalised)."""
    trace = np.zeros((len(logits), 5, 2), dtype=np.float32)
    trace[:, 0, 0] = logits
    monitor = StreamingMonitor(LastValue(), np.zeros((5, 2)), np.ones((5, 2)), 0.5, 3, **kwargs)
    out = monitor.run(trace)
    return out.prob, out.warning


def test_debounce_needs_k_consecutive_scores_and_drops_on_a_stable_one() -> None:
    logits = [0.0, 0.0, 1.0, -1.0, 1.0, 1.0, 1.0, -1.0, 1.0, 1.0]
    prob, warning = _stub_monitor(logits, debounce=2)
    expected = [np.nan, np.nan] + [1 / (1 + math.exp(-v)) for v in logits[2:]]
    np.testing.assert_allclose(prob, expected, rtol=1e-12)
    assert warning.tolist() == [False] * 5 + [True, True, False, False, True]
    _, once = _stub_monitor(logits)  # debounce 1: every unstable score warns
    assert once.tolist() == [False, False, True, False, True, True, True, False, True, True]


def test_stride_and_debounce_count_scores_and_hold_between_them() -> None:
    logits = [0.0, 0.0, 1.0, -1.0, 1.0, 1.0, -1.0, 1.0, 1.0, 1.0]
    prob, warning = _stub_monitor(logits, stride=2, debounce=2)
    assert np.flatnonzero(~np.isnan(prob)).tolist() == [2, 4, 6, 8]
    # scores: t2 unstable, t4 unstable -> warn (held at t5), t6 stable -> drop, t8 unstable (1 of 2)
    assert warning.tolist() == [False] * 4 + [True, True, False, False, False, False]


def test_probability_at_the_threshold_is_unstable() -> None:
    _, warning = _stub_monitor([0.0, 0.0, 0.0])  # sigmoid(0) = 0.5 = threshold
    assert warning.tolist() == [False, False, True]


def test_reset_starts_a_new_episode() -> None:
    monitor = StreamingMonitor(LastValue(), np.zeros((5, 2)), np.ones((5, 2)), 0.5, 3)
    for _ in range(4):
        step = monitor.push(np.ones((5, 2)))
    assert step.prob is not None and step.warning and monitor.frames_seen == 4
    monitor.reset()
    assert monitor.push(np.ones((5, 2))) == (None, False) and monitor.frames_seen == 1


@pytest.mark.parametrize("shape", [(5,), (2, 5), (10,), (1, 5, 2), (5, 3)])
def test_wrong_frame_shape_is_a_clear_error(shape: tuple[int, ...]) -> None:
    monitor = StreamingMonitor(LastValue(), np.zeros((5, 2)), np.ones((5, 2)), 0.5, 3)
    with pytest.raises(MonitorError, match=r"shape \(5, 2\)"):
        monitor.push(np.zeros(shape))


def test_bad_trace_and_nonfinite_frames_are_errors() -> None:
    monitor = StreamingMonitor(LastValue(), np.zeros((5, 2)), np.ones((5, 2)), 0.5, 3)
    with pytest.raises(MonitorError, match=r"\(T, 5, 2\)"):
        monitor.run(np.zeros((10, 2, 5)))
    frame = np.zeros((5, 2))
    frame[3, 1] = np.nan
    with pytest.raises(MonitorError, match="non-finite"):
        monitor.push(frame)
    trace = np.zeros((6, 5, 2))
    trace[4, 0, 0] = np.inf
    with pytest.raises(MonitorError, match="frame 4 has a non-finite"):
        monitor.run(trace)


@pytest.mark.parametrize(
    ("mean", "std", "kwargs", "message"),
    [
        (np.zeros((2, 5)), np.ones((5, 2)), {}, r"mean must have shape \(5, 2\)"),
        (np.zeros((5, 2)), np.ones(10), {}, r"std must have shape \(5, 2\)"),
        (np.zeros((5, 2)), np.zeros((5, 2)), {}, "std must be positive"),
        (np.zeros((5, 2)), np.ones((5, 2)), {"stride": 0}, "stride must be a positive"),
        (np.zeros((5, 2)), np.ones((5, 2)), {"debounce": 1.5}, "debounce must be a positive"),
        (np.zeros((5, 2)), np.ones((5, 2)), {"threshold": 1.5}, r"lie in \[0, 1\]"),
        (np.zeros((5, 2)), np.ones((5, 2)), {"threshold": math.nan}, "undefined"),
    ],
)
def test_bad_constants_are_clear_errors(
    mean: np.ndarray, std: np.ndarray, kwargs: dict[str, Any], message: str
) -> None:
    threshold = kwargs.pop("threshold", 0.5)
    with pytest.raises(MonitorError, match=message):
        StreamingMonitor(LastValue(), mean, std, threshold, 3, **kwargs)


def test_batch_scorer_rejects_windows_of_another_length() -> None:
    scorer = TorchScorer(LastValue(), MonitorConstants(np.zeros((5, 2)), np.ones((5, 2)), 0.5, 3))
    with pytest.raises(MonitorError, match=r"\(B, 3, 5, 2\)"):
        scorer(np.zeros((2, 4, 5, 2)))


# -- a real checkpoint written by the learning stage --------------------------------------------


@pytest.fixture(scope="module")
def trained(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, Path]:
    """(dataset, run) of one short LSTM training on a small planted dataset."""
    torch.set_num_threads(1)
    data = write_dataset(tmp_path_factory.mktemp("data"), {"train": 12, "val": 12, "test": 12})
    run = tmp_path_factory.mktemp("run")
    train_and_test(data, LSTM, {**TRAIN, "max_epochs": 2, "patience": 2}, 0, run)
    return data, run


def test_load_monitor_reproduces_the_runs_own_test_predictions(trained: tuple[Path, Path]) -> None:
    data, run = trained
    monitor = load_monitor(run / "model.pt", run / "metrics.json", data / "normalisation.json")
    metrics = json.loads((run / "metrics.json").read_text())
    stored = json.loads((data / "normalisation.json").read_text())
    assert monitor.threshold == metrics["threshold"]["threshold"]
    assert monitor.window_steps == W and monitor.constants.family == "lstm"
    np.testing.assert_array_equal(monitor.constants.mean, stored["mean"])
    np.testing.assert_array_equal(monitor.constants.std, stored["std"])
    windows = np.load(data / "windows.npy")
    predictions = pl.read_parquet(run / "predictions.parquet").filter(pl.col("split") == "test")
    for sample, prob in predictions.select("sample_id", "prob").head(8).iter_rows():
        out = monitor.run(windows[sample])  # exactly one window: scored on its last frame
        assert np.isnan(out.prob[:-1]).all()
        assert out.prob[-1] == pytest.approx(prob, abs=1e-6)


def test_loader_fills_missing_normalisation_and_rejects_contradictions(
    trained: tuple[Path, Path], tmp_path: Path
) -> None:
    data, run = trained
    ckpt = torch.load(run / "model.pt", weights_only=True)
    old = {k: v for k, v in ckpt.items() if k not in ("mean", "std", "threshold")}
    torch.save(old, tmp_path / "old.pt")
    with pytest.raises(MonitorError, match="normalisation.json"):
        read_trained(tmp_path / "old.pt", run / "metrics.json")
    _, constants = read_trained(tmp_path / "old.pt", run / "metrics.json",
                                data / "normalisation.json")  # fmt: skip
    np.testing.assert_array_equal(constants.mean, ckpt["mean"])
    assert constants.threshold == ckpt["threshold"]
    _, overridden = read_trained(run / "model.pt", threshold=0.9)
    assert overridden.threshold == 0.9
    other = json.loads((data / "normalisation.json").read_text())
    other["std"][0][0] *= 2
    (tmp_path / "other.json").write_text(json.dumps(other))
    with pytest.raises(MonitorError, match="std differs"):
        read_trained(run / "model.pt", normalisation_json=tmp_path / "other.json")
    metrics = json.loads((run / "metrics.json").read_text())
    metrics["threshold"]["threshold"] = 0.123
    (tmp_path / "metrics.json").write_text(json.dumps(metrics))
    with pytest.raises(MonitorError, match="threshold differs"):
        read_trained(run / "model.pt", tmp_path / "metrics.json")
