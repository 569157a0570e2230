"""The replay traces of a dataset's windows, grasp by grasp: what the input audit and the sensor
segments both cut their windows from (same index, same starts, other channels or more frames)."""

from __future__ import annotations

from collections.abc import Iterable, Iterator, Mapping
from pathlib import Path

import numpy as np
import polars as pl

from graspstab.replay.traces import TraceFile


def trace_map(paths: list[str], keys: list[tuple[str, int]]) -> dict[tuple[str, int], str]:
    """(object, shard) -> trace file, from a rule's parallel lists."""
    if len(paths) != len(keys):
        raise ValueError(f"{len(paths)} trace files but {len(keys)} (object, shard) keys")
    return {(str(o), int(k)): p for p, (o, k) in zip(paths, keys, strict=True)}


def grasps_of(
    index: pl.DataFrame,
    traces: Mapping[tuple[str, int], str | Path],
    channels: Iterable[str],
    error: type[ValueError] = ValueError,
) -> Iterator[tuple[np.ndarray, np.ndarray, dict[str, np.ndarray], str]]:
    """Per grasp of ``index``: its rows (positions in the index), their window starts, the
    grasp's ``channels`` and a name for messages. A missing trace file raises ``error``."""
    channels = tuple(channels)
    rows = index.with_row_index("_row")
    for (obj, shard), group in rows.group_by(["object", "shard"], maintain_order=True):
        key = (str(obj), int(shard))
        if key not in traces:
            raise error(f"object {obj!r} shard {shard}: no trace file among the inputs "
                        f"(have {sorted(traces)[:4]}...); rebuild the dataset")  # fmt: skip
        with TraceFile(traces[key]) as npz:
            for gid, windows in group.group_by("grasp_id", maintain_order=True):
                yield (windows["_row"].to_numpy(), windows["start"].to_numpy(),
                       npz.grasp(int(gid[0]), channels),
                       f"object {obj!r} grasp {gid[0]}")  # fmt: skip
