"""Project every rule of the thesis profile's cost from a finished run, since it has never run."""

# Reads ``results/benchmarks/<rule>/*.tsv`` of a finished run (Snakemake's benchmark format: ``s``
# wall seconds, ``max_rss`` MB) plus what its artefacts record (grasps per shard and their
# annealing rate, simulated seconds per replay, epochs, window counts and precision per training
# job, trials per study, conditions x scorers per robustness study), turns each rule into a
# per-unit throughput and multiplies it by the thesis DAG's units. The thesis DAG's rules and jobs
# come from a Snakemake dry run of ``--config profile=thesis`` (no hand list: a rule added to the
# workflow shows up), its scales from its resolved config and the reference's window counts
# (4.1.1). A rule with no scaling model here, or not measured in the run, is printed as
# UNPROJECTED. Only the jobs of the run's own DAG are measured, so stale benchmark files of an
# earlier configuration in the same ``results/`` are ignored (and counted). Where the run's
# protocol options differ from the thesis profile's (the quick profile's energy, squeeze and
# bfloat16 training), the output names the scale factors that carry the difference.
#
#     python benchmarks/project_thesis.py /path/to/run           # its results/ holds the run
#     python benchmarks/project_thesis.py --results results --run-config 'synthesis={shards: 3}'
#
# ``--run-config`` takes the ``--config`` entries the run used (they decide its DAG). Nothing is
# written; the dry runs use a temporary work directory. The output is Markdown (``--json``: JSON).

from __future__ import annotations

import argparse
import json
import math
import re
import subprocess
import sys
import tempfile
import zipfile
from collections import defaultdict
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import polars as pl
import pyarrow.parquet as pq
import yaml

from graspstab.report.dag import rule_graph
from graspstab.report.provenance import read_benchmark

REPO = Path(__file__).resolve().parents[1]
TARGET = "results/report.html"

# The reference's main comparison: training / validation / test windows (4.1.1).
THESIS_WINDOWS = {"train": 43_978, "val": 12_052, "test": 14_587}
# Rules that train one model (metrics.json: epochs, window counts, training seconds, precision).
TRAIN_RULES = ("train_model", "train_sweep_model", "train_split_model", "train_augmented_model",
               "train_input_model")  # fmt: skip
# Rules that label windows from every replayed grasp's traces.
LABEL_RULES = ("label_windows", "label_sweep_reference", "label_input_set")
# The sensor-robustness studies: every condition x (checkpoints + the proxy) on the test windows.
ROBUSTNESS_RULES = ("evaluate_sensor_robustness", "evaluate_pick_robustness")
# Rules whose work does not grow with the thesis's data (downloads, the hand, figures of one
# object or grasp, tables of a few hundred metrics, exports of one model): the run's seconds per
# job, as measured.
PER_JOB_RULES = {
    "fetch_ycb_object": "one mesh copied or downloaded",
    "fetch_hand_description": "one description copied or downloaded",
    "build_hand": "the hand, the same in every profile",
    "plot_hand": "one figure of the hand",
    "plot_objects": "one figure of the objects",
    "plot_replay": "one replay's figure",
    "plot_window": "one window's figure",
    "aggregate_baseline": "a table of run metrics",
    "aggregate_sweep": "a table of run metrics",
    "aggregate_splits": "a table of run metrics",
    "aggregate_inputs": "a table of run metrics",
    "plot_learning": "figures from the study tables",
    "plot_sensor_robustness": "figures from the study table",
    "plot_monitor": "figures from the monitor's summary",
    "export_monitor": "one model exported",
    "export_pick": "one model exported",
    "rulegraph": "the rule and job graphs printed",
    "report": "the HTML page from the other rules' outputs",
}
# Run-versus-thesis config keys that only set how much is done (the scales this script
# multiplies by); any other difference is a protocol difference, reported with what it affects.
SCALE_KEYS = ("profile_name", "synthesis.shards", "synthesis.grasps_per_shard",
              "synthesis.seed_block", "synthesis.split_shards", "train.seeds", "train.max_epochs",
              "train.patience", "tune.trials", "tune.pruner", "sweep.", "splits.", "latency.",
              "sensing.", "audit.", "only_objects", "objects.")  # fmt: skip
REPLAY_DEPENDENT = ("replay_grasps", "label_windows", "label_sweep_reference", "label_input_set",
                    "evaluate_monitor", "plot_unstable_speeds")  # fmt: skip
# Protocol keys whose difference changes a scale factor, and the rules whose factor carries it.
PROTOCOL_EFFECTS = {
    "synthesis.energy": (
        "anneal_grasps (E_hpen is computed at weight 0 too, so the rate per "
        "iteration holds; the accepted path differs), and through the grasps it "
        "makes every per-simulated-second or per-grasp factor: " + ", ".join(REPLAY_DEPENDENT)
    ),  # fmt: skip
    "replay.": (
        "simulated seconds per grasp (when a grasp drops or settles), so "
        + ", ".join(REPLAY_DEPENDENT)
    ),  # fmt: skip
    "contact": "simulated seconds per grasp and steps per second: " + ", ".join(REPLAY_DEPENDENT),
    "model.": (
        "the per-family training rates of "
        + ", ".join((*TRAIN_RULES, "tune_model"))
        + " (precision: corrected by --fp32-factor where the run trained under autocast "
        "and the thesis does not)"
    ),  # fmt: skip
    "train.": "the training rates of " + ", ".join((*TRAIN_RULES, "tune_model")),
    "labels.": "every dataset's windows and steps (the thesis keeps the reference's counts)",
}
# fp32 over bfloat16 job seconds on the CPU, the quick profile's baseline runs at seeds 42/43
# ("Mixed precision on the CPU", docs/benchmarks.md: CNN 320 / 147 s, LSTM 100 / 76 s; the GRU
# trains in fp32 under both settings).
FP32_FACTOR = {"cnn": 2.18, "gru": 1.0, "lstm": 1.32}
CACHE_MARK = "graspstab cache: restored"
# The note of a rule whose whole job time (start-up included) is counted as per-unit work.
UPPER = "start-up counted as per-unit work: an upper bound"


@dataclass
class Job:
    """One job of a dry run: its rule, wildcards, inputs, outputs, log and benchmark paths."""

    rule: str
    wildcards: dict[str, str] = field(default_factory=dict)
    input: list[str] = field(default_factory=list)
    output: list[str] = field(default_factory=list)
    log: list[str] = field(default_factory=list)
    benchmark: str | None = None
    time_scale: float = 1.0  # the job's seconds used over its wall seconds (--cpu-scaled)


@dataclass
class Obs:
    """One measured job: ``compute`` seconds spent on ``units`` of work, plus ``overhead``."""

    group: str
    units: float
    compute: float
    overhead: float
    max_rss: float


@dataclass
class Stage:
    """A rule's projection: measured throughput times the thesis DAG's units."""

    rule: str
    unit: str
    run_jobs: int
    run_units: float
    run_seconds: float
    seconds_per_unit: float | None
    thesis_jobs: int
    thesis_units: float
    job_seconds: float
    longest_job: float
    max_rss_mb: float
    note: str = ""
    epoch_fraction: float | None = None  # training and tuning: epochs run / max_epochs
    stop_fraction: float | None = None  # training: (best epoch + patience) / max_epochs
    projected: bool = True  # False: no scaling model or no measurement (UNPROJECTED)
    rss_thesis_mb: float | None = None  # the measured peak plus the data that grows with scale
    per_job: list[dict[str, Any]] = field(default_factory=list)  # wildcards, seconds per job


