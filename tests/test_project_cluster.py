"""The cost projections against hand-worked schedules, list-scheduling bounds and synthetic runs."""

from __future__ import annotations

import importlib.util
import json
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


# --- The thesis projection (benchmarks/project_thesis.py) on a synthetic run ----------------------

pt = sys.modules["project_thesis"]  # imported by project_cluster

THESIS_CFG = {
    "replay": {"timestep": 0.0005},
    "synthesis": {"shards": 2, "grasps_per_shard": 4, "annealing": {"iterations": 100}},
    "train": {"max_epochs": 10, "patience": 2, "mixed_precision": "auto"},
    "labels": {"window_s": 0.01},
    "splits": {"window_s": 0.01},
    "sweep": {"windows_s": [0.01]},
    "model": {"cnn": {"mixed_precision": None}, "lstm": {"mixed_precision": None}},
}


def _bench(workdir: Path, rel: str, seconds: float, rss: float = 100.0) -> str:
    path = workdir / rel
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(f"s\tmax_rss\n{seconds}\t{rss}\n")
    return rel


def _train_job(workdir: Path, rule: str, family: str, seconds: float, train_seconds: float,
               mixed: bool, sidecar: bool = True, **wildcards: str) -> pt.Job:  # fmt: skip
    """A finished training job: its benchmark, a metrics.json (4 epochs of 8 at 20 steps) and its
    timing sidecar (with ``sidecar``; else the training seconds in metrics.json, as a run made
    before the timings left the data files has them)."""
    name = "_".join([family, *wildcards.values()])
    out = f"results/train/{rule}/{name}/metrics.json"
    timing = f"results/train/{rule}/{name}/timing.json"
    (workdir / out).parent.mkdir(parents=True, exist_ok=True)
    if sidecar:
        (workdir / timing).write_text(json.dumps({"train_seconds": train_seconds}))
    (workdir / out).write_text(json.dumps({
        "family": family, "counts": {"train": {"stable": 60, "unstable": 20},
                                     "val": {"stable": 15, "unstable": 5},
                                     "test": {"stable": 10, "unstable": 10}},
        "epochs_run": 4, "best_epoch": 2, "window_steps": 20,
        **({} if sidecar else {"train_seconds": train_seconds}),
        "params": {"train": {"max_epochs": 8}},
        "placement": {"device": "cpu", "mixed_precision": mixed},
    }))  # fmt: skip
    bench = _bench(workdir, f"results/benchmarks/{rule}/{name}.tsv", seconds)
    outputs = [out, timing] if sidecar else [out]
    return pt.Job(rule, {"model": family, **wildcards}, output=outputs, benchmark=bench)


def _synthetic_run(workdir: Path) -> tuple[list, list]:
    """The run's jobs (measured) and the thesis DAG's jobs for a few rules."""
    run = [
        # cnn trained under bfloat16, lstm in fp32: 100 windows x 20 steps x 4 epochs each
        # cnn's training seconds in its metrics.json: a run from before the timing sidecars
        _train_job(workdir, "train_model", "cnn", 12.0, 10.0, True, False, seed="42"),
        _train_job(workdir, "train_model", "lstm", 22.0, 20.0, mixed=False, seed="42"),
        # the audit measured lstm only, at twice train_model's rate
        _train_job(
            workdir,
            "train_input_model",
            "lstm",
            42.0,
            40.0,
            mixed=False,
            inputs="normal",
            seed="42",
        ),
        pt.Job("plot_hand", output=[], benchmark=_bench(workdir, "results/benchmarks/p.tsv", 3.0)),
        pt.Job("new_rule", output=[], benchmark=_bench(workdir, "results/benchmarks/n.tsv", 5.0)),
    ]
    thesis = [
        pt.Job("train_model", {"model": "cnn", "seed": "42"}),
        pt.Job("train_model", {"model": "lstm", "seed": "42"}),
        pt.Job("train_input_model", {"model": "cnn", "inputs": "normal", "seed": "42"}),
        pt.Job("train_input_model", {"model": "lstm", "inputs": "normal", "seed": "42"}),
        pt.Job("plot_hand"),
        pt.Job("new_rule"),
        pt.Job("rule_the_run_lacks"),
    ]
    return run, thesis


