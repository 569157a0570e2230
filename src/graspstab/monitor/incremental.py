"""Incremental CNN scoring: each new frame costs a few positions' convolutions, not a window's.

A CNN window model (3.4.1: "same"-padded convolutions, eval-mode BatchNorm and GELU, a mean over
the window, a small head) is shift-equivariant except near the window's two ends, where its zero
padding reaches. So, for a window sliding one frame at a time, a layer's output at a position
whose receptive field lies inside the window is the same value the previous window held one
position further on: it is computed once, when its last input frame arrives, and kept in a ring.
A score then recomputes only the positions the padding reaches (a few per layer and end) and sums
the pooled layer. At the 0.2 s baseline (400 frames, kernels 5, 5, 3) that is 21 positions of the
last layer in place of 400 (docs/extensions.md, "Per-frame cost"). It is the batch model's
arithmetic in another order, so its probabilities equal the batch model's to float tolerance
(tests).

BatchNorm is folded into its convolution (eval mode: a per-channel affine map); Dropout is the
identity in eval mode. Computed with NumPy float32 (single-row BLAS calls have far less overhead
per call than PyTorch operators at these sizes).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import torch
from scipy.special import erf
from torch import nn

from graspstab.learning.models import CNNClassifier
from graspstab.learning.train import sigmoid
from graspstab.monitor.constants import MonitorConstants, MonitorError
from graspstab.monitor.scoring import TorchScorer

_SQRT_HALF = np.float32(np.sqrt(0.5))


def _gelu(x: np.ndarray) -> np.ndarray:
    """The exact (erf) GELU of ``nn.GELU()``, float32."""
    return np.float32(0.5) * x * (np.float32(1.0) + erf(x * _SQRT_HALF))


@dataclass(frozen=True)
class _Layer:
    """One Conv1d + BatchNorm1d + GELU block, folded: weights ordered (out, kernel * in)."""

    weight: np.ndarray  # (out, k * in) float32, row-major over (kernel tap, input channel)
    bias: np.ndarray  # (out,) float32
    kernel: int
    left: int  # zero padding before the window ("same": (k - 1) // 2)
    right: int  # and after it (k - 1 - left)

    def apply(self, patches: np.ndarray) -> np.ndarray:
        """Outputs ``(n, out)`` of ``n`` input patches ``(n, k * in)``."""
        return _gelu(patches @ self.weight.T + self.bias)


def _fold(conv: nn.Conv1d, norm: nn.BatchNorm1d) -> _Layer:
    """A convolution with its eval-mode BatchNorm folded in."""
    if conv.stride != (1,) or conv.dilation != (1,) or conv.groups != 1 or conv.padding != "same":
        raise MonitorError(
            "incremental scoring needs stride-1, undilated, ungrouped 'same' convolutions; got "
            f"{conv}"
        )
    if norm.running_mean is None or norm.running_var is None:
        raise MonitorError("incremental scoring needs BatchNorm with running statistics")
    with torch.no_grad():
        scale = norm.weight / torch.sqrt(norm.running_var + norm.eps)
        shift = norm.bias - norm.running_mean * scale
        w = conv.weight * scale[:, None, None]  # (out, in, k)
        b = (conv.bias if conv.bias is not None else torch.zeros_like(shift)) * scale + shift
    k = int(conv.kernel_size[0])
    weight = w.permute(0, 2, 1).reshape(w.shape[0], -1)  # (out, k * in): tap-major
    return _Layer(
        weight=np.ascontiguousarray(weight.numpy(), dtype=np.float32),
        bias=b.numpy().astype(np.float32),
        kernel=k,
        left=(k - 1) // 2,
        right=k - 1 - (k - 1) // 2,
    )


def _blocks(model: CNNClassifier) -> list[_Layer]:
    """The model's feature blocks (Conv1d, BatchNorm1d, GELU[, Dropout]) folded, in order."""
    mods = list(model.features)
    layers, i = [], 0
    while i < len(mods):
        trio = mods[i : i + 3]
        kinds = (nn.Conv1d, nn.BatchNorm1d, nn.GELU)
        if len(trio) < 3 or not all(isinstance(m, t) for m, t in zip(trio, kinds, strict=True)):
            raise MonitorError(f"unexpected CNN block at feature {i}: {trio}")
        if trio[2].approximate != "none":
            raise MonitorError("incremental scoring implements the exact (erf) GELU only")
        layers.append(_fold(trio[0], trio[1]))
        i += 3
        if i < len(mods) and isinstance(mods[i], nn.Dropout):
            i += 1
    return layers


def _head(model: CNNClassifier) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """The head's two Linear layers (Linear, GELU, Dropout, Linear) as float32 arrays."""
    mods = [m for m in model.head if not isinstance(m, nn.Dropout)]
    kinds = (nn.Linear, nn.GELU, nn.Linear)
    if len(mods) != 3 or not all(isinstance(m, t) for m, t in zip(mods, kinds, strict=True)):
        raise MonitorError(f"unexpected CNN head: {model.head}")
    first, last = mods[0], mods[2]
    return tuple(  # type: ignore[return-value]
        t.detach().numpy().astype(np.float32)
        for t in (first.weight, first.bias, last.weight, last.bias)
    )


