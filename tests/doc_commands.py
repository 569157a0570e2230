"""The shell commands the documentation shows, and a checker that says whether each one parses and
would run (tests/test_documented_commands.py).

Every command of a fenced ``bash`` block of README.md and docs/*.md is split at ``&&``, ``||``,
``;`` and ``|`` and each part goes to the first rule of ``RULES`` that claims it; a part no rule
claims fails with "no rule for this command", so a new kind of command cannot slip through
unchecked. What each rule does, cheapest sufficient check first:

* ``snakemake ...``: parsed by Snakemake's own argument parser and ``--config`` parser (an
  unknown option, or a target after ``--config`` that ``--config`` would swallow, fails here),
  then run as a dry run (``--dry-run --quiet``) from the repository root with ``--directory`` a
  scratch folder, in the test's environment (the asset variables as set; ``.ci/run`` sets them).
  The SLURM profile's dry run needs no cluster: the executor plugin
  (snakemake-executor-plugin-slurm, in the ``dev`` extra) plans the jobs without calling sbatch,
  so the profile is used as written, executor included.
* ``python -m graspstab.config ...``: run for real (it only composes and prints the config).
* ``python SCRIPT.py ...``, ``python -m MODULE ...`` of an argparse program (the benchmarks,
  ``tests.asset_archives``, ``venv``): the program is imported and its own ``parse_args`` parses
  the arguments, then it stops (``PARSE_ONLY``): nothing runs.
* ``python -c CODE ...``, ``sha256sum FILE``, ``shasum -a 256 FILE``: run for real in a
  scratch folder.
* ``pytest ...``: ``pytest --collect-only`` with the same arguments on one small test file (the
  options, conftest's included, and the ``-m`` expression parse; no test runs).
* ``pip install``: only the two documented forms, checked statically: ``torch==V`` with V the pin
  of ``.ci/run``, and ``-e '.[EXTRAS]'`` with extras that pyproject.toml defines.
* ``. DIR/bin/activate``: DIR is the venv an earlier part of the same line creates.
* ``apt-get install -y PKGS``: every package is one ``.ci/run`` installs.
* ``createdb``, ``mkdocs``, ``ruff``: every option is one that ``TOOL [SUBCOMMAND] --help`` lists.
  So are ``tail``, ``head``, ``ls`` and ``grep`` (reading a run's logs).
* ``tee [-a] FILE`` (after a pipe): accepted as it is.
* ``nohup CMD ...``: CMD by its own rule.

Output redirections (``> FILE``, ``2>&1``) are dropped before the parts are checked, and a
trailing ``&`` separates like ``;``; any other operator (``<``, subshells) fails.

Placeholders are substituted before any of this (``substitute``): a ``<NAME>`` listed in
``PLACEHOLDERS`` becomes its value there (``<profile>``: quick) or a scratch folder
(``<workdir>``, ``<wd>``, ``<clone>``), and ``path/to/NAME`` or ``/path/to/NAME`` an empty
scratch file NAME; an unlisted ``<NAME>`` fails.
Every ``python`` command runs in a forked child of one interpreter that has Snakemake, pytest and
the config stack imported (``PRELOADED``), the same program with the same arguments without the
imports' 1-2 s each time.

Commands outside fenced blocks (inline code spans, comments of the Snakemake profiles) are
checked without running: a ``snakemake`` one must parse, and no command may put a target after
``--config`` (``--config KEY=VALUE ... TARGET``: ``--config`` swallows the target and Snakemake
stops with "Invalid config definition"; put targets before ``--config``, or after ``--``). The
same holds for the other options that take ``KEY=VALUE`` lists (``SWALLOWING``: ``--resources``,
``--set-threads``, ...), in fenced blocks too.
"""

from __future__ import annotations

import atexit
import contextlib
import io
import json
import re
import shlex
import subprocess
import sys
import tomllib
from collections.abc import Callable, Iterator
from dataclasses import dataclass, field
from importlib.util import find_spec
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
SHELL_FENCES = {"bash", "sh", "shell", "console"}
SEPARATORS = {"&&", "||", ";", "|", "&"}  # "&": in the background, still each part checked
PYTHONS = {"python", "python3"}
# pytest --collect-only runs on this one file only: collecting the whole suite takes 20 s
COLLECT_TARGET = "tests/test_markers.py"
TIMEOUT_S = 120


