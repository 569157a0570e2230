"""The one iterator over usable replays (labels.replays): what the labelling stage and the
grasp-level monitor both read, on hand-made replay tables and trace files."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import polars as pl
import pytest

from graspstab.common.errors import GraspstabError
from graspstab.common.io import save_npz
from graspstab.labels.replays import replay_grasps
from graspstab.replay.traces import trace_key


def _shard(root: Path, obj: str, shard: int, rows: list[tuple[int, bool]]) -> tuple[Path, Path]:
    table = root / f"{obj}_{shard}.parquet"
    pl.DataFrame([{"grasp_id": g, "object": obj, "shard": shard, "diverged": d}
                  for g, d in rows]).write_parquet(table)  # fmt: skip
    traces = root / f"{obj}_{shard}.npz"
    save_npz(traces, **{trace_key(g, "normal"): np.full((4, 5), 10.0 * shard + g, np.float32)
                        for g, _ in rows})  # fmt: skip
    return table, traces


@pytest.fixture
def replays(tmp_path: Path) -> list[tuple[Path, Path]]:
    return [
        _shard(tmp_path, "a", 0, [(0, False), (1, True), (2, False)]),
        _shard(tmp_path, "b", 1, [(5, False)]),
    ]


SPLITS = {"a": "train", "b": "test"}


def test_diverged_replays_are_dropped_and_order_kept(replays) -> None:
    got = list(replay_grasps(replays, SPLITS, ("normal",)))
    assert [(g.object, g.grasp_id, g.shard, g.split) for g in got] == [
        ("a", 0, 0, "train"), ("a", 2, 0, "train"), ("b", 5, 1, "test")]  # fmt: skip
    # each grasp gets its own channel from the right trace file
    assert [float(g.traces["normal"][0, 0]) for g in got] == [0.0, 2.0, 15.0]


def test_splits_and_one_grasp_select(replays) -> None:
    assert [g.grasp_id for g in replay_grasps(replays, SPLITS, ("normal",), keep=("test",))] == [5]
    one = list(replay_grasps(replays, SPLITS, ("normal",), grasp=("a", 2)))
    assert [(g.object, g.grasp_id) for g in one] == [("a", 2)]
    assert list(replay_grasps(replays, SPLITS, ("normal",), keep=("val",))) == []


def test_an_object_without_a_split_is_named_with_its_table(replays) -> None:
    with pytest.raises(GraspstabError, match=r"b_1\.parquet: object 'b' has no split") as err:
        list(replay_grasps(replays, {"a": "train"}, ("normal",)))
    assert isinstance(err.value, KeyError) and not str(err.value).startswith("'")
