"""What each replay protocol gives the learning stage: windows per split and class, by object.

Replays a run's annealed grasps under each named protocol variant (contact model, squeeze,
settle reading) and labels them with the baseline task (3.3), without writing traces: the
measurement behind the choice of the quick profile's defaults (docs/protocols.md).

A variant is a comma-separated list of ``key=value``: ``contact=reference|strict``,
``squeeze=<rad>`` (0 when not given, whatever the profile sets), ``require=either|both``,
``seconds=<replay length>``, ``kp=<servo gain>``, and the load ramp (docs/protocols.md):
``protocol=gravity|ramp`` and any ``replay.ramp`` key (``rate``, ``ceiling``, ``start_s``,
``directions``, ``path``, ``hold_fraction``, ``slip_speed``). Objects run in parallel
(``--jobs``); each prints one line per object, then a summary per variant:

    python benchmarks/protocol_matrix.py --workdir <wd> --variants contact=reference \\
        contact=reference,squeeze=0.1 contact=strict,protocol=ramp,path=hold,seconds=8

Under the ramp it also counts the grasps that slid while loaded (speed >= eq. 23's v_slip after
t0) and how long they stayed in contact after that (``slip_contact_s``, median).
"""

from __future__ import annotations

import argparse
import copy
import multiprocessing as mp
import time
from pathlib import Path
from typing import Any

import mujoco
import numpy as np
import polars as pl

from graspstab.common.runs import earliest_run
from graspstab.config import compose_config
from graspstab.labels.label_windows import grasp_windows
from graspstab.replay.grasp_setup import grasp_load
from graspstab.replay.run import run_replay
from graspstab.replay.scene import build_replay_scene, place_grasp, to_object_frame

CONFIG_DIR = Path(__file__).resolve().parents[1] / "config"
RAMP_KEYS = {"rate", "ceiling", "start_s", "directions", "path", "hold_fraction", "slip_speed"}


def slip_in_contact(traces: dict[str, np.ndarray], replay: dict, labels: dict) -> float | None:
    """Seconds in contact after the object first slid under load (None: it never slid)."""
    dt = replay["timestep"]
    speed = np.linalg.norm(traces["velocity"].astype(np.float64), axis=1)
    start = round(replay["ramp"]["start_s"] / dt)
    slid = np.flatnonzero(speed[start:] >= labels["v_slip"])
    if not len(slid):
        return None
    onset = start + int(slid[0])
    lost = ~np.isfinite(traces["min_distance"][onset:])
    loss = earliest_run(lost, max(1, round(labels["contact_loss_s"] / dt)), len(lost))
    return (len(lost) if loss is None else loss) * dt


def variant_config(spec: str) -> tuple[dict[str, Any], dict[str, Any], dict[str, str]]:
    """Replay and label params of one variant string, and the object splits."""
    pairs = dict(kv.split("=", 1) for kv in spec.split(",") if kv)
    overrides = [f"contact={pairs['contact']}"] if "contact" in pairs else []
    cfg = compose_config(CONFIG_DIR, overrides)
    replay, labels = copy.deepcopy(cfg["replay"]), copy.deepcopy(cfg["labels"])
    # explicit: no squeeze unless given (3.2), whatever the default profile sets
    replay["squeeze"]["angle"] = float(pairs.get("squeeze", 0.0))
    if "require" in pairs:
        labels["settle"]["require"] = pairs["require"]
    if "seconds" in pairs:
        replay["steps"] = round(float(pairs["seconds"]) / replay["timestep"])
    if "kp" in pairs:
        replay["contact"]["actuator"]["kp"] = float(pairs["kp"])
    replay["protocol"] = pairs.get("protocol", replay["protocol"])
    for key in RAMP_KEYS & pairs.keys():
        value = pairs[key]
        replay["ramp"][key] = value if key in ("directions", "path") else float(value)
    splits = {o: e["split"] for o, e in cfg["objects"]["items"].items()}
    return replay, labels, splits


