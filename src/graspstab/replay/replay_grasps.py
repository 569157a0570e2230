"""Replay stage entry point: every grasp of one object x shard under gravity (3.2, eqs. 17-19).

Writes two files per shard:

* ``traces_<k>.npz`` (compressed, float32): per grasp ``g<id>_<channel>`` arrays, channels
  ``position (T, 3)`` and ``velocity (T, 3)`` of the object in the object frame [m, m/s],
  ``min_distance (T,)`` (d_t [m], NaN without hand-object contact), ``normal`` and ``shear
  (T, 5)`` (eq. 18 [N], fingertips in eq. 19's order). A zip member per array, so the labelling
  stage reads one grasp without loading the shard.
* ``replays_<k>.parquet``: one row per grasp, the summary below.

and, with ``timing_path``, the job's timing sidecar (JSON): its wall time, simulated steps per
second and each grasp's wall time, which differ on every run and so stay out of the data.
"""

from __future__ import annotations

import logging
import time
from pathlib import Path
from typing import Any

import mujoco
import numpy as np
import polars as pl

from graspstab.common.io import read_parquet, save_npz, write_parquet
from graspstab.common.logs import setup_logging
from graspstab.common.provenance import provenance, write_timing
from graspstab.common.runs import earliest_run
from graspstab.replay.grasp_setup import deep_stop, grasp_load, slip_sampler
from graspstab.replay.ramp import RampLoad
from graspstab.replay.run import ReplayResult, run_replay
from graspstab.replay.scene import build_replay_scene, place_grasp, to_object_frame
from graspstab.replay.traces import trace_key

log = logging.getLogger("graspstab.replay")


def summarise_replay(
    result: ReplayResult, traces: dict[str, np.ndarray], dt: float, loss_steps: int
) -> dict[str, Any]:
    """Per-grasp summary: how it ended, how far the object moved, how deep the hand reached."""
    pos = traces["position"].astype(np.float64)
    dist = traces["min_distance"].astype(np.float64)
    defined = np.isfinite(dist)
    # first run of undefined d_t at least loss_steps long (3.3.1's rule, here from t = 0)
    loss = earliest_run(~defined, loss_steps, len(dist))
    speed_end = float(np.linalg.norm(traces["velocity"][-1])) if len(pos) else float("nan")
    return {
        "steps": result.steps,
        "duration_s": result.steps * dt,
        "stop_reason": result.stop_reason,
        "diverged": result.stop_reason == "diverged",
        "final_displacement": float(np.linalg.norm(pos[-1] - pos[0])) if len(pos) else np.nan,
        "max_penetration": float(max(0.0, -np.nanmin(dist))) if defined.any() else 0.0,
        "initial_distance": float(dist[0]) if len(dist) else np.nan,
        "contact_loss_s": np.nan if loss is None else loss * dt,
        "final_speed": speed_end,
        "held_at_end": bool(result.stop_reason == "completed" and defined[-1]),
        "contact_overflow": result.overflow,
        "warnings": ",".join(sorted(result.warnings)),
    }


def ramp_summary(load: RampLoad, traces: dict[str, np.ndarray], dt: float) -> dict[str, Any]:
    """Per-grasp load-ramp columns: the largest load it carried and, under the ``hold`` path, when
    and at what load the object first slid (NaN if it never did), loads in units of m g."""
    applied = np.linalg.norm(traces["load"].astype(np.float64), axis=1)
    slid = load.slip_step is not None
    return {
        "load_start_s": load.start_s,
        "load_rate_mg": load.rate,
        "ramp_peak_load_mg": float(applied.max(initial=0.0)) / load.weight,
        "ramp_slip_s": load.slip_step * dt if slid else np.nan,
        "ramp_slip_load_mg": float(applied[load.slip_step]) / load.weight
        if slid and load.slip_step < len(applied) else np.nan,
    }  # fmt: skip


