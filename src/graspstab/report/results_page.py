"""docs/results.md and the README's headline table, written from finished runs' summaries, so no
figure in the docs can drift from the run that made it.

Two steps. ``record`` reads one finished run (its working directory: the summaries its jobs wrote,
its benchmark files, and optionally the ``/usr/bin/time -v`` log and ``free -m`` samples of the
``snakemake`` command) and writes a small JSON record of its figures. ``render`` writes
docs/results.md from every record under ``docs/runs/`` and the README's table between its markers;
``render --check`` fails when either differs from what the records give (a test runs it).

    python -m graspstab.report.results_page record <workdir> --command "snakemake ..." \
        [--time-log F] [--mem-log F] [--install-s S] [--out docs/runs/<profile>.json]
    python -m graspstab.report.results_page render [--check]
"""

from __future__ import annotations

import argparse
import json
import os
import re
import shlex
import sys
from collections.abc import Mapping, Sequence
from datetime import UTC, datetime
from pathlib import Path
from typing import Any

import polars as pl

from graspstab.common.io import read_json, read_parquet, write_text
from graspstab.common.provenance import cpu_model
from graspstab.figures.artefacts import StudyArtefacts
from graspstab.figures.presentation import UNDEFINED, family_label, finite
from graspstab.report.funnel import funnel_total, read_funnel
from graspstab.report.headline import (
    HEADLINE,
    baseline_figure,
    headline_rows,
    proxy_figure,
    run_scale,
)
from graspstab.report.provenance import git_commit, stage_times

REPO = Path(__file__).resolve().parents[3]
RUNS_DIR = Path("docs") / "runs"
PAGE = Path("docs") / "results.md"
README = Path("README.md")
#: The README's generated blocks: name -> its begin and end markers.
MARKERS = {
    name: (f"<!-- results:{name}:begin (python -m graspstab.report.results_page render) -->",
           f"<!-- results:{name}:end -->")
    for name in ("cost", "quick", "wide")
}  # fmt: skip
FAMILIES = ("cnn", "gru", "lstm")
#: The profiles the page has a block for, in order (config/profile/).
PROFILES = ("quick", "study", "closed_loop", "wide", "closed_loop_folds", "thesis")
PROTOCOLS = {"": "reference protocol (gravity)", "creep_free": "creep-free load ramp"}


# --- reading a finished run ---------------------------------------------------------------------


def wall_and_cpu(time_log: Path) -> tuple[float | None, float | None]:
    """Wall and user + system seconds from ``/usr/bin/time -v`` output (None when absent)."""
    text = time_log.read_text(errors="replace")
    wall = re.search(r"Elapsed \(wall clock\) time \(h:mm:ss or m:ss\): ([\d:.]+)", text)
    user = re.search(r"User time \(seconds\): ([\d.]+)", text)
    system = re.search(r"System time \(seconds\): ([\d.]+)", text)
    seconds = None
    if wall:
        parts = [float(p) for p in wall.group(1).split(":")]
        seconds = sum(p * 60**i for i, p in enumerate(reversed(parts)))
    cpu = float(user.group(1)) + float(system.group(1)) if user and system else None
    return seconds, cpu


def memory_above_idle(mem_log: Path) -> tuple[float, float]:
    """(idle MB, peak MB above idle) from ``<time> <used MB>`` lines; the first line is idle."""
    used = [float(line.split()[1]) for line in mem_log.read_text().splitlines() if line.strip()]
    if not used:
        raise SystemExit(f"{mem_log}: no '<time> <used MB>' lines")
    return used[0], max(used) - used[0]


def dir_mb(path: Path) -> float | None:
    """Disk use of a folder in MB (apparent sizes of its files), None when absent."""
    if not path.is_dir():
        return None
    total = 0
    for root, _, files in os.walk(path):
        for name in files:
            p = Path(root) / name
            if not p.is_symlink():
                total += p.stat().st_size
    return total / 1e6


def config_entries(command: str) -> list[str]:
    """The ``KEY=VALUE`` arguments of a ``snakemake ... --config ...`` command (up to ``--`` or
    the next option)."""
    args, out, on = shlex.split(command), [], False
    for a in args:
        if a == "--config":
            on = True
        elif a == "--" or (a.startswith("-") and on):
            on = False
        elif on:
            out.append(a)
    return out


def _studies(root: Path) -> StudyArtefacts:
    s = root / "studies"
    return StudyArtefacts(
        baseline_runs=s / "baseline" / "runs.parquet",
        baseline_summary_defined=s / "baseline" / "summary_defined.parquet",
        sweep_runs=s / "sweep" / "runs.parquet",
        sweep_summary_defined=s / "sweep" / "summary_defined.parquet",
        splits_overview=s / "splits" / "summary.json",
        latency=s / "latency.parquet",
        proxy=s / "proxy.json",
    )


def _fig(f: Any) -> dict[str, Any]:
    return {"mean": f.mean, "std": f.std, "reason": f.reason, "text": f.text()}


def _dataset(path: Path) -> dict[str, Any] | None:
    if not path.is_file():
        return None
    splits = read_json(path).get("splits", {})
    return {
        s: {k: int(splits.get(s, {}).get(k, 0)) for k in ("grasps", "stable", "unstable")}
        for s in ("train", "val", "test")
    }


#: what a record keeps of a protocol's failure anatomy (labels.summarise_anatomy's summary)
ANATOMY_KEYS = ("protocol", "usable", "held", "failed", "types", "moving_at_settle",
                "still_window", "onset_quartiles_s")  # fmt: skip


