"""Every configuration check lives in the config validator (graspstab.config), so
`python -m graspstab.config show` and the Snakefile reject the same inputs with the same message.

The Snakefile and the rule files may stop the workflow only at the sites of a short allow-list;
every other ``raise``, ``assert`` or exit in them fails the test with its file and line. Then the
same bad overrides go through ``show`` and a Snakemake run, which must both refuse them with one
and the same message, and a password in ``tune.storage`` must appear nowhere Snakemake writes.
"""

from __future__ import annotations

import io
import re
import tokenize
from pathlib import Path

import pytest

from graspstab.config.__main__ import main as config_main
from tests.conftest import ASSET_VARIABLES, CONFIG_DIR, REPO, SCHEMA
from tests.toy_workflow import snakemake_command

RULE_FILES = [REPO / "Snakefile", *sorted((REPO / "workflow" / "rules").glob("*.smk"))]

# The only places the workflow's own code may stop it: (file, enclosing def or <module>, what is
# raised). Anything else that checks configuration belongs in src/graspstab/config/ (relations.py,
# validate.py), where `python -m graspstab.config show` runs it too.
ALLOWED = {
    # the one validation call site: the validator's ConfigError re-raised as a WorkflowError
    ("common.smk", "<module>", "WorkflowError"),
    # the split study's object-to-split draw: it depends on the targets (a run that only
    # preprocesses one object needs no complete split), which the validator cannot see
    ("common.smk", "assignments", "WorkflowError"),
}

STOPS = {"raise", "assert"}
EXITS = {("sys", "exit"), ("os", "_exit"), ("", "exit"), ("", "quit")}


def stop_sites(text: str) -> list[tuple[int, str, str]]:
    """(line, enclosing top-level def or ``<module>``, what stops) of every ``raise``,
    ``assert`` and ``sys.exit``/``os._exit``/``exit``/``quit`` call in ``text``: Python tokens,
    so strings and comments never count. Snakemake's rule syntax tokenizes as Python."""
    tokens = [t for t in tokenize.generate_tokens(io.StringIO(text).readline)
              if t.type not in (tokenize.COMMENT, tokenize.NL)]  # fmt: skip
    lines = text.splitlines()
    sites = []
    for i, tok in enumerate(tokens):
        if tok.type != tokenize.NAME:
            continue
        after = [t.string for t in tokens[i + 1 : i + 4]]
        before = tokens[i - 1].string if i else ""
        if tok.string in STOPS:
            what = after[0] if tok.string == "raise" and after else tok.string
        elif before == "." and (tokens[i - 2].string, tok.string) in EXITS and after[:1] == ["("]:
            what = f"{tokens[i - 2].string}.{tok.string}"
        elif before != "." and ("", tok.string) in EXITS and after[:1] == ["("]:
            what = tok.string
        else:
            continue
        sites.append((tok.start[0], _enclosing(lines, tok.start[0]), what))
    return sites


def _enclosing(lines: list[str], line: int) -> str:
    """The top-level ``def`` (or rule) a line sits in, else ``<module>``."""
    for text in reversed(lines[: line - 1] if lines[line - 1][:1].isspace() else []):
        if text and not text[:1].isspace() and not text.startswith("#"):
            head = re.match(r"(?:def|rule|checkpoint)\s+(\w+)", text)
            return head.group(1) if head else "<module>"
    return "<module>"


def test_the_scanner_finds_every_kind_of_stop() -> None:
    text = '''
# raise ValueError("a comment does not count")
NOTE = "raise ValueError and assert in a string do not count"
import sys
if config["x"]: raise ValueError("one-line if")
assert config["y"] > 0, "an assert"


def helper(wildcards):
    """raise in a docstring does not count"""
    if wildcards.k:
        raise WorkflowError(
            "in a function"
        )
    sys.exit(2)


rule r:
    run:
        exit(1)
'''
    assert stop_sites(text) == [
        (5, "<module>", "ValueError"),
        (6, "<module>", "assert"),
        (12, "helper", "WorkflowError"),
        (15, "helper", "sys.exit"),
        (20, "r", "exit"),
    ]


def test_rule_files_check_no_configuration() -> None:
    """No rule file checks configuration itself: each stop is on the allow-list, and each
    allow-list entry still exists (a stale one would let the next check in unseen)."""
    found, stray = set(), []
    for path in RULE_FILES:
        for line, where, what in stop_sites(path.read_text()):
            key = (path.name, where, what)
            found.add(key)
            if key not in ALLOWED:
                stray.append(f"{path.relative_to(REPO)}:{line}: {what} in {where}")
    assert not stray, (
        "checks in the rule files (move configuration checks to src/graspstab/config/relations.py "
        "or validate.py, so `python -m graspstab.config show` runs them too):\n" + "\n".join(stray)
    )
    assert ALLOWED <= found, f"allow-list entries no longer in the rule files: {ALLOWED - found}"