# --- Snakemake: dry runs, rule graph, resolved config -------------------------------------------


def snakemake(args: Sequence[str]) -> str:
    """Run Snakemake on this repository's Snakefile in a throw-away work directory; stdout."""
    with tempfile.TemporaryDirectory(prefix="project_thesis_") as tmp:
        cmd = [sys.executable, "-m", "snakemake", "-s", str(REPO / "Snakefile"), "-d", tmp, *args]
        done = subprocess.run(cmd, capture_output=True, text=True)
    if done.returncode != 0:
        raise RuntimeError(f"{' '.join(cmd)} failed:\n{done.stderr[-3000:]}")
    return done.stdout


def config_args(entries: Sequence[str]) -> list[str]:
    """``--config`` arguments for Snakemake (nothing when there are no entries)."""
    return ["--config", *entries] if entries else []


def dry_run_jobs(entries: Sequence[str], target: str = TARGET) -> list[Job]:
    """Every job of the DAG for ``target`` under ``--config entries`` from scratch (an empty work
    directory); the target goes before ``--config``, which would take it as an entry."""
    out = snakemake(["--dry-run", "--cores", "1", target, *config_args(entries)])
    return parse_dry_run(out)


def parse_dry_run(text: str) -> list[Job]:
    """The job blocks of Snakemake's dry-run listing (``rule NAME:`` then indented fields)."""
    jobs: list[Job] = []
    current: Job | None = None
    for line in text.splitlines():
        head = re.match(r"^(?:local)?(?:rule|checkpoint) (\w+):$", line)
        if head:
            current = Job(rule=head.group(1))
            jobs.append(current)
            continue
        field_ = re.match(r"^\s{4}(\w+): (.*)$", line)
        if current is None or not field_:
            if not line.startswith(" "):
                current = None
            continue
        key, value = field_.groups()
        if key == "wildcards":
            current.wildcards = dict(kv.split("=", 1) for kv in value.split(", "))
        elif key in ("input", "output", "log"):
            setattr(current, key, value.split(", "))
        elif key == "benchmark":
            current.benchmark = value
    return jobs


def rule_edges(entries: Sequence[str], target: str = TARGET) -> list[tuple[str, str]]:
    """(upstream, downstream) rule pairs of the rule graph (``--rulegraph`` DOT output)."""
    return list(rule_graph(snakemake([target, "--rulegraph", *config_args(entries)])).edges)


def parse_entries(entries: Sequence[str]) -> dict[str, Any]:
    """``KEY=VALUE`` entries as Snakemake reads ``--config`` (the value is YAML)."""
    out = {}
    for entry in entries:
        key, _, value = entry.partition("=")
        out[key] = yaml.safe_load(value)
    return out


def resolve_config(entries: Sequence[str]) -> dict[str, Any]:
    """The resolved config for ``--config entries``, as workflow/rules/common.smk composes it."""
    from graspstab.config import load_config

    return load_config(
        REPO / "config",
        REPO / "workflow" / "schemas" / "config.schema.yaml",
        snakemake_config=parse_entries(entries),
        check_files=False,
    )


# --- Reading a run's records --------------------------------------------------------------------


def restored_from_cache(workdir: Path, job: Job) -> bool:
    """Whether the job's log says its outputs came from the content-addressed cache (a copy, so
    its benchmark measures no computation)."""
    for log in job.log:
        path = workdir / log
        if path.is_file() and CACHE_MARK in path.read_text(errors="replace"):
            return True
    return False


def parquet_meta(path: Path) -> dict[str, Any]:
    """The ``graspstab`` JSON a stage stores in its Parquet metadata."""
    meta = pq.read_metadata(path).metadata or {}
    return json.loads(meta.get(b"graspstab", b"{}"))


def parquet_rows(path: Path) -> int:
    """Rows of a Parquet file (its footer only)."""
    return pq.read_metadata(path).num_rows


def split_sizes(counts: Mapping[str, Mapping[str, int]]) -> dict[str, int]:
    """Windows per split from a ``counts``/``splits`` record ({split: {stable, unstable, ...}})."""
    return {s: int(c.get("stable", 0)) + int(c.get("unstable", 0)) for s, c in counts.items()}


def inputs_like(job: Job, pattern: str) -> list[str]:
    """The job's inputs whose path matches ``pattern`` (a regular expression)."""
    return [p for p in job.input if re.search(pattern, p)]


def npz_bytes(path: Path) -> int:
    """Uncompressed bytes of an ``.npz`` archive's arrays (what loading it holds)."""
    with zipfile.ZipFile(path) as z:
        return sum(i.file_size for i in z.infolist())


def npy_row_bytes(path: Path) -> tuple[int, int] | None:
    """(steps, bytes per window-step) of a windows ``.npy`` (n, steps, channels); None if absent."""
    if not path.is_file():
        return None
    arr = np.load(path, mmap_mode="r")
    return int(arr.shape[1]), int(np.prod(arr.shape[2:], dtype=np.int64)) * arr.dtype.itemsize


# --- Per-stage observations of the run ----------------------------------------------------------


def measured_jobs(
    workdir: Path, jobs: Iterable[Job], scale: float = 1.0
) -> tuple[dict[str, list[tuple[Job, float, float]]], list[str]]:
    """(job, seconds, max RSS) per rule for the run's jobs with a benchmark; and warnings.
    ``scale`` multiplies every job's wall seconds and the times its own records hold (annealing,
    simulation, training seconds; ``Job.time_scale``): a run that shared its cores with other
    work, scaled to the CPU it got (:func:`cpu_share`)."""
    out: dict[str, list[tuple[Job, float, float]]] = defaultdict(list)
    warnings = []
    for job in jobs:
        if job.benchmark is None:
            continue
        path = workdir / job.benchmark
        if not path.is_file():
            warnings.append(f"{job.rule}: no benchmark {job.benchmark}")
            continue
        missing = [o for o in job.output if not (workdir / o).exists()]
        if missing:
            warnings.append(f"{job.rule}: {missing[0]} missing, {job.benchmark} not used")
            continue
        if restored_from_cache(workdir, job):
            warnings.append(f"{job.rule}: {job.benchmark} was a cache restore, not used")
            continue
        bench = read_benchmark(path)
        rss = bench["max_rss_mb"]
        job.time_scale = scale
        s = bench["s"] * scale
        out[job.rule].append((job, s, 0.0 if rss is None or math.isnan(rss) else rss))
    return out, warnings


def cpu_share(time_log: Path, measured: Mapping[str, Sequence[tuple[Job, float, float]]]) -> dict:
    """The run's CPU seconds (``/usr/bin/time -v``: every process, Snakemake's own included) per
    second of its jobs' wall time (their benchmarks); about 1 when the jobs had their cores to
    themselves, less when other work shared them. (The benchmarks' own ``cpu_time`` is sampled
    every 30 s after a job's first 15 s, so it misses up to 30 s of a job's end.)"""
    from cost_table import wall_and_cpu

    wall, cpu = wall_and_cpu(time_log)
    jobs = sum(s / j.time_scale for rows in measured.values() for j, s, _ in rows)
    return {"wall_s": wall, "cpu_s": round(cpu, 1) if cpu else cpu, "job_wall_s": round(jobs, 1),
            "cpu_per_job_s": round(cpu / jobs, 3) if cpu and jobs else None}  # fmt: skip


