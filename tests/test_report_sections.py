"""The summaries the report renders (the replay outcome table, the grasp funnel, the studies' seed
summaries) against brute-force computations on small constructed tables, and the report's
sections reading them as written: the report computes none of these numbers itself."""

from __future__ import annotations

import ast
import math
import statistics
from pathlib import Path
from typing import Any

import numpy as np
import polars as pl
import pytest

from graspstab.common.io import read_parquet, read_parquet_metadata, write_json, write_parquet
from graspstab.evaluation import aggregate
from graspstab.figures.artefacts import StudyArtefacts
from graspstab.figures.presentation import defined_summary
from graspstab.labels.funnel import funnel, summarise_funnel
from graspstab.replay.outcomes import COLUMNS, replay_outcomes, summarise_replays
from graspstab.report import creep_free as cf
from graspstab.report.funnel import funnel_total, read_funnel
from graspstab.report.headline import baseline_figure, sweep_figure
from graspstab.report.replay import outcome_rows, replay_parts
from tests.conftest import REPO

NAN = float("nan")
STOPS = ("completed", "contact_lost", "too_deep", "diverged")


def _replays(seed: int, objects: dict[str, int], ramp: bool) -> pl.DataFrame:
    """A replay table as replay_grasps writes it (the columns the summary reads), with every stop
    reason, NaN where a ramp replay never slid or never lost contact."""
    rng = np.random.default_rng(seed)
    rows = []
    for obj, n in objects.items():
        for g in range(n):
            stop = STOPS[int(rng.integers(len(STOPS)))]
            row: dict[str, Any] = {
                "grasp_id": g, "object": obj, "shard": g % 2, "stop_reason": stop,
                "diverged": stop == "diverged", "held_at_end": bool(rng.random() < 0.4),
                "max_penetration": float(rng.uniform(0, 0.01)),
                "duration_s": float(rng.uniform(0.5, 20.0)),
            }  # fmt: skip
            if ramp:
                slip = float(rng.uniform(0.5, 3.0)) if rng.random() < 0.6 else NAN
                loss = slip + float(rng.uniform(0.0, 2.0)) if rng.random() < 0.7 else NAN
                row |= {"ramp_slip_s": slip, "contact_loss_s": loss,
                        "ramp_peak_load_mg": float(rng.uniform(0.1, 3.0))}  # fmt: skip
            rows.append(row)
    return pl.DataFrame(rows)


def _brute(rows: list[dict[str, Any]], ramp: bool) -> dict[str, Any]:
    """The outcome columns by hand: loops, counts and statistics.median."""
    out: dict[str, Any] = {
        "replays": len(rows),
        "held": sum(1 for r in rows if r["held_at_end"]),
        "contact_lost": sum(1 for r in rows if r["stop_reason"] == "contact_lost"),
        "too_deep": sum(1 for r in rows if r["stop_reason"] == "too_deep"),
        "diverged": sum(1 for r in rows if r["diverged"]),
        "median_max_penetration_m": statistics.median(r["max_penetration"] for r in rows),
        "simulated_s": math.fsum(r["duration_s"] for r in rows),
        "slid": None, "median_slip_to_loss_s": None, "median_peak_load_mg": None,
    }  # fmt: skip
    if ramp:
        slid = [r for r in rows if not math.isnan(r["ramp_slip_s"])]
        gaps = [r["contact_loss_s"] - r["ramp_slip_s"] for r in slid
                if not math.isnan(r["contact_loss_s"])]  # fmt: skip
        out["slid"] = len(slid)
        out["median_slip_to_loss_s"] = statistics.median(gaps) if gaps else None
        out["median_peak_load_mg"] = statistics.median(r["ramp_peak_load_mg"] for r in rows)
    return out


def _close(got: dict[str, Any], want: dict[str, Any]) -> None:
    assert set(got) == set(want)
    for k, v in want.items():
        if isinstance(v, float):
            assert got[k] == pytest.approx(v, rel=1e-12, abs=1e-15), k
        else:
            assert got[k] == v, k


@pytest.mark.parametrize("ramp", [False, True])
def test_replay_outcomes_match_a_brute_force_count(ramp: bool) -> None:
    table = _replays(3, {"b_obj": 9, "a_obj": 14, "c_obj": 1}, ramp)
    out = replay_outcomes(table)
    assert list(out.columns) == list(COLUMNS) and dict(out.schema) == COLUMNS
    assert out["object"].to_list() == ["a_obj", "b_obj", "c_obj", None]  # sorted, total last
    rows = table.to_dicts()
    for got in out.iter_rows(named=True):
        obj = got.pop("object")
        mine = [r for r in rows if obj is None or r["object"] == obj]
        _close(got, _brute(mine, ramp))
    total = out.row(-1, named=True)
    assert total["replays"] == table.height == out["replays"][:-1].sum()


