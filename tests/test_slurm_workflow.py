"""The toy workflow through ``snakemake --profile workflow/profiles/slurm`` on a real SLURM
cluster: one node with 2 CPUs, started from Debian's packages (tests/servers/slurm.py) and
stopped once the run is over.

One build, shared by the tests below (the fixture ``slurm_run``, once per session however many
xdist workers ask): a local run of the target (``--cores 2``, no profile), then the SLURM run of
the same target and config, during which the GRU's training job is cancelled with ``scancel``
after its first epoch; then the cluster is stopped. The target is the baseline study's tables,
which takes every stage up to learning for the toy run's three objects (assets, hand,
preprocessing, annealing, replay), the baseline dataset, one training job per model family and
the study's report tables: 29 jobs. The learning studies beyond the baseline are left out for
time (the toy run's report needs 101 jobs).

Command-line settings the SLURM run adds to the profile, each because this node is not the
cluster the profile is sized for (the profile itself is left as a real cluster needs it):

* ``--set-threads train_model=2``: the profile's 4 threads (``--cpus-per-task=4``) cannot be
  scheduled on a 2-CPU node (SLURM 22.05 accepts the job and leaves it pending, reason
  PartitionConfig, for ever). The local run gets the same 2 threads, so the two runs
  differ in the executor only: more threads change torch's float summation order
  and the BLAS/torch thread counts recorded in each metrics file. (The whole toy DAG would need
  ``train_sweep_model=2 tune_model=2`` as well.)
* ``--slurm-init-seconds-before-status-checks 2``: the plugin's 40 s before the first status
  check (and after each finished job), sized for jobs of hours, would be most of a toy run.

Memory and time requests are the profile's: the node declares ``RealMemory`` a little under this
machine's memory, so every request fits (memory is not enforced: no cgroups).
"""

from __future__ import annotations

import csv
import fcntl
import hashlib
import io
import json
import os
import re
import subprocess
import time
from pathlib import Path
from types import SimpleNamespace

import pytest
import yaml

from tests.conftest import REPO
from tests.servers.slurm import MARKER, MissingBinaries, SlurmCluster, find_binaries
from tests.toy_workflow import CONFIG, listed_jobs, snakemake_command, snakemake_run

pytestmark = [pytest.mark.servers, pytest.mark.workflow]

PROFILE = REPO / "workflow" / "profiles" / "slurm"
TARGET = "results/studies/baseline/summary.parquet"
THREADS = ["--set-threads", "train_model=2"]
PACING = ["--slurm-init-seconds-before-status-checks", "2"]
# The job cancelled mid-run, and the line of its log that says it is mid-run (the first epoch
# done, the second under way).
KILLED = ("train_model", {"model": "gru", "seed": "42"})
KILLED_LOG = "results/logs/train_model/gru_seed42.log"
MID_RUN = re.compile(r"epoch 1/\d+ ")
# What must be identical between the two runs (paths relative to the workdir).
DATASET = "results/datasets/baseline"
METRICS = "results/train/baseline/{model}/seed42/metrics.json"
STUDY = "results/studies/baseline"
SACCT_FIELDS = (
    "JobIDRaw,JobName%60,Comment%300,State,ReqCPUS,ReqMem,Timelimit,Submit,Start,End,ElapsedRaw"
)


def _canonical(value, key: str = ""):
    """A JSON value less what legitimately differs between two processes: every key that holds
    a wall-clock duration ("seconds" in its name: the training history's per-epoch times,
    seconds_per_epoch, train_seconds), and the order of the provenance's list of loaded BLAS
    and OpenMP libraries (``platform.blas``: threadpoolctl lists them in the order the process
    happened to load them), which is sorted."""
    if isinstance(value, dict):
        return {k: _canonical(v, k) for k, v in value.items() if "seconds" not in k}
    if isinstance(value, list):
        items = [_canonical(v) for v in value]
        return (
            sorted(items, key=lambda v: json.dumps(v, sort_keys=True)) if key == "blas" else items
        )
    return value


