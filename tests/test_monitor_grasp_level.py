"""Grasp-level evaluation: hand-made replays with known onsets and warnings, the proxy as a
monitor against brute force, the rule's entry point on a real checkpoint, figures, exports."""

from __future__ import annotations

import io
import json
import re
from pathlib import Path
from typing import Any

import numpy as np
import polars as pl
import pytest
import torch
import yaml
from PIL import Image

from graspstab.common.io import load_npz, read_json, write_json, write_parquet
from graspstab.evaluation.proxy import friction_ratio
from graspstab.evaluation.tested_run import train_and_test
from graspstab.monitor.constants import MonitorConstants, MonitorError
from graspstab.monitor.episodes import summarise_episodes
from graspstab.monitor.evaluate_monitor import evaluate_monitor
from graspstab.monitor.export import load_onnx, load_torchscript
from graspstab.monitor.export_models import export_run, pick_candidate
from graspstab.monitor.figures import plot_monitor
from graspstab.monitor.grasp_level import (
    evaluate_monitors,
    read_episodes,
    results_of,
    timeline_grasp,
)
from graspstab.monitor.proxy import (
    ProxyScorer,
    bounded,
    ratio_of,
    select_proxy_threshold,
)
from graspstab.report.monitor import monitor_section
from tests.test_learning_train import LSTM, TRAIN, write_dataset

REPO = Path(__file__).resolve().parents[1]
LABELS: dict[str, Any] = yaml.safe_load((REPO / "config" / "labels" / "default.yaml").read_text())
DT = 5e-4
T = 4000  # 2 s replays
VAL, TEST, TRAIN_OBJ = "o08", "o10", "o00"  # write_dataset's splits: o08 val, o10 test, o00 train
SPLITS = {VAL: "val", TEST: "test", TRAIN_OBJ: "train"}


class LastForceScorer:
    """Stub scorer: a window's probability is its last frame's thumb normal force."""

    def __init__(self, window_steps: int = 20, threshold: float = 0.5) -> None:
        self.constants = MonitorConstants(np.zeros((5, 2)), np.ones((5, 2)), threshold,
                                          window_steps)  # fmt: skip

    def score_one(self, window: np.ndarray) -> float:
        return float(window[-1, 0, 0])

    def __call__(self, windows: np.ndarray) -> np.ndarray:
        return np.asarray(windows)[:, -1, 0, 0].astype(np.float64)


def _grasp(speed: np.ndarray, dist: np.ndarray, thumb: np.ndarray) -> dict[str, np.ndarray]:
    """One grasp's trace channels: velocity along x, d_t, thumb normal force (others 1 N)."""
    normal = np.ones((len(speed), 5), dtype=np.float32)
    normal[:, 0] = thumb
    shear = np.full((len(speed), 5), 0.2, dtype=np.float32)
    velocity = np.zeros((len(speed), 3), dtype=np.float32)
    velocity[:, 0] = speed
    return {"velocity": velocity, "min_distance": dist.astype(np.float32), "normal": normal,
            "shear": shear, "position": np.zeros((len(speed), 3), np.float32)}  # fmt: skip


def _steps(value_before: float, value_after: float, at: int, n: int = T) -> np.ndarray:
    out = np.full(n, value_before, dtype=np.float64)
    out[at:] = value_after
    return out


