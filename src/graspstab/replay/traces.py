"""The replay traces' file layout in one place: member names and the reader every later stage uses.

A shard's traces are one compressed ``.npz`` whose members are ``g<grasp id>_<channel>``; the
labelling stage, the figures and the harnesses read them only through :func:`read_traces`, so the
layout can change here alone and a later stage never imports the replay engine.
"""

from __future__ import annotations

import os
from collections.abc import Iterable
from typing import Any

import numpy as np

from graspstab.common.io import reading
from graspstab.hand.names import FINGERS

# Everything a replay records per time step (object frame): position, velocity, d_t, eq. 18 forces
# and the shear's two fingertip-frame components (graspstab.replay.sensors.shear_components).
CHANNELS = (
    "position", "velocity", "min_distance", "normal", "shear", "shear_distal", "shear_lateral",
)  # fmt: skip
# What the failure anatomy reads, recorded by every replay and never a model input: the object's
# angular speed [rad/s], the largest closing-joint servo force as a share of its range (1:
# saturated), and the contact slip speed [m/s] at each fingertip and at the other hand links
# together (graspstab.replay.slip, sampled every replay.slip_every_s and held in between).
ANATOMY = ("spin", "servo_load", "tip_slip", "link_slip")
# The external force of the load-ramp protocol (object frame) [N]; absent under gravity alone.
LOAD = "load"
# Values per time step of each channel: 3-vectors, d_t, and one per fingertip (eq. 19's order).
WIDTHS = {"position": 3, "velocity": 3, "min_distance": 1, LOAD: 3} | {
    c: len(FINGERS) for c in ("normal", "shear", "shear_distal", "shear_lateral", "tip_slip")
} | {"spin": 1, "servo_load": 1, "link_slip": 1}
# A generous bound on what one npz member adds to its data: zip headers, its name, the npy header.
MEMBER_OVERHEAD = 512


def trace_key(grasp_id: int, channel: str) -> str:
    """The npz member of one grasp's channel."""
    return f"g{int(grasp_id)}_{channel}"


class TraceFile:
    """One shard's traces, open for reading (use as a context manager)."""

    def __init__(self, path: str | os.PathLike[str]) -> None:
        self.path = path
        with reading(path):
            self._npz = np.load(path, allow_pickle=False)

    def __enter__(self) -> TraceFile:
        return self

    def __exit__(self, *exc: Any) -> None:
        self._npz.close()

    def grasp(self, grasp_id: int, channels: Iterable[str] = CHANNELS) -> dict[str, np.ndarray]:
        """The named channels of one grasp; a missing or truncated member names the file."""
        with reading(self.path):
            return {c: self._npz[trace_key(grasp_id, c)] for c in channels}


def read_traces(
    path: str | os.PathLike[str], grasp_id: int, channels: Iterable[str] = CHANNELS
) -> dict[str, np.ndarray]:
    """The named channels of one grasp of a shard's trace file."""
    with TraceFile(path) as traces:
        return traces.grasp(grasp_id, channels)


def trace_bytes(grasps: int, steps: int, load: bool) -> int:
    """The largest size of a shard's trace file: ``grasps`` replays of ``steps`` float32 rows
    each, stored uncompressed. The real file is smaller (npz compression, early stops); the
    replay job checks this much free space before it simulates."""
    channels = [*CHANNELS, *ANATOMY, *([LOAD] if load else [])]
    per_grasp = steps * sum(WIDTHS[c] for c in channels) * 4 + len(channels) * MEMBER_OVERHEAD
    return grasps * per_grasp


def shard_trace_bytes(grasp_table: str | os.PathLike[str], params: dict[str, Any]) -> int:
    """:func:`trace_bytes` for the replay of ``grasp_table`` (its row count, from the Parquet
    footer) under the replay ``params`` (``steps``; the ``load`` channel unless ``protocol`` is
    ``gravity``)."""
    import pyarrow.parquet as pq

    with reading(grasp_table):
        grasps = pq.ParquetFile(grasp_table).metadata.num_rows
    return trace_bytes(grasps, int(params["steps"]), params["protocol"] != "gravity")
