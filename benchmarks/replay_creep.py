"""Creep of held objects under the replay's contact settings (3.2, DESIGN.md "simulation facts").

Two parts, both printed per contact setting (cone, impratio, noslip iterations):

* the analytic scene of the tests: a 0.2 kg box squeezed by two position-driven fingertips with
  5 N (held) or 0.3 N (too weak, friction 1: it must fall); mean |v_z| over the second half of
  4 s after gravity is switched on;
* with ``--workdir``, the quick profile's real grasps of some objects: how many are still held
  after ``--seconds`` and the median speed of the held ones over the last second.

Target: held objects creep at less than a tenth of the 1.2 mm/s instability threshold (3.3.2).

    python benchmarks/replay_creep.py [--workdir . --objects 061_foam_brick,013_apple]
"""

from __future__ import annotations

import argparse
import copy
from pathlib import Path

import mujoco
import numpy as np
import polars as pl
import yaml

from graspstab.replay.run import run_replay
from graspstab.replay.scene import build_replay_scene, place_grasp

DEFAULTS = Path(__file__).resolve().parents[1] / "config" / "replay" / "default.yaml"
SETTINGS = [("pyramidal", 1, 0), ("elliptic", 1, 0), ("elliptic", 10, 0), ("elliptic", 100, 0),
            ("elliptic", 10, 10)]  # fmt: skip
BOX = """
<mujoco>
  <option timestep="0.0005" gravity="0 0 0"/>
  <worldbody>
    <body name="tip_a" pos="-0.035 0 0">
      <joint name="slide_a" type="slide" axis="1 0 0" damping="5"/>
      <geom type="box" size="0.01 0.015 0.015" mass="0.05"/>
    </body>
    <body name="tip_b" pos="0.035 0 0">
      <joint name="slide_b" type="slide" axis="-1 0 0" damping="5"/>
      <geom type="box" size="0.01 0.015 0.015" mass="0.05"/>
    </body>
    <body name="object"><freejoint/><geom type="box" size="0.02 0.02 0.02" mass="0.2"/></body>
  </worldbody>
  <actuator>
    <position joint="slide_a" kp="1000"/><position joint="slide_b" kp="1000"/>
  </actuator>
</mujoco>
"""


def box_creep(cone: str, impratio: float, noslip: int, squeeze: float, seconds: float = 4.0):
    """Mean |v_z| [m/s] of the squeezed box over the second half of ``seconds`` under gravity."""
    spec = mujoco.MjSpec.from_string(BOX)
    spec.option.cone = getattr(mujoco.mjtCone, f"mjCONE_{cone.upper()}")
    spec.option.impratio = impratio
    spec.option.noslip_iterations = noslip
    model = spec.compile()
    data = mujoco.MjData(model)
    model.actuator_forcerange[:] = (-squeeze, squeeze)
    model.actuator_forcelimited[:] = 1
    data.ctrl[:] = 0.05
    for _ in range(400):
        mujoco.mj_step(model, data)
    model.opt.gravity[:] = (0.0, 0.0, -9.81)
    n = int(seconds / model.opt.timestep)
    vz = np.empty(n)
    dof = model.jnt_dofadr[model.body("object").jntadr[0]]
    for i in range(n):
        mujoco.mj_step(model, data)
        vz[i] = data.qvel[dof + 2]
    return float(np.abs(vz[n // 2 :]).mean())


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
                v = np.linalg.norm(run.traces["velocity"][-round(1.0 / dt) :], axis=1)
                speeds.append(float(np.median(v)))
        med = f"{np.median(speeds) * 1000:.3f}" if speeds else "n/a"
        out.append(f"{obj}: held {len(speeds)}/{table.height}, creep {med} mm/s")
    return out


def main() -> None:
    """Print both parts for every setting in SETTINGS."""
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--workdir", type=Path, default=None)
    ap.add_argument("--objects", default="061_foam_brick,009_gelatin_box,013_apple")
    ap.add_argument("--seconds", type=float, default=10.0)
    args = ap.parse_args()
    base = yaml.safe_load(DEFAULTS.read_text())
    for cone, impratio, noslip in SETTINGS:
        held = box_creep(cone, impratio, noslip, 5.0) * 1000
        weak = box_creep(cone, impratio, noslip, 0.3, seconds=1.0) * 1000
        line = (
            f"{cone:9s} impratio {impratio:5g} noslip {noslip:2d}: box held {held:8.4f} mm/s, "
            f"box squeezed too weakly {weak:7.0f} mm/s"
        )
        if args.workdir is not None:
            params = copy.deepcopy(base)
            params.update(cone=cone, impratio=float(impratio), noslip_iterations=noslip)
            objects = args.objects.split(",")
            line += "\n    " + "\n    ".join(grasp_creep(args.workdir, objects, params,
                                                          args.seconds))  # fmt: skip
        print(line, flush=True)


if __name__ == "__main__":
    main()
