"""The replays that can enter a dataset (3.3.1): one iterator over the replay tables and their
trace files, dropping diverged replays and checking each object's split, shared by the labelling
stage and the grasp-level monitor so that both see exactly the same grasps."""

from __future__ import annotations

from collections.abc import Iterable, Iterator, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import polars as pl

from graspstab.common.errors import GraspstabError
from graspstab.common.io import read_parquet
from graspstab.replay.traces import TraceFile


class SplitError(GraspstabError, KeyError):
    """A replayed object that the object set gives no split."""

    def __str__(self) -> str:  # KeyError would quote the message
        return str(self.args[0])


@dataclass(frozen=True)
class ReplayGrasp:
    """One replay that did not diverge: its row of the replay table, its object's split and the
    trace channels asked for, cut to the replay's recorded length."""

    object: str
    grasp_id: int
    shard: int
    split: str
    traces: dict[str, np.ndarray]


def replay_grasps(
    replays: Iterable[tuple[str | Path, str | Path]],
    splits: Mapping[str, str],
    channels: Sequence[str],
    keep: Sequence[str] | None = None,
    grasp: tuple[str, int] | None = None,
) -> Iterator[ReplayGrasp]:
    """Every replay of the (table, traces) pairs, in table order, that did not diverge and whose
    object's split is in ``keep`` (every split when None; only the one ``grasp``, (object, grasp
    id), when given), with its ``channels``. An object without a split is an error: the replays
    and the object set disagree."""
    for table_path, traces_path in replays:
        table = read_parquet(table_path).filter(~pl.col("diverged"))
        with TraceFile(traces_path) as npz:
            for g in table.iter_rows(named=True):
                obj, gid = g["object"], int(g["grasp_id"])
                if obj not in splits:
                    raise SplitError(f"{table_path}: object {obj!r} has no split in the object set")
                if keep is not None and splits[obj] not in keep:
                    continue
                if grasp is not None and grasp != (obj, gid):
                    continue
                tr = npz.grasp(gid, tuple(channels))
                yield ReplayGrasp(obj, gid, int(g["shard"]), splits[obj], tr)
