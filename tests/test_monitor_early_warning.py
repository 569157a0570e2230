"""Early warning at a false-warning budget on constructed grasps: the budget threshold against a
brute-force scan, the grid floor reported, lead times armed at the settle index, and the
evaluation's figures by hand."""

from __future__ import annotations

import numpy as np
import pytest

from graspstab.monitor.early_warning import (
    ScoredGrasp,
    budget_threshold,
    early_warning,
    false_rate,
    grid_of,
    lead_times,
)

DT = 0.01  # one frame = 10 ms, every frame scored


def holding(scores, start=0, split="val") -> ScoredGrasp:
    s = np.asarray(scores, dtype=float)
    return ScoredGrasp(split=split, frames=np.arange(len(s)), scores=s, start=start,
                       end=len(s), stable_end=len(s), onset=None, failing=False)  # fmt: skip


def failing(scores, onset, start=0, split="test") -> ScoredGrasp:
    s = np.asarray(scores, dtype=float)
    return ScoredGrasp(split=split, frames=np.arange(len(s)), scores=s, start=start,
                       end=len(s), stable_end=None, onset=onset, failing=True)  # fmt: skip


def test_false_rate_counts_rising_edges_per_stable_second() -> None:
    g = holding([0.1, 0.9, 0.9, 0.1, 0.8, 0.1, 0.1, 0.1, 0.1, 0.1])  # 0.1 s stable
    assert false_rate([g], 0.5, 1, DT) == (2, pytest.approx(0.1))
    assert false_rate([g], 0.85, 1, DT) == (1, pytest.approx(0.1))
    assert false_rate([g], 0.5, 2, DT)[0] == 1  # the lone 0.8 is debounced away
    assert false_rate([failing([0.9] * 5, 3)], 0.5, 1, DT) == (0, 0.0)  # failing: not counted


def test_budget_threshold_is_the_lowest_from_which_the_budget_holds() -> None:
    rng = np.random.default_rng(3)
    val = [holding(rng.random(400)) for _ in range(5)]  # 20 stable seconds
    budget = 0.5  # 10 edges allowed
    choice = budget_threshold(val, budget, 1, DT)
    grid = grid_of(val)
    rates = [false_rate(val, t, 1, DT)[0] / 20.0 for t in grid]
    # brute force: the lowest grid threshold with every higher one within budget
    want = next(t for i, t in enumerate(grid) if all(r <= budget for r in rates[i:]))
    assert choice["threshold"] == want and not choice["at_floor"]
    assert choice["false_per_s"] <= budget
    assert choice["false_warnings"] == false_rate(val, want, 1, DT)[0]


def test_a_budget_that_never_binds_is_reported_at_the_floor() -> None:
    val = [holding([0.2] * 100)]  # one stuck warning at any threshold <= 0.2: one edge in 1 s
    choice = budget_threshold(val, 5.0, 1, DT)
    assert choice["at_floor"] and choice["threshold"] == pytest.approx(0.2)
    strict = budget_threshold(val, 0.5, 1, DT)  # one edge per second is too many
    assert strict["never_warns"] and strict["false_warnings"] == 0


def test_lead_times_are_armed_at_the_settle_index() -> None:
    # a warning up from frame 0, before the settle index 5: it counts as raised at 5
    up_early = failing([0.9] * 30, onset=20, start=5)
    # a warning raised at 12 and dropped, then again at 19: the first one counts
    dropped = failing([0.1] * 12 + [0.9] * 3 + [0.1] * 4 + [0.9] * 11, onset=20)
    late = failing([0.1] * 25 + [0.9] * 5, onset=20)  # warns after the onset
    leads = lead_times([up_early, dropped, late, holding([0.9] * 10, split="test")], 0.5, 1, DT)
    assert leads == [pytest.approx(0.15), pytest.approx(0.08), None]


def test_early_warning_figures_by_hand() -> None:
    val = [holding([0.1] * 50 + [0.6] + [0.1] * 49)]  # one spike in 1 s at 0.6
    test = [failing([0.1] * 10 + [0.7] * 20, onset=20),  # warned 0.1 s ahead
            failing([0.1] * 18 + [0.7] * 12, onset=20),  # 0.02 s ahead: not 50 ms
            failing([0.1] * 30, onset=20),  # never warned
            holding([0.1] * 100 + [0.8] + [0.1] * 99, split="test")]  # one false warning in 2 s
    out = early_warning(val, test, budget_per_s=0.5, ahead_s=0.05, debounce=1, dt=DT)
    # at or below 0.6 the validation grasp warns once a second, over the budget: just above it
    assert 0.6 < out["threshold"]["threshold"] < 0.7 and not out["threshold"]["at_floor"]
    t = out["test"]
    assert (t["grasps"], t["failing"], t["failing_after_still"]) == (4, 3, 3)
    assert (t["warned_before_onset"], t["warned_ahead"]) == (2, 1)
    assert t["warned_ahead_share"] == pytest.approx(1 / 3)
    assert t["median_lead_s"] == pytest.approx(0.06)
    assert t["false_warnings"] == 1 and t["false_per_s"] == pytest.approx(0.5)