def write_replays(root: Path) -> list[tuple[Path, Path]]:
    """Hand-made replays with known outcomes (shard 0 of VAL, TEST, TRAIN_OBJ):

    VAL 0: slides from 2400 on (onset 2400); the thumb's force crosses 0.5 at 2000: warned
           0.2 s ahead, in time.
    VAL 1: never moves; one force burst [1000, 1100): one false warning.
    VAL 2: diverged (skipped).
    VAL 3: moving from the start, contact lost at 800: neither settle check succeeds, so the 3 s
           fallback lies past the replay's end and there is no usable interval (skipped).
    TEST 0: contact lost at 3000 while moving from 2900 (onset 2900, contact loss); no warning.
    TEST 1: deeper than 8 mm throughout (rejected by the depth rule, skipped).
    TRAIN_OBJ 0: a training object (skipped).
    """
    contact = np.full(T, 0.001)
    burst = np.full(T, 0.1)
    burst[1000:1100] = 0.9
    lost = contact.copy()
    lost[3000:] = np.nan
    early = contact.copy()
    early[800:] = np.nan
    grasps = {
        (VAL, 0): _grasp(_steps(0.0, 0.01, 2400), contact, _steps(0.1, 0.9, 2000)),
        (VAL, 1): _grasp(np.zeros(T), contact, burst),
        (VAL, 2): _grasp(np.zeros(T), contact, np.full(T, 0.1)),
        (VAL, 3): _grasp(np.full(T, 0.01), early, np.full(T, 0.1)),
        (TEST, 0): _grasp(_steps(0.0, 0.02, 2900), lost, np.full(T, 0.1)),
        (TEST, 1): _grasp(np.zeros(T), np.full(T, -0.01), np.full(T, 0.1)),
        (TRAIN_OBJ, 0): _grasp(_steps(0.0, 0.01, 2400), contact, np.full(T, 0.1)),
    }
    pairs = []
    for obj in (VAL, TEST, TRAIN_OBJ):
        mine = {g: ch for (o, g), ch in grasps.items() if o == obj}
        table = root / "replay" / obj / "replays_0.parquet"
        write_parquet(table, pl.DataFrame({
            "object": [obj] * len(mine), "grasp_id": list(mine), "shard": [0] * len(mine),
            "diverged": [obj == VAL and g == 2 for g in mine],
        }))  # fmt: skip
        traces = root / "replay" / obj / "traces_0.npz"
        np.savez(traces, **{f"g{g}_{c}": v for g, ch in mine.items() for c, v in ch.items()})
        pairs.append((table, traces))
    return pairs


def test_read_episodes_keeps_usable_held_out_replays(tmp_path: Path) -> None:
    episodes = {(e.object, e.grasp_id): e for e in
                read_episodes(write_replays(tmp_path), SPLITS, LABELS, DT)}  # fmt: skip
    assert set(episodes) == {(VAL, 0), (VAL, 1), (TEST, 0)}
    lost = episodes[(TEST, 0)]
    assert lost.end == 3000 and lost.contact_lost and lost.split == "test"
    assert lost.forces.shape == (3000, 5, 2) and lost.u[2900:].all() and not lost.u[:2900].any()
    held = episodes[(VAL, 1)]
    assert held.end == T and not held.contact_lost and held.start == 0
    one = list(read_episodes(write_replays(tmp_path), SPLITS, LABELS, DT, grasp=(VAL, 1)))
    assert [(e.object, e.grasp_id) for e in one] == [(VAL, 1)]
    with pytest.raises(KeyError, match="o10"):
        list(read_episodes(write_replays(tmp_path), {VAL: "val"}, LABELS, DT))