def test_replay_outcomes_of_an_empty_protocol_and_of_mixed_tables(tmp_path: Path) -> None:
    """Shards concatenate whatever their columns; a ramp that never slid has no median."""
    table = _replays(5, {"a_obj": 4}, ramp=True).with_columns(
        pl.lit(NAN).alias("ramp_slip_s")
    )
    total = replay_outcomes(table).row(-1, named=True)
    assert total["slid"] == 0 and total["median_slip_to_loss_s"] is None
    paths = []
    for k, part in enumerate((_replays(1, {"a_obj": 3}, False), _replays(2, {"b_obj": 2}, False))):
        paths.append(tmp_path / f"replays_{k}.parquet")
        write_parquet(paths[-1], part)
    out = summarise_replays(paths, tmp_path / "outcomes.parquet", "gravity")
    assert out.equals(read_parquet(tmp_path / "outcomes.parquet"))
    assert out["replays"].to_list() == [3, 2, 5]
    meta = read_parquet_metadata(tmp_path / "outcomes.parquet")
    assert meta["protocol"] == "gravity" and meta["provenance"]["stage"] == "replay"
    assert meta["provenance"]["params"] == {"protocol": "gravity"}


def _dataset(per_object: dict[str, dict[str, dict[str, int]]]) -> dict[str, Any]:
    empty = {"grasps": 0, "stable": 0, "unstable": 0}
    objects = {o: {s: {**empty, **c.get(s, {})} for s in ("train", "val", "test")}
               for o, c in per_object.items()}  # fmt: skip
    return {"objects": objects}


def test_funnel_matches_a_brute_force_count(tmp_path: Path) -> None:
    table = _replays(7, {"a_obj": 6, "b_obj": 5}, ramp=False)
    summaries = [{"object_id": "a_obj", "grasps": 8}, {"object_id": "b_obj", "grasps": 5},
                 {"object_id": "c_obj", "grasps": 2}]  # fmt: skip
    dataset = _dataset({"a_obj": {"train": {"grasps": 3, "stable": 20, "unstable": 6}},
                        "b_obj": {"test": {"grasps": 2, "stable": 7, "unstable": 1},
                                  "val": {"grasps": 1, "stable": 4, "unstable": 0}}})  # fmt: skip
    rows = funnel(summaries, replay_outcomes(table), dataset)
    replays = table.to_dicts()
    for row in rows[:-1]:
        obj = row["object"]
        mine = [r for r in replays if r["object"] == obj]
        counts = dataset["objects"].get(obj)
        want = {
            "object": obj,
            "annealed": next(s["grasps"] for s in summaries if s["object_id"] == obj),
            "replayed": len(mine) if mine else None,
            "diverged": sum(r["diverged"] for r in mine) if mine else None,
            "held": sum(r["held_at_end"] for r in mine) if mine else None,
            "usable": sum(c["grasps"] for c in counts.values()) if counts else 0,
            "windows": sum(c["stable"] + c["unstable"] for c in counts.values()) if counts else 0,
            "unstable": sum(c["unstable"] for c in counts.values()) if counts else 0,
        }
        assert row == want, obj
    total = rows[-1]
    assert total["object"] is None
    assert total["annealed"] == 15 and total["usable"] == 6 and total["windows"] == 38
    assert total["replayed"] is None  # c_obj was never replayed: no total, not a partial one
    # written by the job and read back by the report: the same rows, the total named
    write_json(tmp_path / "dataset.json", dataset)
    paths = []
    for s in summaries:
        paths.append(tmp_path / f"{s['object_id']}.json")
        write_json(paths[-1], s)
    write_parquet(tmp_path / "outcomes.parquet", replay_outcomes(table))
    summarise_funnel(paths, tmp_path / "outcomes.parquet", tmp_path / "dataset.json",
                             tmp_path / "funnel.parquet")  # fmt: skip
    back = read_funnel(tmp_path / "funnel.parquet")
    assert back[:-1] == rows[:-1] and back[-1] == {**total, "object": "all objects"}
    assert funnel_total(back) == back[-1] and funnel_total(None) is None


