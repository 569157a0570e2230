"""The SLURM test run's figures for the docs: jobs, wall time against the local run, and what the
scheduler adds per job, so no figure in docs/cluster.md is typed by hand.

Reads the record ``tests/test_slurm_workflow.py`` writes once per session
(``<basetemp>/slurm_run.json``: the local and SLURM runs' wall seconds, every job's ``sacct``
row, every job's benchmark seconds). Per job, the scheduler's share is split in two:

* queueing: ``sacct`` Start minus Submit (the job waiting for the controller and a free CPU);
* in-job overhead: the job's elapsed time in SLURM minus the seconds its Snakemake benchmark
  measured for the rule itself (the batch script, ``srun``, a fresh Snakemake process reading
  the workflow).

    pytest -m servers tests/test_slurm_workflow.py --basetemp /tmp/slurm-test
    python benchmarks/slurm_overhead.py /tmp/slurm-test/slurm_run.json
"""

from __future__ import annotations

import argparse
import json
import statistics
from datetime import datetime
from pathlib import Path


def figures(record: dict) -> dict[str, float]:
    """The run's figures from the test's record (seconds unless named otherwise)."""
    rows = record["sacct"]
    done = [r for r in rows if r["State"] == "COMPLETED"]
    queued = [
        (datetime.fromisoformat(r["Start"]) - datetime.fromisoformat(r["Submit"])).total_seconds()
        for r in done
    ]
    elapsed = sum(int(r["ElapsedRaw"]) for r in done)
    measured = sum(record["benchmarks"].values())
    return {
        "jobs": len(done),
        "cancelled": len(rows) - len(done),
        "cluster_start_s": record.get("cluster_start_seconds", float("nan")),
        "local_wall_s": record["local"]["seconds"],
        "slurm_wall_s": record["slurm"]["seconds"],
        "queue_mean_s": statistics.mean(queued),
        "queue_max_s": max(queued),
        "elapsed_sum_s": elapsed,
        "benchmark_sum_s": measured,
        "in_job_overhead_mean_s": (elapsed - measured) / len(done),
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("record", type=Path, help="slurm_run.json from the test's basetemp")
    args = parser.parse_args()
    f = figures(json.loads(args.record.read_text()))
    print(
        f"{f['jobs']} jobs completed through SLURM (+{f['cancelled']} cancelled); cluster start "
        f"{f['cluster_start_s']:.0f} s; local run {f['local_wall_s']:.0f} s wall, SLURM run "
        f"{f['slurm_wall_s']:.0f} s wall ({f['slurm_wall_s'] / f['local_wall_s']:.2f}x, the "
        f"cancelled job's retry included)"
    )
    print(
        f"per job: queued {f['queue_mean_s']:.1f} s on average (at most {f['queue_max_s']:.0f} s); "
        f"elapsed in SLURM {f['elapsed_sum_s']:.0f} s in all against {f['benchmark_sum_s']:.0f} s "
        f"measured by the rules' benchmarks: {f['in_job_overhead_mean_s']:.1f} s of overhead a job"
    )


if __name__ == "__main__":
    main()