def doc_files() -> list[Path]:
    """README.md and every page under docs/."""
    return [REPO / "README.md", *sorted((REPO / "docs").glob("*.md"))]


def profile_configs() -> list[Path]:
    """The Snakemake profiles' config files (under workflow/profiles/ or profiles/), whose
    comments show commands."""
    return sorted(
        {*REPO.glob("workflow/profiles/*/config.yaml"), *REPO.glob("profiles/*/config.yaml")}
    )


@dataclass(frozen=True)
class Command:
    where: str  # "docs/cluster.md:19"
    text: str  # one logical line: continuations joined


def _rel(path: Path) -> str:
    return str(path.resolve().relative_to(REPO))


def fenced_commands(path: Path) -> list[Command]:
    """The command lines of the fenced shell blocks of ``path``, continuation lines joined;
    comment-only and blank lines are left out."""
    out: list[Command] = []
    fence: str | None = None
    pending, start = "", 0
    for number, line in enumerate(path.read_text().splitlines(), 1):
        stripped = line.strip()
        if stripped.startswith("```"):
            fence = None if fence is not None else stripped[3:].strip().lower()
            continue
        if fence not in SHELL_FENCES:
            continue
        if not pending:
            if not stripped or stripped.startswith("#"):
                continue
            start = number
        if stripped.endswith("\\"):
            pending += stripped[:-1] + " "
            continue
        out.append(Command(f"{_rel(path)}:{start}", pending + stripped))
        pending = ""
    return out


def _without_fences(text: str) -> str:
    """``text`` with the fenced blocks blanked (line numbers kept)."""
    lines, inside = [], False
    for line in text.splitlines():
        if line.strip().startswith("```"):
            inside = not inside
            lines.append("")
        else:
            lines.append("" if inside else line)
    return "\n".join(lines)


# an inline code span; it may wrap onto the next line but not cross a paragraph
INLINE = re.compile(r"(?<!`)`((?:[^`\n]|\n(?![ \t]*\n))+)`(?!`)")


def inline_commands(path: Path) -> list[Command]:
    """The inline code spans of ``path`` that hold a command line (one naming ``snakemake`` or
    ``--config``), line breaks folded into spaces."""
    text = _without_fences(path.read_text())
    out = []
    for m in INLINE.finditer(text):
        span = " ".join(m.group(1).split())
        if re.search(r"(^|\s)(snakemake|--config)(\s|$)", span):
            line = text.count("\n", 0, m.start()) + 1
            out.append(Command(f"{_rel(path)}:{line}", span))
    return out


def comment_commands(path: Path) -> list[Command]:
    """The ``snakemake`` command lines in the YAML comments of ``path``."""
    out = []
    for number, line in enumerate(path.read_text().splitlines(), 1):
        body = line.strip().lstrip("#").strip()
        if line.strip().startswith("#") and body.startswith("snakemake "):
            out.append(Command(f"{_rel(path)}:{number}", body))
    return out


# Placeholders -------------------------------------------------------------------------------

# ``<NAME>`` in a command: (what it stands for, its substitute; None: a scratch folder NAME)
PLACEHOLDERS: dict[str, tuple[str, str | None]] = {
    "workdir": ("the work directory of a finished run", None),
    "wd": ("a scratch work directory (benchmarks/protocol_matrix.py --workdir)", None),
    "clone": ("a fresh clone that has run the workflow", None),
    "profile": ("a profile's name (config/profile/)", "quick"),
    "seconds": ("a measured duration in seconds", "87"),
}
PLACEHOLDER = re.compile(r"<([A-Za-z_][\w-]*)>")
PLACEHOLDER_PATH = re.compile(r"(?<![\w/])/?path/to/([\w.-]+)")


class UnknownPlaceholder(ValueError):
    pass