def _protocol_block(root: Path) -> dict[str, Any] | None:
    """One protocol's datasets, baseline figures, proxy and sweep (None when not run)."""
    a = _studies(root)
    if not Path(a.baseline_runs).is_file():
        return None
    block: dict[str, Any] = {"datasets": _dataset(root / "datasets" / "baseline" / "summary.json")}
    block["baseline"] = {
        f: {m: _fig(baseline_figure(a, f, "test", m)) for m in ("auprc", "auroc")}
        | {"val_auprc": _fig(baseline_figure(a, f, "val", "auprc"))}
        for f in FAMILIES
    }
    block["proxy"] = _fig(proxy_figure(a))
    if (still := _still_block(a)) is not None:
        block["still"] = still
    if (anatomy := _summary(root / "replay" / "anatomy.json")) is not None:
        block["anatomy"] = {k: anatomy[k] for k in ANATOMY_KEYS}
    if Path(a.sweep_runs).is_file():
        runs = read_parquet(a.sweep_runs).filter(pl.col("split") == "val")
        block["sweep"] = [
            {"family": r["family"], "window_s": float(r["window_s"]), "mean": r["mean"],
             "std": r["std"], "n": int(r["n"])}
            for r in runs.group_by("family", "window_s")
            .agg(pl.col("auprc").mean().alias("mean"), pl.col("auprc").std().alias("std"),
                 pl.len().alias("n"))
            .sort("family", "window_s").iter_rows(named=True)
        ]  # fmt: skip
    return block


def _still_block(a: StudyArtefacts) -> dict[str, Any] | None:
    """The test split's still-now figures (evaluation.detection), read as the jobs wrote them:
    each family's mean and std over seeds, the proxy's and the persistence oracle's blocks, and
    the still-now windows' count, positives and chance. None for a run without them."""
    path = Path(a.baseline_summary_defined)
    if not path.is_file() or not Path(a.proxy).is_file():
        return None
    summary = read_parquet(path).filter(pl.col("split") == "test")
    if "still_auprc_mean" not in summary.columns:
        return None
    rows = {r["family"]: r for r in summary.iter_rows(named=True)}
    proxy = read_json(a.proxy)

    def num(v: Any) -> float | None:
        return float(v) if finite(v) else None

    out: dict[str, Any] = {
        f: {m: {"mean": num(rows[f].get(f"still_{m}_mean")),
                "std": num(rows[f].get(f"still_{m}_std"))} for m in ("auprc", "auroc")}
        for f in FAMILIES if f in rows
    }  # fmt: skip
    block = proxy.get("test_still") or {}
    out["windows"] = {k: num(block.get(k)) for k in ("n", "n_unstable", "chance")}
    out["proxy"] = {m: num(block.get(m)) for m in ("auprc", "auroc")}
    oracle = proxy.get("persistence") or {}
    out["oracle"] = {part: {m: num((oracle.get(key) or {}).get(m)) for m in ("auprc", "auroc")}
                     for part, key in (("all", "test"), ("still", "test_still"))}  # fmt: skip
    return out


def _latency(path: Path) -> list[dict[str, Any]]:
    if not path.is_file():
        return []
    cols = ("study", "family", "window_s", "median_ms", "std_ms")
    t = read_parquet(path)
    return [dict(r) for r in t.select([c for c in cols if c in t.columns]).iter_rows(named=True)]


def _summary(path: Path) -> Any:
    return read_json(path) if path.is_file() else None


def _crossval(results: Path) -> dict[str, Any] | None:
    """Per cross-validated protocol, the k-fold study's answers (all windows, still now) and the
    folds' early warning (answer and per-monitor figures) when they ran."""
    out: dict[str, Any] = {}
    for name, root in (("reference", results), ("creep_free", results / "creep_free")):
        study = _summary(root / "studies" / "crossval" / "summary.json")
        if study is None:
            continue
        warning = _summary(root / "studies" / "crossval" / "early_warning.json")
        out[name] = {
            "folds": study.get("folds"), "objects": study.get("objects"),
            "answer": study.get("answer"), "answer_still": study.get("answer_still"),
            "early_warning": None if warning is None else {
                "answer": warning["answer"], "monitors": warning["monitors"],
                "paired": warning["paired"], "thresholds": warning["thresholds"],
            },
        }  # fmt: skip
    return out or None


def crossval_lines(rec: Mapping[str, Any]) -> list[str]:
    """One paragraph per cross-validated protocol: all windows, still now, early warning. A
    record from before the per-protocol form holds the reference's summary itself."""
    cv = rec.get("crossval")
    if not cv:
        return []
    if "answer" in cv or "verdicts" in cv:  # the reference protocol's summary (older records)
        answer = cv.get("answer") or cv.get("verdicts")
        return ["**Cross-validation across objects**: "
                + (json.dumps(answer) if not isinstance(answer, str) else answer)]  # fmt: skip
    lines = []
    for name, c in cv.items():
        title = {"reference": "reference protocol", "creep_free": "creep-free benchmark"}.get(
            name, name)  # the benchmark's load (ramp or hidden-onset) is the run's config
        text = f"**Cross-validation across objects, {title}**: {c['answer']}"
        if c.get("answer_still"):
            text += f" {c['answer_still']}"
        if c.get("early_warning"):
            text += f" {c['early_warning']['answer']}"
        lines.append(text)
    return lines


