"""Build one window dataset from the replays (thesis 3.3, 3.5.1-3.5.2).

For every replay that is neither diverged nor rejected: the usable interval (3.3.1), timestep
labels (eq. 23), up to ``windows_per_grasp`` window starts (eq. 26, seeded per grasp), predictive
labels (eqs. 29-30; ambiguous and empty targets dropped) and the input windows X_s (eq. 27,
W x 5 fingertips x {normal, shear}). Writes into ``out_dir``:

* ``index.parquet``: sample_id, object, grasp_id, shard, start, end (exclusive, s + W), r, label,
  split (the object's split: every window of a grasp shares it);
* ``windows.npy``: float32 (N, W, 5, 2), for training to memory-map;
* ``motion.npy``: float32 (N, W, 2), the object's motion over each observation period (eq. 23's
  u_t and the speed [m/s], ``labels.dataset.MOTION``), which no model reads: evaluation splits
  windows whose object already moves from still ones with it;
* ``normalisation.json``: per fingertip x channel mean and std over the training windows' time
  steps only, the std floored at ``eps`` (3.5.2).
"""

from __future__ import annotations

import zlib
from pathlib import Path
from typing import Any

import numpy as np
import polars as pl

from graspstab.common.io import save_npy, write_json, write_parquet
from graspstab.labels.anatomy import failure
from graspstab.labels.dataset import CHANNELS, MOTION, normalisation
from graspstab.labels.interval import usable_interval
from graspstab.labels.replays import replay_grasps
from graspstab.labels.sources import source_channels, unstable_steps
from graspstab.labels.windows import (
    event_windows,
    predictive_labels,
    step_counts,
    timestep_labels,
    window_starts,
)


def grasp_rng(seed: int, object_id: str, grasp_id: int) -> np.random.Generator:
    """The window-start stream of one grasp (SeedSequence of seed, object, grasp)."""
    return np.random.default_rng(
        np.random.SeedSequence([int(seed), zlib.crc32(object_id.encode()), int(grasp_id)])
    )


def grasp_windows(
    traces: dict[str, np.ndarray], object_id: str, grasp_id: int, labels: dict[str, Any],
    window_s: float, dt: float, seed: int,
) -> tuple[np.ndarray, np.ndarray, np.ndarray, str | None]:  # fmt: skip
    """Labelled window starts, r_s and labels of one replay, and why it was rejected (if)."""
    w, o, h = step_counts(window_s, labels["offset_s"], labels["horizon_s"], dt)
    speed = np.linalg.norm(traces["velocity"].astype(np.float64), axis=1)
    dist = traces["min_distance"].astype(np.float64)
    ui = usable_interval(speed, dist, dt, labels["settle"], labels["contact_loss_s"])
    empty = np.zeros(0, dtype=np.int64)
    if ui.rejected:
        return empty, np.zeros(0), np.zeros(0, np.int8), ui.rejected
    rng = grasp_rng(seed, object_id, grasp_id)
    if labels.get("form", "share") == "event":
        failed = failure(traces, labels, dt, ui.settle_index, ui.contact_end)
        onset = None if failed is None else failed[0]
        starts, y = event_windows(ui.settle_index, ui.contact_end, onset, w, o, h,
                                  int(labels["windows_per_grasp"]), rng)  # fmt: skip
        return starts, y.astype(np.float64), y, None
    starts = window_starts(ui.settle_index, ui.contact_end, w, o, h,
                           int(labels["windows_per_grasp"]), rng)  # fmt: skip
    u = unstable_steps(traces, labels, ui.settle_index)
    r, y = predictive_labels(u, starts, ui.contact_end, w, o, h,
                             labels["label_low"], labels["label_high"])  # fmt: skip
    keep = y >= 0
    return starts[keep], r[keep], y[keep], None


def label_windows(
    replays: list[tuple[str | Path, str | Path]],
    out_dir: str | Path,
    labels: dict[str, Any],
    splits: dict[str, str],
    window_s: float,
    dt: float,
    seed: int,
    eps: float = 1e-6,
) -> pl.DataFrame:
    """Build the dataset of ``window_s`` from the replays: (summary table, trace file) pairs,
    as the rule declares them."""
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    w = step_counts(window_s, labels["offset_s"], labels["horizon_s"], dt)[0]
    rows: list[dict[str, Any]] = []
    chunks: list[np.ndarray] = []
    motion: list[np.ndarray] = []
    # the event form reads the failure anatomy's onset (labels.anatomy.failure: position)
    event = ("position",) if labels.get("form", "share") == "event" else ()
    wanted = dict.fromkeys(("velocity", "min_distance", *CHANNELS, *source_channels(labels),
                            *event))  # fmt: skip
    for g in replay_grasps(replays, splits, tuple(wanted)):
        tr = g.traces
        starts, r, y, _ = grasp_windows(tr, g.object, g.grasp_id, labels, window_s, dt, seed)
        if not len(starts):
            continue
        feats = np.stack([tr[c] for c in CHANNELS], axis=-1)  # (T, 5, 2)
        idx = starts[:, None] + np.arange(w)[None]
        chunks.append(feats[idx].astype(np.float32))
        speed = np.linalg.norm(tr["velocity"].astype(np.float64), axis=1)
        u = timestep_labels(speed, labels["v_slip"])
        motion.append(np.stack([u[idx], speed[idx]], axis=-1).astype(np.float32))
        for s, rs, ys in zip(starts, r, y, strict=True):
            rows.append({"object": g.object, "grasp_id": g.grasp_id, "shard": g.shard,
                         "start": int(s), "end": int(s) + w, "r": float(rs),
                         "label": int(ys), "split": g.split})  # fmt: skip
    index = pl.DataFrame(
        rows,
        schema={"object": pl.String, "grasp_id": pl.Int64, "shard": pl.Int32, "start": pl.Int64,
                "end": pl.Int64, "r": pl.Float64, "label": pl.Int8, "split": pl.String},
    ).with_row_index("sample_id")  # fmt: skip
    windows = np.concatenate(chunks) if chunks else np.zeros((0, w, 5, 2), np.float32)
    save_npy(out / "windows.npy", np.ascontiguousarray(windows, dtype=np.float32))
    moved = np.concatenate(motion) if motion else np.zeros((0, w, len(MOTION)), np.float32)
    save_npy(out / "motion.npy", np.ascontiguousarray(moved))
    write_json(out / "normalisation.json", normalisation(windows, index, eps))
    write_parquet(out / "index.parquet", index, metadata={"window_steps": w, "dt": dt,
                                                          "window_s": window_s})  # fmt: skip
    return index