def _runs() -> pl.DataFrame:
    """Runs of two families and two windows over three seeds: NaN ranking metrics on a split
    without unstable windows, 0/0 precision where nothing is predicted unstable."""
    rng = np.random.default_rng(11)
    rows = []
    for family in ("cnn", "gru"):
        for window in (0.01, 0.02):
            for seed in (1, 2, 3):
                for split in ("val", "test"):
                    no_pos = split == "val" and family == "gru"
                    tp = 0 if no_pos else int(rng.integers(0, 4))
                    fp = 0 if (family == "cnn" and seed == 2) else int(rng.integers(0, 3))
                    fn = 0 if no_pos else int(rng.integers(1, 4))
                    tn = int(rng.integers(5, 9))
                    prec = tp / (tp + fp) if tp + fp else 0.0
                    rec = tp / (tp + fn) if tp + fn else 0.0
                    f1 = 2 * prec * rec / (prec + rec) if prec + rec else 0.0
                    rows.append({
                        "window_s": window, "family": family, "seed": seed, "split": split,
                        "n": tp + fp + fn + tn, "n_unstable": tp + fn, "tp": float(tp),
                        "fp": float(fp), "fn": float(fn), "tn": float(tn), "precision": prec,
                        "recall": rec, "f1": f1,
                        "auprc": NAN if no_pos else float(rng.uniform(0.3, 1.0)),
                        "auroc": NAN if no_pos else float(rng.uniform(0.3, 1.0)),
                        "accuracy": (tp + tn) / (tp + fp + fn + tn),
                    })  # fmt: skip
    return pl.DataFrame(rows)


def test_seed_summary_matches_a_brute_force_mean_and_std() -> None:
    runs = _runs()
    by = ["family", "window_s", "split"]
    summary = aggregate.seed_summary(runs, by)
    # the metrics are exactly what the report used to compute itself
    assert summary.drop("no_unstable", "no_stable").equals(defined_summary(runs, by))
    rows = runs.to_dicts()
    for got in summary.iter_rows(named=True):
        mine = [r for r in rows if all(r[k] == got[k] for k in by)]
        assert got["seeds"] == len({r["seed"] for r in mine})
        assert got["no_unstable"] == all(r["n_unstable"] == 0 for r in mine)
        assert got["no_stable"] == all(r["n_unstable"] == r["n"] for r in mine)
        for metric in ("auprc", "precision", "recall", "f1", "accuracy"):
            values = []
            for r in mine:
                v = r[metric]
                if metric == "recall" and r["tp"] + r["fn"] == 0:
                    v = NAN
                if metric == "precision" and r["tp"] + r["fp"] == 0:
                    v = NAN
                if metric == "f1" and 2 * r["tp"] + r["fp"] + r["fn"] == 0:
                    v = NAN
                if not math.isnan(v):
                    values.append(v)
            assert got[f"{metric}_n"] == len(values), metric
            if values:
                assert got[f"{metric}_mean"] == pytest.approx(statistics.fmean(values))
            else:
                assert got[f"{metric}_mean"] is None
            if len(values) > 1:
                assert got[f"{metric}_std"] == pytest.approx(statistics.stdev(values))
            else:
                assert got[f"{metric}_std"] is None


def test_the_headline_reads_the_seed_summary_not_the_runs(tmp_path: Path) -> None:
    runs = _runs()
    base = runs.filter(pl.col("window_s") == 0.01).drop("window_s")
    write_parquet(tmp_path / "b.parquet", aggregate.seed_summary(base, ["family", "split"]))
    write_parquet(tmp_path / "s.parquet",
                  aggregate.seed_summary(runs, ["family", "window_s", "split"]))  # fmt: skip
    a = StudyArtefacts(baseline_summary_defined=tmp_path / "b.parquet",
                       sweep_summary_defined=tmp_path / "s.parquet",
                       baseline_runs=tmp_path / "absent.parquet",
                       sweep_runs=tmp_path / "absent.parquet")  # fmt: skip
    test = base.filter((pl.col("family") == "cnn") & (pl.col("split") == "test"))["auprc"]
    fig = baseline_figure(a, "cnn", "test", "auprc")
    assert fig.mean == pytest.approx(test.mean()) and fig.std == pytest.approx(test.std())
    assert baseline_figure(a, "gru", "val", "auprc").text() == (
        "undefined (the validation split holds no unstable window)"
    )
    assert baseline_figure(a, "lstm", "test", "auprc").reason.startswith("no LSTM run")
    val = runs.filter((pl.col("family") == "cnn") & (pl.col("window_s") == 0.02)
                      & (pl.col("split") == "val"))["auprc"]  # fmt: skip
    fig = sweep_figure(a, "cnn", 0.02)
    assert fig.mean == pytest.approx(val.mean()) and fig.std == pytest.approx(val.std())
    assert sweep_figure(a, "gru", 0.02).text() == (
        "undefined (the validation split holds no unstable window)"
    )
    assert "windows [s]: 0.01, 0.02" in sweep_figure(a, "cnn", 0.05).reason
    missing = StudyArtefacts(baseline_summary_defined=tmp_path / "none.parquet")
    assert "none.parquet not produced" in baseline_figure(missing, "cnn", "test", "auprc").text()


