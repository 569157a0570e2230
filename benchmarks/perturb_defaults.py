"""What the creep-free benchmark's load protocol gives an early-warning study, per variant: how
usable grasps fail (anatomy), how long they stay still first, and the still-now windows' classes.

Replays a run's annealed grasps as the creep-free benchmark does (creep_free's contact model,
squeeze and length) under each variant, a list of Hydra overrides on top of the run's config
(``creep_free.load=perturb`` unless a variant sets it), then for every usable grasp its failure
anatomy (graspstab.labels.anatomy) and its baseline windows under each labelling (``--labels``:
``key=value`` changes to the benchmark's labels group, e.g. ``source=contact_slip`` or
``form=event horizon_s=1.0``; the benchmark's own labels when none). Prints, per variant: usable
grasps; the share that fail after a still period of at least ``--still-s`` with a still window
before onset; onset quartiles after settle; the failure types; and per labelling and split the
still-now windows (no eq. 23 step in the observation window), their positives and share. The
measurement behind replay.perturb's defaults (docs/protocols.md, "The hidden-onset
disturbance"):

    python benchmarks/perturb_defaults.py --workdir <wd> --jobs 2 \\
        --variant "replay.perturb.rate=[2,10]" --labels source=displacement form=event
"""

from __future__ import annotations

import argparse
import json
import multiprocessing as mp
import shlex
import time
from pathlib import Path
from typing import Any

import mujoco
import numpy as np
import polars as pl

from graspstab.config import compose_config
from graspstab.labels.anatomy import TYPES, grasp_anatomy
from graspstab.labels.label_windows import grasp_windows
from graspstab.labels.windows import timestep_labels
from graspstab.replay.grasp_setup import grasp_load, slip_sampler
from graspstab.replay.protocols import creep_free_labels, creep_free_replay
from graspstab.replay.run import run_replay
from graspstab.replay.scene import build_replay_scene, place_grasp, to_object_frame

CONFIG_DIR = Path(__file__).resolve().parents[1] / "config"


def variant_config(variant: str) -> tuple[dict[str, Any], dict[str, Any], dict[str, str]]:
    """Replay params, labels and object splits of one variant (Hydra overrides)."""
    overrides = shlex.split(variant)
    if not any(o.startswith("creep_free.load=") for o in overrides):
        overrides = ["creep_free.load=perturb", *overrides]
    cfg = compose_config(CONFIG_DIR, overrides)
    splits = {o: e["split"] for o, e in cfg["objects"]["items"].items()}
    return creep_free_replay(cfg), creep_free_labels(cfg), splits


def labelling(labels: dict[str, Any], change: str) -> dict[str, Any]:
    """``labels`` with the ``key=value`` changes of one ``--labels`` entry (numbers as floats)."""
    out = dict(labels)
    for kv in change.split():
        key, value = kv.split("=", 1)
        if key not in out:
            raise SystemExit(f"--labels: labels has no key {key!r}")
        out[key] = value if isinstance(out[key], str) else float(value)
    return out


def object_rows(args: tuple[str, str, Path, tuple[str, ...]]) -> list[dict[str, Any]]:
    """Replay every grasp of one object under one variant: one row per usable grasp."""
    variant, obj, workdir, changes = args
    replay, labels, splits = variant_config(variant)
    labellings = {c: labelling(labels, c) for c in changes}
    scene = build_replay_scene(workdir / "results/hand", workdir / "results/objects" / obj, replay)
    data = mujoco.MjData(scene.model)
    slip = slip_sampler(scene, replay)
    dt = float(replay["timestep"])
    w = round(labels["window_s"] / dt)
    rows = []
    t0 = time.perf_counter()
    for table in sorted((workdir / "results/grasps" / obj).glob("shard_*.parquet")):
        for g in pl.read_parquet(table).iter_rows(named=True):
            pos = np.array([g[f"wrist_{a}"] for a in "xyz"])
            quat = np.array([g[f"quat_{a}"] for a in "wxyz"])
            place_grasp(scene, data, pos, quat, np.array([g[f"theta_{k:02d}"] for k in range(16)]),
                        np.asarray(replay["gravity"]))  # fmt: skip
            gid = int(g["grasp_id"])
            load = grasp_load(replay, scene, scene.model.opt.gravity.copy(), obj, gid)
            res = run_replay(scene.model, data, scene.layout, int(replay["steps"]),
                             int(replay["chunk_steps"]), round(replay["stop_after_loss_s"] / dt),
                             load, scene.object_body, slip=slip)  # fmt: skip
            if res.stop_reason == "diverged":
                continue
            tr = to_object_frame(res.traces, pos, quat)
            anatomy = grasp_anatomy(tr, labels, dt)
            if anatomy is None:
                continue
            speed = np.linalg.norm(tr["velocity"].astype(np.float64), axis=1)
            u = timestep_labels(speed, labels["v_slip"])
            row = {"object": obj, "grasp_id": gid, "split": splits[obj], **anatomy,
                   "load_start_s": None if load is None else load.start_s}  # fmt: skip
            for change, lab in labellings.items():
                starts, _, y, _ = grasp_windows(tr, obj, gid, lab, lab["window_s"], dt, 0)
                still = np.array([not u[s : s + w].any() for s in starts], dtype=bool)
                row[change] = {"still_windows": int(still.sum()),
                               "still_positive": int((y[still] == 1).sum()),
                               "windows": len(starts), "positive": int((y == 1).sum())}  # fmt: skip
            rows.append(row)
    print(f"  [{variant}] {obj}: {len(rows)} usable grasps, "
          f"{time.perf_counter() - t0:.0f} s", flush=True)  # fmt: skip
    return rows