def _show_message(entries: list[str], capsys: pytest.CaptureFixture[str]) -> str:
    args = ["show", "--config-dir", str(CONFIG_DIR), "--schema", str(SCHEMA), *entries]
    assert config_main(args) == 2
    err = capsys.readouterr().err
    [line] = err.splitlines()
    return line


def _snakemake_message(output: str) -> str:
    """The configuration error Snakemake reports (common.smk's WorkflowError, on stdout in
    Snakemake 9), as `show` prints it: one line."""
    found = re.search(r"^(graspstab configuration error: .*?)^\s+File \"", output, re.S | re.M)
    assert found, output[-3000:]
    return " ".join(line.strip() for line in found.group(1).splitlines() if line.strip())


SECRET = "pw-Never-Shown-7"
BAD = {
    "closed_loop_without_benchmark": (
        ["closed_loop={enabled: true}"],
        "closed_loop.protocols = ['reference', 'creep_free'] names creep_free but "
        "creep_free.enabled is false",
    ),
    "zero_width_label_band": (
        ["labels={label_low: 0.5, label_high: 0.5}"],
        "the ambiguous band between them has zero width",
    ),
    "password_in_storage_url": (
        [f'tune={{storage: "postgresql://graspstab:{SECRET}@db.example.org/graspstab"}}'],
        "tune.storage = postgresql://graspstab:***@db.example.org/graspstab holds a password",
    ),
}


@pytest.mark.workflow  # Snakemake loads the workflow (a few seconds each)
@pytest.mark.parametrize("case", sorted(BAD))
def test_show_and_snakemake_refuse_alike(
    case: str,
    tmp_path: Path,
    bare_env: dict[str, str],
    capsys: pytest.CaptureFixture[str],
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    """The same override is refused by `python -m graspstab.config show` and by a Snakemake dry
    run, with the same message (and never with the password)."""
    import subprocess

    entries, expected = BAD[case]
    for name in ASSET_VARIABLES:  # both compose the configuration in the same environment
        monkeypatch.delenv(name, raising=False)
    shown = _show_message(entries, capsys)
    assert expected in shown, shown
    cmd = snakemake_command(tmp_path, "-n", "results/report.html", "--config", *entries)
    proc = subprocess.run(cmd, capture_output=True, text=True, env=bare_env, timeout=300)
    assert proc.returncode != 0, proc.stdout[-2000:]
    assert "Traceback" not in proc.stdout + proc.stderr
    assert _snakemake_message(proc.stdout + proc.stderr) == shown
    assert SECRET not in proc.stdout + proc.stderr + shown


@pytest.mark.workflow
def test_storage_password_reaches_no_snakemake_log(
    tmp_path: Path, bare_env: dict[str, str]
) -> None:
    """A real (not dry) run, which keeps a log in .snakemake/log/: refused at load time with the
    masked URL and where the password goes instead, and the password is in none of stdout,
    stderr and the files Snakemake wrote."""
    import subprocess

    url = f"postgresql://graspstab:{SECRET}@db.example.org:5432/graspstab_{{model}}"
    cmd = snakemake_command(tmp_path, "--cores", "1", "results/report.html", "--config",
                            f'tune={{storage: "{url}"}}')  # fmt: skip
    proc = subprocess.run(cmd, capture_output=True, text=True, env=bare_env, timeout=300)
    assert proc.returncode != 0
    message = _snakemake_message(proc.stdout + proc.stderr)
    for text in ("tune.storage = postgresql://graspstab:***@db.example.org:5432/graspstab_{model}",
                 "postgresql://graspstab@db.example.org:5432/graspstab_{model},",
                 "~/.pgpass", "PGPASSWORD"):  # fmt: skip
        assert text in message, message
    assert SECRET not in proc.stdout + proc.stderr
    logs = list((tmp_path / ".snakemake" / "log").glob("*.log"))
    assert logs, "Snakemake wrote no log: nothing was checked"
    assert any("holds a password" in log.read_text() for log in logs)
    written = [p for p in tmp_path.rglob("*") if p.is_file()]
    assert not [p for p in written if SECRET.encode() in p.read_bytes()]
