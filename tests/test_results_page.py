"""docs/results.md and the README's headline table are exactly what the records under docs/runs/
give, and a record holds the figures a finished run's report shows, so no documented figure can
drift from the run that made it."""

from __future__ import annotations

import json
import shlex
import shutil
from pathlib import Path

import pytest

import graspstab
from graspstab.report import results_page as rp

REPO = Path(__file__).resolve().parents[1]


def _copy_docs(tmp_path: Path) -> Path:
    """README.md, docs/results.md and docs/runs/ in a scratch repository."""
    (tmp_path / "docs").mkdir()
    shutil.copy(REPO / "README.md", tmp_path / "README.md")
    shutil.copy(REPO / "docs" / "results.md", tmp_path / "docs" / "results.md")
    shutil.copytree(REPO / "docs" / "runs", tmp_path / "docs" / "runs")
    return tmp_path


def test_docs_match_the_records() -> None:
    assert rp.main(["render", "--check", "--repo", str(REPO)]) == 0, (
        "docs/results.md or README.md differ from docs/runs/: run "
        "`python -m graspstab.report.results_page render`"
    )


def test_every_profile_has_a_block() -> None:
    page = (REPO / "docs" / "results.md").read_text()
    profiles = {p.stem for p in (REPO / "config" / "profile").glob("*.yaml")}
    assert profiles == set(rp.PROFILES)
    for profile in rp.PROFILES:
        assert f"## {rp.TITLES[profile]}\n" in page


def test_a_changed_figure_is_caught(tmp_path: Path) -> None:
    repo = _copy_docs(tmp_path)
    quick = repo / "docs" / "runs" / "quick.json"
    rec = json.loads(quick.read_text())
    rec["headline"][0][2] = "12.34 ± 0.56 %"
    quick.write_text(json.dumps(rec))
    assert rp.main(["render", "--check", "--repo", str(repo)]) == 1
    assert rp.main(["render", "--repo", str(repo)]) == 0
    assert "12.34 ± 0.56" in (repo / "README.md").read_text()
    assert "12.34 ± 0.56" in (repo / "docs" / "results.md").read_text()
    assert rp.main(["render", "--check", "--repo", str(repo)]) == 0


def test_readme_needs_its_markers(tmp_path: Path) -> None:
    rec = json.loads((REPO / "docs" / "runs" / "quick.json").read_text())
    with pytest.raises(SystemExit, match="markers"):
        rp.render_readme("# no table here\n", rec)


def test_config_entries_stop_at_the_next_option() -> None:
    cmd = "snakemake --cores 2 results/report.html --config profile=study 'a={b: 1}' -n"
    assert rp.config_entries(cmd) == ["profile=study", "a={b: 1}"]
    assert rp.config_entries("snakemake --config x=1 -- results/report.html") == ["x=1"]
    assert rp.config_entries("snakemake --cores 2 results/report.html") == []


def test_time_and_memory_logs(tmp_path: Path) -> None:
    log = tmp_path / "snake.log"
    log.write_text(
        "128 of 128 steps (100%) done\n"
        "\tUser time (seconds): 2000.5\n\tSystem time (seconds): 99.5\n"
        "\tElapsed (wall clock) time (h:mm:ss or m:ss): 1:02:03\n"
    )
    assert rp.wall_and_cpu(log) == (3723.0, 2100.0)
    mem = tmp_path / "mem"
    mem.write_text("1 800\n3 2000\n5 1500\n")
    assert rp.memory_above_idle(mem) == (800.0, 1200.0)