def stale_benchmarks(workdir: Path, jobs: Iterable[Job]) -> dict[str, int]:
    """Benchmark files under results/benchmarks that no job of the run's DAG writes, per rule."""
    known = {j.benchmark for j in jobs if j.benchmark}
    root = workdir / "results" / "benchmarks"
    out: dict[str, int] = defaultdict(int)
    for path in root.glob("*/*.tsv") if root.is_dir() else []:
        if str(path.relative_to(workdir)) not in known:
            out[path.parent.name] += 1
    return dict(out)


def per_job_obs(measured: Sequence[tuple[Job, float, float]], group_by: str | None) -> list[Obs]:
    """One unit per job (optionally grouped by a wildcard, e.g. the object)."""
    return [
        Obs(j.wildcards.get(group_by, "") if group_by else "", 1.0, s, 0.0, rss)
        for j, s, rss in measured
    ]


def job_timing(workdir: Path, job) -> dict[str, Any] | None:
    """The job's timing sidecar (its output ending in ``timing.json``: wall times and rates), or
    None for a run made before the timings left the data files (they are in its data then)."""
    path = next((p for p in job.output if p.endswith("timing.json")), None)
    return json.loads((workdir / path).read_text()) if path and (workdir / path).is_file() else None


def anneal_obs(workdir: Path, measured, ref_iterations: int) -> list[Obs]:
    """Candidate grasps x (iterations / reference iterations); the annealing time is the grasps
    over the rate the shard table records, the rest of the job (loading, writing) is overhead."""
    out = []
    for job, s, rss in measured:
        meta = parquet_meta(workdir / job.output[0])
        iterations = meta["provenance"]["params"]["annealing"]["iterations"]
        grasps = float(meta["grasps"])
        rate = (job_timing(workdir, job) or meta)["grasps_per_s"]
        compute = min(s, grasps / float(rate) * job.time_scale)
        units = grasps * iterations / ref_iterations
        out.append(Obs(job.wildcards["object"], units, compute, s - compute, rss))
    return out


def replay_obs(workdir: Path, measured) -> tuple[list[Obs], dict[str, float], float]:
    """Simulated seconds per replay job (the summary's ``duration_s``; the grasps' ``wall_s`` in
    the job's timing sidecar are the simulation time, the rest overhead); each object's mean
    simulated seconds per grasp; and the traces' uncompressed bytes per simulated second."""
    out, sim, grasps = [], defaultdict(float), defaultdict(int)
    trace_bytes, trace_sim = 0, 0.0
    for job, s, rss in measured:
        table = pl.read_parquet(workdir / next(p for p in job.output if p.endswith(".parquet")))
        units = float(table["duration_s"].sum())
        timing = job_timing(workdir, job)
        wall = sum(timing["wall_s"]) if timing else float(table["wall_s"].sum())
        compute = min(s, wall * job.time_scale)
        obj = job.wildcards["object"]
        sim[obj] += units
        grasps[obj] += table.height
        for p in job.output:
            if p.endswith(".npz") and (workdir / p).is_file():
                trace_bytes += npz_bytes(workdir / p)
                trace_sim += units
        out.append(Obs(obj, units, compute, s - compute, rss))
    per_grasp = {o: sim[o] / grasps[o] for o in sim if grasps[o]}
    return out, per_grasp, trace_bytes / trace_sim if trace_sim else 0.0


def training_obs(
    workdir: Path, measured, fp32: Mapping[str, float] | None = None, fp32_steps: int | None = None
) -> tuple[list[Obs], dict[str, list[float]], dict[str, bool]]:
    """Window-steps x epochs (training + validation windows each epoch) per training job, grouped
    by family; the metrics' training seconds are the work, the rest (start-up, test evaluation,
    threshold) overhead. Also per job: epochs-run fraction, best epoch, train+val share; and per
    family whether it trained under autocast. ``fp32`` {family: factor}: the training seconds of
    an autocast job at ``fp32_steps`` window steps (where the factor was measured; any window
    when None) are multiplied by its family's factor (the thesis trains in fp32)."""
    out: list[Obs] = []
    stats: dict[str, list[float]] = defaultdict(list)
    amp: dict[str, bool] = {}
    for job, s, rss in measured:
        metrics = json.loads((workdir / next(p for p in job.output if p.endswith("metrics.json")))
                             .read_text())  # fmt: skip
        sizes = split_sizes(metrics["counts"])
        epochs = int(metrics["epochs_run"])
        family = metrics["family"]
        units = epochs * (sizes["train"] + sizes["val"]) * int(metrics["window_steps"])
        compute = min(s, float((job_timing(workdir, job) or metrics)["train_seconds"])
                      * job.time_scale)  # fmt: skip
        mixed = bool(metrics.get("placement", {}).get("mixed_precision", False))
        amp[family] = amp.get(family, False) or mixed
        at_window = fp32_steps is None or int(metrics["window_steps"]) == fp32_steps
        factor = fp32.get(family, 1.0) if (fp32 and mixed and at_window) else 1.0
        out.append(Obs(family, units, compute * factor, s - compute, rss))
        stats["fraction"].append(epochs / int(metrics["params"]["train"]["max_epochs"]))
        stats["best_epoch"].append(float(metrics["best_epoch"]))
        stats["share"].append((sizes["train"] + sizes["val"]) / sum(sizes.values()))
    return out, stats, amp


def tune_obs(workdir: Path, measured, dt: float,
             fp32: Mapping[str, float] | None = None) -> tuple[list[Obs], list[float]]:  # fmt: skip
    """Window-steps x epochs summed over a study's trials, per family; and the epochs-run
    fraction of every study (epochs over trials x max_epochs). ``fp32`` {family: factor}: the
    study's seconds multiplied by it (families that trained under autocast)."""
    out, fractions = [], []
    for job, s, rss in measured:
        best_path = next(p for p in job.output if p.endswith("best.json"))
        best = json.loads((workdir / best_path).read_text())
        trials = pl.read_parquet(workdir / next(p for p in job.output if p.endswith(".parquet")))
        summary = json.loads((workdir / best["params"]["dataset"] / "summary.json").read_text())
        sizes = split_sizes(summary["splits"])
        steps = round(float(summary["window_s"]) / dt)
        epochs = int(trials["epochs_run"].sum())
        units = epochs * (sizes["train"] + sizes["val"]) * steps
        factor = (fp32 or {}).get(best["family"], 1.0)
        out.append(Obs(best["family"], units, s * factor, 0.0, rss))
        fractions.append(epochs / (trials.height * int(best["params"]["train"]["max_epochs"])))
    return out, fractions


