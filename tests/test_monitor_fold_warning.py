"""Early warning over the cross-validation folds: each fold's budget threshold from its own
validation grasps, pooled test figures against brute force, intervals that resample objects and
pair the monitors, and the one-sentence answer."""

from __future__ import annotations

import numpy as np
import polars as pl
import pytest

from graspstab.monitor.early_warning import ScoredGrasp
from graspstab.monitor.fold_warning import ROW_SCHEMA, fold_rows, pooled_warning, warning_answer

DT = 0.01


def _grasp(split: str, obj: str, gid: int, scores: list[float], *, onset: int | None = None,
           holds: bool = True) -> ScoredGrasp:  # fmt: skip
    n = len(scores)
    return ScoredGrasp(split=split, frames=np.arange(n), scores=np.asarray(scores, float),
                       start=0, end=n, stable_end=n if holds else None, onset=onset,
                       failing=not holds, object=obj, grasp_id=gid)  # fmt: skip


def test_each_fold_takes_its_threshold_from_its_validation_grasps() -> None:
    # validation: a holding grasp scoring 0.2 with one 0.6 burst over 1 s of stable time: one
    # false warning per s at any threshold <= 0.6, over a budget of 0.5 per s
    val = [_grasp("val", "v", 0, [0.2] * 50 + [0.6] + [0.2] * 49)]
    # test: a grasp failing at frame 60 whose score rises to 0.7 at 40 (0.2 s ahead), a holding
    # one with a burst of 0.55 (below the threshold) and one with a burst of 0.65 (above it)
    test = [_grasp("test", "t", 0, [0.1] * 40 + [0.7] * 40, onset=60, holds=False),
            _grasp("test", "t", 1, [0.1] * 30 + [0.55] + [0.1] * 69),
            _grasp("test", "u", 2, [0.1] * 30 + [0.65] + [0.1] * 69)]  # fmt: skip
    rows, choices = fold_rows({"m": val + test}, 3, budget_per_s=0.5, ahead_s=0.05,
                              debounce=1, dt=DT)  # fmt: skip
    t = choices["m"]["threshold"]
    assert 0.6 < t < 0.61 and not choices["m"]["at_floor"]  # just above the validation burst
    assert choices["m"]["val_grasps"] == 1 and choices["m"]["test_grasps"] == 3
    assert rows.schema == pl.Schema(ROW_SCHEMA) and rows["fold"].unique().to_list() == [3]
    fail = rows.filter(pl.col("grasp_id") == 0).row(0, named=True)
    assert fail["after_still"] and fail["lead_s"] == pytest.approx(0.2) and fail["warned_ahead"]
    quiet, loud = (rows.filter(pl.col("grasp_id") == i).row(0, named=True) for i in (1, 2))
    assert quiet["false_warnings"] == 0 and quiet["stable_seconds"] == pytest.approx(1.0)
    assert loud["false_warnings"] == 1 and loud["object"] == "u"
    assert quiet["warned_ahead"] is None and not quiet["after_still"]


def _rows(spec: dict[str, dict[str, tuple[int, int, int, float]]]) -> pl.DataFrame:
    """Rows from {monitor: {object: (after_still, warned_ahead, false_warnings, seconds)}}: one
    failing row per grasp after a still period, one holding row carrying the false warnings."""
    rows = []
    for m, objs in spec.items():
        for o, (after, ahead, false, seconds) in objs.items():
            for i in range(after):
                rows.append({"fold": 0, "monitor": m, "object": o, "grasp_id": i,
                             "failing": True, "after_still": True,
                             "lead_s": 0.1 if i < ahead else None, "warned_ahead": i < ahead,
                             "false_warnings": 0, "stable_seconds": 0.0, "threshold": 0.5})
            rows.append({"fold": 0, "monitor": m, "object": o, "grasp_id": 99, "failing": False,
                         "after_still": False, "lead_s": None, "warned_ahead": None,
                         "false_warnings": false, "stable_seconds": seconds, "threshold": 0.5})
    return pl.DataFrame(rows, schema=ROW_SCHEMA)


def test_pooled_figures_and_object_bootstrap_match_brute_force() -> None:
    spec = {"gru": {"a": (4, 3, 1, 10.0), "b": (2, 0, 0, 20.0), "c": (3, 3, 2, 5.0)},
            "proxy": {"a": (4, 1, 0, 10.0), "b": (2, 1, 1, 20.0), "c": (3, 0, 0, 5.0)}}
    out = pooled_warning(_rows(spec), resamples=300, seed=7, level=0.9)
    g = out["monitors"]["gru"]
    assert (g["failing_after_still"], g["warned_ahead"]) == (9, 6)
    assert g["warned_ahead_share"] == pytest.approx(6 / 9)
    assert g["false_per_s"] == pytest.approx(3 / 35) and g["median_lead_s"] == pytest.approx(0.1)
    # brute force: the same object draws, summed per resample
    objs = ["a", "b", "c"]
    draw = np.random.default_rng(7).integers(0, 3, (300, 3))
    def share(m: str) -> np.ndarray:  # noqa: E306
        after = np.array([[spec[m][objs[j]][0] for j in d] for d in draw]).sum(1)
        ahead = np.array([[spec[m][objs[j]][1] for j in d] for d in draw]).sum(1)
        return ahead / after
    lo, hi = np.quantile(share("gru"), [0.05, 0.95])
    assert (g["warned_ahead_share_lo"], g["warned_ahead_share_hi"]) == pytest.approx((lo, hi))
    diff = share("gru") - share("proxy")
    (p,) = out["paired"]
    assert p["monitor"] == "gru" and p["diff"] == pytest.approx(6 / 9 - 2 / 9)
    assert (p["lo"], p["hi"]) == pytest.approx(tuple(np.quantile(diff, [0.05, 0.95])))
    assert out["bootstrap"]["unit"] == "object" and out["objects"] == 3


def test_identical_objects_give_exact_intervals_and_a_clear_verdict() -> None:
    spec = {"cnn": {o: (2, 2, 0, 10.0) for o in "abcd"},
            "proxy": {o: (2, 0, 1, 10.0) for o in "abcd"}}
    out = pooled_warning(_rows(spec), resamples=200, seed=0)
    c = out["monitors"]["cnn"]
    assert c["warned_ahead_share"] == c["warned_ahead_share_lo"] == c["warned_ahead_share_hi"] == 1
    assert out["monitors"]["proxy"]["false_per_s_lo"] == pytest.approx(0.1)
    (p,) = out["paired"]
    assert p["lo"] == p["hi"] == pytest.approx(1.0) and p["verdict"] == "learned better"
    summary = {**out, "folds": 2, "budget_per_s": 0.02, "ahead_s": 0.05}
    text = warning_answer(summary, "creep-free")
    assert text.startswith("Under the creep-free protocol, over 2 folds")
    assert "every learned monitor warns ahead of more failing grasps than the proxy" in text
    assert "cnn 8 of 8 (100 % [100, 100])" in text and "proxy 0 of 8" in text
    assert "one false warning per 50 stable grasp-seconds" in text


def test_no_grasp_failing_after_a_still_period_is_said_so() -> None:
    out = pooled_warning(_rows({"gru": {"a": (0, 0, 0, 5.0)}, "proxy": {"a": (0, 0, 0, 5.0)}}),
                         resamples=50, seed=0)  # fmt: skip
    assert out["monitors"]["gru"]["warned_ahead_share"] is None
    assert out["paired"][0]["verdict"] == "undefined"
    text = warning_answer({**out, "folds": 1, "budget_per_s": 0.02, "ahead_s": 0.05}, "reference")
    assert "no test grasp fails after a still period" in text
