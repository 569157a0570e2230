"""Print per-object preprocessing figures (wall time, peak memory, convex parts) from a run.

Usage: python benchmarks/preprocess_summary.py [WORKDIR]   (default: the current directory)
Reads results/benchmarks/preprocess_object/<id>.tsv (Snakemake's benchmark files) and
results/objects/<id>/meta.json, so it reports the figures of the run that was actually made.
"""

from __future__ import annotations

import csv
import json
import sys
from pathlib import Path


def main(argv: list[str]) -> int:
    workdir = Path(argv[1]) if len(argv) > 1 else Path.cwd()
    bench_dir = workdir / "results" / "benchmarks" / "preprocess_object"
    rows = []
    for tsv in sorted(bench_dir.glob("*.tsv")):
        oid = tsv.stem
        with open(tsv) as fh:
            b = next(csv.DictReader(fh, delimiter="\t"))
        meta = json.loads((workdir / "results" / "objects" / oid / "meta.json").read_text())
        rows.append(
            (
                oid,
                float(b["s"]),
                float(b["max_rss"]),
                meta["convex_parts"],
                meta["watertight_before"],
                meta["watertight_after"],
                meta["volume"] * 1e6,
            )
        )
    if not rows:
        print(f"no benchmark files under {bench_dir}; run the workflow first", file=sys.stderr)
        return 1
    print(
        f"{'object':<22}{'wall [s]':>9}{'max RSS [MB]':>14}{'parts':>7}{'wt raw':>8}"
        f"{'wt fixed':>10}{'vol [cm3]':>11}"
    )
    for oid, s, rss, parts, wb, wa, vol in rows:
        print(f"{oid:<22}{s:>9.1f}{rss:>14.0f}{parts:>7d}{wb!s:>8}{wa!s:>10}{vol:>11.1f}")
    total = sum(r[1] for r in rows)
    print(f"{'total':<22}{total:>9.1f}   ({len(rows)} objects, serial sum of job wall times)")
    return 0


if __name__ == "__main__":
    raise SystemExit(main(sys.argv))