def trim_obs(workdir: Path, measured, dt: float) -> list[Obs]:
    """Windows x steps written per trimmed dataset (a copy of the reference's last steps)."""
    out = []
    for job, s, rss in measured:
        summary = json.loads((workdir / next(p for p in job.output if "summary" in p)).read_text())
        steps = round(int(job.wildcards["ms"]) / 1000 / dt)
        out.append(Obs("", float(summary["windows"]) * steps, s, 0.0, rss))
    return out


def robustness_obs(workdir: Path, measured) -> list[Obs]:
    """Scored windows per robustness study: its table's rows (condition x scorer, the proxy
    included) x the windows of its split (the summary's ``n``)."""
    out = []
    for job, s, rss in measured:
        rows = parquet_rows(workdir / next(p for p in job.output if p.endswith(".parquet")))
        n = json.loads((workdir / next(p for p in job.output if p.endswith(".json"))).read_text())
        out.append(Obs("", float(rows * int(n["n"])), s, 0.0, rss))
    return out


def replay_input_obs(workdir: Path, measured) -> list[Obs]:
    """Simulated seconds of the replay tables a job reads (``duration_s`` summed)."""
    out = []
    for job, s, rss in measured:
        sim = sum(
            float(pl.read_parquet(workdir / p, columns=["duration_s"])["duration_s"].sum())
            for p in inputs_like(job, r"/replays_\d+\.parquet$")
        )  # fmt: skip
        out.append(Obs("", sim, s, 0.0, rss))
    return out


def rows_read_obs(workdir: Path, measured, pattern: str) -> list[Obs]:
    """Rows of the Parquet inputs matching ``pattern`` a job reads (grasps or replays)."""
    out = []
    for job, s, rss in measured:
        rows = sum(parquet_rows(workdir / p) for p in inputs_like(job, pattern))
        out.append(Obs("", float(rows), s, 0.0, rss))
    return out


# --- Projection ---------------------------------------------------------------------------------


def project(rule: str, unit: str, obs: Sequence[Obs], thesis: Sequence[tuple[str, float]],
            note: str = "", fallback: Mapping[str, float] | None = None) -> Stage:  # fmt: skip
    """Thesis job time = the group's mean overhead + its seconds per unit x the job's units; a
    group the run lacks takes ``fallback[group]`` seconds per unit when given, else the pooled
    rate; longest = the slowest."""
    pooled_rate = sum(o.compute for o in obs) / max(sum(o.units for o in obs), 1e-12)
    pooled_over = sum(o.overhead for o in obs) / len(obs)
    by_group: dict[str, list[Obs]] = defaultdict(list)
    for o in obs:
        by_group[o.group].append(o)

    def job_time(group: str, units: float) -> float:
        g = by_group.get(group)
        if not g:
            rate = (fallback or {}).get(group, pooled_rate)
            return pooled_over + rate * units
        rate = sum(o.compute for o in g) / max(sum(o.units for o in g), 1e-12)
        return sum(o.overhead for o in g) / len(g) + rate * units

    times = [job_time(g, u) for g, u in thesis]
    return Stage(
        rule=rule, unit=unit, run_jobs=len(obs), run_units=sum(o.units for o in obs),
        run_seconds=sum(o.compute + o.overhead for o in obs), seconds_per_unit=pooled_rate,
        thesis_jobs=len(thesis), thesis_units=sum(u for _, u in thesis),
        job_seconds=sum(times), longest_job=max(times, default=0.0),
        max_rss_mb=max((o.max_rss for o in obs), default=0.0), note=note,
        per_job=[{"seconds": t} for t in times],
    )  # fmt: skip


def group_rates(obs: Sequence[Obs]) -> dict[str, float]:
    """Seconds per unit per group."""
    units: dict[str, float] = defaultdict(float)
    secs: dict[str, float] = defaultdict(float)
    for o in obs:
        units[o.group] += o.units
        secs[o.group] += o.compute
    return {g: secs[g] / units[g] for g in units if units[g] > 0}


def borrowed_rates(obs: Sequence[Obs], reference: Mapping[str, float]) -> dict[str, float]:
    """Per-family rates for a rule that measured only some families: each family's rate in the
    reference rule (``train_model``) times this rule's measured over predicted seconds."""
    predicted = sum(reference[o.group] * o.units for o in obs if o.group in reference)
    measured = sum(o.compute for o in obs if o.group in reference)
    if predicted <= 0:
        return {}
    return {g: r * measured / predicted for g, r in reference.items()}


def mean(values: Sequence[float]) -> float:
    """Arithmetic mean (NaN for none)."""
    return sum(values) / len(values) if values else float("nan")


def thesis_steps(job: Job, cfg: Mapping[str, Any]) -> int:
    """Window steps of a thesis training job: its sweep window, else the study's window."""
    if "ms" in job.wildcards:
        window_s = int(job.wildcards["ms"]) / 1000
    elif job.rule == "train_split_model":
        window_s = float(cfg["splits"]["window_s"])
    else:
        window_s = float(cfg["labels"]["window_s"])
    return round(window_s / float(cfg["replay"]["timestep"]))


def dataset_steps(job: Job, cfg: Mapping[str, Any]) -> int:
    """Window steps of the dataset a thesis job reads or writes."""
    dt = float(cfg["replay"]["timestep"])
    if job.rule == "label_sweep_reference":
        return round(max(float(w) for w in cfg["sweep"]["windows_s"]) / dt)
    if job.rule == "tune_model":
        return round(float(cfg["tune"]["window_s"]) / dt)
    if job.rule == "evaluate_pick_robustness":
        return round(float(cfg["monitor"]["window_s"]) / dt)
    if job.rule in TRAIN_RULES or "ms" in job.wildcards:
        return thesis_steps(job, cfg)
    return round(float(cfg["labels"]["window_s"]) / dt)


def windows_path(job: Job) -> str | None:
    """The windows file a job writes (labelling) or reads."""
    paths = [p for p in job.output if p.endswith("windows.npy")]
    paths += [p for p in job.input if p.endswith("windows.npy")]
    return paths[0] if paths else None


def data_growth_mb(workdir: Path, rule: str, run_jobs: Sequence[Job], thesis_jobs: Sequence[Job],
                   cfg: Mapping[str, Any], hold: float) -> float | None:  # fmt: skip
    """MB more of windows a thesis job of ``rule`` holds than the run's did, times ``hold``
    (copies held at once): the thesis windows (all splits) x steps x the run file's bytes per
    window-step, less the run's largest file. None when the rule reads no windows."""
    run_files = [workdir / p for j in run_jobs if (p := windows_path(j))]
    run_files = [f for f in run_files if f.is_file()]
    if not run_files:
        return None
    run_mb = max(f.stat().st_size for f in run_files) / 1e6
    total = sum(THESIS_WINDOWS.values())
    growth = 0.0
    for job in thesis_jobs:
        path = windows_path(job)
        shape = npy_row_bytes(workdir / path) if path else None
        shape = shape or npy_row_bytes(run_files[0])
        growth = max(growth, total * dataset_steps(job, cfg) * shape[1] / 1e6 - run_mb)
    return hold * growth


def segment_mb(cfg: Mapping[str, Any], windows: int, steps: int) -> float:
    """MB of the sensing study's raw segments: each window's steps plus the most context frames
    a condition needs (delay and hold), 5 fingertips x 2 channels in float32
    (graspstab.sensing.segments)."""
    from graspstab.sensing.conditions import conditions

    dt = float(cfg["replay"]["timestep"])
    context = max(c["sensor"].context_frames(dt) for c in conditions(cfg["sensing"]))
    return windows * (steps + context) * 5 * 2 * 4 / 1e6


