"""Model architectures (thesis 3.4): shapes, parameter counts, gradient flow and pooling."""

from __future__ import annotations

import warnings
from typing import Any

import pytest
import torch
from torch import nn

from graspstab.learning.models import (
    CNNClassifier,
    RecurrentClassifier,
    build_model,
    count_parameters,
)

CNN_BASE: dict[str, Any] = {
    "family": "cnn",
    "base_channels": 64,
    "kernel_sizes": [5, 5, 3],
    "dropout": 0.2,
    "learning_rate": 1e-3,
}
RNN_COMMON: dict[str, Any] = {
    "bidirectional": False,
    "pooling": "mean",
    "dropout": 0.2,
    "recurrent_dropout": 0.0,
}
GRU_BASE = {
    "family": "gru",
    "hidden_size": 128,
    "num_layers": 2,
    **RNN_COMMON,
    "learning_rate": 1e-3,
}
LSTM_BASE = {
    "family": "lstm",
    "hidden_size": 64,
    "num_layers": 1,
    **RNN_COMMON,
    "learning_rate": 5e-4,
}
CNN_SWEEP = {**CNN_BASE, "base_channels": 96}
GRU_SWEEP = {**GRU_BASE, "hidden_size": 64, "num_layers": 2, "bidirectional": True}
LSTM_SWEEP = {**LSTM_BASE, "hidden_size": 64, "num_layers": 1}

VARIANTS: list[dict[str, Any]] = [
    CNN_BASE,
    GRU_BASE,
    LSTM_BASE,
    {**GRU_BASE, "pooling": "last"},
    {**GRU_BASE, "bidirectional": True, "pooling": "last"},
    {**LSTM_BASE, "bidirectional": True, "pooling": "last", "num_layers": 2},
    {**LSTM_BASE, "pooling": "last"},
    GRU_SWEEP,
]
IDS = [
    "cnn",
    "gru",
    "lstm",
    "gru-last",
    "gru-bi-last",
    "lstm-bi2-last",
    "lstm-last",
    "gru-bi-mean",
]
RECURRENT = [(v, i) for v, i in zip(VARIANTS, IDS, strict=True) if v["family"] != "cnn"]


def _windows(batch: int, steps: int, seed: int = 0) -> torch.Tensor:
    return torch.randn(batch, steps, 5, 2, generator=torch.Generator().manual_seed(seed))


@pytest.mark.parametrize("spec", VARIANTS, ids=IDS)
@pytest.mark.parametrize("steps", [1, 2, 5, 20, 200])
def test_output_is_one_logit_per_window(spec: dict[str, Any], steps: int) -> None:
    torch.manual_seed(0)
    model = build_model(spec)
    out = model(_windows(3, steps))  # training mode: BatchNorm sees 3 * W > 1 values
    assert out.shape == (3,)
    assert out.dtype == torch.float32 and torch.isfinite(out).all()
    model.eval()
    assert model(_windows(1, steps)).shape == (1,)


@pytest.mark.parametrize(
    ("spec", "expected"),
    [
        # Reference (table 4.2) reports 178,753 / 171,777 / 25,217 for the baselines; with 10
        # input features this design gives 1,920 / 2,304 / 1,536 fewer, exactly the weights of
        # 6 extra input features (see test_reference_counts_with_16_input_features).
        (CNN_BASE, 176_833),
        (GRU_BASE, 169_473),
        (LSTM_BASE, 23_681),
        # sweep configurations (section 3.4): CNN base 96, GRU 2 bidirectional layers hidden 64
        (CNN_SWEEP, 394_273),
        (GRU_SWEEP, 120_321),
        (LSTM_SWEEP, 23_681),
    ],
    ids=["cnn", "gru", "lstm", "cnn-sweep", "gru-sweep", "lstm-sweep"],
)
def test_parameter_counts(spec: dict[str, Any], expected: int) -> None:
    assert count_parameters(build_model(spec)) == expected


def test_reference_counts_with_16_input_features() -> None:
    # The same design reproduces table 4.2 exactly when fed 16 features per timestep.
    assert count_parameters(CNNClassifier(in_channels=16, base_channels=64)) == 178_753
    gru = RecurrentClassifier("gru", in_features=16, hidden_size=128, num_layers=2)
    assert count_parameters(gru) == 171_777
    lstm = RecurrentClassifier("lstm", in_features=16, hidden_size=64, num_layers=1)
    assert count_parameters(lstm) == 25_217


