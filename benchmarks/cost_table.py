"""A finished run's cost as a Markdown table, for the docs: job-seconds by rule, wall time, memory.

Reads the run's per-job Snakemake benchmark files (``results/benchmarks/<rule>/*.tsv``: wall
seconds and peak RSS per job) and, when given, the ``/usr/bin/time -v`` output of the
``snakemake`` command (wall time, CPU seconds) and a memory log of ``<unix time> <used MB>`` lines
sampled while it ran (``free -m`` every 2 s; its first line is taken as idle). Prints the table
the docs quote, so no figure in it is typed by hand.

    python benchmarks/cost_table.py <workdir> [--time-log snake.log] [--mem-log mem.log]
        [--top 10]
"""

from __future__ import annotations

import argparse
from pathlib import Path

from graspstab.report.provenance import stage_times
from graspstab.report.results_page import memory_above_idle, wall_and_cpu


def _minutes(seconds: float) -> str:
    return f"{int(seconds // 60)} min {seconds % 60:02.0f} s"


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("workdir", type=Path)
    ap.add_argument("--time-log", type=Path, help="/usr/bin/time -v output of the snakemake run")
    ap.add_argument("--mem-log", type=Path, help="'<unix time> <used MB>' samples during the run")
    ap.add_argument("--top", type=int, default=10, help="rules listed before 'everything else'")
    args = ap.parse_args()
    root = args.workdir / "results" / "benchmarks"
    if not root.is_dir():
        raise SystemExit(f"{root}: no benchmark files (is {args.workdir} a finished run?)")
    benchmarks = {d.name: sorted(d.glob("*.tsv")) for d in sorted(root.iterdir()) if d.is_dir()}
    rows = sorted(stage_times(benchmarks), key=lambda r: -(r["job_s"] or 0.0))
    total = sum(r["job_s"] or 0.0 for r in rows)
    jobs = sum(r["jobs"] for r in rows)
    print("| rule | jobs | job-seconds | share | longest job [s] | peak RSS [MB] |")
    print("|---|---:|---:|---:|---:|---:|")
    for r in rows[: args.top]:
        rss = f"{r['peak_rss_mb']:,.0f}" if r["peak_rss_mb"] is not None else "-"
        print(f"| {r['rule']} | {r['jobs']} | {r['job_s'] or 0:,.0f} | {r['share'] or 0:.0%} "
              f"| {r['max_s'] or 0:,.0f} | {rss} |")  # fmt: skip
    rest = rows[args.top :]
    if rest:
        seconds = sum(r["job_s"] or 0.0 for r in rest)
        print(f"| everything else ({len(rest)} rules) | {sum(r['jobs'] for r in rest)} "
              f"| {seconds:,.0f} | {seconds / total:.0%} | | |")  # fmt: skip
    print(f"| **total** | {jobs} | **{total:,.0f}** | | | |")
    lines = []
    if args.time_log:
        wall, cpu = wall_and_cpu(args.time_log)
        if wall is not None:
            lines.append(f"wall {_minutes(wall)}")
            lines.append(f"job-seconds / wall = {total / wall:.2f} cores busy")
        if cpu is not None:
            lines.append(f"CPU {cpu:,.0f} s (user + system, all processes)")
    if args.mem_log:
        idle, peak = memory_above_idle(args.mem_log)
        lines.append(f"peak memory {peak / 1024:.1f} GB above idle ({idle:,.0f} MB)")
    if lines:
        print()
        print("; ".join(lines))


if __name__ == "__main__":
    main()