def project_stages(
    workdir: Path, run_jobs: list[Job], thesis_jobs: list[Job], thesis_cfg: dict[str, Any],
    epoch_fraction: float | None, run_cfg: Mapping[str, Any] | None = None,
    fp32_factor: Mapping[str, float] | None = None, time_scale: float = 1.0,
) -> tuple[list[Stage], list[str], dict[str, Any]]:  # fmt: skip
    """Every rule of the thesis DAG projected (or marked unprojected); warnings; assumptions.
    ``time_scale`` multiplies the run's job times (:func:`measured_jobs`)."""
    measured, warnings = measured_jobs(workdir, run_jobs, time_scale)
    run_cfg = run_cfg or thesis_cfg
    dt = float(thesis_cfg["replay"]["timestep"])
    # where the fp32/bfloat16 factors were measured: the baseline window
    fp32_steps = round(float(run_cfg["labels"]["window_s"]) / dt)
    syn = thesis_cfg["synthesis"]
    n_objects = len({j.wildcards["object"] for j in thesis_jobs if j.rule == "anneal_grasps"})
    thesis_grasps = n_objects * syn["shards"] * syn["grasps_per_shard"]
    total_windows = sum(THESIS_WINDOWS.values())
    train_val = THESIS_WINDOWS["train"] + THESIS_WINDOWS["val"]
    by_rule: dict[str, list[Job]] = defaultdict(list)
    for j in thesis_jobs:
        by_rule[j.rule].append(j)
    run_by_rule: dict[str, list[Job]] = defaultdict(list)
    for j in run_jobs:
        run_by_rule[j.rule].append(j)
    assumptions: dict[str, Any] = {
        "thesis_windows": THESIS_WINDOWS,
        "thesis_candidate_grasps": thesis_grasps,
    }
    if time_scale != 1.0:
        assumptions["run_job_seconds_scaled_by"] = time_scale

    # the precision each family trains in: the run's (its metrics) against the thesis's on a CPU
    amp_run: dict[str, bool] = {}
    for rule in TRAIN_RULES:
        if measured.get(rule):
            for fam, on in training_obs(workdir, measured[rule])[2].items():
                amp_run[fam] = amp_run.get(fam, False) or on

    def thesis_amp(family: str) -> bool:
        spec = thesis_cfg["model"].get(family, {}).get("mixed_precision")
        value = spec if spec is not None else thesis_cfg["train"].get("mixed_precision", "auto")
        return value in (True, "true") or (value == "native" and amp_run.get(family, False))

    table = FP32_FACTOR if fp32_factor is None else fp32_factor
    factors = {f: table.get(f, 1.0) for f, on in amp_run.items()
               if on and not thesis_amp(f)}  # fmt: skip
    if factors:
        assumptions["fp32_over_bf16_factor"] = factors

    # replay first: its simulated seconds per grasp scale the stages that read replays
    sim_per_grasp: dict[str, float] = {}
    trace_bytes_per_s = 0.0
    replay_obs_cache = None
    if measured.get("replay_grasps"):
        replay_obs_cache = replay_obs(workdir, measured["replay_grasps"])
        _, sim_per_grasp, trace_bytes_per_s = replay_obs_cache
    fallback_sim = mean(list(sim_per_grasp.values()))

    def thesis_sim(job: Job) -> float:
        """Simulated seconds of the thesis replay shards a job reads."""
        total = 0.0
        for p in inputs_like(job, r"/replays_\d+\.parquet$"):
            obj = p.split("/")[-2]
            total += syn["grasps_per_shard"] * sim_per_grasp.get(obj, fallback_sim)
        return total

    tm_rates: dict[str, float] = {}
    stages: list[Stage] = []
    order = sorted(by_rule, key=lambda r: (r != "train_model", r))  # train_model's rates first
    for rule in order:
        jobs = by_rule[rule]
        m = measured.get(rule, [])
        rss_growth: float | None = None
        if not m:
            stages.append(Stage(rule, "job", 0, 0, 0, None, len(jobs), len(jobs), 0.0, 0.0, 0.0,
                                "UNPROJECTED: not measured in the run (no benchmark): counted "
                                "as 0", projected=False))  # fmt: skip
            continue
        if rule == "preprocess_object":
            obs = per_job_obs(m, "object")
            stage = project(rule, "object", obs, [(j.wildcards["object"], 1.0) for j in jobs])
        elif rule == "anneal_grasps":
            ref = int(syn["annealing"]["iterations"])
            obs = anneal_obs(workdir, m, ref)
            per_job = syn["grasps_per_shard"]
            stage = project(rule, f"grasp x {ref} it", obs,
                            [(j.wildcards["object"], per_job) for j in jobs],
                            "run used smaller annealing batches: conservative")  # fmt: skip
        elif rule == "replay_grasps":
            obs = replay_obs_cache[0]
            thesis = [(j.wildcards["object"],
                       syn["grasps_per_shard"] * sim_per_grasp.get(j.wildcards["object"],
                                                                   fallback_sim))
                      for j in jobs]  # fmt: skip
            assumptions["replay_sim_s_per_grasp"] = {k: round(v, 2) for k, v in
                                                     sim_per_grasp.items()}  # fmt: skip
            stage = project(rule, "simulated s", obs, thesis,
                            "each object keeps the run's simulated s per grasp")  # fmt: skip
            run_trace = max((trace_bytes_per_s * o.units for o in obs), default=0.0)
            rss_growth = max(0.0, max(u for _, u in thesis) * trace_bytes_per_s - run_trace) / 1e6
        elif rule in LABEL_RULES:
            run_grasps = sum(
                parquet_rows(workdir / p)
                for j in run_jobs if j.rule == "replay_grasps"
                for p in j.output if p.endswith(".parquet")
            )  # fmt: skip
            obs = [Obs("", run_grasps, s, 0.0, rss) for _, s, rss in m]
            stage = project(rule, "replayed grasp", obs, [("", thesis_grasps) for _ in jobs])
            rss_growth = data_growth_mb(workdir, rule, run_by_rule[rule], jobs, thesis_cfg, 2.0)
        elif rule == "trim_sweep_window":
            obs = trim_obs(workdir, m, dt)
            thesis = [("", total_windows * round(int(j.wildcards["ms"]) / 1000 / dt)) for j in jobs]
            stage = project(rule, "window-step", obs, thesis)
            rss_growth = data_growth_mb(workdir, rule, run_by_rule[rule], jobs, thesis_cfg, 1.0)
        elif rule in TRAIN_RULES:
            obs, stats, amp = training_obs(workdir, m, factors, fp32_steps)
            max_epochs = int(thesis_cfg["train"]["max_epochs"])
            frac = epoch_fraction if epoch_fraction is not None else mean(stats["fraction"])
            epochs = frac * max_epochs
            # split assignments move objects between splits: the run's mean train+val share
            windows = train_val
            if rule == "train_split_model":
                windows = total_windows * mean(stats["share"])
            thesis = [(j.wildcards["model"], epochs * windows * thesis_steps(j, thesis_cfg))
                      for j in jobs]  # fmt: skip
            assumptions[f"{rule}_epochs"] = round(epochs, 1)
            assumptions[f"{rule}_train_val_windows"] = round(windows)
            note = f"{frac:.0%} of max_epochs"
            steps = {int(json.loads((workdir / next(p for p in j.output if p.endswith(".json")))
                                    .read_text())["window_steps"]) for j, _, _ in m}  # fmt: skip
            other = sorted(f for f, on in amp.items() if on and f in factors)
            if other and steps - {fp32_steps}:
                note += (
                    f"; {', '.join(other)} ran bfloat16 at {sorted(steps)} steps, fp32 "
                    f"factor applied at {fp32_steps} only"
                )
            fallback = None
            missing = sorted({g for g, _ in thesis} - {o.group for o in obs})
            if rule == "train_model":
                tm_rates = group_rates(obs)
            elif missing and tm_rates:
                fallback = borrowed_rates(obs, tm_rates)
                measured_fams = ", ".join(sorted(group_rates(obs)))
                note += (
                    f"; {', '.join(missing)} not trained in the run: train_model's rate "
                    f"x this rule's measured/predicted ({measured_fams})"
                )
            stage = project(rule, "window-step-epoch", obs, thesis, note, fallback)
            stage.epoch_fraction = frac
            # sensitivity: stop at the run's best epoch + the thesis patience (3.5.2)
            patience = int(thesis_cfg["train"]["patience"])
            stage.stop_fraction = mean(
                [min(max_epochs, b + patience) / max_epochs for b in stats["best_epoch"]]
            )
            rss_growth = data_growth_mb(workdir, rule, run_by_rule[rule], jobs, thesis_cfg, 1.0)
            if rule == "train_augmented_model":  # every window's raw segment for the sensors
                rss_growth = (rss_growth or 0.0) + max(
                    segment_mb(thesis_cfg, total_windows, thesis_steps(j, thesis_cfg)) for j in jobs
                )
        elif rule == "tune_model":
            same = round(float(run_cfg["tune"]["window_s"]) / dt) == fp32_steps
            obs, fractions = tune_obs(workdir, m, dt, factors if same else {})
            frac = epoch_fraction if epoch_fraction is not None else mean(fractions)
            tune = thesis_cfg["tune"]
            units = (int(tune["trials"]) * frac * int(thesis_cfg["train"]["max_epochs"])
                     * train_val * round(float(tune["window_s"]) / dt))  # fmt: skip
            assumptions["tune_model_epochs_per_trial"] = round(
                frac * int(thesis_cfg["train"]["max_epochs"]), 1
            )
            stage = project(rule, "window-step-epoch", obs,
                            [(j.wildcards["model"], units) for j in jobs],
                            f"{tune['trials']} trials, {frac:.0%} of max_epochs")  # fmt: skip
            stage.epoch_fraction = frac
            rss_growth = data_growth_mb(workdir, rule, run_by_rule[rule], jobs, thesis_cfg, 1.0)
        elif rule in ROBUSTNESS_RULES:
            from graspstab.sensing.conditions import conditions

            n_cond = len(conditions(thesis_cfg["sensing"]))
            obs = robustness_obs(workdir, m)
            thesis = [("", n_cond * (len(inputs_like(j, r"model\.pt$")) + 1)
                       * THESIS_WINDOWS["test"]) for j in jobs]  # fmt: skip
            stage = project(
                rule,
                "scored window",
                obs,
                thesis,
                f"{n_cond} conditions x (checkpoints + proxy) x test windows",
            )
            rss_growth = data_growth_mb(workdir, rule, run_by_rule[rule], jobs, thesis_cfg, 1.0)
            # the test windows' raw segments, and their sensed copy
            rss_growth = (rss_growth or 0.0) + 2 * max(
                segment_mb(thesis_cfg, THESIS_WINDOWS["test"], dataset_steps(j, thesis_cfg))
                for j in jobs
            )
        elif rule == "evaluate_monitor":
            obs = replay_input_obs(workdir, m)
            stage = project(
                rule,
                "held-out simulated s",
                obs,
                [("", thesis_sim(j)) for j in jobs],
                "validation and test replays, each object's simulated s per grasp",
            )
            # one shard's traces at a time
            shard = max(syn["grasps_per_shard"] * v for v in sim_per_grasp.values()) if (
                sim_per_grasp) else 0.0  # fmt: skip
            run_shard = max(
                (
                    parquet_rows(workdir / p)
                    for j in run_by_rule[rule]
                    for p in inputs_like(j, r"/replays_\d+\.parquet$")
                ),
                default=0,
            )
            run_shard_s = run_shard * max(sim_per_grasp.values(), default=0.0)
            rss_growth = max(0.0, (shard - run_shard_s) * trace_bytes_per_s / 1e6)
        elif rule == "evaluate_proxy":
            summary = workdir / "results" / "datasets" / "baseline" / "summary.json"
            n = sum(split_sizes(json.loads(summary.read_text())["splits"]).values())
            obs = [Obs("", float(n), s, 0.0, rss) for _, s, rss in m]
            stage = project(rule, "window", obs, [("", total_windows) for _ in jobs], UPPER)
            rss_growth = data_growth_mb(workdir, rule, run_by_rule[rule], jobs, thesis_cfg, 1.0)
        elif rule == "measure_latency":
            lat_run, lat = run_cfg["latency"], thesis_cfg["latency"]
            obs = [Obs("", float(len(inputs_like(j, r"model\.pt$")) * (lat_run["repeats"]
                                                                        + lat_run["warmup"])),
                       s, 0.0, rss) for j, s, rss in m]  # fmt: skip
            thesis = [("", float(len(inputs_like(j, r"model\.pt$")) * (lat["repeats"]
                                                                       + lat["warmup"])))
                      for j in jobs]  # fmt: skip
            stage = project(
                rule,
                "forward pass",
                obs,
                thesis,
                f"checkpoints x (repeats + warm-up); longer windows cost more; {UPPER}",
            )
        elif rule in ("summarise_grasps", "plot_grasps"):
            obs = rows_read_obs(workdir, m, r"/shard_\d+\.parquet$")
            thesis = [("", float(len(inputs_like(j, r"/shard_\d+\.parquet$"))
                             * syn["grasps_per_shard"])) for j in jobs]  # fmt: skip
            stage = project(rule, "candidate grasp", obs, thesis, UPPER)
        elif rule == "plot_unstable_speeds":
            obs = rows_read_obs(workdir, m, r"/replays_\d+\.parquet$")
            thesis = [("", float(len(inputs_like(j, r"/replays_\d+\.parquet$"))
                             * syn["grasps_per_shard"])) for j in jobs]  # fmt: skip
            stage = project(rule, "replayed grasp", obs, thesis, UPPER)
        elif rule in PER_JOB_RULES:
            stage = project(
                rule,
                "job",
                per_job_obs(m, None),
                [("", 1.0) for _ in jobs],
                f"per job: {PER_JOB_RULES[rule]}",
            )
        else:
            stage = project(rule, "job", per_job_obs(m, None), [("", 1.0) for _ in jobs],
                            "UNPROJECTED: no scaling model in benchmarks/project_thesis.py; "
                            "counted at the run's seconds per job")  # fmt: skip
            stage.projected = False
        for entry, job in zip(stage.per_job, jobs, strict=True):
            entry["wildcards"] = job.wildcards
        stage.rss_thesis_mb = stage.max_rss_mb + (rss_growth or 0.0)
        stages.append(stage)
    return stages, warnings, assumptions


