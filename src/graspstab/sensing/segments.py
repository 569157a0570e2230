"""Force segments that end where a dataset's windows end and reach further back, read from the
replay traces: a sensor's delay and hold need the forces before a window (``sensor_model``)."""

from __future__ import annotations

from collections.abc import Mapping
from pathlib import Path

import numpy as np
import polars as pl

from graspstab.labels.label_windows import CHANNELS
from graspstab.replay.traces import TraceFile


class SegmentError(ValueError):
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
    rows = index.with_row_index("_row")
    for (obj, shard), group in rows.group_by(["object", "shard"], maintain_order=True):
        key = (str(obj), int(shard))
        if key not in traces:
            raise SegmentError(f"object {obj!r} shard {shard}: no trace file among the inputs "
                               f"(have {sorted(traces)[:4]}...); rebuild the dataset")  # fmt: skip
        with TraceFile(traces[key]) as npz:
            for gid, windows in group.group_by("grasp_id", maintain_order=True):
                tr = npz.grasp(int(gid[0]), CHANNELS)
                feats = np.stack([tr[c] for c in CHANNELS], axis=-1)  # (T, 5, 2)
                starts = windows["start"].to_numpy()
                idx = starts[:, None] - context + np.arange(length)[None]
                if idx.max() >= len(feats):
                    raise SegmentError(
                        f"object {obj!r} grasp {gid[0]}: a window ends after the "
                        "trace; the dataset and traces disagree, rebuild them"
                    )
                out[windows["_row"].to_numpy()] = feats[np.clip(idx, 0, None)]
    return out


def trace_map(paths: list[str], keys: list[tuple[str, int]]) -> dict[tuple[str, int], str]:
    """(object, shard) -> trace file, from the rule's parallel lists."""
    if len(paths) != len(keys):
        raise SegmentError(f"{len(paths)} trace files but {len(keys)} (object, shard) keys")
    return {(str(o), int(k)): p for p, (o, k) in zip(paths, keys, strict=True)}
