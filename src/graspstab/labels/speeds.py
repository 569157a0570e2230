"""What "unstable" means under the run's contact model: object speeds behind the labels (3.3.2).

Eq. 23 labels a timestep unstable at ||v|| >= 1.2 mm/s. Whether such a window announces a drop or
a held object's soft-contact creep depends on the contact model (docs/pipeline.md "Grasp replay"),
so the report sets, side by side: the creep of a statically held box under the model in use
(:func:`graspstab.replay.creep.box_creep`), the creep of the run's own grasps still held at the
end, and the median object speed over each labelled window's target interval (eq. 29's T_s).
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np
import polars as pl

from graspstab.common.io import read_parquet
from graspstab.labels.interval import usable_interval
from graspstab.labels.windows import step_counts
from graspstab.replay.creep import HELD_SQUEEZE, box_creep, held_creep
from graspstab.replay.traces import TraceFile


def target_speeds(
    speed: np.ndarray, starts: np.ndarray, w: int, o: int, h: int, contact_end: int
) -> np.ndarray:
    """Median ||v|| over each window's target interval [s + W + O, min(s + W + O + H, end))."""
    out = np.full(len(starts), np.nan)
    for i, s in enumerate(np.asarray(starts, dtype=np.int64)):
        seg = speed[s + w + o : min(s + w + o + h, contact_end, len(speed))]
        if len(seg):
            out[i] = float(np.median(seg))
    return out


def _quantiles(x: np.ndarray) -> dict[str, float | None]:
    x = x[np.isfinite(x)]
    if not len(x):
        return {"n": 0, "q10": None, "q50": None, "q90": None}
    q = np.quantile(x, [0.1, 0.5, 0.9])
    return {"n": int(len(x)), "q10": float(q[0]), "q50": float(q[1]), "q90": float(q[2])}


def summarise_speeds(
    index: pl.DataFrame,
    replay_tables: list[Path],
    trace_files: list[Path],
    contact: dict[str, Any],
    labels: dict[str, Any],
    window_s: float,
    dt: float,
) -> tuple[dict[str, Any], dict[str, np.ndarray]]:
    """The summary (JSON-ready) and the per-class target-interval speeds [m/s] of the dataset
    ``index`` of ``window_s`` windows, labelled with ``labels``."""
    w, o, h = step_counts(window_s, labels["offset_s"], labels["horizon_s"], dt)
    speeds: dict[int, list[np.ndarray]] = {0: [], 1: []}
    held: list[float] = []
    by_grasp = {k: g for k, g in index.group_by(["object", "shard", "grasp_id"])}
    for table_path, trace_path in zip(replay_tables, trace_files, strict=True):
        table = read_parquet(table_path)
        with TraceFile(trace_path) as npz:
            for g in table.iter_rows(named=True):
                key = (g["object"], int(g["shard"]), int(g["grasp_id"]))
                if key not in by_grasp and not g["held_at_end"]:
                    continue
                vel = npz.grasp(g["grasp_id"], ("velocity",))["velocity"].astype(np.float64)
                if g["held_at_end"]:
                    held.append(held_creep(vel, dt))
                if key not in by_grasp:
                    continue
                rows = by_grasp[key]
                speed = np.linalg.norm(vel, axis=1)
                dist = npz.grasp(g["grasp_id"], ("min_distance",))["min_distance"]
                dist = dist.astype(np.float64)
                # the label's target stops at contact end (3.3.4), so the speeds do too
                end = usable_interval(speed, dist, dt, labels["settle"],
                                      labels["contact_loss_s"]).contact_end  # fmt: skip
                got = target_speeds(speed, rows["start"].to_numpy(), w, o, h, end)
                for label in (0, 1):
                    speeds[label].append(got[rows["label"].to_numpy() == label])
    per_class = {k: np.concatenate(v) if v else np.zeros(0) for k, v in speeds.items()}
    summary = {
        "contact_model": contact["name"],
        "contact": contact,
        "v_slip": float(labels["v_slip"]),
        "box_creep": {"squeeze_n": HELD_SQUEEZE, "speed": box_creep(contact, dt=dt)},
        "held_creep": {**_quantiles(np.asarray(held)), "grasps": len(held)},
        "target_speed": {"stable": _quantiles(per_class[0]), "unstable": _quantiles(per_class[1])},
        "units": "m/s",
    }
    return summary, {"stable": per_class[0], "unstable": per_class[1]}