def test_the_replay_sections_render_the_outcome_table(tmp_path: Path) -> None:
    gravity = replay_outcomes(_replays(4, {"a_obj": 5, "b_obj": 3}, ramp=False))
    ramp = replay_outcomes(_replays(4, {"a_obj": 5, "b_obj": 3}, ramp=True))
    write_parquet(tmp_path / "g.parquet", gravity)
    write_parquet(tmp_path / "r.parquet", ramp)
    assert [r["object"] for r in outcome_rows(tmp_path / "g.parquet")] == ["a_obj", "b_obj"]
    html = "".join(replay_parts(tmp_path / "g.parquet", {}))
    a = gravity.row(0, named=True)
    cells = [a["replays"], a["held"], a["contact_lost"], a["too_deep"], a["diverged"],
             f"{a['median_max_penetration_m'] * 1000:.1f}", f"{a['simulated_s']:.0f}", "n/a"]
    assert "<tr><td>a_obj</td>" + "".join(f"<td>{c}</td>" for c in cells) + "</tr>" in html
    assert replay_parts(None, {}) == []
    studies_ = StudyArtefacts()
    main = cf.Benchmark("g", tmp_path / "d", tmp_path / "s", tmp_path / "g.parquet", studies_)
    assert cf.replay_outcomes(main) == {"grasps": 8, "held": gravity["held"][-1],
                                        "lost": gravity["contact_lost"][-1],
                                        "too_deep": gravity["too_deep"][-1],
                                        "diverged": gravity["diverged"][-1]}  # fmt: skip
    total = ramp.row(-1, named=True)
    got = cf.replay_outcomes(
        cf.Benchmark("r", tmp_path / "d", tmp_path / "s", tmp_path / "r.parquet", studies_)
    )
    assert got["slid"] == total["slid"] and got["slip_to_loss_s"] == total["median_slip_to_loss_s"]


def test_no_report_module_aggregates_runs_or_replay_tables() -> None:
    """The means over seeds and the replay counts come from the jobs' summaries: no report module
    calls the seed summary or the replay outcome functions (or their building blocks)."""
    banned = {"defined_summary", "mean_std", "seed_summary", "undefined_as_nan",
              "replay_outcomes", "funnel"}  # fmt: skip
    for path in sorted((REPO / "src" / "graspstab" / "report").glob("*.py")):
        tree = ast.parse(path.read_text())
        for node in ast.walk(tree):
            if isinstance(node, ast.ImportFrom) and node.module and node.module.startswith(
                ("graspstab.evaluation", "graspstab.figures.presentation")
            ):
                assert not {a.name for a in node.names} & banned, (path.name, node.module)


def test_threshold_rules_match_a_brute_force_count() -> None:
    runs = _runs().with_columns(
        pl.Series("threshold_rule", ["min_recall", "best_f1", "undefined", "odd"] * 6)
    )
    got = aggregate.threshold_rules(runs)
    val = [r for r in runs.to_dicts() if r["split"] == "val"]
    order: list[str] = []
    for r in val:
        if r["threshold_rule"] not in order:
            order.append(r["threshold_rule"])
    nan = [r for r in val if math.isnan(r["auprc"]) or math.isnan(r["auroc"])]
    assert got == {
        "runs": len(val),
        "rules": [[k, sum(r["threshold_rule"] == k for r in val)] for k in order],
        "undefined_validation_metrics": len(nan),
        "no_unstable": sum(r["n_unstable"] == 0 for r in nan),
        "no_stable": sum(r["n_unstable"] == r["n"] for r in nan),
    }
    assert got["undefined_validation_metrics"] == 6  # the GRU's validation runs
