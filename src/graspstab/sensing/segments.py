"""Force segments that end where a dataset's windows end and reach further back, read from the
replay traces: a sensor's delay and hold need the forces before a window (``sensor_model``)."""

from __future__ import annotations

from collections.abc import Mapping
from pathlib import Path

import numpy as np
import polars as pl

from graspstab.common.errors import GraspstabError
from graspstab.labels.dataset import CHANNELS
from graspstab.labels.trace_windows import grasps_of


class SegmentError(ValueError, GraspstabError):
    """A window whose grasp has no trace file among the declared inputs."""


def window_segments(
    index: pl.DataFrame,
    traces: Mapping[tuple[str, int], str | Path],
    window_steps: int,
    context: int,
) -> np.ndarray:
    """Raw forces ``(N, context + window_steps, 5, 2)`` of the index's windows in its row order:
    frames ``[start - context, start + W)`` of each window's grasp, the first recorded frame
    repeated where that reaches before the trace starts. ``traces`` maps (object, shard) to the
    shard's trace file."""
    length = context + window_steps
    out = np.empty((len(index), length, 5, len(CHANNELS)), dtype=np.float32)
    for rows, starts, tr, name in grasps_of(index, traces, CHANNELS, SegmentError):
        feats = np.stack([tr[c] for c in CHANNELS], axis=-1)  # (T, 5, 2)
        idx = starts[:, None] - context + np.arange(length)[None]
        if idx.max() >= len(feats):
            raise SegmentError(f"{name}: a window ends after the trace; the dataset and traces "
                               "disagree, rebuild them")  # fmt: skip
        out[rows] = feats[np.clip(idx, 0, None)]
    return out