def _cost(
    workdir: Path, time_log: Path | Sequence[Path] | None, mem_log: Path | None,
    since: float | None = None,
) -> dict[str, Any]:  # fmt: skip
    """Job-seconds by rule from the benchmark files (only those written after ``since``, a Unix
    time, when given: the jobs of a run that reused another's), wall time, memory and disk.
    ``time_log``: one ``/usr/bin/time -v`` log, or one per leg of a run stopped and resumed in
    the same folder (their wall and CPU seconds are summed: an upper bound on one uninterrupted
    run, since jobs a stop cut short ran again)."""
    root = workdir / "results" / "benchmarks"
    benchmarks = {
        d.name: [p for p in sorted(d.glob("*.tsv")) if since is None or p.stat().st_mtime >= since]
        for d in sorted(root.iterdir())
        if d.is_dir()
    }
    benchmarks = {rule: paths for rule, paths in benchmarks.items() if paths}
    rows = sorted(stage_times(benchmarks), key=lambda r: -(r["job_s"] or 0.0))
    cost: dict[str, Any] = {
        "rules": [
            {k: r[k] for k in ("rule", "jobs", "job_s", "max_s", "peak_rss_mb")} for r in rows
        ],
        "job_s": sum(r["job_s"] or 0.0 for r in rows),
        "jobs": sum(r["jobs"] for r in rows),
        "disk_mb": {
            name: dir_mb(workdir / name)
            for name in ("results", ".graspstab-cache", "resources", ".venv")
        },
    }
    logs = [time_log] if isinstance(time_log, Path) else list(time_log or [])
    if logs:
        legs = [wall_and_cpu(p) for p in logs]
        walls, cpus = [w for w, _ in legs], [c for _, c in legs]
        cost["wall_s"] = None if None in walls else sum(walls)  # type: ignore[arg-type]
        cost["cpu_s"] = None if None in cpus else sum(cpus)  # type: ignore[arg-type]
        if len(logs) > 1:
            cost["legs_wall_s"] = walls
        text = logs[-1].read_text(errors="replace")
        done = re.findall(r"(\d+) of (\d+) steps \(100%\) done", text)
        cost["dag_jobs"] = int(done[-1][1]) if done else None
        rss = re.search(r"Maximum resident set size \(kbytes\): (\d+)", text)
        cost["snakemake_rss_mb"] = int(rss.group(1)) / 1024 if rss else None
    if mem_log is not None:
        cost["idle_mb"], cost["mem_peak_mb"] = memory_above_idle(mem_log)
    return cost


def _version(repo: Path) -> str:
    """The graspstab version of the checkout that ran (its pyproject.toml), not of this one."""
    import tomllib

    with open(repo / "pyproject.toml", "rb") as fh:
        return str(tomllib.load(fh)["project"]["version"])


def record(
    workdir: Path,
    command: str,
    time_log: Path | Sequence[Path] | None = None,
    mem_log: Path | None = None,
    install_s: float | None = None,
    repo: Path | None = None,
    note: str = "",
    since: float | None = None,
) -> dict[str, Any]:
    """The figures of one finished run in ``workdir``, from the summaries its jobs wrote;
    ``repo``: the workflow checkout that ran it (its config tree and commit; default the
    workdir, as in a clone); ``note``: anything a reader must know about how it was measured."""
    from graspstab.config.show import locate, resolved

    repo = workdir if repo is None else repo
    results = workdir / "results"
    if not (results / "report.html").is_file():
        raise SystemExit(f"{results / 'report.html'} is missing: is {workdir} a finished run?")
    config = resolved(*locate(repo / "config", None), config_entries(command))
    funnel = results / "report" / "funnel.parquet"
    dataset = results / "datasets" / "baseline" / "summary.json"
    scale = run_scale(
        config,
        len(list((results / "objects").glob("*/meta.json"))),
        funnel_total(read_funnel(funnel)) if funnel.is_file() else None,
        read_json(dataset) if dataset.is_file() else None,
    )
    scale["test_objects"] = sorted(
        p.parent.name for p in (results / "objects").glob("*/meta.json")
        if config["objects"]["items"].get(p.parent.name, {}).get("split") == "test"
    )
    studies = _studies(results)
    protocols = {
        name or "reference": block
        for name, block in (("", _protocol_block(results)),
                            ("creep_free", _protocol_block(results / "creep_free")))
        if block is not None
    }  # fmt: skip
    closed = {
        d.name: _summary(d / "summary.json")
        for d in sorted((results / "closed_loop" / "summary").glob("*"))
        if d.is_dir()
    }
    return {
        "profile": config.get("profile_name", "?"),
        "commit": git_commit(repo),
        "note": note,
        "version": _version(repo),
        "date": datetime.now(UTC).strftime("%Y-%m-%d"),
        "command": command,
        "machine": {
            "cpu": cpu_model(),
            "cores": os.cpu_count(),
            "memory_gb": round(os.sysconf("SC_PAGE_SIZE") * os.sysconf("SC_PHYS_PAGES") / 2**30),
        },
        "install_s": install_s,
        "cost": _cost(workdir, time_log, mem_log, since),
        "scale": scale,
        "headline": headline_rows(studies),
        "protocols": protocols,
        "splits": _summary(results / "studies" / "splits" / "summary.json"),
        "latency": _latency(results / "studies" / "latency.parquet"),
        "monitor": _summary(results / "monitor" / "summary.json"),
        "crossval": _crossval(results),
        "closed_loop": closed or None,
    }


# --- writing the page ---------------------------------------------------------------------------


def _pct(value: Any, digits: int = 2) -> str:
    return f"{100 * float(value):.{digits}f}" if finite(value) else "undefined"


def _pm(fig: Mapping[str, Any], digits: int = 2) -> str:
    if not finite(fig.get("mean")):
        return f"undefined ({fig.get('reason') or 'no value'})"
    if finite(fig.get("std")):
        return f"{_pct(fig['mean'], digits)} ± {_pct(fig['std'], digits)}"
    return _pct(fig["mean"], digits)