def substitute(text: str, scratch: Path) -> str:
    """``text`` with its placeholders replaced: ``<NAME>`` of ``PLACEHOLDERS`` by its value or
    the scratch folder ``NAME`` and ``path/to/NAME`` / ``/path/to/NAME`` by an empty scratch file
    ``NAME``, both created; any other ``<NAME>`` raises ``UnknownPlaceholder``."""

    def folder(m: re.Match[str]) -> str:
        if m.group(1) not in PLACEHOLDERS:
            raise UnknownPlaceholder(
                f"unknown placeholder {m.group(0)}: say what it stands for in PLACEHOLDERS "
                "(tests/doc_commands.py)"
            )
        value = PLACEHOLDERS[m.group(1)][1]
        if value is not None:
            return value
        path = scratch / m.group(1)
        path.mkdir(parents=True, exist_ok=True)
        return str(path)

    def file(m: re.Match[str]) -> str:
        path = scratch / m.group(1)
        if not path.exists():
            path.touch()
        return str(path)

    return PLACEHOLDER_PATH.sub(file, PLACEHOLDER.sub(folder, text))


# Splitting ------------------------------------------------------------------------------------


def tokens(text: str) -> list[str]:
    """Shell words of ``text`` (quotes removed, ``#`` comments dropped), operators apart."""
    lexer = shlex.shlex(text, posix=True, punctuation_chars=True)
    lexer.whitespace_split = True
    return list(lexer)


REDIRECTIONS = {">", ">>", ">&", "&>"}


def without_redirections(words: list[str], text: str) -> list[str]:
    """``words`` less their output redirections (``> FILE``, ``>> FILE``, ``2>&1``, ...): where
    a command's output goes does not change whether it parses. The file descriptor before the
    operator is dropped where the text writes it against the operator (``2>``)."""
    fds = set(re.findall(r"(?<![\w-])(\d)(?=>)", text))
    out: list[str] = []
    skip = False
    for w in words:
        if skip:
            skip = False
        elif w in REDIRECTIONS:
            if out and out[-1] in fds:
                out.pop()
            skip = True
        else:
            out.append(w)
    return out


def parts(words: list[str]) -> list[list[str]]:
    """``words`` split at the list and pipe operators."""
    out: list[list[str]] = [[]]
    for w in words:
        if w in SEPARATORS:
            out.append([])
        else:
            out[-1].append(w)
    return [p for p in out if p]


# Snakemake options that take every following word up to the next option as a KEY=VALUE pair
SWALLOWING = {
    *("--config", "-C", "--resources", "--res", "--set-threads", "--set-resources"),
    *("--default-resources", "--default-res", "--set-scatter", "--set-resource-scopes"),
}


def swallowed_targets(words: list[str]) -> dict[str, list[str]]:
    """Per option of ``SWALLOWING``, the words after it that are no ``KEY=VALUE``: targets
    the option would swallow (Snakemake then stops with 'Invalid config definition' or a
    ValueError)."""
    out: dict[str, list[str]] = {}
    option = None
    for w in words:
        if w in SWALLOWING:
            option = w
        elif w.startswith("-") or w in SEPARATORS:
            option = None
        elif option and "=" not in w:
            out.setdefault(option, []).append(w)
    return out


def swallow_message(words: list[str]) -> str | None:
    swallowed = swallowed_targets(words)
    if not swallowed:
        return None
    return "; ".join(
        f"{option} swallows {targets}: Snakemake reads every word after {option} up to the next "
        f"option as KEY=VALUE and stops; put the targets before {option} (or after --)"
        for option, targets in swallowed.items()
    )


# Running --------------------------------------------------------------------------------------


@dataclass
class Context:
    """What the parts of one command line share."""

    scratch: Path
    env: dict[str, str]
    venvs: set[str] = field(default_factory=set)


