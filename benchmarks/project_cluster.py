"""Project a finished run's wall time on a cluster of N nodes, job by job, from its own timings.

Takes the run's job graph (a Snakemake dry run of its ``--config`` from an empty work directory:
every job with its inputs, outputs, threads and benchmark file; an edge wherever one job's output
is another's input) and each job's measured wall seconds (its ``results/benchmarks`` file), and
replays the graph through a list scheduler: ``nodes`` machines of ``cores`` cores each; a job
starts once every job it reads from has finished and one node has its threads free, the job with
the longest remaining chain first; each job sent to the cluster pays ``overhead`` seconds of
queueing and start-up on top of its measured time (local rules run on the submitting host, free).

It checks itself against the run: one node of the run's cores with no overhead is what the run
did, so that row's projection should come close to the run's measured wall time (printed beside
it when ``--time-log`` is given). What it leaves out: file-system latency, node failures, jobs
slower on a busier or different node class, and Snakemake's own scheduling order.

    python benchmarks/project_cluster.py --results <workdir>/results --run-config profile=wide \\
        --nodes 1 2 4 8 16 32 --cores 2 --overhead 0 60 --time-log <workdir>.snake.log
"""

from __future__ import annotations

import argparse
import heapq
import json
import re
import sys
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))

from cost_table import wall_and_cpu  # noqa: E402
from project_thesis import config_args, hms, snakemake  # noqa: E402

from graspstab.report.provenance import read_benchmark  # noqa: E402


@dataclass
class GraphJob:
    """One job of the dry run: what it reads and writes, its threads and its benchmark file."""

    rule: str
    local: bool = False
    inputs: list[str] = field(default_factory=list)
    outputs: list[str] = field(default_factory=list)
    threads: int = 1
    benchmark: str | None = None
    seconds: float = 0.0


def parse_jobs(text: str) -> list[GraphJob]:
    """The job blocks of a dry-run listing (``rule NAME:`` or ``localrule NAME:``, then fields)."""
    jobs: list[GraphJob] = []
    current: GraphJob | None = None
    for line in text.splitlines():
        head = re.match(r"^(local)?rule (\w+):$", line)
        if head:
            current = GraphJob(rule=head.group(2), local=bool(head.group(1)))
            jobs.append(current)
            continue
        field_ = re.match(r"^\s{4}(\w+): (.*)$", line)
        if current is None or not field_:
            if not line.startswith(" "):
                current = None
            continue
        key, value = field_.groups()
        if key == "input":
            current.inputs = value.split(", ")
        elif key == "output":
            current.outputs = value.split(", ")
        elif key == "threads":
            current.threads = int(value)
        elif key == "benchmark":
            current.benchmark = value
    return jobs


def dependencies(jobs: Sequence[GraphJob]) -> list[list[int]]:
    """For each job, the jobs whose outputs it reads (a folder output covers paths inside it)."""
    producer = {out.rstrip("/"): i for i, job in enumerate(jobs) for out in job.outputs}
    deps: list[list[int]] = []
    for job in jobs:
        found = set()
        for path in job.inputs:
            p = path.rstrip("/")
            while p:
                if p in producer:
                    found.add(producer[p])
                    break
                p = p.rpartition("/")[0]
        deps.append(sorted(found))
    return deps


def bottom_levels(seconds: Sequence[float], deps: Sequence[Sequence[int]]) -> list[float]:
    """Each job's longest chain to the end of the graph, itself included (the list priority)."""
    children: list[list[int]] = [[] for _ in seconds]
    for j, ds in enumerate(deps):
        for d in ds:
            children[d].append(j)
    level: list[float | None] = [None] * len(seconds)
    for start in range(len(seconds)):
        stack = [start]
        while stack:
            j = stack[-1]
            pending = [c for c in children[j] if level[c] is None]
            if pending:
                stack.extend(pending)
                continue
            stack.pop()
            level[j] = seconds[j] + max((level[c] for c in children[j]), default=0.0)
    return [float(x) for x in level]


def schedule(
    seconds: Sequence[float],
    deps: Sequence[Sequence[int]],
    threads: Sequence[int],
    local: Sequence[bool],
    nodes: int,
    cores: int,
    overhead: float = 0.0,
) -> float:
    """Makespan of the list schedule: ``nodes`` x ``cores``, longest remaining chain first; a
    cluster job costs ``overhead`` more than its seconds, a local one runs free beside them."""
    cost = [s + (0.0 if loc else overhead) for s, loc in zip(seconds, local, strict=True)]
    priority = bottom_levels(cost, deps)
    waiting = [len(d) for d in deps]
    children: list[list[int]] = [[] for _ in seconds]
    for j, ds in enumerate(deps):
        for d in ds:
            children[d].append(j)
    free = [cores] * nodes
    ready = [(-priority[j], j) for j in range(len(seconds)) if waiting[j] == 0]
    heapq.heapify(ready)
    running: list[tuple[float, int, int]] = []  # (finish time, job, node or -1 for local)
    now, done = 0.0, 0
    while done < len(seconds):
        held = []
        while ready:
            item = heapq.heappop(ready)
            j = item[1]
            if local[j]:
                heapq.heappush(running, (now + cost[j], j, -1))
                continue
            need = min(threads[j], cores)
            node = max(range(nodes), key=lambda n: free[n])
            if free[node] >= need:
                free[node] -= need
                heapq.heappush(running, (now + cost[j], j, node))
            else:
                held.append(item)
        for item in held:
            heapq.heappush(ready, item)
        if not running:
            raise RuntimeError("the job graph has a cycle or a job needs more cores than a node")
        now, j, node = heapq.heappop(running)
        done += 1
        if node >= 0:
            free[node] += min(threads[j], cores)
        for c in children[j]:
            waiting[c] -= 1
            if waiting[c] == 0:
                heapq.heappush(ready, (-priority[c], c))
    return now


