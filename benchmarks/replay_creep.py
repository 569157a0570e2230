"""Creep of held objects under each named contact model (3.2; docs/design.md, contact model).

Two parts, printed per contact model (config/contact/: reference, strict) and, for the analytic
part, for the solver settings in between:

* the analytic scene of the tests (graspstab.replay.creep.box_creep): a 0.2 kg box squeezed by
  two position-driven fingertips with 5 N (held) or 0.3 N (too weak, friction 1: it must fall);
  mean |v_z| over the second half of 4 s after gravity is switched on;
* with ``--workdir``, a run's real grasps of some objects, replayed with the model's solver
  options and servo gains (and ``--squeeze``): how many are still held after ``--seconds`` and
  the median speed of the held ones over the last second.

Under ``strict`` held objects creep at less than a tenth of the 1.2 mm/s instability threshold
(3.3.2); under ``reference`` (MuJoCo's defaults) at its order.

    python benchmarks/replay_creep.py [--workdir . --objects 061_foam_brick,013_apple]
"""

from __future__ import annotations

import argparse
import copy
from pathlib import Path

import mujoco
import numpy as np
import polars as pl

from graspstab.config import compose_config
from graspstab.replay.creep import HELD_SQUEEZE, WEAK_SQUEEZE, box_creep, held_creep
from graspstab.replay.run import run_replay
from graspstab.replay.scene import build_replay_scene, place_grasp

CONFIG_DIR = Path(__file__).resolve().parents[1] / "config"
MODELS = ("reference", "strict")
# solver settings between the two models (cone, impratio, noslip iterations)
BETWEEN = [("elliptic", 1.0, 0), ("elliptic", 10.0, 0), ("elliptic", 100.0, 0)]


def grasp_creep(workdir: Path, objects: list[str], params: dict, seconds: float) -> list[str]:
    """Per object: held after ``seconds`` / replays, median speed of the held over the last 1 s."""
    out = []
    dt = params["timestep"]
    for obj in objects:
        scene = build_replay_scene(workdir / "results/hand", workdir / "results/objects" / obj,
                                   params)  # fmt: skip
        data = mujoco.MjData(scene.model)
        table = pl.read_parquet(workdir / "results/grasps" / obj / "shard_0.parquet")
        speeds = []
        for g in table.iter_rows(named=True):
            place_grasp(
                scene, data, np.array([g[f"wrist_{a}"] for a in "xyz"]),
                np.array([g[f"quat_{a}"] for a in "wxyz"]),
                np.array([g[f"theta_{k:02d}"] for k in range(16)]), np.array(params["gravity"]),
            )  # fmt: skip
            run = run_replay(scene.model, data, scene.layout, round(seconds / dt), 1000, 400)
            if run.stop_reason == "completed" and np.isfinite(run.traces["min_distance"][-1]):
                speeds.append(held_creep(run.traces["velocity"], dt))
        med = f"{np.median(speeds) * 1000:.3f}" if speeds else "n/a"
        out.append(f"{obj}: held {len(speeds)}/{table.height}, creep {med} mm/s")
    return out


def _line(name: str, contact: dict) -> str:
    held = box_creep(contact, HELD_SQUEEZE) * 1000
    weak = box_creep(contact, WEAK_SQUEEZE, seconds=1.0) * 1000
    return (
        f"{name:10s} ({contact['cone']}, impratio {contact['impratio']:g}, noslip "
        f"{contact['noslip_iterations']}): box held {held:8.4f} mm/s, squeezed too weakly "
        f"{weak:7.0f} mm/s"
    )


def main() -> None:
    """Print both parts for both contact models, the analytic part for the settings between."""
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--workdir", type=Path, default=None)
    ap.add_argument("--objects", default="061_foam_brick,009_gelatin_box,013_apple")
    ap.add_argument("--seconds", type=float, default=10.0)
    ap.add_argument("--squeeze", type=float, default=None, help="[rad]; default: the config's")
    args = ap.parse_args()
    for model in MODELS:
        params = copy.deepcopy(compose_config(CONFIG_DIR, [f"contact={model}"])["replay"])
        if args.squeeze is not None:
            params["squeeze"]["angle"] = args.squeeze
        line = _line(model, params["contact"])
        if args.workdir is not None:
            objects = args.objects.split(",")
            line += "\n    " + "\n    ".join(grasp_creep(args.workdir, objects, params,
                                                          args.seconds))  # fmt: skip
        print(line, flush=True)
    for cone, impratio, noslip in BETWEEN:
        contact = {"cone": cone, "impratio": impratio, "noslip_iterations": noslip}
        print(_line("between", contact), flush=True)


if __name__ == "__main__":
    main()