# Runs ``python ARGS`` requests in forked children of one single-threaded interpreter that has
# Snakemake, pytest and the config stack imported already: the same programs with the same
# arguments, minus the 1-2 s of imports each fresh interpreter would spend (a documented command
# run by this file costs 2-4 s, most of it imports). A request is a JSON line (argv after
# ``python``, cwd, env, output file); the answer is the child's exit status.
PRELOADED = r"""
import json, os, runpy, signal, sys, traceback
import hydra, omegaconf, pytest, snakemake.api, snakemake.cli, yaml
import graspstab.config.__main__

def python(argv):
    if argv[0] == "-m":
        sys.argv = [argv[1], *argv[2:]]
        runpy.run_module(argv[1], run_name="__main__", alter_sys=True)
    elif argv[0] == "-c":
        sys.argv = ["-c", *argv[2:]]
        sys.path.insert(0, "")
        exec(compile(argv[1], "<string>", "exec"), {"__name__": "__main__"})
    else:
        sys.argv = list(argv)
        runpy.run_path(argv[0], run_name="__main__")

def child(request):
    signal.alarm(request["timeout"])
    out = os.open(request["out"], os.O_WRONLY | os.O_CREAT | os.O_TRUNC)
    os.dup2(out, 1)
    os.dup2(out, 2)
    os.chdir(request["cwd"])
    os.environ.clear()
    os.environ.update(request["env"])
    try:
        python(request["argv"])
        code = 0
    except SystemExit as exc:
        code = exc.code if isinstance(exc.code, int) else (0 if exc.code is None else 1)
        if isinstance(exc.code, str):
            print(exc.code, file=sys.stderr)
    except BaseException:
        traceback.print_exc()
        code = 1
    sys.stdout.flush()
    sys.stderr.flush()
    os._exit(code)

for line in sys.stdin:
    request = json.loads(line)
    sys.stdout.flush()
    pid = os.fork()
    if pid == 0:
        child(request)
    _, status = os.waitpid(pid, 0)
    print(os.waitstatus_to_exitcode(status), flush=True)
"""
_preloaded: subprocess.Popen | None = None
# no BLAS thread pool in the interpreter that forks (the children get the request's environment)
ONE_THREAD = {"OPENBLAS_NUM_THREADS": "1", "OMP_NUM_THREADS": "1", "MKL_NUM_THREADS": "1"}


def _stop_preloaded(process: subprocess.Popen) -> None:
    """End of input: the interpreter's loop ends, and it exits."""
    if process.stdin:
        process.stdin.close()
    process.wait(timeout=TIMEOUT_S)


def _run_preloaded(args: list[str], ctx: Context, cwd: Path) -> subprocess.CompletedProcess:
    global _preloaded
    if _preloaded is None or _preloaded.poll() is not None:
        _preloaded = subprocess.Popen(
            [sys.executable, "-c", PRELOADED], stdin=subprocess.PIPE, stdout=subprocess.PIPE,
            cwd=REPO, env={**ctx.env, **ONE_THREAD}, text=True,
        )  # fmt: skip
        atexit.register(_stop_preloaded, _preloaded)
    assert _preloaded.stdin and _preloaded.stdout
    out = ctx.scratch / f"output-{len(list(ctx.scratch.glob('output-*')))}.txt"
    request = {"argv": args, "cwd": str(cwd), "env": ctx.env, "out": str(out),
               "timeout": TIMEOUT_S}  # fmt: skip
    _preloaded.stdin.write(json.dumps(request) + "\n")
    _preloaded.stdin.flush()
    answer = _preloaded.stdout.readline()
    if not answer:
        raise RuntimeError(f"the preloaded interpreter ended (exit {_preloaded.poll()})")
    text = out.read_text() if out.exists() else ""
    return subprocess.CompletedProcess([sys.executable, *args], int(answer), text, "")


def run(argv: list[str], ctx: Context, cwd: Path = REPO) -> subprocess.CompletedProcess:
    """``argv`` run to its end; a ``sys.executable`` one in the preloaded interpreter."""
    if argv[0] == sys.executable:
        return _run_preloaded(argv[1:], ctx, cwd)
    return subprocess.run(
        argv, cwd=cwd, env=ctx.env, capture_output=True, text=True, timeout=TIMEOUT_S
    )


def _tail(proc: subprocess.CompletedProcess, lines: int = 8) -> str:
    text = (proc.stdout + "\n" + proc.stderr).strip().splitlines()
    return "\n".join(text[-lines:])


def _python(argv: list[str]) -> list[str]:
    """``argv`` with its interpreter replaced by the one running the tests (the venv's)."""
    return [sys.executable, *argv[1:]] if argv and argv[0] in PYTHONS else argv


