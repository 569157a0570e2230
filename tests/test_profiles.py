"""The SLURM profile: a dry run of the thesis profile through it (no SLURM binaries needed).

Checks that the executor plugin is installed and accepts the profile, that the thesis DAG has the
job counts its config implies, and that every per-rule request names a real rule and reaches the
jobs with the value the profile's expression gives.
"""

from __future__ import annotations

import re
import subprocess
import sys
from pathlib import Path
from types import SimpleNamespace

import pytest
import yaml

from tests.conftest import CONFIG_DIR, REPO, SCHEMA
from tests.toy_workflow import listed_jobs

PROFILE = REPO / "workflow" / "profiles" / "slurm"
MODELS = 3  # cnn, gru, lstm (workflow/rules/train.smk)
# Dry runs cap a job's threads at --cores (1 unless given); on the cluster nothing caps them.
DRY_CORES = 8


def _snakemake(workdir: Path, env: dict[str, str], *args: str) -> subprocess.CompletedProcess:
    cmd = [sys.executable, "-m", "snakemake", "-s", str(REPO / "Snakefile"), "-d", str(workdir)]
    return subprocess.run([*cmd, *args], capture_output=True, text=True, env=env, timeout=120)


def _job_counts(text: str) -> dict[str, int]:
    """The first "Job stats" table of a dry run: rule -> job count (and "total")."""
    table = text.split("Job stats:", 1)[1]
    counts = {}
    for line in table.splitlines()[3:]:
        m = re.match(r"^(\w+)\s+(\d+)$", line.strip())
        if not m:
            break
        counts[m.group(1)] = int(m.group(2))
    return counts


def _expected_counts() -> dict[str, int]:
    """Per-rule job counts of the thesis DAG, from its resolved config."""
    from graspstab.config import load_config, shards_of

    cfg = load_config(CONFIG_DIR, SCHEMA, {"profile": "thesis"}, check_files=False)
    ids = list(cfg["objects"]["items"]) if cfg["only_objects"] is None else cfg["only_objects"]
    objects = len(ids)
    shards = sum(shards_of(cfg, o) for o in ids)
    sweep, splits = cfg["sweep"], cfg["splits"]
    return {
        "preprocess_object": objects,
        "anneal_grasps": shards,
        "replay_grasps": shards,
        "trim_sweep_window": len(sweep["windows_s"]),
        "train_model": MODELS * len(cfg["train"]["seeds"]),
        "tune_model": MODELS,
        "train_sweep_model": MODELS * len(sweep["windows_s"]) * len(sweep["seeds"]),
        "train_split_model": splits["count"] * len(splits["seeds"]),  # one family (4.4)
    }


@pytest.fixture(scope="module")
def profile() -> dict:
    return yaml.safe_load((PROFILE / "config.yaml").read_text())


@pytest.fixture(scope="module")
def dry_run(tmp_path_factory, bare_env) -> str:
    """The thesis DAG through the SLURM profile (a dry run: nothing is submitted, and no assets
    are needed)."""
    workdir = tmp_path_factory.mktemp("slurm_dry_run")
    proc = _snakemake(
        workdir, bare_env, "--profile", str(PROFILE), "--dry-run", "--cores", str(DRY_CORES),
        "--config", "profile=thesis",
    )  # fmt: skip
    assert proc.returncode == 0, proc.stdout[-3000:] + proc.stderr[-3000:]
    return proc.stdout


@pytest.mark.workflow
def test_thesis_dry_run_job_counts(dry_run):
    counts = _job_counts(dry_run)
    for rule, n in _expected_counts().items():
        assert counts.get(rule) == n, (rule, counts.get(rule), n)
    assert counts["total"] == sum(v for k, v in counts.items() if k != "total")


@pytest.mark.workflow
def test_profile_rules_exist(profile, bare_env, tmp_path):
    proc = _snakemake(tmp_path, bare_env, "--list-rules")
    assert proc.returncode == 0, proc.stderr[-3000:]
    rules = set(proc.stdout.split())
    named = set(profile["set-resources"]) | set(profile["set-threads"])
    assert named <= rules, f"profile names unknown rules: {sorted(named - rules)}"
    assert profile["executor"] == "slurm"


@pytest.mark.workflow
def test_profile_requests_reach_jobs(profile, dry_run):
    """Each job gets the profile's threads and the value of each of its resource expressions
    (first attempt), and every threaded job asks SLURM for one CPU per thread."""
    jobs = listed_jobs(dry_run)
    for rule, requests in profile["set-resources"].items():
        rule_jobs = [j for j in jobs if j["rule"] == rule]
        assert rule_jobs, rule
        for job in rule_jobs:
            assert job["threads"] == min(profile["set-threads"].get(rule, 1), DRY_CORES), rule
            names = {
                "attempt": 1,
                "threads": job["threads"],
                "wildcards": SimpleNamespace(**job["wildcards"]),
            }
            for name, expr in requests.items():
                value = eval(str(expr), names)  # the profile's own expression, as Snakemake does
                assert job["resources"].get(name) == str(value), (rule, name, job)
    for rule, threads in profile["set-threads"].items():
        for job in (j for j in jobs if j["rule"] == rule):
            assert job["resources"].get("cpus_per_task") == str(threads), (rule, job)


