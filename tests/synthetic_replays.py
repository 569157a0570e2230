"""Synthetic replays for tests of the stages after the replay: shard tables and trace files of
made-up grasps, labelled into a baseline dataset by the real labelling stage."""

from __future__ import annotations

from collections.abc import Callable, Iterable
from pathlib import Path

import numpy as np
import polars as pl

from graspstab.common.io import save_npz
from graspstab.labels.label_windows import label_windows
from graspstab.replay.traces import trace_key


def labelled_replays(
    root: Path,
    shards: Iterable[tuple[str, int, tuple[int, ...]]],
    trace: Callable[[int], dict[str, np.ndarray]],
    labels: dict,
    splits: dict[str, str],
    dt: float,
) -> tuple[Path, dict[tuple[str, int], str]]:
    """Write one shard table and trace file per (object, shard, grasp ids), each grasp's channels
    from ``trace(grasp_id)``, and label them into ``root/ds`` (0.05 s window, seed 0). Returns
    the dataset folder and the trace file of each (object, shard)."""
    replays, traces = [], {}
    for obj, shard, grasps in shards:
        table = root / f"{obj}_{shard}.parquet"
        pl.DataFrame([{"grasp_id": g, "object": obj, "shard": shard, "diverged": False}
                      for g in grasps]).write_parquet(table)  # fmt: skip
        path = root / f"{obj}_{shard}.npz"
        save_npz(path, **{trace_key(g, c): v for g in grasps for c, v in trace(g).items()})
        replays.append((table, path))
        traces[(obj, shard)] = str(path)
    label_windows(replays, root / "ds", labels, splits, 0.05, dt, 0)
    return root / "ds", traces
