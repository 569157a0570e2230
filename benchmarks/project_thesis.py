"""Project the cost of the thesis profile from a finished run's per-job benchmarks.

Reads ``results/benchmarks/<rule>/*.tsv`` of a finished run (Snakemake's benchmark format: ``s``
wall seconds, ``max_rss`` MB) plus what its artefacts record (grasps per shard and their annealing
rate, simulated seconds per replay, epochs and window counts per training job, trials per study),
turns each stage into a per-unit throughput and multiplies it by the thesis DAG's units (job list
from a Snakemake dry run of ``--config profile=thesis``, scales from its resolved config and the
reference's window counts, 4.1.1). Only the jobs of the run's own DAG are measured, so stale
benchmark files of an earlier configuration in the same ``results/`` are ignored (and counted).

    python benchmarks/project_thesis.py --results results --run-config 'synthesis={shards: 3}'

``--run-config`` takes the ``--config`` entries the run used (they decide its DAG). Nothing is
written; the dry runs use a temporary work directory.
"""

from __future__ import annotations

import argparse
import json
import math
import re
import subprocess
import sys
import tempfile
from collections import defaultdict
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

import polars as pl
import pyarrow.parquet as pq
import yaml

from graspstab.report.dag import rule_graph
from graspstab.report.provenance import read_benchmark

REPO = Path(__file__).resolve().parents[1]

# The reference's main comparison: training / validation / test windows (4.1.1).
THESIS_WINDOWS = {"train": 43_978, "val": 12_052, "test": 14_587}
TRAIN_RULES = ("train_model", "train_sweep_model", "train_split_model")
LABEL_RULES = ("label_windows", "label_sweep_reference")
CACHE_MARK = "graspstab cache: restored"


@dataclass
class Job:
    """One job of a dry run: its rule, wildcards, outputs, log and benchmark paths."""

    rule: str
    wildcards: dict[str, str] = field(default_factory=dict)
    output: list[str] = field(default_factory=list)
    log: list[str] = field(default_factory=list)
    benchmark: str | None = None


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


def dry_run_jobs(entries: Sequence[str]) -> list[Job]:
    """Every job of the DAG for ``--config entries`` from scratch (an empty work directory)."""
    out = snakemake(["--dry-run", "--cores", "1", *config_args(entries)])
    return parse_dry_run(out)


def parse_dry_run(text: str) -> list[Job]:
    """The job blocks of Snakemake's dry-run listing (``rule NAME:`` then indented fields)."""
    jobs: list[Job] = []
    current: Job | None = None
    for line in text.splitlines():
        head = re.match(r"^(?:local)?rule (\w+):$", line)
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
        elif key in ("output", "log"):
            setattr(current, key, value.split(", "))
        elif key == "benchmark":
            current.benchmark = value
    return jobs


def rule_edges(entries: Sequence[str]) -> list[tuple[str, str]]:
    """(upstream, downstream) rule pairs of the rule graph (``--rulegraph`` DOT output)."""
    return list(rule_graph(snakemake(["--rulegraph", *config_args(entries)])).edges)


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


def split_sizes(counts: Mapping[str, Mapping[str, int]]) -> dict[str, int]:
    """Windows per split from a ``counts``/``splits`` record ({split: {stable, unstable, ...}})."""
    return {s: int(c.get("stable", 0)) + int(c.get("unstable", 0)) for s, c in counts.items()}


# --- Per-stage observations of the run ----------------------------------------------------------


def measured_jobs(
    workdir: Path, jobs: Iterable[Job]
) -> tuple[dict[str, list[tuple[Job, float, float]]], list[str]]:
    """(job, seconds, max RSS) per rule for the run's jobs with a benchmark; and warnings."""
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
        out[job.rule].append((job, bench["s"], 0.0 if rss is None or math.isnan(rss) else rss))
    return out, warnings


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


def anneal_obs(workdir: Path, measured, ref_iterations: int) -> list[Obs]:
    """Candidate grasps x (iterations / reference iterations); the annealing time is the grasps
    over the rate the shard table records, the rest of the job (loading, writing) is overhead."""
    out = []
    for job, s, rss in measured:
        meta = parquet_meta(workdir / job.output[0])
        iterations = meta["provenance"]["params"]["annealing"]["iterations"]
        grasps = float(meta["grasps"])
        compute = min(s, grasps / float(meta["grasps_per_s"]))
        units = grasps * iterations / ref_iterations
        out.append(Obs(job.wildcards["object"], units, compute, s - compute, rss))
    return out