# Runs a program up to and including its ArgumentParser.parse_args, then exits 0 with a marker:
# the arguments are parsed by the program's own parser and nothing else runs.
PARSE_ONLY = r"""
import argparse, runpy, sys
_parse = argparse.ArgumentParser.parse_args
def parse_args(self, args=None, namespace=None):
    _parse(self, args, namespace)
    print("\nARGUMENTS PARSED")
    sys.exit(0)
argparse.ArgumentParser.parse_args = parse_args
kind, target, *rest = sys.argv[1:]
sys.argv = [target, *rest]
if kind == "-m":
    runpy.run_module(target, run_name="__main__", alter_sys=True)
else:
    sys.path.insert(0, __import__("os").path.dirname(target))
    runpy.run_path(target, run_name="__main__")
"""
PARSED = "ARGUMENTS PARSED"


def _parse_only(kind: str, target: str, args: list[str], ctx: Context) -> list[str]:
    if kind == "-m":
        try:
            spec = find_spec(target)
        except ImportError:  # a missing parent package
            spec = None
        source = Path(spec.origin) if spec and spec.origin else None
    else:
        source = REPO / target
    if source is None or not source.is_file():
        return [f"no such {'module' if kind == '-m' else 'script'}: {target}"]
    if "ArgumentParser" not in source.read_text():
        return [f"no rule for this command: {target} is no argparse program, so its "
                "arguments cannot be checked without running it (add a rule here)"]  # fmt: skip
    proc = run([sys.executable, "-c", PARSE_ONLY, kind, target, *args], ctx)
    if proc.returncode != 0 or PARSED not in proc.stdout:
        return [f"{target} rejects its arguments (exit {proc.returncode}):\n{_tail(proc)}"]
    return []


# Rules ----------------------------------------------------------------------------------------

_snakemake_cache: dict[tuple[str, ...], list[str]] = {}


def parse_snakemake(args: list[str]) -> list[str]:
    """Failures of Snakemake's own argument and ``--config`` parsers on ``args`` (no run)."""
    from snakemake.cli import get_argument_parser, parse_config

    problems = [m] if (m := swallow_message(["snakemake", *args])) else []
    err = io.StringIO()
    try:
        with contextlib.redirect_stderr(err):
            parsed = get_argument_parser().parse_args(args)
    except SystemExit:
        lines = [ln for ln in err.getvalue().splitlines() if "error:" in ln]
        return [*problems, f"snakemake rejects the arguments: {' '.join(lines)}"]
    except Exception as exc:  # an option's own parser (e.g. --resources) raises
        return [*problems, f"snakemake rejects the arguments: {type(exc).__name__}: {exc}"]
    try:
        parse_config(parsed.config or [])
    except ValueError as exc:
        if not problems:
            problems.append(f"snakemake rejects --config: {exc}")
    return problems


def check_snakemake(argv: list[str], ctx: Context) -> list[str]:
    args = argv[3:] if argv[0] in PYTHONS else argv[1:]
    problems = parse_snakemake(args)
    if problems:
        return problems
    key = tuple(args)
    if key not in _snakemake_cache:
        workdir = ctx.scratch / "snakemake-workdir"
        workdir.mkdir(exist_ok=True)
        cmd = [sys.executable, "-m", "snakemake", *args, "--dry-run", "--quiet",
               "--directory", str(workdir)]  # fmt: skip
        proc = run(cmd, ctx)
        failed = f"the dry run fails (exit {proc.returncode}):\n{_tail(proc, 15)}"
        _snakemake_cache[key] = [] if proc.returncode == 0 else [failed]
    return _snakemake_cache[key]


def check_graspstab_config(argv: list[str], ctx: Context) -> list[str]:
    proc = run([sys.executable, *argv[1:]], ctx)
    return [] if proc.returncode == 0 else [f"exit {proc.returncode}: {_tail(proc)}"]


def check_python_script(argv: list[str], ctx: Context) -> list[str]:
    return _parse_only("script", argv[1], argv[2:], ctx)


def check_python_module(argv: list[str], ctx: Context) -> list[str]:
    problems = _parse_only("-m", argv[2], argv[3:], ctx)
    if argv[2] == "venv" and not problems:
        ctx.venvs.update(a for a in argv[3:] if not a.startswith("-"))
    return problems


