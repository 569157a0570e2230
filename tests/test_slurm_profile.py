"""Every rule with jobs in a thesis dry run gets thesis-scale SLURM requests from the profile."""

from __future__ import annotations

import re
import subprocess
import sys
from collections.abc import Iterable, Mapping
from pathlib import Path

import pytest
import yaml

from tests.conftest import REPO
from tests.toy_workflow import listed_jobs

PROFILE = REPO / "workflow" / "profiles" / "slurm"
RULE_FILES = [REPO / "Snakefile", *sorted((REPO / "workflow" / "rules").glob("*.smk"))]
REQUIRED = ("mem_mb", "runtime")
# Rules of the thesis DAG that run on the login node beside Snakemake (never submitted), so no
# request applies to them; each named with where it is declared local. A new local rule fails
# the test until it is named here.
LOGIN_NODE = {
    "rulegraph": "localrules in workflow/rules/report.smk (seconds of graph printing)",
}


def local_rules(files: Iterable[Path] = RULE_FILES) -> set[str]:
    """Rules Snakemake runs locally under any executor: named by a ``localrules:`` directive or
    ``localrule: True``, or with nothing to run (no ``script``/``shell``/``run``: targets)."""
    out: set[str] = set()
    for path in files:
        text = path.read_text()
        for m in re.finditer(r"^localrules:[ \t]*(.*\n(?:[ \t]+.*\n)*)", text, flags=re.M):
            out.update(n for n in re.split(r"[\s,]+", m.group(1)) if n)
        for m in re.finditer(r"^rule (\w+):\n((?:[ \t]+.*\n|\n)*)", text, flags=re.M):
            body = m.group(2)
            if re.search(r"^\s+localrule:\s*True", body, re.M) or not re.search(
                r"^\s+(script|shell|run|wrapper|notebook|cwl|template_engine):", body, re.M
            ):
                out.add(m.group(1))
    return out


def missing_requests(
    profile: Mapping, rules: Iterable[str], local: Iterable[str], required=REQUIRED
) -> dict[str, list[str]]:
    """For each rule that SLURM would run, the required requests the profile's ``set-resources``
    does not give it (empty: every such rule is sized)."""
    requests = profile.get("set-resources") or {}
    local = set(local)
    out = {}
    for rule in sorted(set(rules) - local):
        lacks = [k for k in required if k not in (requests.get(rule) or {})]
        if lacks:
            out[rule] = lacks
    return out


@pytest.fixture(scope="module")
def profile() -> dict:
    return yaml.safe_load((PROFILE / "config.yaml").read_text())


@pytest.fixture(scope="module")
def thesis_jobs(tmp_path_factory, bare_env) -> list[dict]:
    """The thesis DAG's jobs, dry-run through the SLURM profile (nothing submitted, no assets)."""
    workdir = tmp_path_factory.mktemp("thesis_dry_run")
    cmd = [sys.executable, "-m", "snakemake", "-s", str(REPO / "Snakefile"), "-d", str(workdir),
           "--profile", str(PROFILE), "--dry-run", "results/report.html",
           "--config", "profile=thesis"]  # fmt: skip
    proc = subprocess.run(cmd, capture_output=True, text=True, env=bare_env, timeout=300)
    assert proc.returncode == 0, proc.stdout[-3000:] + proc.stderr[-3000:]
    jobs = listed_jobs(proc.stdout)
    assert len(jobs) > 400, len(jobs)
    return jobs


@pytest.mark.workflow  # a dry run of the whole thesis DAG (slow, though it runs no job)
def test_every_thesis_rule_has_slurm_requests(profile, thesis_jobs):
    rules = {j["rule"] for j in thesis_jobs}
    local = local_rules() & rules
    assert local == set(LOGIN_NODE), (
        f"local rules of the thesis DAG {sorted(local)} != the ones named in LOGIN_NODE "
        f"{sorted(LOGIN_NODE)}"
    )
    missing = missing_requests(profile, rules, local)
    assert not missing, (
        "rules of the thesis DAG without thesis-scale requests in workflow/profiles/slurm "
        f"set-resources: {missing}"
    )
    # what the jobs carry is the profile's (first attempt), not only the rule's own defaults
    for job in thesis_jobs:
        if job["rule"] not in local:
            assert set(REQUIRED) <= set(job["resources"]), job


def test_checker_flags_a_missing_rule_and_a_missing_request():
    profile = {"set-resources": {
        "train_model": {"mem_mb": "6000 * attempt", "runtime": "360 * attempt"},
        "tune_model": {"mem_mb": 4000},
    }}  # fmt: skip
    rules = ["train_model", "tune_model", "train_input_model", "rulegraph"]
    assert missing_requests(profile, rules, local={"rulegraph"}) == {
        "train_input_model": ["mem_mb", "runtime"],
        "tune_model": ["runtime"],
    }
    assert missing_requests(profile, ["train_model"], local=()) == {}
    assert missing_requests({}, ["a"], local=()) == {"a": ["mem_mb", "runtime"]}


def test_checker_flags_a_rule_removed_from_the_real_profile(profile):
    rules = set(profile["set-resources"])
    assert missing_requests(profile, rules, local=()) == {}
    planted = {**profile, "set-resources": dict(profile["set-resources"])}
    del planted["set-resources"]["train_sweep_model"]
    assert missing_requests(planted, rules, local=()) == {
        "train_sweep_model": ["mem_mb", "runtime"]
    }


def test_local_rules_are_read_from_directives_and_targets(tmp_path):
    smk = tmp_path / "x.smk"
    smk.write_text(
        "localrules:\n    a,\n    b,\n\n\nrule a:\n    shell: 'x'\n\n\n"
        "rule b:\n    script: 'y'\n\n\n"
        "rule c:\n    localrule: True\n    shell: 'z'\n\n\nrule d:\n    input: 'q'\n\n\n"
        "rule e:\n    shell: 'w'\n"
    )
    assert local_rules([smk]) == {"a", "b", "c", "d"}
    # the real workflow: the report's graph printing and the aggregate targets
    assert {"rulegraph", "all"} <= local_rules()