@pytest.mark.workflow
def test_study_profile_trains_the_creep_free_benchmark_at_its_own_seeds(bare_env, tmp_path):
    """creep_free.seeds: the study profile trains the benchmark at seed 42 only, the main run at
    every seed; the report's benchmark list asks for no other creep-free run (no extra jobs)."""
    from graspstab.config import load_config

    cfg = load_config(CONFIG_DIR, SCHEMA, {"profile": "study"}, check_files=False)
    proc = _snakemake(tmp_path, bare_env, "--dry-run", "results/report.html", "--config",
                      "profile=study")  # fmt: skip
    assert proc.returncode == 0, proc.stdout[-3000:] + proc.stderr[-3000:]
    jobs = listed_jobs(proc.stdout)
    seeds = {}
    for j in jobs:
        if j["rule"] in ("train_model", "train_model_creep_free", "train_sweep_model_creep_free"):
            seeds.setdefault(j["rule"], set()).add(int(j["wildcards"]["seed"]))
    assert cfg["creep_free"]["seeds"] == [42]
    assert seeds["train_model_creep_free"] == seeds["train_sweep_model_creep_free"] == {42}
    assert seeds["train_model"] == set(cfg["train"]["seeds"]) == {42, 43, 44}
    counts = _job_counts(proc.stdout)
    assert counts["train_model_creep_free"] == MODELS
    windows = len(cfg["creep_free"]["sweep_windows_s"])
    assert counts["train_sweep_model_creep_free"] == MODELS * windows
    # the benchmark's monitor runs the creep-free sweep's first seed
    monitor = next(j for j in jobs if j["rule"] == "evaluate_monitor_creep_free")
    assert all("/seed42/" in p for p in monitor["input"] if "/train/sweep/" in p)


@pytest.mark.workflow
def test_wide_profile_tests_every_object_once_per_family_and_protocol(bare_env, tmp_path):
    """The wide profile's k-fold study: one training job per protocol x (family, variant) x fold
    x seed, each fold job's assignment testing its own fold's objects only, and the report asks
    for both protocols' study artefacts."""
    from graspstab.config import load_config
    from graspstab.evaluation.folds import kfold_assignments

    cfg = load_config(CONFIG_DIR, SCHEMA, {"profile": "wide"}, check_files=False)
    cv = cfg["crossval"]
    proc = _snakemake(tmp_path, bare_env, "--dry-run", "results/report.html", "--config",
                      "profile=wide")  # fmt: skip
    assert proc.returncode == 0, proc.stdout[-3000:] + proc.stderr[-3000:]
    counts = _job_counts(proc.stdout)
    pairs = len(cv["families"]) + len(cv["variants"]) * len(cv["variant_families"])
    expected = cv["k"] * pairs * len(cv["seeds"])
    assert counts["train_fold_model"] == counts["train_fold_model_creep_free"] == expected
    assert counts["aggregate_crossval"] == counts["aggregate_crossval_creep_free"] == 1
    folds = kfold_assignments(list(cfg["objects"]["items"]), cv["k"], cv["fold_seed"])
    tested = sorted(o for a in folds for o, s in a.items() if s == "test")
    assert tested == sorted(cfg["objects"]["items"])
    jobs = [j for j in listed_jobs(proc.stdout) if j["rule"] == "train_fold_model"]
    assert {int(j["wildcards"]["fold"]) for j in jobs} == set(range(cv["k"]))
    # early warning over the folds: the hidden-onset protocol only, one job per fold reading
    # that fold's own models and its validation and test objects' replays, nothing else
    assert cv["early_warning"] == ["creep_free"] and "evaluate_fold_monitor" not in counts
    assert counts["evaluate_fold_monitor_creep_free"] == cv["k"]
    assert counts["aggregate_fold_warning_creep_free"] == 1
    for j in listed_jobs(proc.stdout):
        if j["rule"] != "evaluate_fold_monitor_creep_free":
            continue
        k = int(j["wildcards"]["fold"])
        held = {o for o, s in folds[k].items() if s in ("val", "test")}
        replays = {Path(p).parent.name for p in j["input"] if "/replay/" in p}
        assert replays == held
        models = [p for p in j["input"] if "/train/crossval/" in p]
        assert len(models) == 2 * len(cv["families"])
        assert all("/forces/" in p and f"/f{k}/" in p for p in models)


