"""The cache verifies what it restores, on the toy run's real entries: in a copy of the run, an
entry of every cached rule is truncated, loses a file or has one byte flipped; the jobs whose
outputs it held are run again, and each ends with the outputs it had and a whole entry."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from graspstab.common.cache import ENTRY_FILE, ResultCache, content_digest
from tests.test_workflow import _dry_jobs
from tests.toy_workflow import copy_run
from tests.toy_workflow import snakemake_run as _snakemake

CACHE = ".graspstab-cache"


def _replace(path: Path, data: bytes) -> None:
    """Write ``data`` as a new file at ``path``: the copy's entries are hard links to the shared
    run's, so a write in place would damage the shared run too."""
    path.unlink()
    path.write_bytes(data)


def _truncate(path: Path) -> None:
    _replace(path, path.read_bytes()[: path.stat().st_size // 2])


def _flip_byte(path: Path) -> None:
    data = bytearray(path.read_bytes())
    data[len(data) // 2] ^= 0x01
    _replace(path, bytes(data))


DAMAGE = {"truncated": _truncate, "deleted": Path.unlink, "byte flipped": _flip_byte}
# The rules whose jobs take every kind of damage: the cheapest jobs of the data chain.
MAIN_RULES = {"anneal_grasps", "replay_grasps"}
# Outputs that are measurements of the run, not results: a recomputing job rewrites them (the
# timing sidecars of annealing and replay, ``<job>.timing.json``, and of training, ``timing.json``).
TIMINGS = "timing.json"


def _entries_by_output(cache: Path) -> dict[tuple[str, str], Path]:
    """Each entry by (rule, digest of its first output): the key that finds its job, since a
    job's current outputs are the bytes its entry holds."""
    found = {}
    for record in cache.glob(f"*/*/{ENTRY_FILE}"):
        files = json.loads(record.read_text())["files"]
        found[(record.parent.parent.name, files["0"]["sha256"])] = record.parent
    return found


def _cheapest_first(workdir: Path, jobs: list[dict]) -> list[dict]:
    """Jobs ordered by their recorded run time (the rule's benchmark file), cheapest first."""

    def seconds(job: dict) -> float:
        bench = workdir / job["benchmark"][0] if job["benchmark"] else None
        if bench is None or not bench.is_file():
            return float("inf")
        return float(bench.read_text().splitlines()[1].split("\t")[0])

    return sorted(jobs, key=seconds)


@pytest.mark.workflow
def test_damaged_entries_of_every_cached_rule_are_repaired(run, tmp_path):
    shared, env, config = run
    workdir = copy_run(shared, tmp_path / "wf").absolute()
    cache = workdir / CACHE
    entries = _entries_by_output(cache)
    # (export_pick is left out: its input holds measured latencies, which the rerun of a damaged
    # sweep model's job measures again, so its key changes and it computes a new entry; its
    # restores go through the same code as every other rule's)
    rules = sorted({rule for rule, _ in entries} - {"export_pick"})
    assert {"preprocess_object", "anneal_grasps", "replay_grasps", "train_model",
            "tune_model", "export_monitor"} <= set(rules), rules  # fmt: skip
    jobs = _dry_jobs(workdir, config, env, "--forceall")

    # the data chain's rules (annealing, replay) take each kind of damage, on their three
    # cheapest jobs; every other cached rule one, the kinds rotating over them (the unit tests in
    # tests/test_cache.py take every kind through the same code, which no rule specialises)
    damaged: list[tuple[dict, Path, str]] = []
    for i, rule in enumerate(rules):
        mine = []
        for job in _cheapest_first(workdir, [j for j in jobs if j["rule"] == rule]):
            first = workdir / job["output"][0]
            entry = entries.get((rule, content_digest(first))) if first.is_file() else None
            if entry is not None:
                mine.append((job, entry))
        assert mine, f"no job of {rule} matches one of its cache entries"
        modes = sorted(DAMAGE)
        for k, (job, entry) in enumerate(mine[: len(modes) if rule in MAIN_RULES else 1]):
            damaged.append((job, entry, modes[(i + k) % len(modes)]))
    assert {mode for _, _, mode in damaged} == set(DAMAGE)

    before = {}
    for job, entry, mode in damaged:
        DAMAGE[mode](entry / "0")  # the first output: data in every rule (never a timing)
        for out in job["output"]:
            before[out] = (workdir / out).read_bytes()
            (workdir / out).unlink()
    targets = sorted(before)
    # the damaged rules only: a recomputed upstream output would otherwise rerun the (unharmed)
    # jobs between it and a target (Snakemake reruns a job whose input a running job rewrites);
    # local rules (the aggregations, the latency measurement) run regardless
    allowed = sorted({job["rule"] for job, _, _ in damaged})
    proc = _snakemake(workdir, *targets, "--allowed-rules", *allowed, *config, env=env)
    output = proc.stdout + proc.stderr
    assert proc.returncode == 0, output[-4000:]

    for job, entry, mode in damaged:
        what = f"{job['rule']} {job['wildcards']} ({mode})"
        # the job's log says which entry it refused and why, and that it stored a whole one
        log_text = (workdir / job["log"][0]).read_text()
        assert f"graspstab cache: cache entry {entry} is damaged: " in log_text, (what, log_text)
        assert f"stored a whole entry at {entry}" in log_text, what
        # the job recomputed: its outputs are what they were, and its entry holds them again
        for k, out in enumerate(job["output"]):
            assert (entry / str(k)).read_bytes() == (workdir / out).read_bytes(), f"{what}: {k}"
            if not out.endswith(TIMINGS):
                assert (workdir / out).read_bytes() == before[out], f"{what}: {out}"
        ResultCache(cache).verify(entry, [str(k) for k in range(len(job["output"]))])
        assert not [p for p in entry.parent.iterdir() if p.name.startswith(".")], what
    # the shared run's entries were not touched through the hard links
    for job, entry, _ in damaged:
        shared_entry = shared / CACHE / entry.relative_to(cache)
        ResultCache(shared / CACHE).verify(
            shared_entry, [str(k) for k in range(len(job["output"]))]
        )