def _minutes(seconds: float | None) -> str:
    if seconds is None:
        return "not measured"
    h, rest = divmod(round(seconds), 3600)
    m, s = divmod(rest, 60)
    return f"{h} h {m:02d} min {s:02d} s" if h else f"{m} min {s:02d} s"


def _mb(value: float | None) -> str:
    if value is None:
        return "-"
    return f"{value / 1024:.1f} GB" if value >= 1024 else f"{value:,.0f} MB"


def _table(header: Sequence[str], rows: Sequence[Sequence[Any]], left: int = 1) -> str:
    """A Markdown table, its first ``left`` columns left-aligned and the rest right-aligned."""
    align = ["---"] * left + ["---:"] * (len(header) - left)
    lines = ["| " + " | ".join(header) + " |", "|" + "|".join(align) + "|"]
    lines += ["| " + " | ".join(str(c) for c in row) + " |" for row in rows]
    return "\n".join(lines)


def _short(commit: str) -> str:
    return commit[:7] + ("-dirty" if commit.endswith("-dirty") else "")


def chance(datasets: Mapping[str, Any] | None) -> float | None:
    """The test split's unstable share (the AUPRC of a scorer that knows nothing)."""
    if not datasets:
        return None
    t = datasets["test"]
    n = t["stable"] + t["unstable"]
    return t["unstable"] / n if n else None


def _run_lines(rec: Mapping[str, Any]) -> list[str]:
    m, c = rec["machine"], rec["cost"]
    busy = c["job_s"] / c["wall_s"] if c.get("wall_s") else None
    disk = ", ".join(
        f"`{k}/` {_mb(v)}" for k, v in c["disk_mb"].items() if v is not None
    )
    return [
        f"Commit `{_short(rec['commit'])}` (graspstab {rec['version']}), recorded {rec['date']} "
        f"on {m['cpu']} ({m['cores']} cores, {m['memory_gb']} GiB), from a fresh clone with the "
        "README's install line and local asset copies:",
        "",
        "```bash",
        rec["command"],
        "```",
        "",
        f"**Cost.** Install {_minutes(rec.get('install_s'))}; the command "
        f"**{_minutes(c.get('wall_s'))}** wall, {c['jobs']} jobs, {c['job_s']:,.0f} job-seconds"
        + (f" ({busy:.2f} cores busy)" if busy else "")
        + (f" (in {len(c['legs_wall_s'])} legs on the same folder, "
           f"{' + '.join(_minutes(w) for w in c['legs_wall_s'])}: the sum bounds one "
           "uninterrupted run from above, as the jobs a stop cut short ran again)"
           if c.get("legs_wall_s") else "")
        + (f"; the machine's used memory peaked **{_mb(c['mem_peak_mb'])}** above idle"
           if c.get("mem_peak_mb") is not None else "")
        + f", the largest job {_mb(max((r['peak_rss_mb'] or 0) for r in c['rules']))} RSS; "
        f"disk {disk}."
        + (f" {rec['note']}" if rec.get("note") else ""),
    ]  # fmt: skip


def _cost_table(rec: Mapping[str, Any], top: int = 10) -> str:
    c = rec["cost"]
    rows = [
        [r["rule"], r["jobs"], f"{r['job_s'] or 0:,.0f}",
         f"{(r['job_s'] or 0) / c['job_s']:.0%}" if c["job_s"] else "-",
         f"{r['max_s'] or 0:,.0f}", _mb(r["peak_rss_mb"])]
        for r in c["rules"][:top]
    ]  # fmt: skip
    rest = c["rules"][top:]
    if rest:
        s = sum(r["job_s"] or 0 for r in rest)
        share = f"{s / c['job_s']:.0%}" if c["job_s"] else "-"
        n = sum(r["jobs"] for r in rest)
        rows.append([f"everything else ({len(rest)} rules)", n, f"{s:,.0f}", share, "", ""])
    rows.append(["**total**", c["jobs"], f"**{c['job_s']:,.0f}**", "", "", ""])
    return _table(["rule", "jobs", "job-seconds", "share", "longest job [s]", "peak RSS"], rows)


def _datasets_line(rec: Mapping[str, Any]) -> str:
    s = rec["scale"]
    w = s.get("windows") or {}
    share = s.get("test_unstable_share")
    return (
        f"**Data.** {s['objects']} objects, {s['candidate_grasps']:,} candidate grasps annealed, "
        f"{s['usable_grasps'] if s['usable_grasps'] is not None else 'no'} usable grasps; "
        + " / ".join(f"{w.get(k, 0):,}" for k in ("train", "val", "test"))
        + " train / validation / test windows at the 0.2 s baseline window; chance (the test "
        f"split's unstable share) {_pct(share, 1)} %. Seeds {', '.join(map(str, s['seeds']))}, "
        f"at most {s['max_epochs']} epochs, {s['trials']} tuning trials per family. "
        f"Deviations from the reference: {', '.join(s['protocol']['deviations']) or 'none'}."
    )


def _headline_table(rec: Mapping[str, Any]) -> str:
    rows = [[sec, what, ref, run, gap] for sec, what, run, ref, gap in rec["headline"]]
    return _table(["section", "figure", "reference", "this run", "run - reference [points]"],
                  rows, left=2)  # fmt: skip


def _protocol_table(block: Mapping[str, Any]) -> str:
    rows = []
    for f in FAMILIES:
        b = block["baseline"][f]
        rows.append([family_label(f), _pm(b["auprc"]), _pm(b["auroc"]), _pm(b["val_auprc"])])
    rows.append(["friction-ratio proxy", _pm(block["proxy"]), "-", "-"])
    rows.append(["chance (test unstable share)", _pct(chance(block["datasets"])), "50.00", "-"])
    return _table(["scorer", "test AUPRC", "test AUROC", "validation AUPRC"], rows)