def config_differences(run: Any, thesis: Any, prefix: str = "") -> list[tuple[str, Any, Any]]:
    """(dotted key, run value, thesis value) for every leaf where the two configs differ."""
    if isinstance(run, Mapping) and isinstance(thesis, Mapping):
        out = []
        for key in sorted(set(run) | set(thesis), key=str):
            out += config_differences(run.get(key), thesis.get(key), f"{prefix}{key}.")
        return out
    return [] if run == thesis else [(prefix.rstrip("."), run, thesis)]


def protocol_differences(run_cfg: Mapping[str, Any],
                         thesis_cfg: Mapping[str, Any]) -> list[dict[str, Any]]:  # fmt: skip
    """The run-versus-thesis differences that are not scales, each with the scale factors whose
    projection it makes uncertain (unknown keys say so)."""
    out = []
    for key, a, b in config_differences(run_cfg, thesis_cfg):
        if any(key == s or key.startswith(s if s.endswith(".") else s + ".") for s in SCALE_KEYS):
            continue
        effect = next((e for p, e in PROTOCOL_EFFECTS.items() if key.startswith(p)),
                      "not classified: check which rates it changes")  # fmt: skip
        out.append({"key": key, "run": a, "thesis": b, "affects": effect})
    return out


def critical_path(stages: Sequence[Stage], edges: Sequence[tuple[str, str]]) -> tuple[float, list]:
    """Longest chain through the rule graph, each rule weighing its longest single job."""
    weight = {s.rule: s.longest_job for s in stages}
    preds: dict[str, list[str]] = defaultdict(list)
    for a, b in edges:
        preds[b].append(a)
    memo: dict[str, tuple[float, list[str]]] = {}

    def longest(rule: str) -> tuple[float, list[str]]:
        if rule not in memo:
            best = max((longest(p) for p in preds[rule]), default=(0.0, []), key=lambda t: t[0])
            memo[rule] = (best[0] + weight.get(rule, 0.0), [*best[1], rule])
        return memo[rule]

    return max((longest(r) for r in weight), key=lambda t: t[0])


