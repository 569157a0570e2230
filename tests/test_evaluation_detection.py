"""Prediction against detection (evaluation.detection): the still-now split, the persistence
oracle and the ranked blocks, on planted observation periods against brute-force references."""

from __future__ import annotations

import math

import numpy as np
import pytest
from sklearn.metrics import average_precision_score, roc_auc_score

from graspstab.evaluation.detection import (
    end_speed,
    ranked,
    split_by_motion,
    still_now,
    unstable_share,
)

V_SLIP = 0.0012


def _motion(speeds: np.ndarray) -> np.ndarray:
    """Windows' motion (N, W, 2) from their speeds: eq. 23's u_t and the speed."""
    return np.stack([(speeds >= V_SLIP).astype(np.float32), speeds], -1).astype(np.float32)


def test_one_unstable_step_makes_a_window_moving_now() -> None:
    speeds = np.zeros((4, 10))
    speeds[1, 9] = V_SLIP  # the last step only, exactly at the threshold (eq. 23: >=)
    speeds[2, 0] = 0.5  # the first step only
    speeds[3] = V_SLIP * 0.999  # creeping just below v_slip all along: still
    m = _motion(speeds)
    assert still_now(m).tolist() == [True, False, False, True]
    assert unstable_share(m).tolist() == pytest.approx([0.0, 0.1, 0.1, 0.0])


def test_persistence_oracle_and_end_speed_against_brute_force() -> None:
    rng = np.random.default_rng(0)
    speeds = rng.exponential(V_SLIP, (50, 40))
    m = _motion(speeds)
    for i in range(50):
        assert unstable_share(m)[i] == pytest.approx(np.mean([v >= V_SLIP for v in speeds[i]]))
        # dt 1 ms: the last 10 ms are the last 10 steps
        assert end_speed(m, 0.001)[i] == pytest.approx(np.mean(speeds[i, -10:]), rel=1e-6)
    assert end_speed(m, 0.05)[0] == pytest.approx(speeds[0, -1], rel=1e-6)  # at least one step


def test_ranked_blocks_count_chance_and_match_scikit_learn() -> None:
    rng = np.random.default_rng(1)
    y = (rng.random(300) < 0.3).astype(np.int8)
    s = rng.normal(y, 1.0)
    still = rng.random(300) < 0.6
    parts = split_by_motion(s, y, still)
    for name, mask in (("still", still), ("moving", ~still)):
        got = parts[name]
        assert got["n"] == mask.sum() and got["n_unstable"] == y[mask].sum()
        assert got["chance"] == pytest.approx(y[mask].mean())
        assert got["auprc"] == pytest.approx(average_precision_score(y[mask], s[mask]))
        assert got["auroc"] == pytest.approx(roc_auc_score(y[mask], s[mask]))
    # no still-now window becomes unstable: the ranking is undefined, not a number
    none = ranked(s[:20], np.zeros(20))
    assert none["n_unstable"] == 0 and none["chance"] == 0.0 and math.isnan(none["auprc"])
    empty = ranked(np.zeros(0), np.zeros(0))
    assert empty["n"] == 0 and math.isnan(empty["chance"]) and math.isnan(empty["auroc"])
