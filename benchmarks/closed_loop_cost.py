"""What closing the loop costs: closed-loop replays against the open-loop replay, same grasps.

The reflex runs with a streaming monitor around the reference's 0.01 s LSTM (3.4.3's sweep
configuration, random weights) whose threshold is 1, so it scores every stride of every replay
and never fires: the most the loop can cost (once it fires with release ``never`` it stops
scoring and the chunks grow back). Also times the ``always`` policy (a fixed schedule: per-step
targets, open-loop chunks). Needs a finished run's hand, objects and grasps.

    python benchmarks/closed_loop_cost.py --results <workdir>/results --objects 014_lemon \\
        --grasps 8 --run-config profile=wide [--protocol creep_free]
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

import mujoco
import numpy as np
import torch

from graspstab.closedloop.closed_loop import protocol_params, replay_once
from graspstab.closedloop.policies import Policy, actuator_axes, make_reflex
from graspstab.closedloop.reflex import ReflexParams
from graspstab.common.io import read_parquet
from graspstab.config import load_config
from graspstab.config.show import parse_snakemake_config
from graspstab.learning.models import build_model
from graspstab.monitor.constants import MonitorConstants
from graspstab.monitor.scoring import TorchScorer
from graspstab.replay.grasp_setup import slip_sampler
from graspstab.replay.scene import build_replay_scene

ROOT = Path(__file__).resolve().parents[1]


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--results", type=Path, required=True)
    ap.add_argument("--objects", nargs="+", required=True)
    ap.add_argument("--grasps", type=int, default=8, help="grasps per object (the first ones)")
    ap.add_argument("--run-config", nargs="*", default=[], help="the run's --config KEY=VALUE")
    ap.add_argument("--protocol", choices=["reference", "creep_free"], default="reference")
    args = ap.parse_args()
    torch.set_num_threads(1)
    cfg = load_config(ROOT / "config", ROOT / "workflow/schemas/config.schema.yaml",
                      parse_snakemake_config(args.run_config), check_files=False)  # fmt: skip
    params = protocol_params(cfg, args.protocol)
    cl, mon = cfg["closed_loop"], cfg["monitor"]
    dt = float(params["timestep"])
    torch.manual_seed(0)
    model = build_model(cfg["sweep"]["models"]["lstm"])
    window = round(cl["window_s"] / dt)
    scorer = TorchScorer(model, MonitorConstants(np.zeros((5, 2)), np.ones((5, 2)), 1.0, window))
    lstm = Policy("lstm", "monitor", scorer, threshold=1.0)
    always = Policy("always", "always")
    reflex = ReflexParams(**cl["reflex"])
    walls: dict[str, list[float]] = {"open loop": [], "lstm monitor": [], "always": []}
    ran: dict[str, int] = dict.fromkeys(walls, 0)  # steps simulated
    steps = 0
    for obj in args.objects:
        scene = build_replay_scene(args.results / "hand", args.results / "objects" / obj, params)
        data = mujoco.MjData(scene.model)
        slip = slip_sampler(scene, params)
        closing, upper = actuator_axes(scene, scene.model.nu)
        grasps = read_parquet(args.results / "grasps" / obj / "shard_0.parquet").head(args.grasps)
        for g in grasps.iter_rows(named=True):
            t0 = time.perf_counter()
            base = replay_once(scene, data, g, obj, params, slip=slip)
            walls["open loop"].append(time.perf_counter() - t0)
            steps += base.steps
            ran["open loop"] += base.steps
            for name, policy in (("lstm monitor", lstm), ("always", always)):
                grip = make_reflex(policy, reflex, closing, upper, dt, stride=mon["stride"],
                                   debounce=mon["debounce"])  # fmt: skip
                t0 = time.perf_counter()
                run = replay_once(scene, data, g, obj, params, grip, slip)
                walls[name].append(time.perf_counter() - t0)
                ran[name] += run.steps
                if name == "lstm monitor":
                    # the stop rules are checked between chunks, so a shorter chunk may stop
                    # a dropped grasp sooner: compare the steps both ran
                    n = min(run.steps, base.steps)
                    gap = float(np.abs(run.traces["normal"][:n] - base.traces["normal"][:n]).max())
                    print(f"{obj} grasp {g['grasp_id']}: {base.steps} open-loop steps "
                          f"({base.stop_reason}), {run.steps} closed-loop; largest normal-force "
                          f"difference over the common steps {gap:.2e} N")
    chunk = make_reflex(lstm, reflex, closing, upper, dt).delay + 1
    print(f"\n{args.protocol}: {len(walls['open loop'])} grasps, {steps} open-loop steps, "
          f"chunks of {chunk} steps while the monitor is live (stride {mon['stride']})")
    base = sum(walls["open loop"])
    per_step = base / ran["open loop"]
    for name, w in walls.items():
        # a shorter chunk may stop a dropped grasp sooner: the per-step ratio is the fair one
        print(f"{name:>14}: {sum(w):7.2f} s wall, {sum(w) / base:.2f} x the open loop; "
              f"{ran[name]} steps, {sum(w) / ran[name] / per_step:.2f} x its wall per step")


if __name__ == "__main__":
    main()