# --- Output -------------------------------------------------------------------------------------


def hms(seconds: float) -> str:
    """Seconds as h:mm:ss (days spelled out beyond 24 h)."""
    s = round(seconds)
    days, s = divmod(s, 86_400)
    text = f"{s // 3600}:{s % 3600 // 60:02d}:{s % 60:02d}"
    return f"{days}d {text}" if days else text


def _short(value: Any) -> str:
    text = json.dumps(value)
    return text if len(text) <= 40 else text[:37] + "..."


def render(stages: Sequence[Stage], totals: Mapping[str, Any], warnings: Sequence[str],
           assumptions: Mapping[str, Any],
           differences: Sequence[Mapping[str, Any]] = ()) -> str:  # fmt: skip
    """Markdown: the per-rule table, unprojected rules, totals, differences, assumptions."""
    t = totals
    lines = [
        f"Thesis DAG ({t['thesis_config']}, target {t['target']}): {t['jobs']} jobs of "
        f"{len(stages)} rules; measured run: {t['run_dir']} ({t['run_config'] or 'default'}).",
        "",
        "| rule | jobs | unit | run units | run job-s | s/unit | thesis units | projected job-s "
        "| longest job | peak RSS run [MB] | RSS thesis est. [MB] | note |",
        "|---|---:|---|---:|---:|---:|---:|---:|---:|---:|---:|---|",
    ]
    for s in sorted(stages, key=lambda s: (s.projected, -s.job_seconds)):
        rate = f"{s.seconds_per_unit:.3g}" if s.seconds_per_unit is not None else "-"
        rss = f"{s.rss_thesis_mb:,.0f}" if s.rss_thesis_mb is not None else "-"
        name = s.rule if s.projected else f"**{s.rule}**"
        lines.append(
            f"| {name} | {s.thesis_jobs} | {s.unit} | {s.run_units:.4g} | {s.run_seconds:,.0f} | "
            f"{rate} | {s.thesis_units:.4g} | {s.job_seconds:,.0f} | {hms(s.longest_job)} | "
            f"{s.max_rss_mb:,.0f} | {rss} | {s.note} |"
        )
    lines.append(f"| **total** | {t['jobs']} | | | | | | **{t['job_seconds']:,.0f}** "
                 f"({t['job_seconds'] / 86_400:.1f} core-days) | | | | |")  # fmt: skip
    unprojected = [s for s in stages if not s.projected]
    lines.append("")
    if unprojected:
        lines += [
            f"**WARNING: {len(unprojected)} rule(s) UNPROJECTED** "
            f"({sum(s.thesis_jobs for s in unprojected)} jobs; their job-seconds are the run's "
            "per-job time or 0, not a projection):",
            *(f"- **{s.rule}** ({s.thesis_jobs} jobs): {s.note}" for s in unprojected),
        ]
    else:
        lines.append("Every rule of the thesis DAG is projected.")
    lines += [
        "",
        "**Totals**",
        "",
        f"- thesis DAG: {t['jobs']} jobs, {t['job_seconds']:,.0f} job-seconds "
        f"({hms(t['job_seconds'])}, {t['job_seconds'] / 86_400:.1f} core-days)",
        f"- critical path (longest job of each rule along the rule graph): "
        f"{hms(t['critical_path_s'])}: {' -> '.join(t['critical_path'])}",
        f"- wall on {t['cores']} cores: {hms(t['wall_local_s'])} "
        f"(job-seconds / {t['cores']}; the critical path is a lower bound)",
        f"- wall on a {t['cluster_cores']}-core cluster: {hms(t['wall_cluster_s'])} "
        f"(max of job-seconds / {t['cluster_cores']} and the critical path)",
        f"- training at every job's max_epochs instead: x{t['max_epochs_factor']:.2f} on training "
        "and tuning job-seconds",
        f"- training jobs stopping at the run's best epoch + the thesis patience instead: "
        f"{t['early_stop_job_seconds']:,.0f} job-seconds "
        f"({t['early_stop_job_seconds'] / 86_400:.1f} core-days), "
        f"{hms(t['early_stop_wall_local_s'])} on {t['cores']} cores",
    ]
    if t.get("bf16_job_seconds") is not None:
        lines.append(
            f"- without the fp32 correction (training as fast as the run's bfloat16): "
            f"{t['bf16_job_seconds']:,.0f} job-seconds ({t['bf16_job_seconds'] / 86_400:.1f} "
            "core-days)"
        )
    lines += ["", "**Where the run's options differ from the thesis profile's** (scale factors "
              "measured under the run's option; the thesis runs the other):", ""]  # fmt: skip
    if differences:
        lines += ["| option | run | thesis | scale factors carrying the difference |",
                  "|---|---|---|---|"]  # fmt: skip
        lines += [f"| `{d['key']}` | {_short(d['run'])} | {_short(d['thesis'])} | {d['affects']} |"
                  for d in differences]  # fmt: skip
    else:
        lines.append("none: the run used the thesis profile's protocol options.")
    lines += [
        "",
        "**Assumptions**",
        "",
        "- one core per job (every rule's threads: 1); per-unit rates are the run's; each job's "
        "non-compute time (start-up, I/O, test evaluation) is kept per job; a training epoch "
        "costs (train + val windows) x window steps; the thesis's sweep, tuning and input-audit "
        "datasets hold the main comparison's windows (4.1.1), split assignments the same total "
        "with the run's train+val share; epochs run = the run's mean fraction of max_epochs.",
        "- RSS thesis est.: the run's peak plus the data a thesis job holds beyond the run's "
        "(windows: all splits x steps x bytes per window-step, twice while labelling; the "
        "sensing rules' raw segments, with delay and hold context; replay: one shard's traces); "
        "other rules as measured.",
    ]
    lines += [f"- {k}: {v}" for k, v in assumptions.items()]
    if warnings:
        lines += ["", "**Warnings**", "", *(f"- {w}" for w in warnings)]
    return "\n".join(lines)