def test_count_parameters_matches_brute_force() -> None:
    model = build_model(GRU_SWEEP)
    brute = 0
    for _, p in model.named_parameters():
        brute += p.numel()
    assert count_parameters(model) == brute
    for p in model.head.parameters():
        p.requires_grad_(False)
    assert count_parameters(model) == brute - sum(p.numel() for p in model.head.parameters())


def _backward(model: nn.Module, steps: int = 20) -> dict[str, torch.Tensor]:
    model.zero_grad()
    model(_windows(4, steps, seed=1)).sum().backward()
    grads = {}
    for name, p in model.named_parameters():
        assert p.grad is not None, name
        assert torch.isfinite(p.grad).all(), name
        grads[name] = p.grad
    return grads


@pytest.mark.parametrize(("spec", "name"), [(CNN_BASE, "cnn")] + RECURRENT, ids=["cnn"] + IDS[1:])
def test_gradients_reach_every_parameter(spec: dict[str, Any], name: str) -> None:
    torch.manual_seed(0)
    model = build_model(spec)
    model.eval()  # no dropout; BatchNorm uses running statistics
    for pname, grad in _backward(model).items():
        assert grad.abs().sum() > 0, pname
    model.train()
    for pname, grad in _backward(model).items():
        module = model.get_submodule(pname.rsplit(".", 1)[0])
        if isinstance(module, nn.Conv1d) and pname.endswith("bias"):
            # a bias right before training-mode BatchNorm is removed with the batch mean
            assert grad.abs().max() < 1e-4, pname
        else:
            assert grad.abs().sum() > 0, pname


@pytest.mark.parametrize(("spec", "name"), RECURRENT, ids=IDS[1:])
def test_pooling_uses_the_right_timesteps(spec: dict[str, Any], name: str) -> None:
    torch.manual_seed(0)
    model = build_model(spec).eval()
    x = _windows(2, 12)
    base = model(x)
    changed = x.clone()
    index = -1 if spec["pooling"] == "last" else 0
    changed[:, index] += 1.0
    assert not torch.allclose(model(changed), base)


@pytest.mark.parametrize(("spec", "name"), RECURRENT, ids=IDS[1:])
def test_last_pooling_is_each_directions_final_state(spec: dict[str, Any], name: str) -> None:
    model = build_model({**spec, "pooling": "last"}).eval()
    x = _windows(2, 9)
    _, state = model.rnn(x.reshape(2, 9, 10))
    h_n = state[0] if isinstance(state, tuple) else state
    directions = 2 if spec["bidirectional"] else 1
    final = torch.cat(list(h_n[-directions:]), dim=-1)  # last layer, forward then backward
    torch.testing.assert_close(model(x), model.head(final).squeeze(-1))


def test_build_model_rejects_unknown_family_and_pooling() -> None:
    with pytest.raises(ValueError, match="transformer"):
        build_model({"family": "transformer"})
    with pytest.raises(ValueError, match="family"):
        build_model({"hidden_size": 64})
    with pytest.raises(ValueError, match="pooling.*max.*mean.*last"):
        build_model({**GRU_BASE, "pooling": "max"})
    with pytest.raises(ValueError, match="fingertips"):
        build_model(CNN_BASE)(torch.zeros(2, 4, 5, 3))


def test_build_model_uses_spec_and_input_size() -> None:
    model = build_model({**LSTM_BASE, "hidden_size": 32, "optimizer": "adamw"}, channels=3)
    assert isinstance(model, RecurrentClassifier)
    assert isinstance(model.rnn, nn.LSTM)
    assert (model.rnn.input_size, model.rnn.hidden_size) == (15, 32)
    assert model(torch.zeros(2, 7, 5, 3)).shape == (2,)
    cnn = build_model({**CNN_BASE, "kernel_sizes": [3, 3, 3]})
    assert isinstance(cnn, CNNClassifier)
    assert [m.kernel_size for m in cnn.modules() if isinstance(m, nn.Conv1d)] == [(3,)] * 3


def test_single_layer_recurrent_dropout_does_not_warn() -> None:
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        model = build_model({**LSTM_BASE, "recurrent_dropout": 0.3})
    assert model.rnn.dropout == 0.0
    assert build_model({**GRU_BASE, "recurrent_dropout": 0.3}).rnn.dropout == 0.3


@pytest.mark.parametrize("spec", [CNN_BASE, GRU_BASE, LSTM_BASE], ids=IDS[:3])
def test_seeded_construction_is_deterministic(spec: dict[str, Any]) -> None:
    torch.manual_seed(123)
    first = build_model(spec).state_dict()
    torch.manual_seed(123)
    second = build_model(spec).state_dict()
    assert first.keys() == second.keys()
    for key in first:
        assert torch.equal(first[key], second[key]), key
