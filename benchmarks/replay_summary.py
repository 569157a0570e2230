"""Per-object replay outcomes of a workflow run (3.2), from results/replay/<id>/.

Prints per object: replays, held to the end, contact lost and too deep (both stopped early),
diverged, replays whose d_t stays below -8 mm for at least 1 s (the labelling stage's rejection
rule, 3.3.1, applied here to the whole replay), the median speed of the held objects over their
last second (creep), the simulated and wall time, and, when the baseline dataset exists, the
replays that give it no window and their wall time (what a filter before the replay could save
at most).

    python benchmarks/replay_summary.py <workdir>
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

import numpy as np
import polars as pl

from graspstab.common.runs import earliest_run
from graspstab.replay.traces import trace_key


def deep_for(dist: np.ndarray, depth: float, steps: int) -> bool:
    """Whether ``dist`` stays below ``-depth`` for ``steps`` consecutive rows."""
    return earliest_run(np.nan_to_num(dist, nan=0.0) < -depth, steps, len(dist)) is not None


def with_wall(table: pl.DataFrame, workdir: Path, obj: str, shard: str) -> pl.DataFrame:
    """``table`` with each grasp's wall time ``wall_s``, from the replay job's timing sidecar (a
    run made before the timings left the data files has the column already)."""
    if "wall_s" in table.columns:
        return table
    sidecar = f"results/benchmarks/replay_grasps/{obj}_shard_{shard}.timing.json"
    timing = json.loads((workdir / sidecar).read_text())
    walls = pl.DataFrame({"grasp_id": timing["grasp_id"], "wall_s": timing["wall_s"]},
                         schema_overrides={"grasp_id": table.schema["grasp_id"]})  # fmt: skip
    return table.join(walls, on="grasp_id", how="left")


def main() -> None:
    """Print the table for every object with replay tables in the work directory."""
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("workdir", type=Path)
    ap.add_argument("--timestep", type=float, default=0.0005)
    args = ap.parse_args()
    dt = args.timestep
    print(
        f"{'object':22s} replays  held  lost  too deep  diverged  deep>=1s  creep q50 [mm/s]  "
        "simulated [s]  wall [s]  windowless  windowless wall [s]"
    )
    index_path = args.workdir / "results" / "datasets" / "baseline" / "index.parquet"
    yielding = (
        set(pl.read_parquet(index_path).select("object", "shard", "grasp_id").unique().rows())
        if index_path.exists() else None
    )  # fmt: skip
    totals = np.zeros(6, dtype=int)
    sums = np.zeros(4)
    for obj_dir in sorted((args.workdir / "results" / "replay").iterdir()):
        tables = sorted(obj_dir.glob("replays_*.parquet"))
        if not tables:
            continue
        deep, creep, read = 0, [], []
        for table_path in tables:
            table = pl.read_parquet(table_path)
            shard = table_path.stem.split("_")[1]
            with np.load(obj_dir / f"traces_{shard}.npz") as traces:
                for row in table.iter_rows(named=True):
                    dist = traces[trace_key(row["grasp_id"], "min_distance")]
                    deep += deep_for(dist, 0.008, round(1.0 / dt))
                    if row["held_at_end"]:
                        vel = traces[trace_key(row["grasp_id"], "velocity")][-round(1.0 / dt) :]
                        creep.append(float(np.median(np.linalg.norm(vel, axis=1))))
            read.append(with_wall(table, args.workdir, obj_dir.name, shard))
        table = pl.concat(read)
        counts = [
            table.height,
            int(table["held_at_end"].sum()),
            int((table["stop_reason"] == "contact_lost").sum()),
            int((table["stop_reason"] == "too_deep").sum()),
            int(table["diverged"].sum()),
            deep,
        ]
        totals += counts
        med = f"{np.median(creep) * 1000:.3f}" if creep else "n/a"
        none, none_wall = "n/a", "n/a"
        row_sums = [table["duration_s"].sum(), table["wall_s"].sum(), 0.0, 0.0]
        if yielding is not None:
            keys = zip(table["object"], table["shard"], table["grasp_id"], strict=True)
            empty = np.array([k not in yielding for k in keys])
            row_sums[2:] = [float(empty.sum()), float(table["wall_s"].to_numpy()[empty].sum())]
            none, none_wall = f"{int(row_sums[2])}", f"{row_sums[3]:.0f}"
        sums += row_sums
        print(
            f"{obj_dir.name:22s} {counts[0]:7d} {counts[1]:5d} {counts[2]:5d} {counts[3]:9d} "
            f"{counts[4]:9d} {counts[5]:9d}  {med:>16s}  {row_sums[0]:13.0f}  "
            f"{row_sums[1]:8.0f}  {none:>10s}  {none_wall:>19s}"
        )
    t = totals
    tail = f"{int(sums[2]):>10d}  {sums[3]:19.0f}" if yielding is not None else ""
    print(f"{'total':22s} {t[0]:7d} {t[1]:5d} {t[2]:5d} {t[3]:9d} {t[4]:9d} {t[5]:9d}  "
          f"{'':16s}  {sums[0]:13.0f}  {sums[1]:8.0f}  {tail}")  # fmt: skip


if __name__ == "__main__":
    main()