def test_known_onsets_leads_and_false_warnings(tmp_path: Path) -> None:
    frame, kept = evaluate_monitors(
        read_episodes(write_replays(tmp_path), SPLITS, LABELS, DT),
        {"stub": LastForceScorer()}, LABELS, DT, stride=1, debounce=1, keep_traces={(VAL, 0)},
    )  # fmt: skip
    rows = {(r["object"], r["grasp_id"]): r for r in frame.iter_rows(named=True)}
    warned = rows[(VAL, 0)]
    assert warned["onset"] == 2400 and warned["onset_kind"] == "horizon"
    assert warned["first_warning"] == 2000 and warned["warned_in_time"]
    assert warned["lead_time_s"] == pytest.approx(0.2)
    stable = rows[(VAL, 1)]
    assert stable["onset"] is None and stable["false_warnings"] == 1
    # the stable stretch: from the first scored frame (19) to the end less offset and horizon
    assert stable["stable_seconds"] == pytest.approx((T - 200 - 300 - 19) * DT)
    assert stable["warning_seconds"] == pytest.approx(100 * DT)
    fell = rows[(TEST, 0)]
    assert fell["onset"] == 2900 and fell["onset_kind"] == "contact_lost"
    assert fell["first_warning"] is None and not fell["warned_in_time"]
    summary = summarise_episodes(results_of(frame.filter(pl.col("split") == "val")))
    assert summary["failing_grasps"] == 1 and summary["in_time_share"] == 1.0
    assert summary["false_warnings_per_stable_s"] == pytest.approx(1 / stable["stable_seconds"])
    assert set(kept) == {(VAL, 0)} and kept[(VAL, 0)]["traces"]["stub"].warning[2000]
    # a stride of 10 moves the first warning to the next scored frame at or after 2000
    coarse, _ = evaluate_monitors(read_episodes(write_replays(tmp_path), SPLITS, LABELS, DT),
                                  {"stub": LastForceScorer()}, LABELS, DT, stride=10,
                                  debounce=1)  # fmt: skip
    first = coarse.filter(pl.col("grasp_id") == 0, pl.col("object") == VAL)["first_warning"][0]
    assert first == 19 + 10 * int(np.ceil((2000 - 19) / 10))
    assert timeline_grasp(frame, "stub", "val") == (VAL, 0)
    assert timeline_grasp(frame, "stub", "test") == (TEST, 0)  # failing, not warned
    assert timeline_grasp(frame, "missing") is None


def test_proxy_monitor_scores_the_friction_ratio_and_picks_its_threshold_like_brute_force() -> None:
    rng = np.random.default_rng(3)
    windows = rng.uniform(0.05, 2.0, size=(300, 4, 5, 2)).astype(np.float32)
    labels = (friction_ratio(windows) + rng.normal(0, 0.3, 300) > 1.0).astype(np.int8)
    p = bounded(friction_ratio(windows))
    scorer = ProxyScorer(0.5)
    np.testing.assert_allclose(scorer(windows[:, -1:]), p, rtol=1e-12)
    assert scorer.score_one(windows[7, -1:]) == pytest.approx(p[7])
    assert ratio_of(float(bounded(0.7))) == pytest.approx(0.7)
    choice = select_proxy_threshold(windows, labels, {"rule": "min_recall", "min_recall": 0.9})
    # brute force: every distinct score as a threshold; most precise with recall >= 0.9
    best = None
    for t in np.unique(p):
        pred = p >= t
        recall = (pred & (labels == 1)).sum() / labels.sum()
        precision = (pred & (labels == 1)).sum() / pred.sum()
        if recall >= 0.9 and (best is None or precision > best[1]):
            best = (t, precision)
    assert choice["threshold"] == pytest.approx(best[0]) and choice["rule"] == "min_recall"
    assert choice["precision"] == pytest.approx(best[1])
    assert choice["ratio"] == pytest.approx(best[0] / (1 - best[0]))
    with pytest.raises(ValueError, match="no validation window"):
        select_proxy_threshold(windows[:0], labels[:0], {"rule": "min_recall", "min_recall": 0.9})


@pytest.fixture(scope="module")
def trained_lstm(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, Path]:
    """(dataset, run) of a short LSTM training on write_dataset's planted windows (W = 20)."""
    torch.set_num_threads(1)
    data = write_dataset(tmp_path_factory.mktemp("data"), {"train": 12, "val": 12, "test": 12})
    run = tmp_path_factory.mktemp("run")
    train_and_test(data, LSTM, {**TRAIN, "max_epochs": 2, "patience": 2}, 0, run)
    return data, run


MONITOR = {"window_s": 0.01, "stride": 5, "debounce": 1, "batch_size": 64,
           "timeline_family": "lstm", "early_warning": {"budget_per_s": 0.02, "ahead_s": 0.05}}


@pytest.fixture(scope="module")
def evaluated(tmp_path_factory: pytest.TempPathFactory, trained_lstm: tuple[Path, Path]) -> Path:
    data, run = trained_lstm
    root = tmp_path_factory.mktemp("monitor")
    evaluate_monitor(
        write_replays(root), {"lstm": (run / "model.pt", run / "metrics.json")}, data, SPLITS,
        LABELS, DT, MONITOR, TRAIN["threshold"], root / "episodes.parquet", root / "summary.json",
        root / "timeline.npz",
    )  # fmt: skip
    return root