def test_a_run_in_legs_sums_their_wall_and_cpu_and_says_so(tmp_path: Path) -> None:
    bench = tmp_path / "results" / "benchmarks" / "replay_grasps"
    bench.mkdir(parents=True)
    (bench / "a.tsv").write_text("s\th:m:s\tmax_rss\tmax_vms\tmax_uss\tmax_pss\tio_in\t"
                                 "io_out\tmean_load\tcpu_time\n60.0\t0:01:00\t500\t1\t1\t1\t"
                                 "0\t0\t100\t59\n")  # fmt: skip
    logs = []
    for i, (wall, user) in enumerate((("1:00:00", 3000.0), ("30:00", 1500.0))):
        logs.append(tmp_path / f"leg{i}.log")
        logs[-1].write_text(f"\tUser time (seconds): {user}\n\tSystem time (seconds): 0\n"
                            f"\tElapsed (wall clock) time (h:mm:ss or m:ss): {wall}\n")
    cost = rp._cost(tmp_path, logs, None)
    assert cost["wall_s"] == 5400.0 and cost["cpu_s"] == 4500.0
    assert cost["legs_wall_s"] == [3600.0, 1800.0] and cost["job_s"] == 60.0
    assert "legs_wall_s" not in rp._cost(tmp_path, logs[0], None)


@pytest.mark.workflow
def test_record_of_the_toy_run_holds_the_report_figures(run) -> None:
    workdir, _, config = run
    command = "snakemake --cores 2 results/report.html " + shlex.join(config)
    rec = rp.record(workdir, command, repo=REPO)
    html = (workdir / "results" / "report.html").read_text()
    # the headline figures are the report's, read from the same summaries
    for _, _, figure, _, _ in rec["headline"]:
        assert figure.split(" (")[0] in html, figure
    assert rec["commit"].split("-")[0] in html
    assert rec["version"] == graspstab.__version__  # the checkout's, not the environment's
    # every benchmarked job is counted; both protocols of the toy run are read
    tsv = list((workdir / "results" / "benchmarks").rglob("*.tsv"))
    assert rec["cost"]["jobs"] == len(tsv)
    assert set(rec["protocols"]) == {"reference", "creep_free"}
    summary = json.loads((workdir / "results/datasets/baseline/summary.json").read_text())
    test = summary["splits"]["test"]
    assert rec["protocols"]["reference"]["datasets"]["test"]["unstable"] == test["unstable"]
    assert rec["scale"]["seeds"] == [42]
    # each protocol's failure anatomy, as its job wrote it
    for name, root in (("reference", "results"), ("creep_free", "results/creep_free")):
        anatomy = json.loads((workdir / root / "replay" / "anatomy.json").read_text())
        kept = rec["protocols"][name]["anatomy"]
        assert kept == {k: anatomy[k] for k in rp.ANATOMY_KEYS}
        assert f"of {anatomy['usable']} usable grasps" in rp.anatomy_line(
            rec["protocols"][name], name)
    # and the record renders: its block names the commit and the command
    block = rp.profile_block(rec)
    assert rec["commit"][:7] in block and command in block


def test_cost_counts_only_the_jobs_after_since(tmp_path: Path) -> None:
    """A run that reused an earlier run's outputs in the same folder is costed by its own jobs."""
    import os

    bench = tmp_path / "results" / "benchmarks"
    header = "s\th:m:s\tmax_rss\n"
    for rule, seconds, mtime in (("old_rule", 100.0, 1_000.0), ("new_rule", 7.0, 2_000.0)):
        (bench / rule).mkdir(parents=True)
        f = bench / rule / "job.tsv"
        f.write_text(header + f"{seconds}\t0:00:00\t50\n")
        os.utime(f, (mtime, mtime))
    every = rp._cost(tmp_path, None, None)
    assert every["job_s"] == 107.0 and every["jobs"] == 2
    later = rp._cost(tmp_path, None, None, since=1_500.0)
    assert later["job_s"] == 7.0 and [r["rule"] for r in later["rules"]] == ["new_rule"]


def _still_record_block(n_unstable: int) -> dict:
    fig = {"mean": 0.95, "std": 0.01, "reason": "", "text": "95.00 ± 1.00 %"}
    families = ("cnn", "gru", "lstm")
    still_fig = {"mean": 0.41 if n_unstable else None, "std": 0.02 if n_unstable else None}
    return {
        "datasets": None,
        "baseline": {f: {"auprc": fig, "auroc": fig, "val_auprc": fig} for f in families},
        "proxy": {"mean": 0.9, "std": None, "reason": "", "text": "90.00 %"},
        "still": {
            **{f: {"auprc": still_fig, "auroc": still_fig} for f in families},
            "windows": {"n": 120.0, "n_unstable": float(n_unstable),
                        "chance": n_unstable / 120},
            "proxy": {"auprc": 0.3 if n_unstable else None, "auroc": 0.55 if n_unstable else None},
            "oracle": {"all": {"auprc": 0.99, "auroc": 0.98},
                       "still": {"auprc": n_unstable / 120 if n_unstable else None,
                                 "auroc": 0.5 if n_unstable else None}},
        },
    }  # fmt: skip