def replay_grasps(
    object_id: str,
    object_dir: str | Path,
    hand_dir: str | Path,
    grasp_table: str | Path,
    traces_path: str | Path,
    summary_path: str | Path,
    params: dict[str, Any],
    log_file: str | Path | None = None,
    timing_path: str | Path | None = None,
) -> pl.DataFrame:
    """Replay every grasp of ``grasp_table``; write the traces, the summary table and (with
    ``timing_path``) the timing sidecar."""
    setup_logging(log_file)
    t0 = time.perf_counter()
    grasps = read_parquet(grasp_table)
    scene = build_replay_scene(hand_dir, object_dir, params)
    data = mujoco.MjData(scene.model)
    dt = float(params["timestep"])
    steps, chunk = int(params["steps"]), int(params["chunk_steps"])
    stop_loss = max(1, round(float(params["stop_after_loss_s"]) / dt))
    loss_steps = max(1, round(float(params["contact_loss_s"]) / dt))
    too_deep = deep_stop(params)
    slip = slip_sampler(scene, params)
    gravity = np.asarray(params["gravity"], dtype=np.float64)
    arrays: dict[str, np.ndarray] = {}
    rows, walls = [], []
    for i, g in enumerate(grasps.iter_rows(named=True)):
        pos = np.array([g[f"wrist_{a}"] for a in "xyz"])
        quat = np.array([g[f"quat_{a}"] for a in "wxyz"])
        joints = np.array([g[f"theta_{k:02d}"] for k in range(16)])
        start = time.perf_counter()
        place_grasp(scene, data, pos, quat, joints, gravity)
        load = grasp_load(params, scene, scene.model.opt.gravity.copy(), object_id,
                          int(g["grasp_id"]))  # fmt: skip
        result = run_replay(scene.model, data, scene.layout, steps, chunk, stop_loss, load,
                            scene.object_body, too_deep, slip=slip)  # fmt: skip
        traces = to_object_frame(result.traces, pos, quat)
        for channel, values in traces.items():
            arrays[trace_key(g["grasp_id"], channel)] = values
        summary = summarise_replay(result, traces, dt, loss_steps)
        if load is not None:
            summary.update(ramp_summary(load, traces, dt))
        rows.append(
            {
                "grasp_id": int(g["grasp_id"]),
                "object": object_id,
                "shard": int(g["shard"]),
                **summary,
            }
        )
        walls.append(time.perf_counter() - start)
        log.info(
            "%s grasp %d (%d/%d): %s after %.2f s, moved %.1f mm, deepest %.1f mm (%.1f s wall)",
            object_id, g["grasp_id"], i + 1, grasps.height, summary["stop_reason"],
            summary["duration_s"], summary["final_displacement"] * 1e3,
            summary["max_penetration"] * 1e3, walls[-1],
        )  # fmt: skip
    table = pl.DataFrame(rows)
    save_npz(traces_path, **arrays)
    elapsed = time.perf_counter() - t0
    simulated = float(table["duration_s"].sum()) if table.height else 0.0
    steps_per_s = simulated / dt / elapsed if elapsed > 0 else None
    meta = {
        "object_id": object_id,
        "grasps": table.height,
        "simulated_s": simulated,
        "frame": "object frame (centre of mass, +z up); row t = state before step t",
        "contact_model": params["contact"]["name"],
        "squeeze_rad": float(params["squeeze"]["angle"]),
        "protocol": params["protocol"],
        "mujoco_version": mujoco.__version__,
        "provenance": provenance("replay", params),
    }
    write_parquet(summary_path, table, metadata=meta)
    write_timing(timing_path, {
        "object_id": object_id,
        "wall_time_s": elapsed,
        "simulated_s": simulated,
        "steps_per_s": steps_per_s,
        "grasp_id": [r["grasp_id"] for r in rows],
        "wall_s": walls,
    })  # fmt: skip
    log.info(
        "%s: %d replays in %.1f s (%.0f simulated steps/s); held to the end %d, stopped early %d",
        object_id, table.height, elapsed, steps_per_s or 0,
        int(table["held_at_end"].sum()) if table.height else 0,
        int((table["stop_reason"] != "completed").sum()) if table.height else 0,
    )  # fmt: skip
    return table