def output_hashes(workdir: Path) -> dict[str, str]:
    """sha256 of what the two runs must share: every file of the baseline dataset and every
    report table of the baseline study byte for byte; each model's metrics.json and the study's
    summary.json as their content less wall-clock durations and library load order
    (``_canonical``, as sorted-key JSON)."""
    hashes = {}
    for path in sorted((workdir / DATASET).rglob("*")) + sorted(
        (workdir / STUDY).glob("*.parquet")
    ):
        if path.is_file():
            hashes[str(path.relative_to(workdir))] = hashlib.sha256(path.read_bytes()).hexdigest()
    jsons = [METRICS.format(model=m) for m in ("cnn", "gru", "lstm")] + [f"{STUDY}/summary.json"]
    for rel in jsons:
        path = workdir / rel
        if path.is_file():
            content = json.dumps(_canonical(json.loads(path.read_text())), sort_keys=True)
            hashes[rel] = hashlib.sha256(content.encode()).hexdigest()
    return hashes


def _sacct(cluster: SlurmCluster, run_id: str) -> list[dict[str, str]]:
    out = cluster.client(
        "sacct",
        "-X",
        "--parsable2",
        "--noheader",
        "--starttime",
        "2000-01-01T00:00",
        "--name",
        run_id,
        "--format",
        SACCT_FIELDS,
    )
    names = [f.split("%")[0] for f in SACCT_FIELDS.split(",")]
    return [
        dict(zip(names, row, strict=True))
        for row in csv.reader(io.StringIO(out), delimiter="|")
        if row
    ]


def _kill_mid_run(cluster: SlurmCluster, proc: subprocess.Popen, workdir: Path) -> dict:
    """Wait for the GRU training job's first epoch in its log, then scancel its SLURM job."""
    rule, wildcards = KILLED
    comment = f"rule_{rule}_wildcards_{'_'.join(wildcards.values())}"
    log = workdir / KILLED_LOG
    deadline = time.monotonic() + 1500
    while time.monotonic() < deadline:
        assert proc.poll() is None, (
            "the SLURM run ended before the GRU's training job was cancelled"
        )
        if log.is_file() and MID_RUN.search(log.read_text(errors="replace")):
            queue = cluster.client("squeue", "-h", "-o", "%i|%k|%T")
            running = [
                r.split("|")[0]
                for r in queue.splitlines()
                if r.split("|")[1:] == [comment, "RUNNING"]
            ]
            assert running, (
                f"{KILLED_LOG} says epoch 1 is done but no running job {comment}: {queue}"
            )
            cluster.client("scancel", running[0])
            return {"jobid": running[0], "comment": comment, "log": log.read_text()[-2000:]}
        time.sleep(0.2)
    raise AssertionError(f"no first epoch in {KILLED_LOG} within 1500 s")


def _build(root: Path, env: dict[str, str]) -> dict:
    """Local run, SLURM run with the cancellation, the scheduler's records, the cluster
    stopped; everything the tests check, as JSON."""
    record: dict = {}
    local = root / "local"
    local.mkdir()
    t0 = time.monotonic()
    proc = snakemake_run(local, TARGET, *THREADS, *CONFIG, env=env)
    record["local"] = {
        "returncode": proc.returncode,
        "seconds": time.monotonic() - t0,
        "tail": proc.stdout[-3000:] + proc.stderr[-3000:],
        "hashes": output_hashes(local),
    }
    if proc.returncode != 0:
        return record
    dry = snakemake_run(local, TARGET, *THREADS, *CONFIG, "--dry-run", "--forceall", env=env)
    record["planned"] = listed_jobs(dry.stdout)

    cluster = SlurmCluster(root / "cluster")
    t0 = time.monotonic()
    cluster.start()
    record["cluster_start_seconds"] = time.monotonic() - t0
    slurm = root / "slurm"
    slurm.mkdir()
    try:
        cmd = snakemake_command(slurm, "--profile", str(PROFILE), TARGET, *THREADS, *PACING,
                                *CONFIG)  # fmt: skip
        log_path = root / "slurm_run.log"
        t0 = time.monotonic()
        with log_path.open("w") as out:
            proc = subprocess.Popen(
                cmd, env=dict(env, **cluster.env), stdout=out, stderr=subprocess.STDOUT
            )
            try:
                record["killed"] = _kill_mid_run(cluster, proc, slurm)
                proc.wait(timeout=1800)
            finally:
                if proc.poll() is None:
                    proc.kill()
                    proc.wait()
        text = log_path.read_text(errors="replace")
        record["slurm"] = {
            "returncode": proc.returncode,
            "seconds": time.monotonic() - t0,
            "tail": text[-6000:],
            "hashes": output_hashes(slurm),
            "jobs": listed_jobs(text),
            "failure_seen": f"SLURM-job '{record['killed']['jobid']}' failed" in text,
            "restarted": "Trying to restart job" in text,
        }
        run_id = re.search(r"SLURM run ID: (\S+)", text)
        assert run_id, text[-3000:]
        record["sacct"] = _sacct(cluster, run_id.group(1))
        record["tmp_files"] = [
            str(p.relative_to(slurm)) for p in (slurm / "results").rglob("*.tmp")
        ]
        incomplete = slurm / ".snakemake" / "incomplete"
        record["incomplete"] = [p.name for p in incomplete.iterdir()] if incomplete.is_dir() else []
        record["benchmarks"] = {
            str(p.relative_to(slurm / "results" / "benchmarks")): float(
                p.read_text().split("\n")[1].split("\t")[0]
            )
            for p in (slurm / "results" / "benchmarks").rglob("*.tsv")
        }
    finally:
        pids = {name: p.pid for name, p in cluster.procs.items()}
        cluster.stop(check=False)
        record["daemons"] = pids
        record["leftovers"] = cluster.leftovers()
        record["marker"] = str(cluster.root)
    return record