def measure(jobs: Sequence[GraphJob], workdir: Path) -> tuple[int, dict[str, int]]:
    """Fill each job's seconds from its benchmark file; (jobs measured, unmeasured per rule)."""
    measured, missing = 0, {}
    for job in jobs:
        path = workdir / job.benchmark if job.benchmark else None
        if path is not None and path.exists():
            job.seconds = read_benchmark(path)["s"]
            measured += 1
        else:
            missing[job.rule] = missing.get(job.rule, 0) + 1
    return measured, missing


def project(
    jobs: Sequence[GraphJob], nodes: Sequence[int], cores: int, overheads: Sequence[float]
) -> dict[str, object]:
    """The projection table: makespan per node count and overhead, plus the graph's bounds."""
    deps = dependencies(jobs)
    seconds = [j.seconds for j in jobs]
    args = ([j.threads for j in jobs], [j.local for j in jobs])
    rows = [
        {
            "nodes": n,
            "cores": n * cores,
            **{f"overhead_{o:g}": schedule(seconds, deps, *args, n, cores, o) for o in overheads},
        }
        for n in nodes
    ]
    return {
        "jobs": len(jobs),
        "job_seconds": sum(seconds),
        "critical_path_s": max(bottom_levels(seconds, deps), default=0.0),
        "rows": rows,
    }


def render(result: Mapping[str, object], overheads: Sequence[float], run_wall: float | None,
           cores: int, missing: Mapping[str, int]) -> str:  # fmt: skip
    """A Markdown table and the bounds it rests on."""
    head = " | ".join(f"wall, {o:g} s per job" for o in overheads)
    lines = [f"| nodes x {cores} cores | {head} |", "|---:|" + "---:|" * len(overheads)]
    for row in result["rows"]:
        cells = " | ".join(hms(row[f"overhead_{o:g}"]) for o in overheads)
        lines.append(f"| {row['nodes']} ({row['cores']} cores) | {cells} |")
    lines += [
        "",
        f"{result['jobs']} jobs, {result['job_seconds']:.0f} job-seconds "
        f"({hms(result['job_seconds'])}); critical path {hms(result['critical_path_s'])} "
        "(no node count goes below it)",
    ]
    if run_wall is not None:
        lines.append(f"the run itself: {hms(run_wall)} wall (compare the 1-node, 0 s row)")
    if missing:
        lines.append(
            "jobs without a benchmark file, counted as 0 s: "
            + ", ".join(f"{r} {n}" for r, n in sorted(missing.items()))
        )
    return "\n".join(lines)


def main(argv: Sequence[str] | None = None) -> None:
    """Dry-run the run's DAG, read its benchmarks, schedule it on each node count, print."""
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--results", type=Path, required=True, help="the finished run's results/")
    ap.add_argument("--run-config", nargs="*", default=[], metavar="KEY=VALUE",
                    help="the --config entries the run used (they decide its DAG)")  # fmt: skip
    ap.add_argument("--target", nargs="+", default=["results/report.html"],
                    help="the run's targets (several: the jobs any of them needs)")
    ap.add_argument("--nodes", type=int, nargs="+", default=[1, 2, 4, 8, 16, 32])
    ap.add_argument("--cores", type=int, default=2, help="cores per node")
    ap.add_argument("--overhead", type=float, nargs="+", default=[0.0, 60.0],
                    help="seconds of queueing and start-up per cluster job")  # fmt: skip
    ap.add_argument("--time-log", type=Path, help="/usr/bin/time -v output of the run")
    ap.add_argument("--json", action="store_true")
    args = ap.parse_args(argv)
    workdir = args.results.resolve().parent
    text = snakemake(["--dry-run", "--cores", "1", *config_args(args.run_config), "--",
                      *args.target])  # fmt: skip
    jobs = parse_jobs(text)
    if not jobs:
        raise SystemExit("the dry run listed no jobs: check --run-config and --target")
    _, missing = measure(jobs, workdir)
    result = project(jobs, args.nodes, args.cores, args.overhead)
    run_wall = wall_and_cpu(args.time_log)[0] if args.time_log else None
    if args.json:
        print(json.dumps({**result, "run_wall_s": run_wall, "unmeasured": missing}, indent=2))
    else:
        print(render(result, args.overhead, run_wall, args.cores, missing))


if __name__ == "__main__":
    main()
