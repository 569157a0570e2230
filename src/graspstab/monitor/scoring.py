"""One scoring interface (raw windows in, probabilities out) so the monitor runs any format.

A scorer takes *raw* force windows (newtons, ``(B, W, 5, 2)`` float32, fingertips in eq. 19's
order, channels normal and shear) and returns the instability probability of each. The eager
scorer here normalises exactly as ``learning.data.WindowData.batch`` does (float32, subtract the
training mean, divide by the training std) and runs the model's own ``forward``; the exported
formats (``monitor.export``) normalise inside their graph. Every scorer turns the model's logit
into a probability with the learning stage's float64 ``sigmoid``, the function the validation
threshold was selected with, so a probability at the threshold is decided identically.
"""

from __future__ import annotations

from typing import Protocol

import numpy as np
import torch
from torch import nn

from graspstab.learning.train import sigmoid
from graspstab.monitor.constants import FRAME_SHAPE, MonitorConstants, MonitorError


class WindowScorer(Protocol):
    """What the monitor needs of a model: its constants and raw-window scoring."""

    constants: MonitorConstants

    def score_one(self, window: np.ndarray) -> float:
        """Probability of one raw window ``(W, 5, 2)`` float32 (C-contiguous)."""
        ...

    def __call__(self, windows: np.ndarray) -> np.ndarray:
        """Probabilities ``(B,)`` float64 of raw windows ``(B, W, 5, 2)``."""
        ...


def check_windows(windows: np.ndarray, window_steps: int) -> np.ndarray:
    """Raw windows as C-contiguous float32 ``(B, W, 5, 2)``, or an error naming the expectation."""
    x = np.ascontiguousarray(windows, dtype=np.float32)
    if x.ndim != 4 or x.shape[1:] != (window_steps, *FRAME_SHAPE):
        raise MonitorError(
            f"expected raw windows of shape (B, {window_steps}, {FRAME_SHAPE[0]}, "
            f"{FRAME_SHAPE[1]}) (batch, window steps, fingertips, (normal, shear)); got {x.shape}"
        )
    return x


class TorchScorer:
    """Eager PyTorch scoring of a learning-stage model (batch 1 into a preallocated buffer)."""

    def __init__(self, model: nn.Module, constants: MonitorConstants) -> None:
        self.model = model.eval()
        self.constants = constants
        self._mean = torch.as_tensor(constants.mean, dtype=torch.float32)
        self._std = torch.as_tensor(constants.std, dtype=torch.float32)
        self._one = torch.zeros((1, constants.window_steps, *FRAME_SHAPE), dtype=torch.float32)

    def score_one(self, window: np.ndarray) -> float:
        """Probability of one raw window, normalised into the preallocated batch-1 buffer."""
        with torch.inference_mode():
            torch.sub(torch.from_numpy(window), self._mean, out=self._one[0])
            self._one.div_(self._std)
            logit = self.model(self._one)
        return float(sigmoid(np.float64(logit.item())))

    def __call__(self, windows: np.ndarray) -> np.ndarray:
        """Probabilities of a batch of raw windows."""
        x = torch.from_numpy(check_windows(windows, self.constants.window_steps))
        with torch.inference_mode():
            logits = self.model((x - self._mean) / self._std)
        return sigmoid(logits.double().numpy())