def test_entry_point_writes_per_grasp_rows_summaries_and_a_timeline(
    evaluated: Path, trained_lstm: tuple[Path, Path]
) -> None:
    frame = pl.read_parquet(evaluated / "episodes.parquet")
    summary = read_json(evaluated / "summary.json")
    assert frame.group_by("monitor").len().sort("monitor").rows() == [("lstm", 3), ("proxy", 3)]
    metrics = json.loads((trained_lstm[1] / "metrics.json").read_text())
    lstm = summary["monitors"]["lstm"]
    assert lstm["threshold"] == metrics["threshold"]["threshold"] and lstm["window_steps"] == 20
    assert summary["replays"] == {"val": 2, "test": 1}
    assert summary["settings"]["stride_s"] == pytest.approx(5 * DT)
    for name in ("lstm", "proxy"):
        for split in ("val", "test"):
            rows = frame.filter(pl.col("monitor") == name, pl.col("split") == split)
            assert summary["monitors"][name]["splits"][split] == json.loads(json.dumps(
                summarise_episodes(results_of(rows)), default=float))  # fmt: skip
    proxy = summary["monitors"]["proxy"]
    assert proxy["window_steps"] == 1 and proxy["threshold_choice"]["windows"] == 24
    # early warning at the budget: one entry per monitor, over the test replay
    ew = summary["early_warning"]
    assert ew["budget_per_s"] == 0.02 and set(ew["monitors"]) == {"lstm", "proxy"}
    for e in ew["monitors"].values():
        assert e["test"]["grasps"] == 1 and e["threshold"]["false_per_s"] is not None
    # the onset is a property of the replay, not of the monitor
    assert frame.group_by("object", "grasp_id").agg(pl.col("onset").n_unique())["onset"].max() == 1
    arrays = load_npz(evaluated / "timeline.npz")
    tl = summary["timeline"]
    assert tl["monitor"] == "lstm" and tl["split"] == "test" and (tl["object"], tl["grasp_id"]) == (
        TEST, 0)  # the only test replay
    lo, start, end, onset = arrays["frames"].tolist()
    assert (end, onset) == (3000, 2900) and lo == max(0, 2900 - 8000)
    assert arrays["forces"].shape == (end - lo, 5, 2) and len(arrays["prob_lstm"]) == end - lo


def test_fold_entry_points_score_a_folds_replays_and_pool_the_folds(
    tmp_path: Path, trained_lstm: tuple[Path, Path]
) -> None:
    """evaluate_fold_monitor on a fold whose validation and test objects are the hand-made
    replays' (the training object is not read), twice as two folds with the splits swapped, then
    aggregate_fold_warning and the report's part: the rows per monitor and test grasp agree with
    the per-fold thresholds, and the pooled counts with the rows."""
    from graspstab.monitor.aggregate_fold_warning import aggregate_fold_warning
    from graspstab.monitor.evaluate_fold_monitor import evaluate_fold_monitor
    from graspstab.report.crossval import _warning_parts

    _, run = trained_lstm
    replays = write_replays(tmp_path)
    runs = {"lstm": (run / "model.pt", run / "metrics.json")}
    folds = [SPLITS, {VAL: "test", TEST: "val", TRAIN_OBJ: "train"}]
    out = []
    for k, assignment in enumerate(folds):
        grasps, thresholds = tmp_path / f"f{k}" / "grasps.parquet", tmp_path / f"f{k}" / "t.json"
        summary = evaluate_fold_monitor(replays, runs, assignment, k, LABELS, DT, MONITOR, grasps,
                                        thresholds)  # fmt: skip
        rows = pl.read_parquet(grasps)
        assert set(rows["monitor"]) == {"lstm", "proxy"} and set(rows["fold"]) == {k}
        test = {o for o, s in assignment.items() if s == "test"}
        assert set(rows["object"]) == test  # test grasps only; validation chose the threshold
        for name, choice in summary["thresholds"].items():
            mine = rows.filter(pl.col("monitor") == name)
            assert (mine["threshold"] == choice["threshold"]).all()
            assert choice["val_grasps"] == {0: 2, 1: 1}[k]  # usable replays of the val object
        out.append((grasps, thresholds))
    pooled = aggregate_fold_warning([g for g, _ in out], [t for _, t in out], "creep_free",
                                    {"resamples": 100, "seed": 0, "level": 0.95},
                                    tmp_path / "rows.parquet", tmp_path / "ew.json")  # fmt: skip
    every = pl.read_parquet(tmp_path / "rows.parquet")
    for name, r in pooled["monitors"].items():
        mine = every.filter(pl.col("monitor") == name)
        assert r["grasps"] == mine.height == 3 and r["folds"] == 2
        assert r["failing_after_still"] == int(mine["after_still"].sum())
        assert pooled["thresholds"][name]["at_floor"] <= 2
    assert pooled["folds"] == 2 and pooled["answer"].startswith("Under the creep-free protocol")
    html = "\n".join(_warning_parts(read_json(tmp_path / "ew.json"), "hidden-onset"))
    assert "crossval-warning-creep_free" in html and pooled["answer"].split(",")[0] in html