def _still_cell(fig: Mapping[str, Any] | None, reason: str) -> str:
    if not fig or fig.get("mean") is None:
        return f"{UNDEFINED} ({reason})"
    return _pm(fig) if "std" in fig else _pct(fig["mean"])


def _still_reason(block: Mapping[str, Any]) -> str:
    w = block["still"]["windows"]
    if not w.get("n"):
        return "no still-now test window"
    return "no still-now test window becomes unstable" if not w.get("n_unstable") else "no value"


def still_table(block: Mapping[str, Any]) -> str | None:
    """Prediction, not detection: test AUPRC and AUROC on all windows and on the still-now ones
    (the object still over the whole observation period), with the still-now windows' count,
    positives and chance; None for a record without them."""
    st = block.get("still")
    if not st:
        return None
    why = _still_reason(block)
    rows = []
    for f in FAMILIES:
        if f in st:
            b = block["baseline"][f]
            rows.append([family_label(f), _pm(b["auprc"]), _still_cell(st[f]["auprc"], why),
                         _pm(b["auroc"]), _still_cell(st[f]["auroc"], why)])  # fmt: skip
    proxy = {m: {"mean": st["proxy"][m]} for m in ("auprc", "auroc")}
    rows.append(["friction-ratio proxy", _pm(block["proxy"]), _still_cell(proxy["auprc"], why),
                 "-", _still_cell(proxy["auroc"], why)])  # fmt: skip
    o = st["oracle"]
    rows.append(["persistence oracle (reads object motion)",
                 _still_cell({"mean": o["all"]["auprc"]}, "no value"),
                 _still_cell({"mean": o["still"]["auprc"]}, why),
                 _still_cell({"mean": o["all"]["auroc"]}, "no value"),
                 _still_cell({"mean": o["still"]["auroc"]}, why)])  # fmt: skip
    w = st["windows"]
    rows.append(["still-now test windows: count, unstable, chance",
                 "-", f"{int(w['n'] or 0):,}, {int(w['n_unstable'] or 0):,}, "
                 f"{_still_cell({'mean': w['chance']}, 'no window')}", "-", "-"])  # fmt: skip
    return _table(["scorer", "test AUPRC, all windows", "still now", "test AUROC, all windows",
                   "still now"], rows)  # fmt: skip


def anatomy_line(block: Mapping[str, Any], title: str) -> str | None:
    """The failure anatomy of one protocol in a sentence (None for a record without it)."""
    a = block.get("anatomy")
    if not a:
        return None
    types = ", ".join(f"{t.replace('_', ' ')} {n}" for t, n in a["types"].items() if n)
    q = a["onset_quartiles_s"]
    onset = (f"; the failing motion begins a median {q[1]:.2f} s after settling (quartiles "
             f"{q[0]:.2f}-{q[2]:.2f} s)") if q[1] is not None else ""  # fmt: skip
    return (f"**Failure anatomy, {title}**: of {a['usable']} usable grasps, {a['failed']} fail "
            f"after settling ({types or 'no type'}){onset}. {a['moving_at_settle']} of them "
            f"already move at their settle index; {a['still_window']} leave a still observation "
            "window before their onset, the only failures an early warning can foresee.")


def _sweep_table(block: Mapping[str, Any]) -> str:
    sweep = block.get("sweep") or []
    windows = sorted({r["window_s"] for r in sweep})
    cell = {(r["family"], r["window_s"]): r for r in sweep}
    rows = []
    for f in FAMILIES:
        row = [family_label(f)]
        for w in windows:
            r = cell.get((f, w))
            row.append(_pm({"mean": r["mean"], "std": r["std"]}, 2) if r else "-")
        rows.append(row)
    return _table(["family"] + [f"{w:g} s" for w in windows], rows)


def _latency_table(rec: Mapping[str, Any]) -> str | None:
    rows = rec.get("latency") or []
    if not rows:
        return None
    return _table(
        ["study", "family", "window [s]", "median ± std [ms]"],
        [[r.get("study", "-"), family_label(r["family"]), f"{r['window_s']:g}",
               f"{r['median_ms']:.3f} ± {r.get('std_ms') or 0:.3f}"] for r in rows],
        left=2,
    )  # fmt: skip


def _splits_line(rec: Mapping[str, Any]) -> str | None:
    s = rec.get("splits")
    if not s:
        return None
    return (
        f"**Split robustness** (4.4): test AUPRC {_pm(s)} % over "
        f"{s.get('defined', '?')} of {s.get('assignments', '?')} sampled split assignments."
    )