def check_in_scratch(argv: list[str], ctx: Context) -> list[str]:
    """Run for real in the scratch folder (cheap, and its files are placeholders)."""
    proc = run(_python(argv), ctx, cwd=ctx.scratch)
    return [] if proc.returncode == 0 else [f"exit {proc.returncode}: {_tail(proc)}"]


def check_pytest(argv: list[str], ctx: Context) -> list[str]:
    args = argv[3:] if argv[0] in PYTHONS else argv[1:]
    cmd = [sys.executable, "-m", "pytest", *args, "--collect-only", "-q", "-n", "0",
           "-p", "no:cacheprovider", COLLECT_TARGET]  # fmt: skip
    proc = run(cmd, ctx)
    # 5: every test of the one file deselected by -m (no test collected), still a valid command
    return [] if proc.returncode in (0, 5) else [f"exit {proc.returncode}: {_tail(proc)}"]


def _ci_text() -> str:
    return (REPO / ".ci" / "run").read_text()


def check_pip(argv: list[str], ctx: Context) -> list[str]:
    args = argv[4:] if argv[0] in PYTHONS else argv[2:]
    if (argv[3] if argv[0] in PYTHONS else argv[1]) != "install" or not args:
        return ["no rule for this command: only `pip install` is checked"]
    pins = re.findall(r"torch==([\w.+]+)", _ci_text())
    extras_defined = tomllib.loads((REPO / "pyproject.toml").read_text())["project"][
        "optional-dependencies"
    ]
    problems = []
    if args[0].startswith("torch=="):
        if [args[0].split("==", 1)[1]] != pins or len(args) != 1:
            problems.append(f"{' '.join(args)}: .ci/run pins torch=={pins}")
    elif args[0] == "-e" and len(args) == 2:
        m = re.fullmatch(r"\.(?:\[([\w,-]+)\])?", args[1])
        if not m:
            problems.append(f"-e {args[1]}: expected the repository root, '.[EXTRAS]'")
        else:
            extras = (m.group(1) or "").split(",") if m.group(1) else []
            unknown = [e for e in extras if e not in extras_defined]
            if unknown:
                problems.append(f"extras {unknown} are not in pyproject.toml "
                                f"({sorted(extras_defined)})")  # fmt: skip
    else:
        problems.append(f"no rule for this command: pip install {' '.join(args)}")
    return problems


def check_activate(argv: list[str], ctx: Context) -> list[str]:
    if len(argv) == 2 and any(argv[1] == f"{v.rstrip('/')}/bin/activate" for v in ctx.venvs):
        return []
    return [f"{' '.join(argv)}: no earlier `python3 -m venv DIR` on this line creates it"]


def check_apt_get(argv: list[str], ctx: Context) -> list[str]:
    m = re.search(r'^PACKAGES="([^"]*)"', _ci_text(), re.M)
    known = set(m.group(1).split()) if m else set()
    if argv[1:3] != ["install", "-y"]:
        return ["no rule for this command: only `apt-get install -y PACKAGES` is checked"]
    unknown = [p for p in argv[3:] if p not in known]
    return [f"packages {unknown} are not among those .ci/run installs"] if unknown else []


# tool: number of subcommand words; tail, head, ls and grep read the run's logs
HELP_TOOLS = {"createdb": 0, "mkdocs": 1, "ruff": 1, "tail": 0, "head": 0, "ls": 0, "grep": 0}


def check_tee(argv: list[str], ctx: Context) -> list[str]:
    """``tee [-a] FILE``: copies its input to a file; nothing to parse but its options."""
    unknown = [a for a in argv[1:] if a.startswith("-") and a not in ("-a", "--append")]
    return [f"tee: options {unknown} are not checked"] if unknown else []


def check_help_tool(argv: list[str], ctx: Context) -> list[str]:
    sub = argv[1 : 1 + HELP_TOOLS[argv[0]]]
    try:
        proc = run([argv[0], *sub, "--help"], ctx)
    except FileNotFoundError:
        hint = (" (Debian: apt-get install -y postgresql-client; .ci/run installs postgresql)"
                if argv[0] == "createdb" else "")  # fmt: skip
        return [f"{argv[0]} is not on PATH{hint}"]
    if proc.returncode != 0:
        return [f"{' '.join([argv[0], *sub])} --help fails: {_tail(proc)}"]
    options = [a.split("=", 1)[0] for a in argv[1 + len(sub) :] if a.startswith("-")]
    unknown = [
        o for o in options if not re.search(rf"(?<![\w-]){re.escape(o)}(?![\w-])", proc.stdout)
    ]
    return [f"{' '.join([argv[0], *sub])} --help does not list {unknown}"] if unknown else []