def replay_obs(workdir: Path, measured) -> tuple[list[Obs], dict[str, float]]:
    """Simulated seconds per replay job (the summary's ``duration_s``; its ``wall_s`` is the
    simulation time, the rest overhead); and each object's mean simulated seconds per grasp."""
    out, sim, grasps = [], defaultdict(float), defaultdict(int)
    for job, s, rss in measured:
        table = pl.read_parquet(workdir / next(p for p in job.output if p.endswith(".parquet")))
        units = float(table["duration_s"].sum())
        compute = min(s, float(table["wall_s"].sum()))
        obj = job.wildcards["object"]
        sim[obj] += units
        grasps[obj] += table.height
        out.append(Obs(obj, units, compute, s - compute, rss))
    return out, {o: sim[o] / grasps[o] for o in sim if grasps[o]}


def training_obs(workdir: Path, measured) -> tuple[list[Obs], dict[str, list[float]]]:
    """Window-steps x epochs (training + validation windows each epoch) per training job, grouped
    by family; the metrics' training seconds are the work, the rest (start-up, test evaluation,
    threshold) overhead. Also per job: epochs-run fraction, best epoch, train+val share."""
    out: list[Obs] = []
    stats: dict[str, list[float]] = defaultdict(list)
    for job, s, rss in measured:
        metrics = json.loads((workdir / next(p for p in job.output if p.endswith(".json")))
                             .read_text())  # fmt: skip
        sizes = split_sizes(metrics["counts"])
        epochs = int(metrics["epochs_run"])
        units = epochs * (sizes["train"] + sizes["val"]) * int(metrics["window_steps"])
        compute = min(s, float(metrics["train_seconds"]))
        out.append(Obs(metrics["family"], units, compute, s - compute, rss))
        stats["fraction"].append(epochs / int(metrics["params"]["train"]["max_epochs"]))
        stats["best_epoch"].append(float(metrics["best_epoch"]))
        stats["share"].append((sizes["train"] + sizes["val"]) / sum(sizes.values()))
    return out, stats


def tune_obs(workdir: Path, measured, dt: float) -> tuple[list[Obs], list[float]]:
    """Window-steps x epochs summed over a study's trials, per family; and the epochs-run
    fraction of every study (epochs over trials x max_epochs)."""
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
        out.append(Obs(best["family"], units, s, 0.0, rss))
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


# --- Projection ---------------------------------------------------------------------------------


def project(rule: str, unit: str, obs: Sequence[Obs], thesis: Sequence[tuple[str, float]],
            note: str = "") -> Stage:  # fmt: skip
    """Thesis job time = the group's mean overhead + its seconds per unit x the job's units
    (the pooled rate where the thesis has a group the run lacks); longest = the slowest."""
    pooled_rate = sum(o.compute for o in obs) / max(sum(o.units for o in obs), 1e-12)
    pooled_over = sum(o.overhead for o in obs) / len(obs)
    by_group: dict[str, list[Obs]] = defaultdict(list)
    for o in obs:
        by_group[o.group].append(o)

    def job_time(group: str, units: float) -> float:
        g = by_group.get(group)
        if not g:
            return pooled_over + pooled_rate * units
        rate = sum(o.compute for o in g) / max(sum(o.units for o in g), 1e-12)
        return sum(o.overhead for o in g) / len(g) + rate * units

    times = [job_time(g, u) for g, u in thesis]
    return Stage(
        rule=rule, unit=unit, run_jobs=len(obs), run_units=sum(o.units for o in obs),
        run_seconds=sum(o.compute + o.overhead for o in obs), seconds_per_unit=pooled_rate,
        thesis_jobs=len(thesis), thesis_units=sum(u for _, u in thesis),
        job_seconds=sum(times), longest_job=max(times, default=0.0),
        max_rss_mb=max((o.max_rss for o in obs), default=0.0), note=note,
    )  # fmt: skip


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