def profile_block(rec: Mapping[str, Any]) -> str:
    """One profile's section body from its record."""
    parts = [
        "\n".join(_run_lines(rec)),
        _cost_table(rec),
        *([f"**On a cluster**: `{rec['cluster']['command']}` projects this run's own job graph "
           "and job timings onto N nodes:\n\n" + rec["cluster"]["markdown"].strip()]
          if rec.get("cluster") else []),
        _datasets_line(rec),
        "**Headline** (chapter-4 figures beside the reference's):",
        _headline_table(rec),
    ]
    order = {"reference": 0, "creep_free": 1}
    for name, block in sorted(rec["protocols"].items(), key=lambda kv: order.get(kv[0], 9)):
        title = PROTOCOLS.get("" if name == "reference" else name, name)
        parts.append(f"**Baseline at the 0.2 s window, {title}** (mean ± std over seeds, %):")
        parts.append(_protocol_table(block))
        if (still := still_table(block)) is not None:
            parts.append(
                f"**Prediction, not detection, {title}**: the same test windows, and those whose "
                "object is still over the whole observation period (*still now*: only foresight "
                "can rank them); the persistence oracle reads the object's motion, which no "
                "sensor sees, and is a reference line, never a monitor:"
            )
            parts.append(still)
        if (anatomy := anatomy_line(block, title)) is not None:
            parts.append(anatomy)
        if block.get("sweep"):
            parts.append(f"**Window sweep, {title}**: validation AUPRC (%), mean ± std over seeds:")
            parts.append(_sweep_table(block))
    if (line := _splits_line(rec)) is not None:
        parts.append(line)
    if (lat := _latency_table(rec)) is not None:
        parts.append("**Latency** (4.5): one window at batch 1 on one thread:")
        parts.append(lat)
    parts += crossval_lines(rec)
    for protocol, summary in (rec.get("closed_loop") or {}).items():
        if summary and summary.get("answer"):
            parts.append(f"**Closed loop, {protocol}**: {summary['answer']}")
    return "\n\n".join(parts)


INTRO = """\
# Results

<!-- Written by `python -m graspstab.report.results_page render` from the records in
docs/runs/; edit the script or rerun a profile, never this page. -->

The current figures of every profile, each block written by a script from the summaries of the
finished run it names (commit, command, machine), so that no figure here is typed by hand:

```bash
python -m graspstab.report.results_page record <clone> --command "<the snakemake command>" \\
    --time-log <clone>.snake.log --mem-log <clone>.mem --install-s <seconds> \\
    --out docs/runs/<profile>.json
python -m graspstab.report.results_page render
```

A run is measured from a fresh clone on the machine named in its block: the README's install
line, the assets from local copies (`GRASPSTAB_YCB_DIR`, `GRASPSTAB_HAND_DIR`), then the command
under `/usr/bin/time -v`, with the machine's used memory (`free -m`) sampled every 2 s. Figures
are percentages on the unseen test objects, mean ± std over seeds; chance is the test split's
unstable share, the AUPRC of a scorer that knows nothing (AUROC's chance is 50 %). How the
figures changed between versions, and why, is in the changelog (CHANGELOG.md in the repository).
What each protocol option changes is in [replay protocols](protocols.md); the extensions'
figures are explained in [extensions](extensions.md); how to read a report is in
[reading the report](report.md).

**Reproducibility.** A rerun repeats exactly on the same hardware and library build (CPU family,
BLAS build and thread count choose the kernels and the order of floating-point reductions). On
another machine the learning figures move within their seed spread, and the usable-grasp rule
can move a few grasps between datasets.

## The reference

Chapter 4 of the reference, five seeds (42-46), 43,978 / 12,052 / 14,587 training / validation /
test windows (4.1.1):

| section | figure | reference |
|---|---|---|
| 4.3 | GRU test AUPRC / AUROC, 0.2 s window | 98.43 ± 0.05 / 97.78 ± 0.07 % |
| 4.7 | CNN / GRU / LSTM test AUPRC (the saved checkpoints, fig. 4.10) | 98.03 / 98.34 / 98.41 % |
| 4.7 | friction-ratio proxy, test AUPRC | 96.27 % |
| 4.1.1 | chance: unstable share of the test windows | 59.2 % (8,632 of 14,587) |
| 4.4 | split robustness, the 0.01 s LSTM over 30 assignments | 97.14 ± 2.49 % |
| 4.5 | LSTM at 0.01 s, validation AUPRC (the latency-aware pick) | 98.747 ± 0.022 % |
"""

TITLES = {
    "quick": "Quick profile",
    "study": "Study profile",
    "closed_loop": "Closed-loop profile: does a warning save the grasp?",
    "wide": "Wide profile: generalisation across objects",
    "closed_loop_folds": "Closed loop over the folds: does a warning save the grasp on unseen "
                         "objects?",
    "thesis": "Thesis profile, projected",
}
COMMANDS = {
    "quick": "snakemake --cores 2 results/report.html",
    "study": "snakemake --cores 2 results/report.html --config profile=study",
    "closed_loop": "snakemake --cores 2 results/report.html --config profile=closed_loop",
    "wide": "snakemake --cores 2 results/report.html --config profile=wide",
    "closed_loop_folds": (
        "snakemake --cores 2 results/report.html --config profile=closed_loop_folds"
    ),
    "thesis": (
        "snakemake --profile workflow/profiles/slurm results/report.html --config profile=thesis"
    ),
}


#: profiles added after the results were first generated: no earlier figures exist
NEW_PROFILES = ("closed_loop_folds",)


def _missing_block(profile: str) -> str:
    before = ("No run of it has been made yet." if profile in NEW_PROFILES else
              "Its last figures measured before the results were generated are in the changelog "
              "(version 0.1.0).")  # fmt: skip
    return (
        f"No run of this profile has been recorded at the current version. Its command is "
        f"`{COMMANDS[profile]}`; record the finished run as above to add its block here. {before}"
    )


def projection_block(proj: Mapping[str, Any]) -> str:
    """The thesis profile's projected cost, from the harness's output on a recorded run."""
    run = proj["run"]
    return (
        "`config/profile/thesis.yaml` is the reference's scale with every reference protocol "
        "choice; it has not been run. Its cost is projected from the "
        f"{run['profile']} profile's run recorded above (commit `{_short(run['commit'])}`, "
        f"{run['machine']['cpu']}): each rule's measured throughput times the thesis workflow's "
        "units ([projecting costs](cluster.md#projecting-the-cost-before-you-run-it)), with\n\n"
        f"```bash\n{proj['command']}\n```\n\n" + proj["markdown"].strip()
    )


