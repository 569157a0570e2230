"""Incremental CNN scoring equals the batch model on every window (independent reference: the
eager model scoring each full window in one batch)."""

from __future__ import annotations

from typing import Any

import numpy as np
import pytest
import torch
from torch import nn

from graspstab.learning.models import build_model
from graspstab.monitor.constants import MonitorConstants, MonitorError
from graspstab.monitor.incremental import IncrementalCNNScorer
from graspstab.monitor.scoring import TorchScorer
from graspstab.monitor.stream import StreamingMonitor, score_trace
from tests.test_monitor_stream import _stats, _trace

# even kernels: PyTorch warns that "same" padding copies the input; the case is tested on purpose
pytestmark = pytest.mark.filterwarnings("ignore:Using padding='same' with even kernel")


@pytest.fixture(autouse=True)
def _one_thread() -> None:
    torch.set_num_threads(1)


def _cnn(kernel_sizes: list[int], base: int = 6, seed: int = 0) -> nn.Module:
    """A small CNN with non-trivial BatchNorm statistics (so folding them in is checked)."""
    torch.manual_seed(seed)
    model = build_model({"family": "cnn", "base_channels": base, "kernel_sizes": kernel_sizes,
                         "dropout": 0.5})  # fmt: skip
    with torch.no_grad():
        for mod in model.modules():
            if isinstance(mod, nn.BatchNorm1d):
                mod.running_mean.uniform_(-1.0, 1.0)
                mod.running_var.uniform_(0.3, 3.0)
                mod.weight.uniform_(0.5, 1.5)
                mod.bias.uniform_(-0.5, 0.5)
    return model.train()  # the scorer must evaluate it in eval mode


def _batch_probs(model: nn.Module, trace: np.ndarray, steps: int, c: MonitorConstants) -> Any:
    """Every full window of the trace scored at once by the eager model."""
    windows = np.lib.stride_tricks.sliding_window_view(trace, steps, axis=0)
    return TorchScorer(model.eval(), c)(np.moveaxis(windows, -1, 1))


@pytest.mark.parametrize(
    ("kernel_sizes", "steps"),
    [([5, 5, 3], 12), ([5, 5, 3], 40), ([3], 5), ([4, 3, 6], 17), ([2, 7], 11)],
)
def test_incremental_scores_equal_the_batch_model_on_every_window(
    kernel_sizes: list[int], steps: int
) -> None:
    model = _cnn(kernel_sizes)
    mean, std = _stats()
    c = MonitorConstants(mean, std, 0.5, steps)
    trace = _trace(5 * steps + 3, mean, std)  # every ring wraps several times
    monitor = StreamingMonitor.from_scorer(IncrementalCNNScorer(model, c))
    got = [monitor.push(frame).prob for frame in trace]
    assert got[: steps - 1] == [None] * (steps - 1)
    reference = _batch_probs(model, trace, steps, c)
    assert reference.std() > 1e-3  # the trace moves the score, so the check bites
    np.testing.assert_allclose(np.array(got[steps - 1 :], dtype=float), reference,
                               rtol=0, atol=1e-6)  # fmt: skip


@pytest.mark.parametrize(("stride", "debounce"), [(1, 1), (3, 2), (7, 1)])
def test_incremental_monitor_equals_the_window_monitor_and_resets(stride: int, debounce: int):
    model = _cnn([5, 5, 3])
    mean, std = _stats(3)
    trace = _trace(90, mean, std, seed=4)
    probs = _batch_probs(model, trace, 16, MonitorConstants(mean, std, 0.5, 16))
    c = MonitorConstants(mean, std, float(np.median(probs)), 16)  # crossed both ways
    inc = StreamingMonitor.from_scorer(IncrementalCNNScorer(model, c), stride=stride,
                                       debounce=debounce)  # fmt: skip
    inc.run(_trace(37, mean, std, seed=9))  # state from another episode, then run() resets
    got = inc.run(trace)
    ref = score_trace(TorchScorer(model.eval(), c), trace, stride=stride, debounce=debounce)
    np.testing.assert_array_equal(np.isnan(got.prob), np.isnan(ref.prob))
    np.testing.assert_allclose(got.prob[~np.isnan(got.prob)], ref.prob[~np.isnan(ref.prob)],
                               rtol=0, atol=1e-6)  # fmt: skip
    np.testing.assert_array_equal(got.warning, ref.warning)
    assert got.warning.any() and not got.warning.all()  # the threshold is crossed both ways


def test_batch_calls_and_score_one_use_the_eager_model() -> None:
    model = _cnn([5, 5, 3])
    mean, std = _stats()
    c = MonitorConstants(mean, std, 0.5, 12)
    scorer = IncrementalCNNScorer(model, c)
    windows = np.stack([_trace(12, mean, std, seed=s) for s in range(3)])
    np.testing.assert_array_equal(scorer(windows), TorchScorer(model, c)(windows))
    assert scorer.score_one(windows[1]) == TorchScorer(model, c).score_one(windows[1])


def test_incremental_scoring_refuses_what_it_cannot_do() -> None:
    mean, std = _stats()
    with pytest.raises(MonitorError, match="too short"):
        # kernels 5, 5, 3 reach 5 positions in from each end: 10 frames leave no clean position
        IncrementalCNNScorer(_cnn([5, 5, 3]), MonitorConstants(mean, std, 0.5, 10))
    lstm = build_model({"family": "lstm", "hidden_size": 4, "num_layers": 1})
    with pytest.raises(MonitorError, match="CNN family"):
        IncrementalCNNScorer(lstm, MonitorConstants(mean, std, 0.5, 12))
    scorer = IncrementalCNNScorer(_cnn([3]), MonitorConstants(mean, std, 0.5, 6))
    with pytest.raises(MonitorError, match="a score needs 6"):
        scorer.score_window()