def project_stages(
    workdir: Path, run_jobs: list[Job], thesis_jobs: list[Job], thesis_cfg: dict[str, Any],
    epoch_fraction: float | None,
) -> tuple[list[Stage], list[str], dict[str, Any]]:  # fmt: skip
    """Every rule of the thesis DAG projected; warnings; the assumptions used."""
    measured, warnings = measured_jobs(workdir, run_jobs)
    dt = float(thesis_cfg["replay"]["timestep"])
    syn = thesis_cfg["synthesis"]
    n_objects = len({j.wildcards["object"] for j in thesis_jobs if j.rule == "anneal_grasps"})
    thesis_grasps = n_objects * syn["shards"] * syn["grasps_per_shard"]
    total_windows = sum(THESIS_WINDOWS.values())
    train_val = THESIS_WINDOWS["train"] + THESIS_WINDOWS["val"]
    by_rule: dict[str, list[Job]] = defaultdict(list)
    for j in thesis_jobs:
        by_rule[j.rule].append(j)
    assumptions: dict[str, Any] = {
        "thesis_windows": THESIS_WINDOWS,
        "thesis_candidate_grasps": thesis_grasps,
    }
    stages = []
    for rule, jobs in by_rule.items():
        m = measured.get(rule, [])
        if not m:
            stages.append(Stage(rule, "job", 0, 0, 0, None, len(jobs), len(jobs), 0.0, 0.0, 0.0,
                                "not measured (no benchmark): counted as 0"))  # fmt: skip
            continue
        if rule == "preprocess_object":
            obs = per_job_obs(m, "object")
            stages.append(project(rule, "object", obs,
                                  [(j.wildcards["object"], 1.0) for j in jobs]))  # fmt: skip
        elif rule == "anneal_grasps":
            ref = int(syn["annealing"]["iterations"])
            obs = anneal_obs(workdir, m, ref)
            per_job = syn["grasps_per_shard"]
            stages.append(project(rule, f"grasp x {ref} it", obs,
                                  [(j.wildcards["object"], per_job) for j in jobs],
                                  "run used smaller annealing batches: conservative"))  # fmt: skip
        elif rule == "replay_grasps":
            obs, sim_per_grasp = replay_obs(workdir, m)
            fallback = mean(list(sim_per_grasp.values()))
            thesis = [(j.wildcards["object"],
                       syn["grasps_per_shard"] * sim_per_grasp.get(j.wildcards["object"], fallback))
                      for j in jobs]  # fmt: skip
            assumptions["replay_sim_s_per_grasp"] = {k: round(v, 2) for k, v in
                                                     sim_per_grasp.items()}  # fmt: skip
            stages.append(project(rule, "simulated s", obs, thesis,
                                  "each object keeps the run's simulated s per grasp"))  # fmt: skip
        elif rule in LABEL_RULES:
            run_grasps = sum(
                pl.scan_parquet(workdir / p).select(pl.len()).collect().item()
                for j in run_jobs if j.rule == "replay_grasps"
                for p in j.output if p.endswith(".parquet")
            )  # fmt: skip
            obs = [Obs("", run_grasps, s, 0.0, rss) for _, s, rss in m]
            stages.append(project(rule, "replayed grasp", obs,
                                  [("", thesis_grasps) for _ in jobs]))  # fmt: skip
        elif rule == "trim_sweep_window":
            obs = trim_obs(workdir, m, dt)
            thesis = [("", total_windows * round(int(j.wildcards["ms"]) / 1000 / dt)) for j in jobs]
            stages.append(project(rule, "window-step", obs, thesis))
        elif rule in TRAIN_RULES:
            obs, stats = training_obs(workdir, m)
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
            stages.append(project(rule, "window-step-epoch", obs, thesis,
                                  f"{frac:.0%} of max_epochs"))  # fmt: skip
            stages[-1].epoch_fraction = frac
            # sensitivity: stop at the run's best epoch + the thesis patience (3.5.2)
            patience = int(thesis_cfg["train"]["patience"])
            stages[-1].stop_fraction = mean(
                [min(max_epochs, b + patience) / max_epochs for b in stats["best_epoch"]]
            )
        elif rule == "tune_model":
            obs, fractions = tune_obs(workdir, m, dt)
            frac = epoch_fraction if epoch_fraction is not None else mean(fractions)
            tune = thesis_cfg["tune"]
            units = (int(tune["trials"]) * frac * int(thesis_cfg["train"]["max_epochs"])
                     * train_val * round(float(tune["window_s"]) / dt))  # fmt: skip
            assumptions["tune_model_epochs_per_trial"] = round(
                frac * int(thesis_cfg["train"]["max_epochs"]), 1
            )
            stages.append(
                project(
                    rule,
                    "window-step-epoch",
                    obs,
                    [(j.wildcards["model"], units) for j in jobs],
                    f"{tune['trials']} trials, {frac:.0%} of max_epochs",
                )
            )
            stages[-1].epoch_fraction = frac
        else:
            stages.append(project(rule, "job", per_job_obs(m, None), [("", 1.0) for _ in jobs]))
    return stages, warnings, assumptions


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


