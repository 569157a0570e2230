"""The report's "Provenance" section: config hash, commit and versions, per-rule wall times from
the benchmark files (timings, not data), the grasp funnel and the resolved configuration."""

from __future__ import annotations

import json
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import networkx as nx

import graspstab
from graspstab.common.provenance import stable_hash
from graspstab.report import html as H
from graspstab.report.funnel import funnel_table
from graspstab.report.provenance import git_commit, package_versions, stage_times

REPO_DIR = Path(graspstab.__file__).resolve().parents[2]


def stage_table(rows: Sequence[Mapping[str, Any]], own_rule: str = "report") -> str:
    """Per-rule wall times and peak memory from the benchmark files (``own_rule``, the rule
    writing this report, cannot have its benchmark yet)."""
    total = sum(r["job_s"] or 0.0 for r in rows)
    body = []
    for r in rows:
        unbenchmarked = (
            "runs now: benchmark after this report"
            if r["rule"] == own_rule
            else ("no benchmark file")
        )
        jobs = str(r["jobs"])
        if r["dag_jobs"] is not None and r["dag_jobs"] != r["jobs"]:
            jobs += f" (DAG: {r['dag_jobs']})"
        if r["missing"]:
            jobs += f" ({r['missing']} benchmark files missing)"
        bench = r["job_s"] is not None
        body.append([
            r["rule"], jobs,
            f"{r['job_s']:.1f}" if bench else unbenchmarked,
            H.fmt(r["share"], ".1%") if bench else "—",
            f"{r['max_s']:.1f} ({r['max_job']})" if r["max_s"] is not None else "—",
            H.fmt(r["peak_rss_mb"], ".0f") if bench else "—",
        ])  # fmt: skip
    jobs, dag_jobs = sum(r["jobs"] for r in rows), sum(r["dag_jobs"] or 0 for r in rows)
    all_jobs = f"{jobs} (DAG: {dag_jobs})" if dag_jobs and dag_jobs != jobs else str(jobs)
    body.append(["all rules", all_jobs, f"{total:.1f}", "100%", "", ""])
    return H.table(
        ["rule", "jobs", "total job-seconds", "share", "longest job [s]", "peak RSS [MB]"],
        body,
        caption="Per-stage wall time from every rule's Snakemake benchmark files: job-seconds sum "
        "the jobs' wall times (with several cores the run's elapsed time is shorter); peak RSS is "
        "the largest over the rule's jobs; 'DAG' is the job count in this run's DAG when it "
        "differs from the benchmarked jobs",
    )


def provenance_parts(
    config: Mapping[str, Any],
    benchmarks: Mapping[str, Sequence[Path]],
    graph: nx.DiGraph | None,
    counts: Mapping[str, int] | None,
    funnel_rows: Sequence[Mapping[str, Any]] | None,
) -> list[str]:
    """Config hash, commit, versions, stage times, the grasp funnel (``funnel_rows``: the rows of
    rule ``summarise_funnel``'s table; None: not given) and the resolved config."""
    order = list(nx.topological_sort(graph)) if graph is not None else None
    return [
        H.heading(2, "provenance", "Provenance"),
        H.table(
            ["item", "value"],
            [
                ["config hash", stable_hash(dict(config))],
                ["git commit", git_commit(REPO_DIR)],
                *[[f"package {k}", v] for k, v in package_versions().items()],
            ],
            caption="Run provenance",
        ),
        H.heading(3, "stage-times", "Stage wall times and memory"),
        stage_table(stage_times(benchmarks, counts, order))
        if benchmarks or counts
        else '<p class="note">No benchmark files given to the report.</p>',
        H.heading(3, "funnel", "Grasp funnel"),
        funnel_table(funnel_rows)
        if funnel_rows is not None
        else '<p class="note">No grasp funnel given to the report.</p>',
        H.heading(3, "configuration", "Resolved configuration"),
        "<details><summary>Resolved configuration (JSON)</summary><pre>"
        + H.esc(json.dumps(config, indent=2, sort_keys=True))
        + "</pre></details>",
    ]