class IncrementalCNNScorer:
    """A CNN window model scored frame by frame with each layer's shift-invariant part cached.

    Feed every frame with :meth:`push_frame` (the monitor does) and call :meth:`score_window` on
    any frame once ``window_steps`` frames have arrived; the result is the probability of the
    last ``window_steps`` frames. ``score_one`` and batch calls run the eager model, so this is
    also a plain :class:`~graspstab.monitor.scoring.WindowScorer`.
    """

    def __init__(self, model: nn.Module, constants: MonitorConstants) -> None:
        if not isinstance(model, CNNClassifier):
            raise MonitorError(
                f"incremental scoring is for the CNN family; got {type(model).__name__} (use "
                "TorchScorer or an exported model)"
            )
        model = model.eval()
        self.constants = constants
        self._eager = TorchScorer(model, constants)
        self._layers = _blocks(model)
        self._w1, self._b1, self._w2, self._b2 = _head(model)
        w = constants.window_steps
        # padding reach from each end after each level (level 0, the input: none)
        self._reach_left = np.cumsum([0] + [layer.left for layer in self._layers]).tolist()
        self._reach_right = np.cumsum([0] + [layer.right for layer in self._layers]).tolist()
        if self._reach_left[-1] + self._reach_right[-1] >= w:
            raise MonitorError(
                f"a window of {w} frames is too short for incremental scoring of a CNN whose "
                f"padding reaches {self._reach_left[-1]} + {self._reach_right[-1]} positions in "
                "from its ends; score it with TorchScorer"
            )
        self._mean = np.asarray(constants.mean, dtype=np.float32).reshape(-1)
        self._std = np.asarray(constants.std, dtype=np.float32).reshape(-1)
        widths = [len(self._mean)] + [len(layer.bias) for layer in self._layers]
        # one ring per level (normalised input, then each layer's clean outputs), each value at
        # slots t % W and t % W + W, so any run of <= W consecutive times is one slice
        self._rings = [np.zeros((2 * w, c), dtype=np.float32) for c in widths]
        self.reset()

    def reset(self) -> None:
        """Forget every frame (a new grasp episode)."""
        for ring in self._rings:
            ring.fill(0.0)
        self._t = -1  # time of the newest frame

    def push_frame(self, frame: np.ndarray) -> None:
        """Take one raw frame (5, 2): normalise it and compute each layer's newest clean value."""
        w = self.constants.window_steps
        t = self._t = self._t + 1
        z = (np.asarray(frame, dtype=np.float32).reshape(-1) - self._mean) / self._std
        self._put(0, t, z)
        for level, layer in enumerate(self._layers, start=1):
            # this layer's value at time u needs level-1 values at u - left .. u + right, the
            # newest of which (t minus that level's right reach) has just arrived; it exists
            # once u - left reaches the first time that level holds (its left reach)
            u = t - self._reach_right[level]
            if u - layer.left >= self._reach_left[level - 1]:
                start = (u - layer.left) % w
                patch = self._rings[level - 1][start : start + layer.kernel].reshape(1, -1)
                self._put(level, u, layer.apply(patch)[0])

    def _put(self, level: int, t: int, value: np.ndarray) -> None:
        ring, w = self._rings[level], self.constants.window_steps
        ring[t % w] = value
        ring[t % w + w] = value

    def _span(self, level: int, lo: int, hi: int) -> np.ndarray:
        """Window positions ``lo:hi`` of one level's clean values (a view)."""
        w = self.constants.window_steps
        first = (self._t + 1) % w  # the slot of window position 0
        return self._rings[level][first + lo : first + hi]

    def score_window(self) -> float:
        """Probability of the window of the last ``window_steps`` frames pushed."""
        w = self.constants.window_steps
        if self._t + 1 < w:
            raise MonitorError(f"{self._t + 1} frames pushed; a score needs {w}")
        left_vals = np.zeros((0, self._rings[0].shape[1]), dtype=np.float32)  # level 0: none
        right_vals = left_vals
        for level, layer in enumerate(self._layers, start=1):
            k_in = self._rings[level - 1].shape[1]
            reach_l, new_l = self._reach_left[level - 1], self._reach_left[level]
            reach_r, new_r = self._reach_right[level - 1], self._reach_right[level]
            # left end: positions 0 .. new_l - 1 read level-1 positions -left .. new_l-1+right
            below = np.concatenate([
                np.zeros((layer.left, k_in), dtype=np.float32),
                left_vals,
                self._span(level - 1, reach_l, new_l + layer.right),
            ])
            left_vals = layer.apply(_patches(below, layer.kernel))
            # right end: positions w - new_r .. w - 1 read w - new_r - left .. w - 1 + right
            below = np.concatenate([
                self._span(level - 1, w - new_r - layer.left, w - reach_r),
                right_vals,
                np.zeros((layer.right, k_in), dtype=np.float32),
            ])
            right_vals = layer.apply(_patches(below, layer.kernel))
        top = len(self._layers)
        inner = self._span(top, self._reach_left[top], w - self._reach_right[top])
        total = (left_vals.sum(axis=0, dtype=np.float32)
                 + inner.sum(axis=0, dtype=np.float32)
                 + right_vals.sum(axis=0, dtype=np.float32))  # fmt: skip
        pooled = total / np.float32(w)
        hidden = _gelu(self._w1 @ pooled + self._b1)
        logit = float((self._w2 @ hidden + self._b2)[0])
        return float(sigmoid(np.float64(logit)))

    def score_one(self, window: np.ndarray) -> float:
        """Probability of one raw window, by the eager model (no cached state used)."""
        return self._eager.score_one(window)

    def __call__(self, windows: np.ndarray) -> np.ndarray:
        """Probabilities of a batch of raw windows, by the eager model."""
        return self._eager(windows)


def _patches(x: np.ndarray, kernel: int) -> np.ndarray:
    """Every run of ``kernel`` consecutive rows of ``x`` (n, c) as one row (n - k + 1, k * c)."""
    n, c = x.shape
    if n < kernel:  # an end the padding does not reach (e.g. the left end of an even kernel)
        return np.zeros((0, kernel * c), dtype=x.dtype)
    return np.lib.stride_tricks.sliding_window_view(x.reshape(-1), kernel * c)[::c]