@pytest.mark.workflow
def test_the_closed_loop_over_the_folds_runs_every_object_on_its_own_folds_files(
    bare_env, tmp_path
):
    """closed_loop_folds: one job per object under the hidden-onset protocol, each reading its
    own test fold's models and budget thresholds; one summary; no fixed-split closed loop; the
    folds without cross-validation, or with the pick, are refused with the fix."""
    from graspstab.config import load_config
    from graspstab.evaluation.folds import kfold_assignments

    cfg = load_config(CONFIG_DIR, SCHEMA, {"profile": "closed_loop_folds"}, check_files=False)
    cv = cfg["crossval"]
    proc = _snakemake(tmp_path, bare_env, "--dry-run", "results/report.html", "--config",
                      "profile=closed_loop_folds")  # fmt: skip
    assert proc.returncode == 0, proc.stdout[-3000:] + proc.stderr[-3000:]
    counts = _job_counts(proc.stdout)
    assert counts["closed_loop_fold_object"] == len(cfg["objects"]["items"]) == 44
    assert counts["aggregate_closed_loop_folds"] == 1 and "closed_loop_object" not in counts
    # the shuffled controls deal from every object's tightening times: a second job per object
    assert counts["closed_loop_fold_shuffled"] == 44 and counts["closed_loop_fold_offsets"] == 1
    shuffled = next(j for j in listed_jobs(proc.stdout) if j["rule"] == "closed_loop_fold_shuffled")
    assert "results/closed_loop/folds/creep_free/offsets.json" in shuffled["input"]
    folds = kfold_assignments(list(cfg["objects"]["items"]), cv["k"], cv["fold_seed"])
    for j in listed_jobs(proc.stdout):
        if j["rule"] != "closed_loop_fold_object":
            continue
        obj = j["wildcards"]["object"]
        k = next(i for i, a in enumerate(folds) if a[obj] == "test")
        assert f"results/creep_free/monitor/crossval/f{k}/thresholds.json" in j["input"]
        models = [p for p in j["input"] if "/train/crossval/" in p]
        assert models and all("/forces/" in p and f"/f{k}/" in p for p in models)
    for override, message in (
        (["closed_loop={folds: {enabled: true, grasps: 2}}"], "needs the cross-validation"),
        (["profile=closed_loop_folds", "overrides=[\"closed_loop.policies=[none,pick]\"]"],
         "the pick is an export"),
    ):  # fmt: skip
        proc = _snakemake(tmp_path, bare_env, "--dry-run", "results/report.html", "--config",
                          *override)  # fmt: skip
        assert proc.returncode != 0 and message in proc.stdout + proc.stderr, override


@pytest.mark.workflow
def test_closed_loop_runs_every_test_object_per_protocol_on_that_protocols_monitors(
    bare_env, tmp_path
):
    """closed_loop.enabled: one job per protocol x test object, whose monitors are that
    protocol's first-seed sweep models at closed_loop.window_s (the pick: the reference's only);
    naming creep_free without the benchmark is an error that says how to fix it."""
    from graspstab.config import load_config

    on = ["closed_loop={enabled: true}", "creep_free={enabled: true}"]
    cfg = load_config(CONFIG_DIR, SCHEMA, {}, check_files=False)
    proc = _snakemake(tmp_path, bare_env, "--dry-run", "closed_loop", "--config", *on)
    assert proc.returncode == 0, proc.stdout[-3000:] + proc.stderr[-3000:]
    jobs = [j for j in listed_jobs(proc.stdout) if j["rule"] == "closed_loop_object"]
    tests = sorted(o for o, v in cfg["objects"]["items"].items() if v["split"] == "test")
    assert sorted((j["wildcards"]["protocol"], j["wildcards"]["object"]) for j in jobs) == sorted(
        (p, o) for p in ("creep_free", "reference") for o in tests
    )
    for j in jobs:
        sweep = [p for p in j["input"] if "/train/sweep/" in p]
        root = "results/creep_free/" if j["wildcards"]["protocol"] == "creep_free" else "results/"
        assert len(sweep) == 6 and all(p.startswith(root) and "/w10ms/seed42/" in p for p in sweep)
        pick = any("monitor/export/pick" in p for p in j["input"])
        assert pick == (j["wildcards"]["protocol"] == "reference")
    summaries = [j for j in listed_jobs(proc.stdout) if j["rule"] == "aggregate_closed_loop"]
    assert sorted(j["wildcards"]["protocol"] for j in summaries) == ["creep_free", "reference"]
    # the report reads each protocol's summary and every closed-loop job's benchmark
    proc = _snakemake(tmp_path, bare_env, "--dry-run", "results/report.html", "--config", *on)
    assert proc.returncode == 0, proc.stdout[-3000:] + proc.stderr[-3000:]
    (report,) = [j for j in listed_jobs(proc.stdout) if j["rule"] == "report"]
    for p in ("creep_free", "reference"):
        assert f"results/closed_loop/summary/{p}/summary.json" in report["input"]
        assert f"results/figures/closed_loop/{p}_timeline.png" in report["input"]
        for o in tests:
            assert f"results/benchmarks/closed_loop_object/{p}_{o}.tsv" in report["input"]
    proc = _snakemake(tmp_path, bare_env, "--dry-run", "closed_loop", "--config", on[0])
    assert proc.returncode != 0
    assert "set creep_free.enabled=true, or closed_loop.protocols=[reference]" in proc.stdout
