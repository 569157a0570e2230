"""Inference latency (thesis 4.5): CPU forward pass at batch size 1 after warm-up.

Median and standard deviation over repeated single-window forward passes, and the throughput
that median implies; the total decision latency of a configuration adds the window's duration.
"""

from __future__ import annotations

import time

import numpy as np
import torch
from torch import nn


def measure_latency(
    model: nn.Module,
    window_steps: int,
    repeats: int = 200,
    warmup: int = 20,
    channels: int = 2,
    fingertips: int = 5,
    seed: int = 0,
) -> dict[str, float]:
    """Forward-pass latency of one window [ms]: median, std, mean; throughput [windows/s]."""
    model.eval()
    generator = torch.Generator().manual_seed(seed)
    x = torch.randn(1, window_steps, fingertips, channels, generator=generator)
    times = np.empty(repeats)
    with torch.inference_mode():
        for _ in range(warmup):
            model(x)
        for i in range(repeats):
            t0 = time.perf_counter()
            model(x)
            times[i] = time.perf_counter() - t0
    ms = times * 1e3
    median = float(np.median(ms))
    return {
        "median_ms": median,
        "std_ms": float(ms.std(ddof=1)) if repeats > 1 else float("nan"),
        "mean_ms": float(ms.mean()),
        "throughput_per_s": 1e3 / median,
        "repeats": int(repeats),
        "threads": int(torch.get_num_threads()),
    }
