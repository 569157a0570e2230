"""The cluster projection's scheduler against hand-worked schedules and Graham's list bounds."""

from __future__ import annotations

import importlib.util
import sys
from pathlib import Path

import numpy as np
import pytest

_PATH = Path(__file__).resolve().parents[1] / "benchmarks" / "project_cluster.py"
_SPEC = importlib.util.spec_from_file_location("project_cluster", _PATH)
pc = importlib.util.module_from_spec(_SPEC)
sys.modules["project_cluster"] = pc  # dataclasses look their module up
_SPEC.loader.exec_module(pc)

DRY_RUN = """\
Building DAG of jobs...
rule build_hand:
    input: resources/orcahand_description
    output: results/hand
    jobid: 1
    benchmark: results/benchmarks/build_hand.tsv
    resources: tmpdir=/tmp

rule anneal:
    input: results/hand/contact_candidates.npz, results/objects/pear/sdf.npz
    output: results/grasps/pear/shard0.parquet
    jobid: 2
    benchmark: results/benchmarks/anneal/pear_0.tsv
    threads: 2
    wildcards: object=pear, shard=0

localrule report:
    input: results/grasps/pear/shard0.parquet
    output: results/report.html
    jobid: 0
"""


def test_dry_run_parsing_links_outputs_to_inputs_including_folders():
    jobs = pc.parse_jobs(DRY_RUN)
    assert [j.rule for j in jobs] == ["build_hand", "anneal", "report"]
    assert [j.local for j in jobs] == [False, False, True]
    assert jobs[1].threads == 2 and jobs[0].threads == 1
    assert jobs[1].benchmark == "results/benchmarks/anneal/pear_0.tsv"
    # anneal reads a file inside build_hand's folder output; the object's sdf has no producer
    assert pc.dependencies(jobs) == [[], [0], [1]]


def test_independent_jobs_fill_the_cores():
    secs, deps = [10.0] * 4, [[]] * 4
    one = dict(threads=[1] * 4, local=[False] * 4)
    assert pc.schedule(secs, deps, **one, nodes=1, cores=2) == pytest.approx(20.0)
    assert pc.schedule(secs, deps, **one, nodes=2, cores=2) == pytest.approx(10.0)
    assert pc.schedule(secs, deps, **one, nodes=1, cores=1) == pytest.approx(40.0)
    # a job per node when each needs the node's two cores
    two = dict(threads=[2] * 4, local=[False] * 4)
    assert pc.schedule(secs, deps, **two, nodes=2, cores=2) == pytest.approx(20.0)


def test_a_chain_costs_its_length_plus_overhead_per_cluster_job():
    secs, deps = [10.0, 20.0, 30.0], [[], [0], [1]]
    kw = dict(threads=[1] * 3, nodes=8, cores=4)
    assert pc.schedule(secs, deps, local=[False] * 3, **kw) == pytest.approx(60.0)
    assert pc.schedule(secs, deps, local=[False] * 3, overhead=5.0, **kw) == pytest.approx(75.0)
    # a local job (run on the submitting host) pays no overhead
    assert pc.schedule(secs, deps, local=[False, False, True], overhead=5.0, **kw) == (
        pytest.approx(70.0)
    )


def test_longest_chain_goes_first():
    # job 0 (1 s) feeds a 10 s job; jobs 2 and 3 are 5 s each, free; one core:
    # chain first gives 1 + 10 + 5 + 5 = 21 either way, but on two cores the chain-first
    # order finishes at 11 where the short-jobs-first order would need 15
    secs, deps = [1.0, 10.0, 5.0, 5.0], [[], [0], [], []]
    kw = dict(threads=[1] * 4, local=[False] * 4)
    assert pc.schedule(secs, deps, **kw, nodes=1, cores=2) == pytest.approx(11.0)
    assert pc.bottom_levels(secs, deps) == [11.0, 10.0, 5.0, 5.0]


def test_random_graphs_respect_the_list_schedule_bounds():
    rng = np.random.default_rng(3)
    for _ in range(50):
        n = int(rng.integers(1, 40))
        secs = list(rng.exponential(10.0, n))
        deps = [sorted(set(rng.integers(0, j, int(rng.integers(0, 3))).tolist())) if j else []
                for j in range(n)]  # fmt: skip
        m = int(rng.integers(1, 5))
        span = pc.schedule(secs, deps, [1] * n, [False] * n, nodes=m, cores=1)
        path = max(pc.bottom_levels(secs, deps))
        lower = max(path, sum(secs) / m)
        assert lower - 1e-9 <= span <= sum(secs) / m + path + 1e-9  # Graham (1969)
        assert pc.schedule(secs, deps, [1] * n, [False] * n, nodes=n, cores=1) == (
            pytest.approx(path)
        )