def check_wrapped(argv: list[str], ctx: Context) -> list[str]:
    """``nohup CMD ...``: the command it runs, by that command's rule."""
    rule = rule_for(argv[1:]) if len(argv) > 1 else None
    if rule is None:
        return [f"no rule for this command: {shlex.join(argv[1:])}"]
    return rule[2](argv[1:], ctx)


def _is_python(argv: list[str], *then: str) -> bool:
    return argv[0] in PYTHONS and argv[1 : 1 + len(then)] == list(then)


Rule = tuple[str, Callable[[list[str]], bool], Callable[[list[str], Context], list[str]]]
RULES: list[Rule] = [
    ("snakemake", lambda a: a[0] == "snakemake" or _is_python(a, "-m", "snakemake"),
     check_snakemake),
    ("graspstab.config", lambda a: _is_python(a, "-m", "graspstab.config"),
     check_graspstab_config),
    ("pytest", lambda a: a[0] == "pytest" or _is_python(a, "-m", "pytest"), check_pytest),
    ("pip", lambda a: a[0] == "pip" or _is_python(a, "-m", "pip"), check_pip),
    ("python -c", lambda a: _is_python(a, "-c") and len(a) >= 3, check_in_scratch),
    ("checksum", lambda a: a[0] == "sha256sum" or a[:3] == ["shasum", "-a", "256"],
     check_in_scratch),
    ("python -m", lambda a: _is_python(a, "-m") and len(a) >= 3, check_python_module),
    ("python script", lambda a: len(a) >= 2 and a[0] in PYTHONS and a[1].endswith(".py"),
     check_python_script),
    ("activate", lambda a: a[0] in (".", "source"), check_activate),
    ("apt-get", lambda a: a[0] == "apt-get", check_apt_get),
    ("--help", lambda a: a[0] in HELP_TOOLS, check_help_tool),
    ("tee", lambda a: a[0] == "tee", check_tee),
    ("nohup", lambda a: a[0] == "nohup", check_wrapped),
]  # fmt: skip


def rule_for(argv: list[str]) -> Rule | None:
    return next((r for r in RULES if r[1](argv)), None)


def check_command(text: str, scratch: Path, env: dict[str, str]) -> list[str]:
    """Every failure of one documented command line (empty: it parses and would run)."""
    ctx = Context(scratch, env)
    try:
        words = tokens(substitute(text, scratch))
    except UnknownPlaceholder as exc:
        return [str(exc)]
    except ValueError as exc:
        return [f"not a shell command line ({exc}): {text}"]
    words = without_redirections(words, text)
    operators = [w for w in words if re.fullmatch(r"[();<>|&]+", w) and w not in SEPARATORS]
    if operators:
        return [f"no rule for this command: the operators {operators} are not checked"]
    problems = []
    for argv in parts(words):
        rule = rule_for(argv)
        if rule is None:
            problems.append(f"no rule for this command: {shlex.join(argv)}")
            continue
        problems += [f"{shlex.join(argv)}\n  -> {p}" for p in rule[2](argv, ctx)]
    return problems


def check_inline(text: str) -> list[str]:
    """Failures of a command shown outside a fenced block (not run): a target swallowed by
    ``--config``; for ``snakemake``, Snakemake's parsers."""
    try:
        words = shlex.split(text)  # no operators: a span shows one command, maybe <placeholders>
    except ValueError:
        words = text.split()  # a span that shows part of a quoted value
    if words and words[0] == "snakemake":
        return parse_snakemake(words[1:])
    message = swallow_message(words)
    return [message] if message else []


def all_fenced() -> Iterator[Command]:
    for path in doc_files():
        yield from fenced_commands(path)


def all_inline() -> Iterator[Command]:
    for path in doc_files():
        yield from inline_commands(path)
    for path in profile_configs():
        yield from comment_commands(path)
