"""Model architectures (thesis 3.4): CNN, GRU and LSTM window classifiers giving one logit.

Every model takes a normalised window ``x`` of shape ``(B, W, 5, C)`` and returns logits of shape
``(B,)``. The five fingertips and ``C`` force channels are flattened fingertip-major into ``5C``
features per timestep (feature ``f * C + c`` is channel ``c`` of fingertip ``f``).

Design (the simplest family found that reproduces the parameter counts of table 4.2):

* CNN: Conv1d channels ``base -> 2 base -> 4 base`` (kernels 5, 5, 3, "same" padding), each with
  BatchNorm1d and GELU, dropout after the first two; AdaptiveAvgPool1d(1); head
  ``Linear(4 base, 2 base) -> GELU -> Dropout -> Linear(2 base, 1)``. Conv biases are kept although
  BatchNorm makes them redundant, because the reference's counts include them.
* GRU/LSTM: ``D = hidden_size * directions`` pooled features; head
  ``Dropout -> Linear(D, D) -> GELU -> Dropout -> Linear(D, 1)``.

With the thesis's 10 input features (5 fingertips x 2 channels) the baseline configurations have
CNN 176,833, GRU 169,473 and LSTM 23,681 parameters, against table 4.2's 178,753, 171,777 and
25,217. The differences (1,920 = 6*64*5, 2,304 = 6*3*128, 1,536 = 6*4*64) are exactly those of
6 extra input features: this design with 16 input features reproduces all three reference counts.
No equally simple design matched all three with 10 features, so the reference's counts were
presumably taken with a 16-feature input; the 10-feature model is what the spec describes.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Any

import torch
from torch import nn

FAMILIES = ("cnn", "gru", "lstm")
POOLINGS = ("mean", "last")


def _check_input(x: torch.Tensor, in_features: int) -> None:
    """Validate a ``(B, W, 5, C)`` window batch early so shape errors name the expectation
    (static dimensions only: the batch stays symbolic when a model is traced or exported)."""
    if x.ndim != 4 or x.shape[2] * x.shape[3] != in_features:
        raise ValueError(
            f"expected input of shape (B, W, fingertips, channels) with fingertips * channels = "
            f"{in_features}, got {tuple(x.shape)}"
        )
    if x.shape[1] < 1:
        raise ValueError("window length W must be >= 1")


class CNNClassifier(nn.Module):
    """Temporal CNN (3.4.1): finds short local force patterns anywhere in the window."""

    def __init__(
        self,
        in_channels: int = 10,
        base_channels: int = 64,
        kernel_sizes: Sequence[int] = (5, 5, 3),
        dropout: float = 0.2,
    ) -> None:
        super().__init__()
        kernel_sizes = tuple(int(k) for k in kernel_sizes)
        if not kernel_sizes:
            raise ValueError("kernel_sizes must name at least one convolution")
        self.in_channels = in_channels
        layers: list[nn.Module] = []
        width = in_channels
        for i, kernel in enumerate(kernel_sizes):
            out = base_channels * 2**i
            layers += [
                nn.Conv1d(width, out, kernel_size=kernel, padding="same"),
                nn.BatchNorm1d(out),
                nn.GELU(),
            ]
            if i < len(kernel_sizes) - 1:
                layers.append(nn.Dropout(dropout))
            width = out
        self.features = nn.Sequential(*layers)
        self.pool = nn.AdaptiveAvgPool1d(1)
        self.head = nn.Sequential(
            nn.Linear(width, width // 2),
            nn.GELU(),
            nn.Dropout(dropout),
            nn.Linear(width // 2, 1),
        )

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        """Map ``(B, W, 5, C)`` windows to ``(B,)`` instability logits."""
        _check_input(x, self.in_channels)
        h = x.flatten(2).transpose(1, 2)  # (B, 5C, W)
        h = self.pool(self.features(h)).squeeze(-1)
        return self.head(h).squeeze(-1)


class RecurrentClassifier(nn.Module):
    """GRU/LSTM classifier (3.4.2-3.4.3): builds a running summary of the force history."""

    def __init__(
        self,
        cell: str = "gru",
        in_features: int = 10,
        hidden_size: int = 64,
        num_layers: int = 1,
        bidirectional: bool = False,
        pooling: str = "mean",
        dropout: float = 0.2,
        recurrent_dropout: float = 0.0,
    ) -> None:
        super().__init__()
        rnn_types: dict[str, type[nn.RNNBase]] = {"gru": nn.GRU, "lstm": nn.LSTM}
        if cell not in rnn_types:
            raise ValueError(f"unknown cell {cell!r}; valid values: {sorted(rnn_types)}")
        if pooling not in POOLINGS:
            raise ValueError(f"unknown pooling {pooling!r}; valid values: {list(POOLINGS)}")
        self.in_features = in_features
        self.hidden_size = hidden_size
        self.bidirectional = bidirectional
        self.pooling = pooling
        self.rnn = rnn_types[cell](
            input_size=in_features,
            hidden_size=hidden_size,
            num_layers=num_layers,
            batch_first=True,
            bidirectional=bidirectional,
            # inter-layer dropout only exists between stacked layers; PyTorch warns otherwise
            dropout=recurrent_dropout if num_layers > 1 else 0.0,
        )
        width = hidden_size * (2 if bidirectional else 1)
        self.head = nn.Sequential(
            nn.Dropout(dropout),
            nn.Linear(width, width),
            nn.GELU(),
            nn.Dropout(dropout),
            nn.Linear(width, 1),
        )

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        """Map ``(B, W, 5, C)`` windows to ``(B,)`` instability logits."""
        _check_input(x, self.in_features)
        seq = x.flatten(2)
        if seq.device.type == "cpu" and torch.is_autocast_enabled("cpu"):
            # CPU autocast keeps a GRU in fp32 but sends an LSTM to oneDNN's bfloat16 kernels,
            # which need AVX-512: run both recurrent cells in fp32 there (the head still casts)
            with torch.autocast("cpu", enabled=False):
                out, _ = self.rnn(seq.float())  # (B, W, D)
        else:
            out, _ = self.rnn(seq)  # (B, W, D)
        if self.pooling == "mean":
            pooled = out.mean(dim=1)
        elif self.bidirectional:
            # each direction's final state: forward at the last step, backward at the first
            h = self.hidden_size
            pooled = torch.cat([out[:, -1, :h], out[:, 0, h:]], dim=-1)
        else:
            pooled = out[:, -1]
        return self.head(pooled).squeeze(-1)


def build_model(spec: Mapping[str, Any], channels: int = 2, fingertips: int = 5) -> nn.Module:
    """Build a classifier from a model config, ignoring training-only keys (e.g. learning_rate)."""
    family = spec.get("family")
    if family not in FAMILIES:
        raise ValueError(f"unknown model family {family!r}; valid values: {list(FAMILIES)}")
    features = channels * fingertips
    if family == "cnn":
        cnn_keys = ("base_channels", "kernel_sizes", "dropout")
        return CNNClassifier(in_channels=features, **{k: spec[k] for k in cnn_keys if k in spec})
    rnn_keys = (
        "hidden_size",
        "num_layers",
        "bidirectional",
        "pooling",
        "dropout",
        "recurrent_dropout",
    )
    kwargs = {k: spec[k] for k in rnn_keys if k in spec}
    return RecurrentClassifier(cell=family, in_features=features, **kwargs)


def count_parameters(model: nn.Module) -> int:
    """Trainable parameter count, as reported in table 4.2."""
    return sum(p.numel() for p in model.parameters() if p.requires_grad)