def object_counts(args: tuple[str, str, Path, int | None]) -> dict[str, Any]:
    """Replay and label every grasp (the first ``limit``) of one object under one variant."""
    spec, obj, workdir, limit = args
    replay, labels, splits = variant_config(spec)
    t0 = time.perf_counter()
    scene = build_replay_scene(workdir / "results/hand", workdir / "results/objects" / obj, replay)
    data = mujoco.MjData(scene.model)
    dt = replay["timestep"]
    out = {"object": obj, "split": splits[obj], "grasps": 0, "held": 0, "usable": 0,
           "rejected": 0, "stable": 0, "unstable": 0, "simulated_s": 0.0, "slid": 0}  # fmt: skip
    speeds: list[float] = []
    in_contact: list[float] = []
    for table in sorted((workdir / "results/grasps" / obj).glob("shard_*.parquet")):
        grasps = pl.read_parquet(table)
        for g in (grasps if limit is None else grasps.head(limit)).iter_rows(named=True):
            pos = np.array([g[f"wrist_{a}"] for a in "xyz"])
            quat = np.array([g[f"quat_{a}"] for a in "wxyz"])
            place_grasp(scene, data, pos, quat, np.array([g[f"theta_{k:02d}"] for k in range(16)]),
                        np.asarray(replay["gravity"]))  # fmt: skip
            stop = round(replay["stop_after_loss_s"] / dt)
            load = grasp_load(replay, scene, scene.model.opt.gravity.copy(), obj,
                              int(g["grasp_id"]))  # fmt: skip
            res = run_replay(scene.model, data, scene.layout, replay["steps"],
                             replay["chunk_steps"], stop, load, scene.object_body)  # fmt: skip
            tr = to_object_frame(res.traces, pos, quat)
            if load is not None and (after := slip_in_contact(tr, replay, labels)) is not None:
                out["slid"] += 1
                in_contact.append(after)
            out["grasps"] += 1
            out["simulated_s"] += res.steps * dt
            out["held"] += int(res.stop_reason == "completed")
            if res.stop_reason == "diverged":
                continue
            starts, _, y, rejected = grasp_windows(tr, obj, int(g["grasp_id"]), labels,
                                                   labels["window_s"], dt, 0)  # fmt: skip
            out["rejected"] += int(rejected is not None)
            out["usable"] += int(len(starts) > 0)
            out["stable"] += int((y == 0).sum())
            out["unstable"] += int((y == 1).sum())
            w = round(labels["window_s"] / dt)
            speed = np.linalg.norm(tr["velocity"].astype(np.float64), axis=1)
            speeds += [float(np.median(speed[s + w : s + 2 * w])) for s in starts[y == 1]]
    out["wall_s"] = time.perf_counter() - t0
    out["slip_contact_s"] = float(np.median(in_contact)) if in_contact else float("nan")
    out["unstable_speed_q50_mm_s"] = float(np.median(speeds)) * 1e3 if speeds else float("nan")
    print(f"  [{spec}] {obj}: {out}", flush=True)
    return out


def main() -> None:
    """Run every variant over every object with shard tables, print the tables."""
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--workdir", type=Path, required=True)
    ap.add_argument("--variants", nargs="+", default=["contact=reference"])
    ap.add_argument("--objects", default=None, help="comma-separated ids (default: all)")
    ap.add_argument("--jobs", type=int, default=2)
    ap.add_argument("--max-grasps", type=int, default=None, help="first N grasps of each shard")
    args = ap.parse_args()
    objects = args.objects.split(",") if args.objects else sorted(
        p.name for p in (args.workdir / "results/grasps").iterdir() if p.is_dir())  # fmt: skip
    tasks = [(v, o, args.workdir, args.max_grasps) for v in args.variants for o in objects]
    with mp.get_context("spawn").Pool(args.jobs) as pool:
        rows = pool.map(object_counts, tasks, chunksize=1)
    table = pl.DataFrame([{"variant": v, **r} for (v, *_), r in zip(tasks, rows, strict=True)])
    with pl.Config(tbl_rows=200, tbl_cols=20, tbl_width_chars=200):
        for v in args.variants:
            t = table.filter(pl.col("variant") == v)
            print(
                f"\n== {v}: {t['wall_s'].sum():.0f} job-s, {t['simulated_s'].sum():.0f} s simulated"
            )
            print(t.drop("variant", "wall_s").sort("split", "object"))
            summary = t.group_by("split").agg(
                pl.col("grasps", "usable", "stable").sum(),
                pl.col("unstable").sum().alias("n_unstable"),
                (pl.col("stable") + pl.col("unstable") > 0).sum().alias("objects_with_windows"),
            )
            total = pl.col("stable") + pl.col("n_unstable")
            summary = summary.with_columns(
                (pl.col("n_unstable") / total).alias("unstable_share")
            ).sort("split")
            print(summary)


if __name__ == "__main__":
    main()