def load_records(repo: Path) -> dict[str, dict[str, Any]]:
    """Every record under docs/runs/ by profile (a projection record under its own key)."""
    out = {}
    for path in sorted((repo / RUNS_DIR).glob("*.json")):
        rec = json.loads(path.read_text())
        out[rec.get("profile", path.stem)] = rec
    return out


def render_page(records: Mapping[str, Mapping[str, Any]]) -> str:
    """docs/results.md from the records."""
    parts = [INTRO]
    for profile in PROFILES:
        parts.append(f"## {TITLES[profile]}")
        rec = records.get(profile)
        if profile == "thesis":
            proj = records.get("thesis_projection")
            parts.append(projection_block(proj) if proj else _missing_block(profile))
            continue
        parts.append(profile_block(rec) if rec else _missing_block(profile))
    return "\n\n".join(p.strip("\n") for p in parts) + "\n"


def readme_table(rec: Mapping[str, Any]) -> str:
    """The README's headline table: the reference beside the quick profile's record."""
    by = {what: (run, ref) for _, what, run, ref, _ in rec["headline"]}
    quick = rec["protocols"]["reference"]
    s = rec["scale"]
    w = s["windows"]

    def cell(what: str) -> str:
        return by[what][0].replace(" %", "") if what in by else "-"

    names = [h[1] for h in HEADLINE]
    rows = [
        ["GRU", "98.43 ± 0.05", cell(names[0])],
        ["CNN", "98.03", cell(names[3])],
        ["LSTM", "98.41", cell(names[5])],
        ["friction-ratio proxy", "96.27", cell(names[2])],
        ["chance (test unstable share)", "59.2", _pct(chance(quick["datasets"]), 1)],
        ["split robustness (0.01 s LSTM)", "97.14 ± 2.49 (30 splits)",
         f"{cell(names[6])} ({(rec.get('splits') or {}).get('assignments', '?')})"],
        ["seeds; train / val / test windows", "5; 43,978 / 12,052 / 14,587",
         f"{len(s['seeds'])}; {w['train']:,} / {w['val']:,} / {w['test']:,}"],
        ["measured at", "the reference",
         f"`{_short(rec['commit'])}`, `{rec['command']}`, {_minutes(rec['cost'].get('wall_s'))} "
         f"on {rec['machine']['cores']} cores"],
    ]  # fmt: skip
    return _table(["figure", "reference", "quick profile"], rows)


def readme_text(rec: Mapping[str, Any]) -> str:
    """What the table shows, in words: where the proxy stands against each family, on how many
    test objects and windows."""
    block = rec["protocols"]["reference"]
    proxy = block["proxy"].get("mean")
    fams = {f: block["baseline"][f]["auprc"].get("mean") for f in FAMILIES}
    defined = {f: v for f, v in fams.items() if finite(v)}
    if not defined or not finite(proxy):
        return "Some of the figures above are undefined; the table gives the reasons."
    best = max(defined, key=lambda f: defined[f])
    above = [family_label(f) for f, v in defined.items() if v > proxy]
    below = [family_label(f) for f, v in defined.items() if v <= proxy]
    w = rec["scale"]["windows"]
    gap = 100 * (defined[best] - proxy)
    objects = rec["scale"].get("test_objects") or []
    text = (
        f"These rest on {w['test']:,} test windows of {len(objects)} test objects "
        f"({', '.join(objects)}). The best learned model ({family_label(best)}) is "
        f"{abs(gap):.2f} AUPRC points {'above' if gap > 0 else 'below'} the one-frame "
        "friction-ratio proxy"
    )
    if below:
        text += f"; the proxy scores at or above the {' and the '.join(below)}"
    if above and below:
        text += f" and below the {' and the '.join(above)}"
    return text + "." + still_text(block)


def still_text(block: Mapping[str, Any]) -> str:
    """One sentence on the still-now test windows (early warning proper), from the record."""
    st = block.get("still")
    if not st:
        return ""
    w = st["windows"]
    n, pos = int(w.get("n") or 0), int(w.get("n_unstable") or 0)
    if n == 0:
        return " No test window has its object still over the whole observation period."
    if pos == 0:
        return (
            f" Of the {n:,} test windows whose object is still over the whole observation "
            "period, none becomes unstable: on this split every unstable window already moves "
            "while it is observed, so the figures above measure recognising motion under way, "
            "and early warning cannot be measured here."
        )
    cells = ", ".join(
        f"{family_label(f)} {_still_cell(st[f]['auprc'], 'undefined')}"
        for f in FAMILIES if f in st
    )  # fmt: skip
    return (
        f" On the {n:,} still-now test windows ({pos:,} unstable, chance "
        f"{_pct(w.get('chance'))} %), test AUPRC is {cells}, proxy "
        f"{_still_cell({'mean': st['proxy']['auprc']}, 'undefined')}: early warning proper."
    )


def readme_cost(rec: Mapping[str, Any]) -> str:
    """The README's quick-start table: what the install and the quick profile take."""
    c = rec["cost"]
    disk = c["disk_mb"]
    rest = ", ".join(f"`{k}/` {_mb(v)}" for k, v in disk.items() if v is not None and k != ".venv")
    largest = max((r["peak_rss_mb"] or 0) for r in c["rules"])
    rows = [
        ["install", _minutes(rec.get("install_s")), "-", f"{_mb(disk.get('.venv'))} (`.venv/`)"],
        [f"`{rec['command']}`",
         f"{_minutes(c.get('wall_s'))} ({c['jobs']} jobs, {c['job_s']:,.0f} job-seconds)",
         f"peak {_mb(c.get('mem_peak_mb'))} above idle (largest job {_mb(largest)})", rest],
    ]  # fmt: skip
    m = rec["machine"]
    text = (
        f"Recorded at `{_short(rec['commit'])}` on {m['cpu']} ({m['cores']} cores)."
        + (f" {rec['note']}" if rec.get("note") else "")
    )
    return _table(["step", "wall time", "memory", "disk"], rows, left=4) + "\n\n" + text


