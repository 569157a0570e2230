"""Preview of the labelling stage (3.3) on a workflow run's replays, before its rule exists.

Applies the usable-interval rules, timestep labels and predictive labels of
``graspstab.labels`` with the default config to every replay under results/replay and prints per
object: usable grasps, rejected (depth rule), grasps without a valid window, and stable/unstable
windows at the baseline task (W, O, H = 400, 200, 300), plus how the settle index was found.
``--require`` picks the settle reading (3.3.1 when one check succeeds: either, or both).

    python benchmarks/label_preview.py <workdir> [--require both]
"""

from __future__ import annotations

import argparse
import collections
from pathlib import Path

import numpy as np
import polars as pl
import yaml

from graspstab.labels.interval import usable_interval
from graspstab.labels.label_windows import grasp_rng
from graspstab.labels.windows import predictive_labels, step_counts, timestep_labels, window_starts
from graspstab.replay.traces import trace_key

CONFIG = Path(__file__).resolve().parents[1] / "config"


def main() -> None:
    """Print the per-object counts and the totals."""
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("workdir", type=Path)
    ap.add_argument("--require", choices=("either", "both"), default=None)
    args = ap.parse_args()
    lab = yaml.safe_load((CONFIG / "labels" / "default.yaml").read_text())
    if args.require:
        lab["settle"]["require"] = args.require
    dt = yaml.safe_load((CONFIG / "replay" / "default.yaml").read_text())["timestep"]
    w, o, h = step_counts(lab["window_s"], lab["offset_s"], lab["horizon_s"], dt)
    rules: collections.Counter = collections.Counter()
    total = collections.Counter()
    print(f"{'object':22s} grasps usable rejected no-window  stable unstable ambiguous")
    for path in sorted((args.workdir / "results" / "replay").glob("*/replays_*.parquet")):
        table = pl.read_parquet(path)
        row_counts = collections.Counter(grasps=table.height)
        with np.load(path.with_name(path.name.replace("replays_", "traces_")).with_suffix(".npz")) \
                as traces:  # fmt: skip
            for row in table.filter(~pl.col("diverged")).iter_rows(named=True):
                vel = traces[trace_key(row["grasp_id"], "velocity")].astype(np.float64)
                dist = traces[trace_key(row["grasp_id"], "min_distance")].astype(np.float64)
                speed = np.linalg.norm(vel, axis=1)
                ui = usable_interval(speed, dist, dt, lab["settle"], lab["contact_loss_s"])
                rules[ui.settle_rule] += 1
                if ui.rejected:
                    row_counts["rejected"] += 1
                    continue
                rng = grasp_rng(0, row["object"], row["grasp_id"])  # the dataset's (seed 0)
                starts = window_starts(ui.settle_index, ui.contact_end, w, o, h,
                                       lab["windows_per_grasp"], rng)  # fmt: skip
                if not len(starts):
                    row_counts["no-window"] += 1
                    continue
                row_counts["usable"] += 1
                u = timestep_labels(speed, lab["v_slip"])
                _, y = predictive_labels(u, starts, ui.contact_end, w, o, h,
                                         lab["label_low"], lab["label_high"])  # fmt: skip
                row_counts.update(stable=int((y == 0).sum()), unstable=int((y == 1).sum()),
                                  ambiguous=int((y == -1).sum()))  # fmt: skip
        total.update(row_counts)
        keys = ("grasps", "usable", "rejected", "no-window", "stable", "unstable", "ambiguous")
        print(f"{table['object'][0]:22s} " + " ".join(f"{row_counts[k]:>6d}" for k in keys))
    keys = ("grasps", "usable", "rejected", "no-window", "stable", "unstable", "ambiguous")
    print(f"{'total':22s} " + " ".join(f"{total[k]:>6d}" for k in keys))
    print("settle rule:", dict(rules))


if __name__ == "__main__":
    main()