def test_figures_and_report_section_from_the_entry_points_outputs(
    evaluated: Path, tmp_path: Path
) -> None:
    leads, timeline = tmp_path / "leads.png", tmp_path / "timeline.png"
    plot_monitor(evaluated / "episodes.parquet", evaluated / "summary.json",
                 evaluated / "timeline.npz", leads, timeline, dpi=60)  # fmt: skip
    for png in (leads, timeline):
        with Image.open(io.BytesIO(png.read_bytes())) as img:
            assert img.size[0] > 100
    html = monitor_section({"summary": evaluated / "summary.json", "leads_figure": leads,
                            "timeline_figure": timeline})  # fmt: skip
    assert 'id="monitor"' in html and 'id="monitor-leads"' in html
    assert "friction-ratio proxy" in html
    assert not re.search(r"\bnan\b", re.sub(r'src="data:[^"]*"', "", html), re.IGNORECASE)
    # header + (lstm, proxy) x (test, val); the early-warning table: header + lstm, proxy
    assert html.count("<tr>") == 1 + 2 * 2 + 1 + 2
    assert "Early warning at a false-warning budget" in html


def test_export_run_writes_files_that_reproduce_the_checkpoint(
    trained_lstm: tuple[Path, Path], tmp_path: Path
) -> None:
    _, run = trained_lstm
    out = {k: tmp_path / f"m.{k}" for k in ("onnx", "pt", "json")}
    info = export_run(run / "model.pt", run / "metrics.json", out["onnx"], out["pt"], out["json"])
    assert max(info["parity"].values()) < 1e-5
    sidecar = read_json(out["json"])
    assert sidecar["threshold"] == json.loads((run / "metrics.json").read_text())["threshold"][
        "threshold"]
    assert load_onnx(out["onnx"]).constants.window_steps == 20
    assert load_torchscript(out["pt"]).constants.family == "lstm"


def test_pick_candidate_maps_the_sweeps_choice_to_its_run(tmp_path: Path) -> None:
    runs = {"lstm_w10ms": ("a.pt", "a.json"), "gru_w50ms": ("b.pt", "b.json")}
    summary = tmp_path / "summary.json"
    write_json(summary, {"choice": {"defined": True, "pick": {"family": "lstm", "window_s": 0.01}}})
    assert pick_candidate(summary, runs) == ("a.pt", "a.json")
    write_json(summary, {"choice": {"defined": True, "pick": {"family": "cnn", "window_s": 0.01}}})
    with pytest.raises(MonitorError, match="cnn_w10ms is not among"):
        pick_candidate(summary, runs)
    write_json(summary, {"choice": {"defined": False, "reason": "no AUPRC"}})
    with pytest.raises(MonitorError, match="undefined .no AUPRC"):
        pick_candidate(summary, runs)
