"""Replay throughput: the replay stage against raw ``mj_step`` on the same scene (docs/design.md).

For each grasp of a shard table, in one run: the replay as the stage runs it (chunked rollout,
sensors, stop rules), then the same placed grasp stepped by a plain ``mj_step`` loop for the same
number of steps. Prints the effective and raw steps per second and their ratio (target: within
15 %), replays per hour on 2 cores at the configured settings, and the traces' storage per
simulated second (compressed float32, as the stage writes them).

    python benchmarks/replay_throughput.py --object-dir results/objects/061_foam_brick \\
        --hand-dir results/hand --grasps results/grasps/061_foam_brick/shard_0.parquet
"""

from __future__ import annotations

import argparse
import io
import time
from pathlib import Path

import mujoco
import numpy as np
import polars as pl
import yaml

from graspstab.replay.run import run_replay
from graspstab.replay.scene import build_replay_scene, place_grasp, to_object_frame

DEFAULTS = Path(__file__).resolve().parents[1] / "config" / "replay" / "default.yaml"


def main() -> None:
    """Print the figures for up to ``--limit`` grasps of one shard table."""
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--object-dir", type=Path, required=True)
    ap.add_argument("--hand-dir", type=Path, required=True)
    ap.add_argument("--grasps", type=Path, required=True, help="a shard table of the object")
    ap.add_argument("--limit", type=int, default=16)
    args = ap.parse_args()
    params = yaml.safe_load(DEFAULTS.read_text())
    dt = float(params["timestep"])
    scene = build_replay_scene(args.hand_dir, args.object_dir, params)
    data = mujoco.MjData(scene.model)
    gravity = np.asarray(params["gravity"])
    stop = max(1, round(params["stop_after_loss_s"] / dt))
    total_steps = replay_s = raw_s = 0.0
    arrays = {}
    for row in pl.read_parquet(args.grasps).head(args.limit).iter_rows(named=True):
        pos = np.array([row[f"wrist_{a}"] for a in "xyz"])
        quat = np.array([row[f"quat_{a}"] for a in "wxyz"])
        joints = np.array([row[f"theta_{k:02d}"] for k in range(16)])
        place_grasp(scene, data, pos, quat, joints, gravity)
        t0 = time.perf_counter()
        result = run_replay(
            scene.model, data, scene.layout, params["steps"], params["chunk_steps"], stop
        )
        traces = to_object_frame(result.traces, pos, quat)
        replay_s += time.perf_counter() - t0
        arrays.update({f"g{row['grasp_id']}_{c}": v for c, v in traces.items()})
        place_grasp(scene, data, pos, quat, joints, gravity)
        t0 = time.perf_counter()
        for _ in range(result.steps):
            mujoco.mj_step(scene.model, data)
        raw_s += time.perf_counter() - t0
        total_steps += result.steps
    buf = io.BytesIO()
    np.savez_compressed(buf, **arrays)
    n = min(args.limit, pl.read_parquet(args.grasps).height)
    simulated = total_steps * dt
    print(f"object {args.object_dir.name}: {n} replays, {simulated:.1f} s simulated")
    print(f"replay stage: {total_steps / replay_s:8.0f} steps/s ({replay_s:.1f} s)")
    print(f"raw mj_step:  {total_steps / raw_s:8.0f} steps/s ({raw_s:.1f} s)")
    print(f"ratio {raw_s / replay_s:.3f} (replay rate / raw rate; target >= 0.85)")
    print(f"replays per hour on 2 cores: {2 * 3600 * n / replay_s:.0f} (early stops included)")
    print(f"trace storage: {buf.tell() / simulated / 1024:.1f} KiB per simulated second")


if __name__ == "__main__":
    main()