def report(
    variant: str, rows: list[dict[str, Any]], still_s: float, changes: tuple[str, ...]
) -> dict[str, Any]:
    """The variant's figures (see the module docstring)."""
    failed = [r for r in rows if r["outcome"] == "failed"]
    late = [r for r in failed if r["onset_s"] >= still_s and r["still_window"]]
    onsets = [r["onset_s"] for r in failed]
    still_now = {}
    for change in changes:
        splits = {}
        for split in ("train", "val", "test"):
            part = [r[change] for r in rows if r["split"] == split]
            n = sum(p["still_windows"] for p in part)
            pos = sum(p["still_positive"] for p in part)
            splits[split] = {"still_windows": n, "positive": pos,
                             "share": round(pos / n, 3) if n else None,
                             "windows": sum(p["windows"] for p in part),
                             "all_positive": sum(p["positive"] for p in part)}  # fmt: skip
        still_now[change or "benchmark labels"] = splits
    return {
        "variant": variant,
        "usable": len(rows),
        "failed": len(failed),
        "failed_after_still": len(late),
        "failed_after_still_share": round(len(late) / len(rows), 3) if rows else None,
        "onset_quartiles_s": [round(float(q), 2) for q in np.quantile(onsets, [0.25, 0.5, 0.75])]
        if onsets else None,
        "types": {t: sum(r["type"] == t for r in failed) for t in TYPES},
        "types_after_still": {t: sum(r["type"] == t for r in late) for t in TYPES},
        "still_now": still_now,
    }


def main() -> None:
    """Run every variant over every object with shard tables, print one JSON line each."""
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--workdir", type=Path, required=True)
    ap.add_argument("--variant", action="append", default=None,
                    help="Hydra overrides, space-separated (repeat for several variants)")
    ap.add_argument("--objects", default=None, help="comma-separated ids (default: all)")
    ap.add_argument("--jobs", type=int, default=2)
    ap.add_argument("--still-s", type=float, default=0.5, help="still period before onset [s]")
    ap.add_argument("--labels", nargs="+", default=[""],
                    help="labellings: each a space-separated list of labels key=value changes")
    ap.add_argument("--rows", type=Path, default=None, help="write every grasp's row here (JSON)")
    args = ap.parse_args()
    objects = args.objects.split(",") if args.objects else sorted(
        p.name for p in (args.workdir / "results/grasps").iterdir() if p.is_dir())  # fmt: skip
    variants = args.variant or [""]
    changes = tuple(args.labels)
    tasks = [(v, o, args.workdir, changes) for v in variants for o in objects]
    with mp.get_context("spawn").Pool(args.jobs) as pool:
        parts = pool.map(object_rows, tasks, chunksize=1)
    everything = {}
    for v in variants:
        rows = [r for t, part in zip(tasks, parts, strict=True) if t[0] == v for r in part]
        everything[v] = rows
        print(json.dumps(report(v, rows, args.still_s, changes)), flush=True)
    if args.rows:
        args.rows.write_text(json.dumps(everything, default=float))


if __name__ == "__main__":
    main()
