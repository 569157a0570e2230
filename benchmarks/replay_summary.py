"""Per-object replay outcomes of a workflow run (3.2), from results/replay/<id>/.

Prints per object: replays, held to the end, contact lost and too deep (both stopped early),
diverged, replays whose d_t stays below -8 mm for at least 1 s (the labelling stage's rejection
rule, 3.3.1, applied here to the whole replay), the median speed of the held objects over their
last second (creep), and the simulated and wall time.

    python benchmarks/replay_summary.py <workdir>
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np
import polars as pl

from graspstab.common.runs import earliest_run
from graspstab.replay.traces import trace_key


def deep_for(dist: np.ndarray, depth: float, steps: int) -> bool:
    """Whether ``dist`` stays below ``-depth`` for ``steps`` consecutive rows."""
    return earliest_run(np.nan_to_num(dist, nan=0.0) < -depth, steps, len(dist)) is not None


def main() -> None:
    """Print the table for every object with replay tables in the work directory."""
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("workdir", type=Path)
    ap.add_argument("--timestep", type=float, default=0.0005)
    args = ap.parse_args()
    dt = args.timestep
    print(
        f"{'object':22s} replays  held  lost  too deep  diverged  deep>=1s  creep q50 [mm/s]  "
        "simulated [s]  wall [s]"
    )
    totals = np.zeros(6, dtype=int)
    for obj_dir in sorted((args.workdir / "results" / "replay").iterdir()):
        tables = sorted(obj_dir.glob("replays_*.parquet"))
        if not tables:
            continue
        deep, creep = 0, []
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
        table = pl.concat([pl.read_parquet(p) for p in tables])
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
        print(
            f"{obj_dir.name:22s} {counts[0]:7d} {counts[1]:5d} {counts[2]:5d} {counts[3]:9d} "
            f"{counts[4]:9d} {counts[5]:9d}  {med:>16s}  {table['duration_s'].sum():13.0f}  "
            f"{table['wall_s'].sum():8.0f}"
        )
    t = totals
    print(f"{'total':22s} {t[0]:7d} {t[1]:5d} {t[2]:5d} {t[3]:9d} {t[4]:9d} {t[5]:9d}")


if __name__ == "__main__":
    main()