def render(stages: Sequence[Stage], totals: Mapping[str, Any], warnings: Sequence[str],
           assumptions: Mapping[str, Any]) -> str:  # fmt: skip
    """The text table, totals, assumptions and warnings."""
    lines = [
        f"{'rule':22s} {'jobs':>5s} {'unit':18s} {'run units':>11s} {'run s':>8s} "
        f"{'s/unit':>10s} {'thesis units':>13s} {'job-s':>10s} {'longest':>11s} {'RSS MB':>7s}"
    ]
    for s in sorted(stages, key=lambda s: -s.job_seconds):
        rate = f"{s.seconds_per_unit:10.3g}" if s.seconds_per_unit is not None else f"{'-':>10s}"
        lines.append(
            f"{s.rule:22s} {s.thesis_jobs:5d} {s.unit:18s} {s.run_units:11.4g} "
            f"{s.run_seconds:8.0f} {rate} {s.thesis_units:13.4g} {s.job_seconds:10.0f} "
            f"{hms(s.longest_job):>11s} {s.max_rss_mb:7.0f}" + (f"  ({s.note})" if s.note else "")
        )
    t = totals
    lines += [
        "",
        f"thesis DAG: {t['jobs']} jobs, {t['job_seconds']:.0f} job-seconds "
        f"({hms(t['job_seconds'])})",
        f"critical path (longest job of each rule along the rule graph): "
        f"{hms(t['critical_path_s'])}: {' -> '.join(t['critical_path'])}",
        f"wall on {t['cores']} cores: {hms(t['wall_local_s'])} "
        f"(job-seconds / {t['cores']}; the critical path is a lower bound)",
        f"wall on a {t['cluster_cores']}-core cluster: {hms(t['wall_cluster_s'])} "
        f"(max of job-seconds / {t['cluster_cores']} and the critical path)",
        f"training at every job's max_epochs instead: x{t['max_epochs_factor']:.2f} on training "
        "and tuning job-seconds",
        f"training jobs stopping at the run's best epoch + the thesis patience instead: "
        f"{hms(t['early_stop_job_seconds'])} job-seconds, {hms(t['early_stop_wall_local_s'])} "
        f"on {t['cores']} cores",
        "",
        "assumptions:",
        "  one core per job (every rule's threads: 1); per-unit rates are the run's; each job's",
        "  non-compute time (start-up, I/O, test evaluation) is kept per job; a training epoch",
        "  costs (train + val windows) x window steps; the thesis's sweep and tuning datasets",
        "  hold the main comparison's windows (4.1.1), split assignments the same total with the",
        "  run's train+val share; epochs run = the run's mean fraction of max_epochs.",
    ]
    lines += [f"  {k}: {v}" for k, v in assumptions.items()]
    if warnings:
        lines += ["", "warnings:", *(f"  {w}" for w in warnings)]
    return "\n".join(lines)


def main(argv: Sequence[str] | None = None) -> None:
    """Dry-run both DAGs, measure the run, project the thesis profile, print."""
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
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
    ap.add_argument(
        "--epoch-fraction",
        type=float,
        default=None,
        help="epochs run / max_epochs at thesis scale (default: the run's mean)",
    )
    ap.add_argument("--cores", type=int, default=2)
    ap.add_argument("--cluster-cores", type=int, default=100)
    ap.add_argument("--json", action="store_true", help="print JSON instead of the table")
    args = ap.parse_args(argv)  # fmt: skip

    workdir = args.results.resolve().parent
    run_jobs = dry_run_jobs(args.run_config)
    thesis_jobs = dry_run_jobs(args.thesis_config)
    thesis_cfg = resolve_config(args.thesis_config)
    stages, warnings, assumptions = project_stages(
        workdir, run_jobs, thesis_jobs, thesis_cfg, args.epoch_fraction
    )
    for rule, n in sorted(stale_benchmarks(workdir, run_jobs).items()):
        warnings.append(
            f"{rule}: {n} benchmark file(s) not in the run's DAG ignored "
            "(stale, or the run's --config differs from --run-config)"
        )
    cp_s, cp = critical_path(stages, rule_edges(args.thesis_config))
    job_seconds = sum(s.job_seconds for s in stages)
    learning = [s for s in stages if s.epoch_fraction]
    learn_s = sum(s.job_seconds for s in learning)
    full = sum(s.job_seconds / s.epoch_fraction for s in learning)
    factor = full / learn_s if learn_s else 1.0
    stopping = [s for s in stages if s.stop_fraction and s.epoch_fraction]
    stop_delta = sum(s.job_seconds * (s.stop_fraction / s.epoch_fraction - 1) for s in stopping)
    totals = {
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
    }
    if args.json:
        print(
            json.dumps(
                {
                    "stages": [asdict(s) for s in stages],
                    "totals": totals,
                    "assumptions": assumptions,
                    "warnings": warnings,
                },
                indent=2,
            )
        )
    else:
        print(render(stages, totals, warnings, assumptions))


if __name__ == "__main__":
    main()