def test_still_now_table_and_sentence_from_the_record() -> None:
    """Prediction, not detection in docs/results.md and the README: the still-now figures beside
    the all-window ones, and the plain sentence when no still-now window becomes unstable."""
    from graspstab.report.results_page import still_table, still_text

    some = _still_record_block(12)
    table = still_table(some)
    assert "| GRU | 95.00 ± 1.00 | 41.00 ± 2.00 |" in table
    assert "| persistence oracle (reads object motion) | 99.00 | 10.00 |" in table
    assert "120, 12, 10.00" in table
    assert "On the 120 still-now test windows (12 unstable, chance 10.00 %)" in still_text(some)
    none = _still_record_block(0)
    assert "undefined (no still-now test window becomes unstable)" in still_table(none)
    assert "none becomes unstable" in still_text(none)
    # a record written before these figures: no table, no sentence
    old = {k: v for k, v in some.items() if k != "still"}
    assert still_table(old) is None and still_text(old) == ""


def test_anatomy_line_from_the_record() -> None:
    block = {"anatomy": {"protocol": "perturb", "usable": 10, "held": 4, "failed": 6,
                         "types": {"fingertip_slip": 2, "link_slip": 4, "rotation": 0},
                         "moving_at_settle": 1, "still_window": 5,
                         "onset_quartiles_s": [1.0, 2.0, 3.5]}}
    line = rp.anatomy_line(block, "hidden-onset disturbance")
    assert "of 10 usable grasps, 6 fail after settling (fingertip slip 2, link slip 4)" in line
    assert "median 2.00 s after settling (quartiles 1.00-3.50 s)" in line
    assert "1 of them already move" in line and "5 leave a still observation window" in line
    assert rp.anatomy_line({}, "x") is None


def test_crossval_answers_per_protocol_reach_the_page_and_the_readme(tmp_path: Path) -> None:
    """A wide record's per-protocol answers (all windows, still now, early warning over the
    folds) are written into docs/results.md and the README's across-objects block; a record of
    the older form (the reference summary itself) still renders."""
    results = tmp_path / "results"
    for root, name in ((results, "reference"), (results / "creep_free", "creep_free")):
        d = root / "studies" / "crossval"
        d.mkdir(parents=True)
        (d / "summary.json").write_text(json.dumps({
            "folds": 11, "objects": 44, "answer": f"ALL-{name}.",
            "answer_still": f"STILL-{name}."}))  # fmt: skip
        if name == "creep_free":
            (d / "early_warning.json").write_text(json.dumps(
                {"answer": "WARN-creep_free.", "monitors": {}, "paired": [], "thresholds": {}}))
    cv = rp._crossval(results)
    assert set(cv) == {"reference", "creep_free"} and cv["reference"]["early_warning"] is None
    rec = {"crossval": cv, "commit": "0123456789abcdef", "cost": {"wall_s": 600.0},
           "machine": {"cores": 2}}  # fmt: skip
    lines = rp.crossval_lines(rec)
    assert lines[0] == "**Cross-validation across objects, reference protocol**: ALL-reference. " \
        "STILL-reference."
    assert lines[1].endswith("ALL-creep_free. STILL-creep_free. WARN-creep_free.")
    assert "WARN-creep_free." in rp.readme_wide(rec) and "`0123456`" in rp.readme_wide(rec)
    assert "no run is recorded" in rp.readme_wide(None)
    assert rp.crossval_lines({"crossval": {"answer": "OLD."}}) == [
        "**Cross-validation across objects**: OLD."]
    quick = json.loads((REPO / "docs" / "runs" / "quick.json").read_text())
    readme = rp.render_readme((REPO / "README.md").read_text(), quick, rec)
    assert "WARN-creep_free." in readme
