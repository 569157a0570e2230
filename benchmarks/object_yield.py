"""Per-object yield of a workflow run: what each object gives the learning stage, and why an
object gives nothing (the wide profile's 44 objects, docs/results.md "Generalisation across
objects").

Prints per object: mass, shape class, smallest and largest extent, replays, replays held to the
end, median time to contact loss of the others, windows in the baseline dataset (and the
creep-free benchmark's, when present), the unstable share, and for an object with no window the
likely cause, read from those measured quantities:

* "heavy": mass >= --heavy kg and most replays lose contact within --drop-s seconds (the hand's
  position servos, kp of 3.2, cannot carry it);
* "thin": smallest extent < --thin m (the fingers close past it);
* "small": largest extent < --small m (the hand cannot oppose fingers on it);
* "drops": none of these; the grasps drop or the windows are rejected for another reason.

    python benchmarks/object_yield.py <workdir> [--objects config/objects/ycb44.yaml] [--markdown]
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

import numpy as np
import polars as pl
import yaml


def dataset_counts(path: Path) -> dict[str, tuple[int, int]]:
    """object -> (windows, unstable) of a dataset index, or {} when absent."""
    if not path.exists():
        return {}
    idx = pl.read_parquet(path)
    g = idx.group_by("object").agg(pl.len().alias("n"), pl.col("label").sum().alias("u"))
    return {r["object"]: (int(r["n"]), int(r["u"])) for r in g.iter_rows(named=True)}


def cause(mass: float, lo: float, hi: float, quick_drops: float, args: argparse.Namespace) -> str:
    if mass >= args.heavy and quick_drops >= 0.5:
        return "heavy"
    if lo < args.thin:
        return "thin"
    if hi < args.small:
        return "small"
    return "drops"


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("workdir", type=Path)
    ap.add_argument("--objects", type=Path, default=Path("config/objects/ycb44.yaml"))
    ap.add_argument("--heavy", type=float, default=0.3, help="[kg] heavy above this")
    ap.add_argument("--drop-s", type=float, default=1.0, help="[s] a quick drop")
    ap.add_argument("--thin", type=float, default=0.02, help="[m] thin below this extent")
    ap.add_argument("--small", type=float, default=0.05, help="[m] small below this extent")
    ap.add_argument("--window", default="w10ms", help="the sweep dataset to count (sweep/<w>)")
    ap.add_argument("--markdown", action="store_true", help="print a Markdown table (for docs)")
    args = ap.parse_args()
    items = yaml.safe_load(args.objects.read_text())["items"]
    res = args.workdir / "results"
    base = dataset_counts(res / "datasets" / "sweep" / args.window / "index.parquet")
    cf = dataset_counts(res / "creep_free" / "datasets" / "sweep" / args.window / "index.parquet")
    rows = []
    for obj, entry in items.items():
        meta_path = res / "objects" / obj / "meta.json"
        replays = sorted((res / "replay" / obj).glob("replays_*.parquet"))
        if not meta_path.exists() or not replays:
            rows.append({"object": obj, "status": "not run"})
            continue
        ext = sorted(json.loads(meta_path.read_text())["extents"])
        rep = pl.concat([pl.read_parquet(p) for p in replays])
        lost = rep.filter(~pl.col("held_at_end"))
        loss_s = lost["contact_loss_s"].drop_nulls().to_numpy()
        quick = float(np.mean(loss_s < args.drop_s)) if loss_s.size else 0.0
        n, u = base.get(obj, (0, 0))
        row = {
            "object": obj,
            "mass_kg": entry["mass"],
            "shape": entry.get("shape", "?"),
            "min_cm": round(100 * ext[0], 1),
            "max_cm": round(100 * ext[-1], 1),
            "replays": rep.height,
            "held": int(rep["held_at_end"].sum()),
            "loss_s_median": round(float(np.median(loss_s)), 2) if loss_s.size else None,
            "windows": n,
            "unstable_pct": round(100 * u / n, 1) if n else None,
        }
        if cf:
            cn, cu = cf.get(obj, (0, 0))
            row |= {"cf_windows": cn, "cf_unstable_pct": round(100 * cu / cn, 1) if cn else None}
        row["status"] = "usable" if n else cause(entry["mass"], ext[0], ext[-1], quick, args)
        rows.append(row)
    table = pl.DataFrame(rows, infer_schema_length=None)
    if args.markdown:
        print("| " + " | ".join(table.columns) + " |")
        print("|" + "---|" * len(table.columns))
        for r in table.iter_rows():
            print("| " + " | ".join("" if v is None else str(v) for v in r) + " |")
        return
    with pl.Config(tbl_rows=-1, tbl_cols=-1, tbl_width_chars=200, tbl_hide_dataframe_shape=True):
        print(table)
    usable = table.filter(pl.col("status") == "usable")
    print(
        f"\n{usable.height} of {table.height} objects give windows; "
        f"{int(usable['windows'].sum())} windows in all"
    )
    for status, g in table.filter(pl.col("status") != "usable").group_by("status"):
        print(f"{status[0]}: {', '.join(sorted(g['object']))}")


if __name__ == "__main__":
    main()