@pytest.fixture(scope="session")
def slurm_binaries() -> dict[str, str]:
    """Every SLURM, munge and MariaDB program the cluster needs. A missing one fails every test
    here with the apt-get line that installs it (before the assets are looked for); it never
    skips."""
    try:
        return find_binaries()
    except MissingBinaries as exc:
        pytest.fail(str(exc), pytrace=False)


@pytest.fixture(scope="session")
def slurm_run(slurm_binaries, tmp_path_factory, asset_env) -> dict:
    """The build's record, once per session (the first xdist worker to ask builds it under a file
    lock, the others read its record)."""
    root = tmp_path_factory.getbasetemp()
    if os.environ.get("PYTEST_XDIST_WORKER"):
        root = root.parent
    root = root / "slurm_run"
    record_path = root.with_suffix(".json")
    root.mkdir(exist_ok=True)
    with open(root.with_suffix(".lock"), "w") as lock:
        fcntl.flock(lock, fcntl.LOCK_EX)
        try:
            if not record_path.is_file():
                try:
                    record = _build(root, asset_env)
                except Exception as exc:  # reported to every test, not retried
                    record = {"error": f"{type(exc).__name__}: {exc}"}
                record_path.write_text(json.dumps(record, indent=1))
        finally:
            fcntl.flock(lock, fcntl.LOCK_UN)
    record = json.loads(record_path.read_text())
    assert "error" not in record, record["error"]
    assert record["local"]["returncode"] == 0, record["local"]["tail"]
    assert record["slurm"]["returncode"] == 0, record["slurm"]["tail"]
    return record


def _comment(job: dict) -> str:
    values = "_".join(job["wildcards"].values())
    return f"rule_{job['rule']}_wildcards_{values}" if values else f"rule_{job['rule']}"


def _minutes(limit: str) -> int:
    """sacct's Timelimit ([D-]HH:MM:SS) in minutes."""
    days, _, clock = limit.rpartition("-")
    h, m, s = (int(x) for x in clock.split(":"))
    return (int(days or 0) * 24 + h) * 60 + m + s // 60


def test_every_job_went_through_the_scheduler_once(slurm_run):
    """sacct lists one completed SLURM job per rule instance the local dry run plans, no other
    job, and the cancelled one: the whole DAG went through sbatch."""
    planned = sorted(_comment(j) for j in slurm_run["planned"])
    assert len(planned) == 29, planned
    rows = slurm_run["sacct"]
    completed = sorted(r["Comment"] for r in rows if r["State"] == "COMPLETED")
    assert completed == planned
    others = [(r["Comment"], r["State"].split()[0]) for r in rows if r["State"] != "COMPLETED"]
    assert others == [(slurm_run["killed"]["comment"], "CANCELLED")]  # "CANCELLED by <uid>"