def readme_wide(rec: Mapping[str, Any] | None) -> str:
    """The README's across-objects paragraph: the wide profile's answers per protocol, or that
    no run of it is recorded."""
    lines = crossval_lines(rec) if rec else []
    if not lines:
        return ("Across objects (the `wide` profile) no run is recorded at the current version, "
                "so [`docs/results.md`](docs/results.md) has no figures for it.")  # fmt: skip
    return (f"Across objects (the `wide` profile, `{_short(rec['commit'])}`, "  # type: ignore[index]
            f"{_minutes(rec['cost'].get('wall_s'))} on {rec['machine']['cores']} cores; "  # type: ignore[index]
            "intervals are 95 % bootstrap over objects):\n\n" + "\n\n".join(lines))


def render_readme(readme: str, rec: Mapping[str, Any],
                  wide: Mapping[str, Any] | None = None) -> str:  # fmt: skip
    """The README with each generated block between its markers replaced from the quick
    record (and the wide profile's, for the across-objects block)."""
    bodies = {
        "cost": readme_cost(rec),
        "quick": readme_table(rec) + "\n\n" + readme_text(rec),
        "wide": readme_wide(wide),
    }
    for name, (begin_mark, end_mark) in MARKERS.items():
        begin, end = readme.find(begin_mark), readme.find(end_mark)
        if begin < 0 or end < begin:
            raise SystemExit(f"README.md lacks the markers {begin_mark!r} ... {end_mark!r}")
        cut = begin + len(begin_mark)
        readme = readme[:cut] + "\n" + bodies[name] + "\n" + readme[end:]
    return readme


def main(argv: Sequence[str] | None = None) -> int:
    ap = argparse.ArgumentParser(prog="python -m graspstab.report.results_page",
                                 description=__doc__.splitlines()[0])  # fmt: skip
    sub = ap.add_subparsers(dest="cmd", required=True)
    rec = sub.add_parser("record", help="write a finished run's record (JSON)")
    rec.add_argument("workdir", type=Path)
    rec.add_argument("--command", required=True, help="the snakemake command the run used")
    rec.add_argument("--time-log", type=Path, nargs="+",
                     help="/usr/bin/time -v output of that command (several: the legs of a run "
                          "stopped and resumed in the same folder, summed)")  # fmt: skip
    rec.add_argument("--mem-log", type=Path, help="'<unix time> <used MB>' samples (free -m)")
    rec.add_argument("--install-s", type=float, help="seconds the install line took")
    rec.add_argument("--repo", type=Path, help="the checkout that ran it (default: workdir)")
    rec.add_argument("--note", default="", help="how it was measured, where that matters")
    rec.add_argument("--since", type=float,
                     help="count only jobs whose benchmark file is newer (Unix time): a run "
                          "that reused an earlier run's outputs in the same folder")  # fmt: skip
    rec.add_argument("--cluster", type=Path,
                     help="benchmarks/project_cluster.py's output for this run (markdown)")
    rec.add_argument("--cluster-command", default="",
                     help="the command that printed it (shown beside the projection)")
    rec.add_argument("--out", type=Path, help="record file (default: stdout)")
    pro = sub.add_parser("projection", help="record the thesis projection of a recorded run")
    pro.add_argument("markdown", type=Path, help="benchmarks/project_thesis.py's output")
    pro.add_argument("--command", required=True, help="the command that printed it")
    pro.add_argument("--run", type=Path, required=True, help="the record of the run it read")
    pro.add_argument("--out", type=Path, default=RUNS_DIR / "thesis_projection.json")
    ren = sub.add_parser("render", help="write docs/results.md and the README's table")
    ren.add_argument("--repo", type=Path, default=REPO)
    ren.add_argument("--check", action="store_true", help="fail if either file would change")
    args = ap.parse_args(argv)
    if args.cmd == "record":
        data = record(args.workdir, args.command, args.time_log, args.mem_log, args.install_s,
                      args.repo, args.note, args.since)  # fmt: skip
        if args.cluster is not None:
            data["cluster"] = {"command": args.cluster_command,
                               "markdown": args.cluster.read_text()}  # fmt: skip
        text = json.dumps(data, indent=1, sort_keys=True, default=str) + "\n"
        if args.out is None:
            sys.stdout.write(text)
        else:
            write_text(args.out, text)
        return 0
    if args.cmd == "projection":
        run = json.loads(args.run.read_text())
        data = {"profile": "thesis_projection", "command": args.command,
                "run": {k: run[k] for k in ("profile", "commit", "command", "machine")},
                "markdown": args.markdown.read_text()}  # fmt: skip
        write_text(args.out, json.dumps(data, indent=1, sort_keys=True) + "\n")
        return 0
    records = load_records(args.repo)
    outputs = {args.repo / PAGE: render_page(records)}
    if "quick" in records:
        readme = (args.repo / README).read_text()
        outputs[args.repo / README] = render_readme(readme, records["quick"], records.get("wide"))
    stale = [p for p, text in outputs.items() if not p.is_file() or p.read_text() != text]
    if args.check:
        for p in stale:
            print(f"{p} is out of date with docs/runs/: run "
                  "`python -m graspstab.report.results_page render`", file=sys.stderr)  # fmt: skip
        return 1 if stale else 0
    for p in stale:
        write_text(p, outputs[p])
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