def test_thesis_projection_covers_every_rule_and_flags_the_unscalable(tmp_path):
    run, thesis = _synthetic_run(tmp_path)
    stages, warnings, assumptions = pt.project_stages(
        tmp_path, run, thesis, THESIS_CFG, epoch_fraction=None, fp32_factor={"cnn": 2.0}
    )
    by = {s.rule: s for s in stages}
    assert set(by) == {j.rule for j in thesis}  # every rule of the thesis DAG, none dropped
    assert not warnings
    assert assumptions["fp32_over_bf16_factor"] == {"cnn": 2.0}  # lstm trained in fp32
    # thesis units per job: 50% of 10 epochs x 56,030 train+val windows x 20 steps
    units = 0.5 * 10 * 56_030 * 20
    rate = 10.0 / (4 * 100 * 20)  # the cnn's measured seconds per window-step-epoch
    cnn, lstm = by["train_model"].per_job
    assert cnn["wildcards"]["model"] == "cnn"
    assert cnn["seconds"] == pytest.approx(2.0 + 2.0 * rate * units)  # overhead + fp32 rate
    assert lstm["seconds"] == pytest.approx(2.0 + 2 * rate * units)
    # the audit's cnn: train_model's cnn rate x the audit's lstm measured/predicted (2x)
    audit = {j["wildcards"]["model"]: j["seconds"] for j in by["train_input_model"].per_job}
    assert audit["cnn"] == pytest.approx(2.0 + 2 * 2.0 * rate * units)
    assert audit["lstm"] == pytest.approx(2.0 + 4 * rate * units)
    assert "cnn not trained in the run" in by["train_input_model"].note
    # a known per-job rule is projected at its measured seconds
    assert by["plot_hand"].projected and by["plot_hand"].job_seconds == pytest.approx(3.0)
    # no scaling model, and not measured at all: both unprojected, and said so
    assert not by["new_rule"].projected and "UNPROJECTED" in by["new_rule"].note
    assert not by["rule_the_run_lacks"].projected
    assert by["rule_the_run_lacks"].job_seconds == 0.0
    totals = {"thesis_config": "profile=thesis", "target": "t", "jobs": 7, "run_dir": "r",
              "run_config": "", "job_seconds": 1.0, "critical_path_s": 1.0, "critical_path": [],
              "cores": 2, "wall_local_s": 0.5, "cluster_cores": 100, "wall_cluster_s": 1.0,
              "max_epochs_factor": 1.0, "early_stop_job_seconds": 1.0,
              "early_stop_wall_local_s": 0.5, "bf16_job_seconds": None}  # fmt: skip
    text = pt.render(stages, totals, warnings, assumptions)
    assert "WARNING: 2 rule(s) UNPROJECTED" in text
    assert "- **new_rule** (1 jobs)" in text and "- **rule_the_run_lacks** (1 jobs)" in text


def test_protocol_differences_name_the_factors_they_make_uncertain():
    run = {"replay": {"squeeze": {"angle": 0.25}, "timestep": 0.0005},
           "synthesis": {"energy": {"name": "hpen"}, "shards": 1},
           "model": {"cnn": {"mixed_precision": "native"}}, "train": {"seeds": [42]},
           "new_group": {"x": 1}}  # fmt: skip
    thesis = {"replay": {"squeeze": {"angle": 0.0}, "timestep": 0.0005},
              "synthesis": {"energy": {"name": "reference"}, "shards": 8},
              "model": {"cnn": {"mixed_precision": None}}, "train": {"seeds": [42, 43]},
              "new_group": {"x": 2}}  # fmt: skip
    diffs = {d["key"]: d["affects"] for d in pt.protocol_differences(run, thesis)}
    # the scales (shards, seeds) are what the projection multiplies by, not differences
    assert set(diffs) == {"replay.squeeze.angle", "synthesis.energy.name",
                          "model.cnn.mixed_precision", "new_group.x"}  # fmt: skip
    assert "replay_grasps" in diffs["replay.squeeze.angle"]
    assert "evaluate_monitor" in diffs["synthesis.energy.name"]
    assert "train_input_model" in diffs["model.cnn.mixed_precision"]
    assert "not classified" in diffs["new_group.x"]


def test_dry_run_parsing_keeps_inputs_for_the_thesis_projection():
    jobs = pt.parse_dry_run(DRY_RUN)
    assert [j.rule for j in jobs] == ["build_hand", "anneal", "report"]
    assert jobs[1].input == ["results/hand/contact_candidates.npz",
                             "results/objects/pear/sdf.npz"]  # fmt: skip
    assert jobs[1].wildcards == {"object": "pear", "shard": "0"}
    assert pt.inputs_like(jobs[1], r"sdf\.npz$") == ["results/objects/pear/sdf.npz"]


def test_a_run_that_shared_its_cores_is_detected_and_scaled(tmp_path):
    """--time-log: the run's CPU seconds per job wall second; --cpu-scaled scales every job's
    seconds and the times its records hold (here the training seconds) by it."""
    job = _train_job(tmp_path, "train_model", "lstm", 20.0, 16.0, mixed=False, seed="42")
    log = tmp_path / "time.log"
    log.write_text(
        "\tUser time (seconds): 8.0\n\tSystem time (seconds): 2.0\n"
        "\tElapsed (wall clock) time (h:mm:ss or m:ss): 0:15.00\n"
    )
    wall, _ = pt.measured_jobs(tmp_path, [job])
    share = pt.cpu_share(log, wall)
    assert share == {"wall_s": 15.0, "cpu_s": 10.0, "job_wall_s": 20.0, "cpu_per_job_s": 0.5}
    scaled, _ = pt.measured_jobs(tmp_path, [job], share["cpu_per_job_s"])
    assert scaled["train_model"][0][1] == 10.0 and job.time_scale == 0.5
    (obs,), _, _ = pt.training_obs(tmp_path, scaled["train_model"])
    assert (obs.compute, obs.overhead) == (8.0, 2.0)
    # the share is of wall seconds, whatever the jobs were scaled by
    assert pt.cpu_share(log, scaled)["job_wall_s"] == 20.0