def main(argv: Sequence[str] | None = None) -> None:
    """Dry-run both DAGs, measure the run, project the thesis profile, print."""
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("workdir", type=Path, nargs="?", default=None,
                    help="the finished run's work directory (instead of --results)")  # fmt: skip
    ap.add_argument(
        "--results",
        type=Path,
        default=REPO / "results",
        help="the finished run's results/ folder (its parent is the work directory)",
    )
    ap.add_argument(
        "--run-config",
        nargs="*",
        default=[],
        metavar="KEY=VALUE",
        help="the --config entries the run used (decide which jobs it ran)",
    )
    ap.add_argument(
        "--thesis-config",
        nargs="*",
        default=["profile=thesis"],
        metavar="KEY=VALUE",
        help="the --config of the projected run (default: profile=thesis)",
    )
    ap.add_argument("--target", default=TARGET, help="the target of both runs")
    ap.add_argument(
        "--epoch-fraction",
        type=float,
        default=None,
        help="epochs run / max_epochs at thesis scale (default: the run's mean)",
    )
    ap.add_argument(
        "--fp32-factor", nargs="*", default=[], metavar="FAMILY=X",
        help="fp32 over bfloat16 training time for a family the run trained under autocast and "
             f"the thesis does not (default {FP32_FACTOR}; 1 leaves the run's rate)",
    )  # fmt: skip
    ap.add_argument(
        "--time-log",
        type=Path,
        help="the run's /usr/bin/time -v output: checks that its jobs had their cores",
    )
    ap.add_argument(
        "--cpu-scaled", action="store_true",
        help="with --time-log: scale every job's seconds by the run's CPU seconds per job wall "
             "second (when under 1: the run shared its cores with other work)",
    )  # fmt: skip
    ap.add_argument("--cores", type=int, default=2)
    ap.add_argument("--cluster-cores", type=int, default=100)
    ap.add_argument("--json", action="store_true", help="print JSON instead of Markdown")
    args = ap.parse_args(argv)  # fmt: skip

    workdir = args.workdir.resolve() if args.workdir else args.results.resolve().parent
    fp32 = {**FP32_FACTOR, **{k: float(v) for k, v in
                              (e.split("=", 1) for e in args.fp32_factor)}}  # fmt: skip
    run_jobs = dry_run_jobs(args.run_config, args.target)
    thesis_jobs = dry_run_jobs(args.thesis_config, args.target)
    thesis_cfg = resolve_config(args.thesis_config)
    run_cfg = resolve_config(args.run_config)
    share, scale = None, 1.0
    if args.time_log:
        share = cpu_share(args.time_log, measured_jobs(workdir, run_jobs)[0])
        ratio = share["cpu_per_job_s"]
        if args.cpu_scaled and ratio is not None and ratio < 1.0:
            scale = ratio
    elif args.cpu_scaled:
        ap.error("--cpu-scaled needs --time-log")
    stages, warnings, assumptions = project_stages(
        workdir, run_jobs, thesis_jobs, thesis_cfg, args.epoch_fraction, run_cfg, fp32, scale
    )
    if share is not None:
        assumptions["run_cpu_share"] = share
        if share["cpu_per_job_s"] is not None and share["cpu_per_job_s"] < 0.9:
            warnings.append(
                f"the run's processes used {share['cpu_per_job_s']:.2f} CPU seconds per second "
                "of its jobs' wall time: other work shared its cores, so its wall-second rates "
                + ("are scaled by that (--cpu-scaled)" if scale != 1.0 else
                   "are slow (--cpu-scaled scales them by it)")
            )  # fmt: skip
    # the same without the precision correction, for the sensitivity line
    bf16 = None
    if "fp32_over_bf16_factor" in assumptions:
        plain, _, _ = project_stages(workdir, run_jobs, thesis_jobs, thesis_cfg,
                                     args.epoch_fraction, run_cfg, {}, scale)  # fmt: skip
        bf16 = sum(s.job_seconds for s in plain)
    for rule, n in sorted(stale_benchmarks(workdir, run_jobs).items()):
        warnings.append(
            f"{rule}: {n} benchmark file(s) not in the run's DAG ignored "
            "(stale, or the run's --config differs from --run-config)"
        )
    unprojected = [s.rule for s in stages if not s.projected]
    if unprojected:
        print(f"WARNING: unprojected rules: {', '.join(unprojected)}", file=sys.stderr)
    cp_s, cp = critical_path(stages, rule_edges(args.thesis_config, args.target))
    job_seconds = sum(s.job_seconds for s in stages)
    learning = [s for s in stages if s.epoch_fraction]
    learn_s = sum(s.job_seconds for s in learning)
    full = sum(s.job_seconds / s.epoch_fraction for s in learning)
    factor = full / learn_s if learn_s else 1.0
    stopping = [s for s in stages if s.stop_fraction and s.epoch_fraction]
    stop_delta = sum(s.job_seconds * (s.stop_fraction / s.epoch_fraction - 1) for s in stopping)
    totals = {
        "run_dir": str(workdir),
        "run_config": " ".join(args.run_config),
        "thesis_config": " ".join(args.thesis_config),
        "target": args.target,
        "jobs": sum(s.thesis_jobs for s in stages),
        "job_seconds": job_seconds,
        "critical_path_s": cp_s,
        "critical_path": cp,
        "cores": args.cores,
        "wall_local_s": job_seconds / args.cores,
        "cluster_cores": args.cluster_cores,
        "wall_cluster_s": max(job_seconds / args.cluster_cores, cp_s),
        "max_epochs_factor": factor,
        "early_stop_job_seconds": job_seconds + stop_delta,
        "early_stop_wall_local_s": (job_seconds + stop_delta) / args.cores,
        "bf16_job_seconds": bf16,
        "unprojected": unprojected,
    }
    differences = protocol_differences(run_cfg, thesis_cfg)
    if args.json:
        print(json.dumps({"stages": [asdict(s) for s in stages], "totals": totals,
                          "assumptions": assumptions, "differences": differences,
                          "warnings": warnings}, indent=2, default=str))  # fmt: skip
    else:
        print(render(stages, totals, warnings, assumptions, differences))


if __name__ == "__main__":
    main()