def test_sacct_shows_the_requests_of_the_profile(slurm_run):
    """Every SLURM job asked for what Snakemake planned (CPUs = threads, --mem = mem_mb,
    -t = runtime); for the rules the profile sizes, that is the profile's own expression at the
    job's attempt: the retry of the cancelled job asks for twice the memory and time."""
    profile = yaml.safe_load((PROFILE / "config.yaml").read_text())
    threads = dict(t.split("=") for t in THREADS[1:])
    by_comment: dict[str, list[dict]] = {}
    for row in sorted(slurm_run["sacct"], key=lambda r: int(r["JobIDRaw"])):
        by_comment.setdefault(row["Comment"], []).append(row)
    checked = set()
    for comment, rows in by_comment.items():
        job = next(j for j in slurm_run["planned"] if _comment(j) == comment)
        for attempt, row in enumerate(rows, start=1):
            expected_threads = int(threads.get(job["rule"], job["threads"]))
            requests = profile["set-resources"].get(job["rule"])
            if requests is not None:
                names = {
                    "attempt": attempt,
                    "threads": expected_threads,
                    "wildcards": SimpleNamespace(**job["wildcards"]),
                }
                mem = eval(str(requests["mem_mb"]), names)  # the profile's expression
                runtime = eval(str(requests["runtime"]), names)
                checked.add(job["rule"])
            else:  # the rule's own request (every rule sets mem_mb and runtime)
                assert attempt == 1, comment
                mem, runtime = int(job["resources"]["mem_mb"]), int(job["resources"]["runtime"])
            got = (int(row["ReqCPUS"]), int(row["ReqMem"].rstrip("Mn")), _minutes(row["Timelimit"]))
            assert got == (expected_threads, mem, runtime), (comment, attempt, row)
    assert {
        "preprocess_object",
        "anneal_grasps",
        "replay_grasps",
        "label_windows",
        "train_model",
    } <= checked
    train = [r for c, rs in by_comment.items() if c.startswith("rule_train_model_") for r in rs]
    assert {int(r["ReqCPUS"]) for r in train} == {2}  # the set-threads override reached sbatch
    retried = by_comment[slurm_run["killed"]["comment"]]
    assert [r["State"].split()[0] for r in retried] == ["CANCELLED", "COMPLETED"]
    assert int(retried[1]["ReqMem"].rstrip("Mn")) == 2 * int(retried[0]["ReqMem"].rstrip("Mn"))


def test_outputs_identical_to_the_local_run(slurm_run):
    """The dataset files and report tables byte for byte, the metrics less their wall-clock
    durations: SLURM changes where the jobs run, not what they compute."""
    local, slurm = slurm_run["local"]["hashes"], slurm_run["slurm"]["hashes"]
    assert any(k.startswith(DATASET + "/") for k in local)
    assert sum(k.startswith(STUDY + "/") and k.endswith(".parquet") for k in local) >= 4
    assert sum(k.endswith("/metrics.json") for k in local) == 3
    assert slurm == local


def test_cancelled_job_was_resubmitted_with_nothing_half_written(slurm_run):
    """scancel of the GRU's training job after its first epoch: Snakemake saw the job fail,
    resubmitted it (the profile's retries: 1), and the run finished with no partial file, no
    incomplete marker, and the GRU's metrics identical to the local run's."""
    killed = slurm_run["killed"]
    assert MID_RUN.search(killed["log"]), killed["log"]
    assert slurm_run["slurm"]["failure_seen"], slurm_run["slurm"]["tail"]
    assert slurm_run["slurm"]["restarted"], slurm_run["slurm"]["tail"]
    assert slurm_run["tmp_files"] == []
    assert slurm_run["incomplete"] == []
    gru = METRICS.format(model="gru")
    assert slurm_run["slurm"]["hashes"][gru] == slurm_run["local"]["hashes"][gru]


def test_cluster_stopped_with_nothing_left(slurm_run):
    """After the build stopped the cluster, none of its daemons (munged, mariadbd, slurmdbd,
    slurmctld, slurmd) nor any job step or process started from its environment is running."""
    assert set(slurm_run["daemons"]) == {"munged", "mariadbd", "slurmdbd", "slurmctld", "slurmd"}
    assert slurm_run["leftovers"] == []
    marker = slurm_run["marker"]
    for entry in Path("/proc").iterdir():
        if entry.name.isdigit():
            try:
                environ = (entry / "environ").read_bytes()
            except OSError:
                continue
            assert f"{MARKER}={marker}".encode() not in environ.split(b"\0"), entry.name
    for name, pid in slurm_run["daemons"].items():  # gone, or the pid reused by another program
        try:
            assert Path(f"/proc/{pid}/comm").read_text().strip() != name, (name, pid)
        except FileNotFoundError:
            pass
