"""Messages quoted in docs/troubleshooting.md, running.md and report.md are ones the code prints."""

from __future__ import annotations

import ast
import bisect
import importlib.util
import io
import re
import tokenize
from functools import cache
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[1]
PAGES = ("docs/troubleshooting.md", "docs/running.md", "docs/report.md")

# A page marks what it quotes by the fence: ```text holds a message as printed, with <placeholder>
# for what differs between runs; ```log holds lines copied from a run's logs, where the logging
# prefix (date, time, level, logger), every number and hash and every {...} mapping are
# run-specific.
FENCE = re.compile(r"^```(text|log)\n(.*?)^```", re.M | re.S)
PLACEHOLDER = re.compile(r"<[a-z][a-z0-9 _./-]*>")
NUMBER = re.compile(r"\{[^{}]*\}|\b[0-9a-f]{8,}\b|\d+(?:[.,:]\d+)*(?:e-?\d+)?%?")
LOG_PREFIX = re.compile(r"^\d{4}-\d\d-\d\d \d\d:\d\d:\d\d,\d{3} [A-Z]+ [\w.]+: ")
LOG_FORMAT = "%(asctime)s %(levelname)s %(name)s: %(message)s"  # what LOG_PREFIX strips

# Messages printed by Snakemake, Python or Optuna rather than by graspstab, quoted on the pages:
# each must be in the source of the listed modules (package, path inside it), graspstab's own
# source added for the lines that mix both (a schema error wraps jsonschema's message).
EXTERNAL_MESSAGES = (
    "Using workflow specific profile <profile> for setting default command line arguments.",
    "Error: Directory cannot be locked. Please make sure that no other Snakemake process is "
    "trying to create the same files in the following directory:",
    "If you are sure that no other instances of snakemake are running on this directory, the "
    "remaining lock was likely caused by a kill signal or a power loss. It can be removed with "
    "the --unlock argument.",
    "Unlocked working directory.",
    "The files below seem to be incomplete. If you are sure that certain files are not "
    "incomplete, mark them as complete with",
    "snakemake --cleanup-metadata <filenames>",
    "To re-generate the files rerun your command with the --rerun-incomplete flag.",
    "Incomplete files:",
    "Error in rule <rule>:",
    "log: <log file> (check log file(s) for error details)",
    "Logfile <log file>: empty file",
    "Exiting because a job execution failed. Look above for error messages",
    "Complete log(s): <snakemake log>",
    "At least one job did not complete successfully.",
    "Finished jobid: <id> (Rule: <rule>)",
    "<done> of <total> steps (<percent>) done",
    "This was a dry-run (flag -n). The order of jobs does not reflect the order of execution.",
    "Command '<command>' returned non-zero exit status <status>.",
    "Command '<command>' died with <signal>.",
    "- <key>: <value> does not match <pattern>",
    "Trial <n> finished with value: <value> and parameters: <params>. Best is trial <n> with "
    "value: <value>.",
    "Trial <n> pruned. <reason>",
)
EXTERNAL_MODULES = (
    ("snakemake", "cli.py"),
    ("snakemake", "exceptions.py"),
    ("snakemake", "persistence/__init__.py"),
    ("snakemake", "workflow.py"),
    ("snakemake", "logging.py"),
    ("snakemake", "scheduling/job_scheduler.py"),
    ("subprocess", ""),
    ("jsonschema", "_keywords.py"),
    ("optuna", "study/study.py"),
    ("optuna", "study/_optimize.py"),
)


def _spans(text: str) -> list[str]:
    """The source text of every string literal, implicitly concatenated ones joined."""
    starts = [0]
    for line in text.splitlines(keepends=True):
        starts.append(starts[-1] + len(line))

    def offset(pos: tuple[int, int]) -> int:
        return starts[pos[0] - 1] + pos[1]

    groups: list[list[str]] = []
    joining = False  # the previous token was a string: the next one concatenates
    depth, fstart = 0, 0  # Python 3.12+: f-strings come as FSTRING_START ... FSTRING_END
    fstring = (getattr(tokenize, "FSTRING_START", -1), getattr(tokenize, "FSTRING_END", -1))
    for tok in tokenize.generate_tokens(io.StringIO(text).readline):
        if tok.type == fstring[0]:
            depth, fstart = depth + 1, fstart if depth else offset(tok.start)
            continue
        if depth:
            depth -= tok.type == fstring[1]
            if depth:
                continue
            literal = text[fstart : offset(tok.end)]
        elif tok.type == tokenize.STRING:
            literal = tok.string
        else:
            if tok.type not in (tokenize.NL, tokenize.COMMENT):
                joining = False
            continue
        if joining:
            groups[-1].append(literal)
        else:
            groups.append([literal])
        joining = True
    return [" ".join(g) for g in groups]


HOLE = re.compile(r"%(?:\(\w+\))?[-#0 +]*\d*(?:\.\d+)?[sdrifgexXc]|\{[^{}]*\}|\n")


def _parts(literal: str) -> list[str]:
    """The constant runs of one literal between its interpolations (f-string fields, str.format
    and %-fields) and line breaks, and those of the literals inside its f-string fields."""
    try:
        node = ast.parse(f"({literal})", mode="eval").body
    except SyntaxError:
        return []
    return _runs(node)


def _runs(node: ast.expr) -> list[str]:
    """The constant runs of a parsed literal (see _parts)."""
    values = node.values if isinstance(node, ast.JoinedStr) else [node]
    runs, current, nested = [], "", []
    for v in values:
        if isinstance(v, ast.Constant) and isinstance(v.value, str):
            pieces = HOLE.split(v.value)
            current += pieces[0]
            for piece in pieces[1:]:
                runs.append(current)
                current = piece
        else:
            runs.append(current)
            current = ""
            inner = [
                n for n in ast.walk(v) if n is not v and isinstance(n, ast.JoinedStr | ast.Constant)
            ]
            nested += [r for n in inner for r in _runs(n)]
    runs.append(current)
    return [r for r in runs + nested if r]


