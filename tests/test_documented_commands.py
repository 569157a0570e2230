"""Every shell command the README, docs/ and the Snakemake profiles show parses and would run
(the rules, placeholders and what each check runs: tests/doc_commands.py)."""

from __future__ import annotations

import os
import shlex

import pytest

from tests.doc_commands import (
    Command,
    all_fenced,
    all_inline,
    check_command,
    check_inline,
    doc_files,
    fenced_commands,
    tokens,
    without_redirections,
)

FENCED = list(all_fenced())
INLINE = list(all_inline())


def _same(text: str) -> str:
    try:
        return shlex.join(tokens(text))  # comments and spacing apart
    except ValueError:
        return text


# a command shown in several places is checked once, named by all of them
PLACES: dict[str, list[Command]] = {}
for _c in FENCED:
    PLACES.setdefault(_same(_c.text), []).append(_c)
UNIQUE = [places[0].text for places in PLACES.values()]
WHERE = {places[0].text: ", ".join(c.where for c in places) for places in PLACES.values()}


def _param(text: str):
    """A command; Snakemake dry runs of whole profiles are slow, so they go with the workflow
    tests (the fast subset still parses them: test_inline_command_parses covers every page)."""
    slow = "snakemake" in text.split("&&")[-1].split()[:1] or text.startswith("snakemake")
    return pytest.param(text, id=WHERE[text], marks=[pytest.mark.workflow] if slow else [])


@pytest.mark.parametrize("text", [_param(t) for t in UNIQUE])
def test_fenced_command_parses_and_would_run(text, tmp_path):
    problems = check_command(text, tmp_path, dict(os.environ))
    assert not problems, f"{WHERE[text]}: {text}\n" + "\n".join(problems)


@pytest.mark.parametrize("command", INLINE, ids=[c.where for c in INLINE])
def test_inline_command_parses(command):
    problems = check_inline(command.text)
    assert not problems, f"{command.where}: {command.text}\n" + "\n".join(problems)


def test_the_pages_show_commands():
    """The extraction finds the README's install line and the docs' fenced commands."""
    readme = fenced_commands(doc_files()[0])
    assert any(c.text.startswith("python3 -m venv .venv && ") for c in readme)
    assert {c.where.split(":")[0] for c in FENCED} >= {"README.md", "docs/cluster.md"}


@pytest.mark.parametrize(
    ("command", "expected"),
    [
        ("snakemake --profile workflow/profiles/slurm --config profile=thesis results/report.html",
         "--config swallows ['results/report.html']"),
        ("snakemake --cores 2 --no-such-option results/report.html",
         "unrecognized arguments: --no-such-option"),
        ("frobnicate --now", "no rule for this command"),
        ("pip install torch==0.0.1", ".ci/run pins torch"),
        ("pip install -e '.[no_such_extra]'", "extras ['no_such_extra'] are not in pyproject"),
        (". .venv/bin/activate", "no earlier `python3 -m venv DIR`"),
        ("python benchmarks/no_such_script.py", "no such script"),
        ("python benchmarks/project_thesis.py --no-such-option", "rejects its arguments"),
        ("apt-get install -y no-such-package", "not among those .ci/run installs"),
        ("mkdocs build --no-such-option", "does not list ['--no-such-option']"),
        ("snakemake --cores 2 results/report.html < input", "operators ['<'] are not checked"),
        ("python benchmarks/cost_table.py <somewhere>", "unknown placeholder <somewhere>"),
        ("python -m no_such_package.module --help", "no such module"),
        ("snakemake --cores 2 --resources mem_mb=4000 results/report.html",
         "--resources swallows ['results/report.html']"),
    ],
)  # fmt: skip
def test_planted_broken_commands_fail(command, expected, tmp_path):
    problems = check_command(command, tmp_path, dict(os.environ))
    assert any(expected in p for p in problems), problems


def test_planted_broken_inline_commands_fail():
    broken = "snakemake --cores 2 --config profile=wide results/datasets/sweep/w10ms/summary.json"
    assert "--config swallows" in check_inline(broken)[0]
    assert "--config swallows" in check_inline("--config profile=study results/report.html")[0]
    assert not check_inline("snakemake --cores 2 --config profile=wide -- results/report.html")
    assert not check_inline("snakemake --cores 2 results/report.html --config profile=study")


def test_redirections_are_dropped_and_the_rest_checked():
    words = tokens("snakemake --cores 2 results/report.html 2>&1 | tee run.log")
    kept = without_redirections(words, "snakemake --cores 2 results/report.html 2>&1")
    assert kept == ["snakemake", "--cores", "2", "results/report.html", "|", "tee", "run.log"]
    kept = without_redirections(tokens("snakemake --cores 2 > log"), "snakemake --cores 2 > log")
    assert kept == ["snakemake", "--cores", "2"]
