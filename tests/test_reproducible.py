"""Byte-reproducible outputs (docs/design.md, data contracts): a rerun on the same machine, with
the same configuration and code, rewrites every data file byte for byte. Run-time measurements
(wall times, rates) live in each job's sidecars (its ``*.timing.json`` / ``timing.json``, its log,
Snakemake's benchmark file), never in the data; the compute platform is in the data, in a stable
order.

The toy run is not repeated (it costs minutes): in a copy of it, with the result cache off, one
job of each rule kind that writes data is recomputed and its outputs compared with the run's."""

from __future__ import annotations

import hashlib
import json
import re
import time
from pathlib import Path

import pytest

from tests.toy_workflow import OBJECT, copy_run, listed_jobs, snakemake_run

# No cache (a restore would copy the earlier bytes and prove nothing); reruns by modification
# time only (the copy's code, params and software are the run's).
RERUN = ["cache={enabled: false}", "--rerun-triggers", "mtime", "--force"]

# Three Snakemake calls, each forcing the jobs of its targets and running what they feed on the
# way to its other targets (and what is older than its inputs). A job upstream of another call's
# target must not share its call (a rerun object would rerun its every shard, a rerun dataset
# every model of the aggregate), and comes after it.
STEPS = {
    "aggregate": ["results/studies/baseline/summary.json"],  # aggregate_baseline: study tables
    "chain": [
        f"results/grasps/{OBJECT}/shard_0.parquet",  # anneal_grasps: one shard
        f"results/grasps/{OBJECT}/summary.json",  # summarise_grasps
        f"results/replay/{OBJECT}/replays_0.parquet",  # replay_grasps: the same shard
        "results/datasets/baseline/index.parquet",  # label_windows: the labelled dataset
        "results/tune/lstm/best.json",  # tune_model (on the tuning window's dataset)
        "results/train/baseline/lstm/seed42/metrics.json",  # train_model: metrics, .pt
        "results/monitor/export/baseline_lstm/model.onnx",  # export_monitor: TorchScript, ONNX
    ],
    "object": [f"results/objects/{OBJECT}/meta.json"],  # preprocess_object (CoACD, SDF)
}
RULES = {
    "aggregate": {"aggregate_baseline"},
    "chain": {"anneal_grasps", "summarise_grasps", "replay_grasps", "label_windows",
              "label_sweep_reference", "trim_sweep_window", "tune_model", "train_model",
              "export_monitor"},
    "object": {"preprocess_object"},
}  # fmt: skip

# The outputs that differ between runs by nature, each rerun job's own: its timing sidecar (wall
# times and rates). Nothing else of these jobs may differ. Elsewhere in the workflow, not rerun
# here, a whole forced rerun of the toy run on the same machine (the record) changed only,
# besides these sidecars, what is by nature run-dependent (docs/design.md, data contracts):
# - results/studies/latency.parquet: measure_latency's measured inference latencies;
# - what is computed from them: the sweep study's operating_points.parquet and summary.json (and
#   their creep-free twins; its runs and summary tables are the same bytes), the learning figures
#   latency.png and operating_points.png, the latency-aware pick (export_pick: the same model
#   unless the latencies reorder it) and, where it runs, the closed loop (its monitors react
#   after their measured latency);
# - results/report.html (the stage wall times) and results/report/rulegraph.dot (Snakemake's
#   --rulegraph lists its edges in no fixed order);
# - resources/*/source.json, the fetch records (when the files were fetched);
# - tuning's Optuna database study.sqlite (trial times; not an output: tuning's outputs,
#   best.json and trials.parquet, are data and rerun the same).
RUN_DEPENDENT = re.compile(r"^results/benchmarks/[^/]+/[^/]+\.timing\.json$"
                           r"|^results/train/[^ ]+/timing\.json$")  # fmt: skip


def _sha256(path: Path) -> str:
    return hashlib.sha256(path.read_bytes()).hexdigest()


def _rerun(workdir: Path, targets: list[str], config: list[str], env: dict[str, str]) -> list:
    proc = snakemake_run(workdir, *targets, *config, *RERUN, env=env)
    assert proc.returncode == 0, proc.stdout[-3000:] + proc.stderr[-3000:]
    return listed_jobs(proc.stdout + proc.stderr)


@pytest.mark.workflow
def test_rerun_rewrites_every_data_file_byte_for_byte(run, tmp_path):
    shared, env, config = run
    workdir = copy_run(shared, tmp_path / "wf", cache=False)
    before = {str(p.relative_to(workdir)): _sha256(p)
              for p in (workdir / "results").rglob("*") if p.is_file()}  # fmt: skip
    # tuning resumes a study it finds (its trial done: nothing to run); without it, it reruns
    (workdir / "results" / "tune" / "lstm" / "study.sqlite").unlink()
    start = time.time()
    ran = {step: _rerun(workdir, targets, config, env) for step, targets in STEPS.items()}
    outputs = []
    for step, jobs in ran.items():
        assert {j["rule"] for j in jobs} == RULES[step], step
        for job in jobs:
            # computed, not restored (the cache is off): the log is the job's own
            log_text = (workdir / job["log"][0]).read_text()
            assert not log_text.startswith("graspstab cache"), job
            outputs += job["output"]
    assert {
        "results/tune/lstm/trials.parquet",
        "results/train/baseline/lstm/seed42/model.pt",
        "results/datasets/baseline/windows.npy",
        "results/monitor/export/baseline_lstm/model.torchscript.pt",
    } <= set(outputs)
    differ, sidecars = [], []
    for rel in outputs:
        path = workdir / rel
        assert path.stat().st_mtime >= start, f"{rel} was not rewritten"
        if RUN_DEPENDENT.match(rel):
            assert rel in before  # the run wrote the same sidecar
            sidecars.append(rel)
            timing = json.loads(path.read_text())
            assert any(k.endswith(("seconds", "_s")) for k in timing), (rel, timing)
        elif _sha256(path) != before[rel]:
            differ.append(rel)
    assert not differ, f"rerun outputs that differ from the run's: {differ}"
    # exactly the sidecars of the rerun jobs that time themselves were left out
    assert sorted(sidecars) == [
        f"results/benchmarks/anneal_grasps/{OBJECT}_shard_0.timing.json",
        f"results/benchmarks/replay_grasps/{OBJECT}_shard_0.timing.json",
        "results/train/baseline/lstm/seed42/timing.json",
    ]