class Corpus:
    """Every constant run of the string literals of some source files. A quoted fragment is in
    it when it is inside one run, or is a run's end, whole runs and a run's start in a row (the
    message composed of several literals or f-string fields), at most MAX_PIECES pieces."""

    MAX_PIECES = 4
    MIN_EDGE = 2  # the shortest run end or start a composed fragment may use

    def __init__(self, files: list[Path]):
        runs = {r for f in files for lit in _spans(f.read_text()) for r in _parts(lit)}
        self.runs = runs
        self.text = "\x00".join(sorted(runs))
        self.starts = sorted(runs)
        self.ends = sorted(r[::-1] for r in runs)

    @staticmethod
    def _has_prefix(sorted_runs: list[str], prefix: str) -> bool:
        i = bisect.bisect_left(sorted_runs, prefix)
        return i < len(sorted_runs) and sorted_runs[i].startswith(prefix)

    def holds(self, fragment: str) -> bool:
        if fragment in self.text:
            return True
        n = len(fragment)

        def first(i: int) -> bool:  # fragment[:i] ends a run
            head = fragment[:i]
            return head in self.runs or (
                i >= self.MIN_EDGE and self._has_prefix(self.ends, head[::-1])
            )

        def last(j: int) -> bool:  # fragment[j:] starts a run
            tail = fragment[j:]
            return tail in self.runs or (
                n - j >= self.MIN_EDGE and self._has_prefix(self.starts, tail)
            )

        frontier = [(i, 1) for i in range(1, n) if first(i)]
        while frontier:
            j, pieces = frontier.pop()
            if last(j):
                return True
            if pieces + 1 < self.MAX_PIECES:
                frontier += [(k, pieces + 1) for k in range(j + 1, n) if fragment[j:k] in self.runs]
        return False


@cache
def graspstab_corpus() -> Corpus:
    files = [*(REPO / "src").rglob("*.py"), *(REPO / "workflow").rglob("*.py"),
             *(REPO / "workflow").rglob("*.smk"), REPO / "Snakefile"]  # fmt: skip
    return Corpus(files)


@cache
def external_corpus() -> Corpus:
    files = []
    for package, rel in EXTERNAL_MODULES:
        origin = Path(importlib.util.find_spec(package).origin)
        files.append(origin.parent / rel if rel else origin)
    return Corpus(files + [REPO / "src" / "graspstab" / "config" / "validate.py"])


def fragments(line: str) -> list[str]:
    """The literal text of a quoted line, between its placeholders."""
    return [f for f in (p.strip() for p in PLACEHOLDER.split(line)) if f]


def quoted_lines() -> list[tuple[str, str, str]]:
    """(page, fence kind, line) of every non-empty line in a marked block of the pages."""
    out = []
    for page in PAGES:
        path = REPO / page
        if not path.exists():
            continue
        for kind, body in FENCE.findall(path.read_text()):
            out += [(page, kind, line.strip()) for line in body.splitlines() if line.strip()]
    return out


def normalised(kind: str, line: str) -> str:
    """A ``log`` line with its logging prefix, numbers and mappings turned into placeholders."""
    if kind != "log":
        return line
    return NUMBER.sub("<n>", LOG_PREFIX.sub("", line))


def matches(line: str, message: str) -> bool:
    """``line`` is (part of) ``message``, a placeholder of either standing for anything."""
    pattern = re.escape(PLACEHOLDER.sub("\x00", line)).replace("\x00", ".*")
    return re.search(pattern, PLACEHOLDER.sub("\x00", message)) is not None


def is_external(line: str) -> bool:
    """The line is (part of) one of EXTERNAL_MESSAGES."""
    return any(matches(line, m) for m in EXTERNAL_MESSAGES)


LINES = quoted_lines()


def test_pages_quote_messages():
    assert {p for p, _, _ in LINES} == set(PAGES), "a page is missing or quotes nothing"
    assert LOG_FORMAT in (REPO / "src" / "graspstab" / "common" / "logs.py").read_text()


@pytest.mark.parametrize(
    ("page", "kind", "line"), LINES, ids=[f"{p}:{ln[:50]}" for p, _, ln in LINES]
)
def test_quoted_line_is_printed_by_the_code(page, kind, line):
    text = normalised(kind, line)
    corpus = graspstab_corpus()
    missing = [f for f in fragments(text) if not corpus.holds(f)]
    if missing and not is_external(text):
        pytest.fail(f"{page}: {line!r}: not in src/ or workflow/ ({missing}) nor in "
                    "EXTERNAL_MESSAGES")  # fmt: skip


@pytest.mark.parametrize("message", EXTERNAL_MESSAGES)
def test_external_message_is_printed_by_its_package(message):
    corpus = external_corpus()
    missing = [f for f in fragments(message) if not corpus.holds(f)]
    assert not missing, f"{message!r}: {missing} not in {EXTERNAL_MODULES}"
    quoted = [normalised(k, ln) for _, k, ln in LINES]
    assert any(matches(q, message) for q in quoted), f"{message!r} is quoted on no page"


def test_corpus_rejects_a_changed_message():
    """The check has teeth: a reworded message is not found."""
    corpus = graspstab_corpus()
    assert corpus.holds("must be a positive number of kilograms")
    assert not corpus.holds("must be a positive mass in kilograms")
    assert corpus.holds("graspstab configuration error: object '")
