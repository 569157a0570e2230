"""The toy-scale workflow configuration the end-to-end tests share, and how they call Snakemake."""

from __future__ import annotations

import fcntl
import json
import os
import re
import shutil
import subprocess
import sys
from pathlib import Path
from typing import Any

REPO = Path(__file__).resolve().parents[1]

OBJECT = "061_foam_brick"
# One object per split (lemon moved to validation): the learning studies need all three. These
# three yield held grasps at the toy settings below, so every split has windows.
OBJECTS = "only_objects=[061_foam_brick,014_lemon,077_rubiks_cube]"
SPLITS = "objects={items: {014_lemon: {split: val}}}"
# Coarse CoACD settings keep the toy run fast; the defaults are exercised in the 12-object run.
FAST = "preprocess={coacd: {resolution: 500, mcts_iterations: 20, preprocess_resolution: 30}}"
# Two shards of four grasps (four for the validation object), each one seed block, a short
# schedule, batches of four (so batching is exercised).
TOY_SYNTHESIS = (
    "synthesis={shards: 2, grasps_per_shard: 4, seed_block: null, split_shards: {val: 4}, "
    "annealing: {iterations: 1500, batch_size: 4}}"
)
# Replays of 1 s in chunks of 0.25 s; the load ramp (creep-free benchmark) on the linear path from
# 0.3 s, reaching a ceiling of 5 m g at 0.8 s (so its recorded load is F(t) to the letter).
TOY_REPLAY = (
    "replay={steps: 2000, chunk_steps: 500, ramp: {start_s: 0.3, rate: 10.0, ceiling: 5.0, "
    "path: linear}}"
)
# The creep-free benchmark beside the main run: 1 s ramp replays, a one-window sweep.
TOY_CREEP_FREE = "creep_free={enabled: true, seconds: 1.0, sweep_windows_s: [0.01]}"
# Every learning study at toy size: one seed, two epochs, one tuning trial, two sweep windows.
TOY_LEARNING = [
    "train={seeds: [42], max_epochs: 2, patience: 1}",
    "tune={trials: 1}",
    "sweep={windows_s: [0.01, 0.02], seeds: [42]}",
    "splits={count: 2, seeds: [42]}",
    "latency={repeats: 5, warmup: 1}",
]
CONFIG = [
    "--config",
    OBJECTS,
    SPLITS,
    FAST,
    TOY_SYNTHESIS,
    TOY_REPLAY,
    TOY_CREEP_FREE,
    *TOY_LEARNING,
]


def snakemake_command(workdir: Path, *args: str) -> list[str]:
    """The command line of Snakemake on this repository's workflow in ``workdir``."""
    return [sys.executable, "-m", "snakemake", "-s", str(REPO / "Snakefile"), "-d", str(workdir),
            *args]  # fmt: skip


def snakemake_run(workdir: Path, *args: str, env: dict[str, str]) -> subprocess.CompletedProcess:
    cmd = snakemake_command(workdir, "--cores", "2", *args)
    return subprocess.run(cmd, capture_output=True, text=True, env=env, timeout=1200)


def shared_toy_run(tmp_path_factory: Any, env: dict[str, str]) -> tuple[Path, dict, list]:
    """The toy run (``results/report.html`` at CONFIG), built once per pytest session however many
    xdist workers ask for it: the first to ask builds it under a file lock in the session's
    shared temporary folder, the others wait for the lock and reuse it (a failed build is
    reported to each, not retried). Serially the folder is the session's own.
    (workdir, env, config), as tests/conftest.py's ``run`` returns it."""
    root = tmp_path_factory.getbasetemp()
    if os.environ.get("PYTEST_XDIST_WORKER"):  # the workers' folders sit in the session's
        root = root.parent
    workdir, record = root / "toy_run", root / "toy_run.json"
    with open(root / "toy_run.lock", "w") as lock:
        fcntl.flock(lock, fcntl.LOCK_EX)
        try:
            if not record.is_file():
                workdir.mkdir(exist_ok=True)
                proc = snakemake_run(workdir, "results/report.html", *CONFIG, env=env)
                tail = proc.stdout[-4000:] + proc.stderr[-4000:]
                record.write_text(json.dumps({"returncode": proc.returncode, "tail": tail}))
        finally:
            fcntl.flock(lock, fcntl.LOCK_UN)
    built = json.loads(record.read_text())
    assert built["returncode"] == 0, built["tail"]
    return workdir, env, CONFIG


def listed_jobs(text: str) -> list[dict]:
    """The jobs Snakemake printed (dry or real run): rule; inputs, outputs, log and benchmark as
    lists; wildcards and resources as dicts; threads (1 when not printed)."""
    jobs = []
    for block in re.split(r"^(?=(?:local)?rule \w+:$)", text, flags=re.M)[1:]:
        fields = dict(re.findall(r"^    (\w+): (.*)$", block, flags=re.M))

        def items(name: str, fields: dict = fields) -> list[str]:
            return [v.strip() for v in fields[name].split(",")] if name in fields else []

        jobs.append({
            "rule": re.match(r"(?:local)?rule (\w+):", block).group(1),
            **{name: items(name) for name in ("input", "output", "log", "benchmark")},
            "wildcards": dict(w.split("=", 1) for w in items("wildcards")),
            # only name=value pairs: a job's own stderr, in the same stream, can land inside the
            # line (seen once in a full-suite run: a pair without "=")
            "resources": dict(r.split("=", 1) for r in items("resources") if "=" in r),
            "threads": int(fields.get("threads", 1)),
        })  # fmt: skip
    return jobs


def copy_run(source: Path, dest: Path, *leave_out: str, cache: bool = True) -> Path:
    """A copy of the finished run at ``source`` (results, resources, Snakemake's metadata) that a
    test may run Snakemake in without touching the shared run, less the files and folders named
    ``leave_out``. With ``cache``, the copy's cache is seeded with every entry of the run's,
    hard-linked (entries are never written in place, so what the test stores lands in the copy
    alone); without, it has none (for a test that runs with the cache disabled)."""
    name = ".graspstab-cache"
    skip = shutil.ignore_patterns(name, "locks", "incomplete", *leave_out)
    shutil.copytree(source, dest, symlinks=True, ignore=skip)
    if cache:
        shutil.copytree(source / name, dest / name, symlinks=True, copy_function=os.link)
    return dest
