"""train.device and train.mixed_precision: what they resolve to with and without a GPU, and that
mixed precision (bfloat16 autocast, run here on the CPU) trains every family to the same test
metrics as fp32 within a stated tolerance. No test needs a GPU."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np
import pytest
import torch
import yaml
from conftest import CONFIG_DIR, SCHEMA

from graspstab.config import ConfigError, load_config
from graspstab.evaluation.tested_run import train_and_test
from graspstab.learning import device
from graspstab.learning.data import load_window_data
from graspstab.learning.device import resolve
from graspstab.learning.models import build_model
from graspstab.learning.train import TrainSettings, fit, predict_logits, sigmoid
from tests.test_learning_train import CNN, LSTM, TRAIN, write_dataset

GRU: dict[str, Any] = {**LSTM, "family": "gru"}
# bfloat16 keeps 8 bits of mantissa. Trained under autocast, a model takes another path through
# the epochs (another best epoch), so only its metrics can be compared with fp32's: test AUPRC and
# AUROC within METRIC_TOLERANCE. The same weights evaluated under autocast must give nearly the
# same probabilities: at most PROBABILITY_TOLERANCE apart on every test window.
METRIC_TOLERANCE = 0.03
PROBABILITY_TOLERANCE = 0.01


@pytest.fixture(autouse=True)
def _one_thread() -> None:
    torch.set_num_threads(1)


@pytest.fixture(scope="module")
def planted(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return write_dataset(tmp_path_factory.mktemp("planted"), {"train": 30, "val": 30, "test": 30})


def _no_gpu(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(torch.cuda, "is_available", lambda: False)


def test_defaults_are_auto_and_resolve_to_cpu_fp32_without_a_gpu(monkeypatch) -> None:
    _no_gpu(monkeypatch)
    train = yaml.safe_load((CONFIG_DIR / "train" / "default.yaml").read_text())
    settings = TrainSettings.from_config(train, {})
    assert (settings.device, settings.mixed_precision) == ("auto", "auto")
    placement = settings.placement()
    assert placement.device == torch.device("cpu") and placement.amp_dtype is None
    assert placement.describe() == {"device": "cpu", "mixed_precision": False,
                                    "amp_dtype": "float32"}  # fmt: skip
    forced = resolve("cpu", True)
    assert forced.amp_dtype == torch.bfloat16 and not forced.scaler().is_enabled()


def test_auto_takes_cuda_with_autocast_when_a_gpu_is_present(monkeypatch) -> None:
    monkeypatch.setattr(torch.cuda, "is_available", lambda: True)
    for bf16, dtype in ((True, torch.bfloat16), (False, torch.float16)):
        monkeypatch.setattr(torch.cuda, "is_bf16_supported", lambda bf16=bf16: bf16)
        placement = resolve("auto", "auto")
        assert placement.device.type == "cuda" and placement.amp_dtype == dtype
    assert resolve("auto", False).amp_dtype is None
    assert resolve("cpu", "auto") == resolve("cpu", False)  # auto: autocast on CUDA only


def test_native_autocasts_only_where_the_hardware_has_half_precision(monkeypatch) -> None:
    _no_gpu(monkeypatch)
    for has_bf16, dtype in ((True, torch.bfloat16), (False, None)):
        monkeypatch.setattr(device, "cpu_has_native_bf16", lambda has_bf16=has_bf16: has_bf16)
        assert resolve("auto", "native") == resolve("cpu", "native")
        assert resolve("cpu", "native").amp_dtype == dtype
    monkeypatch.setattr(torch.cuda, "is_available", lambda: True)
    monkeypatch.setattr(torch.cuda, "is_bf16_supported", lambda: True)
    assert resolve("auto", "native").amp_dtype == torch.bfloat16  # CUDA, whatever the CPU has


def test_a_model_spec_overrides_the_train_groups_precision() -> None:
    settings = TrainSettings.from_config({**TRAIN, "mixed_precision": "auto"},
                                         {**CNN, "mixed_precision": "native"})  # fmt: skip
    assert settings.mixed_precision == "native"
    cfg = load_config(CONFIG_DIR, SCHEMA, {"model": {"cnn": {"mixed_precision": "native"}}},
                      check_files=False)  # fmt: skip
    assert cfg["model"]["cnn"]["mixed_precision"] == "native"
    with pytest.raises(ConfigError, match="model.lstm.mixed_precision"):
        load_config(CONFIG_DIR, SCHEMA, {"model": {"lstm": {"mixed_precision": "bf16"}}},
                    check_files=False)  # fmt: skip


def test_cuda_without_a_gpu_and_unknown_values_fail_with_the_fix(monkeypatch) -> None:
    _no_gpu(monkeypatch)
    with pytest.raises(RuntimeError, match="train.device: auto"):
        resolve("cuda", "auto")
    with pytest.raises(ValueError, match="train.device = 'gpu'"):
        resolve("gpu", "auto")
    with pytest.raises(ValueError, match="train.mixed_precision = 'fp16'"):
        resolve("auto", "fp16")


def test_the_schema_refuses_an_unknown_device() -> None:
    with pytest.raises(ConfigError, match="train.device"):
        load_config(CONFIG_DIR, SCHEMA, {"train": {"device": "gpu"}}, check_files=False)


@pytest.mark.parametrize("spec", [CNN, GRU, LSTM], ids=lambda s: s["family"])
def test_mixed_precision_matches_fp32_within_tolerance(spec, planted, tmp_path, monkeypatch):
    """Every family trained under bfloat16 autocast on the CPU learns the planted signal and
    scores the test split like fp32 (METRIC_TOLERANCE), and it did run in reduced precision."""
    _no_gpu(monkeypatch)
    records = {}
    for amp in (False, True):
        train = {**TRAIN, "device": "auto", "mixed_precision": amp}
        records[amp] = train_and_test(planted, spec, train, 0, tmp_path / f"amp{amp}",
                                   checkpoint=False)  # fmt: skip
    fp32, amp = records[False], records[True]
    assert fp32["placement"]["amp_dtype"] == "float32"
    assert amp["placement"] == {"device": "cpu", "mixed_precision": True, "amp_dtype": "bfloat16"}
    for metric in ("auprc", "auroc"):
        assert fp32["test"][metric] > 0.95 and amp["test"][metric] > 0.95, metric
        assert abs(amp["test"][metric] - fp32["test"][metric]) <= METRIC_TOLERANCE, metric
    # reduced precision really ran: the two trainings' losses differ
    assert amp["history"][0]["train_loss"] != fp32["history"][0]["train_loss"]


@pytest.mark.parametrize("spec", [CNN, GRU, LSTM], ids=lambda s: s["family"])
def test_autocast_inference_gives_the_fp32_probabilities(spec, planted, monkeypatch) -> None:
    """The same trained weights scored under autocast and in fp32: every test probability within
    PROBABILITY_TOLERANCE, and not all identical (autocast really ran)."""
    _no_gpu(monkeypatch)
    data = load_window_data(planted)
    torch.manual_seed(0)
    model = build_model(spec)
    fit(model, data, TrainSettings.from_config({**TRAIN, "mixed_precision": False}, spec), 0)
    rows = data.rows("test")
    fp32 = sigmoid(predict_logits(model, data, rows, 1024))
    amp = sigmoid(predict_logits(model, data, rows, 1024, resolve("cpu", True)))
    diff = np.abs(amp - fp32)
    print(f"{spec['family']}: max |p_amp - p_fp32| = {diff.max():.4f}")
    assert diff.max() <= PROBABILITY_TOLERANCE, diff.max()
    assert diff.max() > 0


def test_fit_returns_cpu_weights_and_leaves_the_model_on_the_cpu(planted, monkeypatch) -> None:
    _no_gpu(monkeypatch)
    torch.manual_seed(0)
    model = build_model(CNN)
    settings = TrainSettings.from_config({**TRAIN, "max_epochs": 1, "mixed_precision": True}, CNN)
    result = fit(model, load_window_data(planted), settings, 0)
    assert all(t.device.type == "cpu" and t.dtype != torch.bfloat16
               for t in result.state_dict.values())  # fmt: skip
    assert all(p.device.type == "cpu" and p.dtype == torch.float32 for p in model.parameters())
    assert result.placement["mixed_precision"] is True
