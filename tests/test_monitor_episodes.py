"""Grasp-level warning scores: hand-made episodes with known onsets and warnings."""

from __future__ import annotations

import math

import numpy as np
import pytest

from graspstab.labels.windows import predictive_labels, step_counts, timestep_labels
from graspstab.monitor.constants import MonitorConstants
from graspstab.monitor.episodes import (
    EpisodeResult,
    evaluate_episode,
    failure_onset,
    first_scored,
    lead_times,
    rises,
    summarise_episodes,
)
from graspstab.monitor.stream import StreamingMonitor

DT, OFFSET_S, HORIZON_S, WINDOW_S = 5e-4, 0.1, 0.15, 0.2  # config/labels/default.yaml
W, OFF, H = step_counts(WINDOW_S, OFFSET_S, HORIZON_S, DT)  # 400, 200, 300
N = 4000  # frames per hand-made replay (2 s)


def spans(*ranges: tuple[int, int], n: int = N) -> np.ndarray:
    """A bool trace that is true on the given [a, b) ranges."""
    out = np.zeros(n, dtype=bool)
    for a, b in ranges:
        out[a:b] = True
    return out


def episode(
    warning: np.ndarray,
    unstable: np.ndarray,
    start: int = 500,
    end: int = N,
    contact_lost: bool = False,
    ready: int = 0,
    split: str = "test",
) -> EpisodeResult:
    return evaluate_episode(
        warning, unstable.astype(np.uint8), start, end, contact_lost=contact_lost, dt=DT,
        offset_s=OFFSET_S, horizon_s=HORIZON_S, object_id="obj", grasp_id=7, split=split,
        ready=ready,
    )  # fmt: skip


def test_step_counts_are_the_labelling_stage_ones() -> None:
    assert (W, OFF, H) == (400, 200, 300)


def test_lead_time_of_a_warning_k_steps_before_the_onset_is_exact() -> None:
    onset, k = 2000, 350
    r = episode(spans((onset - k, onset + 50)), spans((onset, onset + H)))
    assert (r.onset, r.onset_kind, r.first_warning) == (onset, "horizon", onset - k)
    assert r.lead_time_s == pytest.approx(k * DT, abs=1e-12)
    assert r.warned_in_time and r.warnable and r.failing
    assert (r.false_warnings, r.stable_seconds, r.warning_seconds) == (None, None, None)


def test_in_time_needs_the_full_offset_ahead() -> None:
    onset = 2000
    u = spans((onset, onset + 2 * H))
    exact = episode(spans((onset - OFF, onset + 10)), u)  # exactly the offset ahead: in time
    assert exact.warned_in_time and exact.lead_time_s == pytest.approx(OFF * DT)
    late = episode(spans((onset - OFF + 1, onset + 10)), u)  # one step short: late
    assert not late.warned_in_time
    assert late.lead_time_s == pytest.approx((OFF - 1) * DT)


def test_a_warning_at_or_after_the_onset_has_no_lead_time() -> None:
    onset = 2000
    for t in (onset, onset + 40):
        r = episode(spans((t, t + 10)), spans((onset, onset + H)))
        assert r.first_warning == t
        assert r.lead_time_s is None and not r.warned_in_time


def test_no_warning() -> None:
    r = episode(spans(), spans((2000, 2000 + H)))
    assert r.onset == 2000 and r.first_warning is None
    assert r.lead_time_s is None and not r.warned_in_time


def test_the_first_warning_counts_even_if_dropped_before_the_onset() -> None:
    onset = 3000
    r = episode(spans((1000, 1100), (onset - 50, onset)), spans((onset, onset + H)))
    assert r.first_warning == 1000
    assert r.lead_time_s == pytest.approx((onset - 1000) * DT)
    assert r.false_warnings is None  # a failing grasp has no false warnings


def test_stable_grasp_with_two_bursts_counts_two_false_warnings() -> None:
    start, end = 500, N
    hi = end - OFF - H  # the stable stretch ends OFF + H before the interval does
    # two bursts, then a third inside the last OFF + H steps (uncheckable: not counted)
    warn = spans((1000, 1100), (2000, 2250), (hi + 10, hi + 60))
    u = spans((1500, 1500 + H - 1))  # a blip one step short of the horizon
    r = episode(warn, u, start, end)
    assert not r.failing and r.onset is None and r.onset_kind is None
    assert r.false_warnings == 2
    assert r.stable_seconds == pytest.approx((hi - start) * DT)
    assert r.warning_seconds == pytest.approx(350 * DT)
    assert r.first_warning == 1000 and not r.warned_in_time and r.warnable is None
    summary = summarise_episodes([r])
    assert summary["false_warnings_per_stable_s"] == pytest.approx(2 / ((hi - start) * DT))
    assert summary["stable_warning_share"] == pytest.approx(350 / (hi - start))


def test_an_unstable_blip_shorter_than_the_horizon_is_no_onset() -> None:
    assert failure_onset(spans((1500, 1500 + H - 1)), 500, N, H) is None
    assert failure_onset(spans((1500, 1500 + H)), 500, N, H) == 1500
    # the first run long enough, not the first blip
    assert failure_onset(spans((1200, 1300), (1500, 1500 + H)), 500, N, H) == 1500


def test_a_run_must_lie_in_the_usable_interval() -> None:
    u = spans((100, 100 + 2 * H), (N - 100, N))
    assert failure_onset(u, 500, N - 200, H) is None  # before start, after end: unread
    assert failure_onset(u, 150, N - 200, H) == 150  # a run already under way at start
    assert failure_onset(spans((1000, 1000 + H)), 500, 1000 + H - 1, H) is None  # cut by end


def test_a_run_cut_by_contact_loss_is_an_onset_whatever_its_length() -> None:
    end = 3000
    u = spans((1200, 1300), (end - 40, end + 500))  # unstable up to the contact end
    assert failure_onset(u, 500, end, H) is None
    assert failure_onset(u, 500, end, H, contact_lost=True) == end - 40
    r = episode(spans((end - 300, end)), u, 500, end, contact_lost=True)
    assert (r.onset, r.onset_kind) == (end - 40, "contact_lost")
    assert r.lead_time_s == pytest.approx(260 * DT) and r.warned_in_time
    summary = summarise_episodes([r, episode(spans(), spans((1000, 1000 + H)))])
    assert (summary["failing_grasps"], summary["failing_by_contact_loss"]) == (2, 1)
    # contact lost while still (u = 0 at the end): no onset
    assert failure_onset(spans((end - 40, end - 1)), 500, end, H, contact_lost=True) is None
    # an earlier full-horizon run wins over the cut one
    both = spans((1000, 1000 + H), (end - 40, end))
    assert failure_onset(both, 500, end, H, contact_lost=True) == 1000
    # the whole interval unstable and cut: onset at start
    assert failure_onset(spans((0, N)), 500, 600, H, contact_lost=True) == 500


def test_onset_agrees_with_the_predictive_label() -> None:
    onset = 2500
    u = timestep_labels(np.where(spans((onset, onset + H)), 0.01, 0.0), 0.0012)
    assert failure_onset(u, 500, N, H) == onset
    # the window ending OFF before the onset has its whole target unstable: r = 1, label 1
    r, y = predictive_labels(u, np.array([onset - W - OFF]), N, W, OFF, H, 0.35, 0.65)
    assert r.tolist() == [1.0] and y.tolist() == [1]


def test_warnings_outside_the_usable_interval_are_ignored() -> None:
    start, end = 500, 3000
    outside = spans((100, 400), (end + 10, end + 200))
    stable = episode(outside, spans(), start, end)
    assert stable.false_warnings == 0 and stable.first_warning is None
    assert stable.warning_seconds == 0.0
    failing = episode(outside, spans((2000, 2000 + H)), start, end)
    assert failing.first_warning is None and failing.lead_time_s is None
    # a warning up across start counts as raised at start, once
    across = episode(spans((400, 700)), spans(), start, end)
    assert across.first_warning == start and across.false_warnings == 1


def test_ready_moves_the_evaluated_start() -> None:
    start, ready = 500, 899  # a monitor started at 500 with a 400-frame window scores from 899
    r = episode(spans(), spans(), start, N, ready=ready)
    assert r.stable_seconds == pytest.approx((N - OFF - H - ready) * DT)
    early = episode(spans(), spans((ready + OFF - 1, ready + OFF - 1 + H)), start, N, ready=ready)
    assert early.warnable is False
    just = episode(spans(), spans((ready + OFF, ready + OFF + H)), start, N, ready=ready)
    assert just.warnable is True
    # the warnable share leaves out grasps that failed too early to be warned in time
    onset = ready + OFF
    warned = episode(spans((ready, N)), spans((onset, onset + H)), start, N, ready=ready)
    s = summarise_episodes([early, warned])
    assert s["warnable_failing_grasps"] == 1
    assert s["in_time_share"] == pytest.approx(0.5) and s["in_time_share_warnable"] == 1.0
    none = summarise_episodes([early])
    assert none["in_time_share"] == 0.0 and none["in_time_share_warnable"] is None
    assert {k: none["undefined"][k] for k in ("in_time_share_warnable", "median_lead_s")} == {
        "in_time_share_warnable": "no failing grasp left room for a warning in time",
        "median_lead_s": "no failing grasp was warned before its onset",
    }
    assert "in_time_share" not in none["undefined"]


def test_rises_and_first_scored() -> None:
    w = spans((0, 3), (5, 6), (8, 10), n=10)
    assert rises(w, 0, 10).tolist() == [0, 5, 8]
    assert rises(w, 1, 9).tolist() == [1, 5, 8]
    assert rises(w, 4, 4).tolist() == []
    assert first_scored(np.array([np.nan, np.nan, 0.3, np.nan])) == 2
    assert first_scored(np.full(3, np.nan)) is None


def test_bad_inputs_are_refused() -> None:
    u = spans()
    with pytest.raises(ValueError, match="bool"):
        episode(np.zeros(N), u)  # a probability, not thresholded
    with pytest.raises(ValueError, match="equal-length"):
        episode(spans(n=N - 1), u)
    with pytest.raises(ValueError, match="within"):
        episode(spans(), u, 500, N + 1)
    with pytest.raises(ValueError, match="0 or 1"):
        evaluate_episode(spans(), np.full(N, 2), 0, N, contact_lost=False, dt=DT,
                         offset_s=OFFSET_S, horizon_s=HORIZON_S, object_id="o", grasp_id=0,
                         split="test")  # fmt: skip


def _mixed() -> list[EpisodeResult]:
    u = spans((2000, 2000 + H))
    return [
        episode(spans((2000 - 400, 2000)), u),  # in time, lead 0.2 s
        episode(spans((2000 - 300, 2000)), u),  # in time, lead 0.15 s
        episode(spans((2000 - 100, 2000)), u),  # late, lead 0.05 s
        episode(spans((2100, 2200)), u),  # after the onset
        episode(spans(), u),  # not warned
        episode(spans((1000, 1010)), spans(), 500, 2500 + OFF + H),  # stable: 1 s, 1 warning
        episode(spans(), spans(), 500, 1000 + OFF + H, split="val"),  # stable: 0.25 s, none
    ]


def test_summary_figures() -> None:
    s = summarise_episodes(_mixed())
    assert (s["grasps"], s["failing_grasps"], s["stable_grasps"]) == (7, 5, 2)
    assert (s["warned_in_time"], s["warned_late"], s["not_warned"]) == (2, 2, 1)
    assert s["in_time_share"] == pytest.approx(0.4)
    assert s["in_time_share_warnable"] == pytest.approx(0.4)
    assert s["lead_time_grasps"] == 3
    assert s["median_lead_s"] == pytest.approx(0.15)  # of 0.05, 0.15, 0.2 (mean 0.133)
    assert s["stable_seconds"] == pytest.approx(1.25)
    assert s["false_warnings"] == 1
    assert s["false_warnings_per_stable_s"] == pytest.approx(1 / 1.25)
    assert s["stable_warning_share"] == pytest.approx(10 / 2500)
    assert s["splits"] == ["test", "val"] and s["undefined"] == {}
    assert sorted(lead_times(_mixed()).tolist()) == pytest.approx([0.05, 0.15, 0.2])


def test_summary_without_failing_grasps_leaves_the_warning_figures_undefined() -> None:
    s = summarise_episodes([r for r in _mixed() if not r.failing])
    assert s["failing_grasps"] == 0
    assert s["in_time_share"] is None and s["median_lead_s"] is None
    assert s["undefined"]["in_time_share"] == "no failing grasp"
    assert s["undefined"]["median_lead_s"] == "no failing grasp"
    assert s["undefined"]["in_time_share_warnable"] == "no failing grasp"
    assert s["false_warnings_per_stable_s"] == pytest.approx(0.8)
    assert lead_times([]).shape == (0,)


def test_summary_without_stable_grasps_leaves_the_rate_undefined() -> None:
    s = summarise_episodes([r for r in _mixed() if r.failing])
    assert s["stable_grasps"] == 0 and s["stable_seconds"] == 0.0
    assert s["false_warnings_per_stable_s"] is None and s["stable_warning_share"] is None
    assert s["undefined"]["false_warnings_per_stable_s"] == "no stable grasp"
    assert "in_time_share" not in s["undefined"]
    # failing grasps none of which was warned before onset: no median, with its reason
    unwarned = summarise_episodes([_mixed()[4]])
    assert unwarned["median_lead_s"] is None and unwarned["in_time_share"] == 0.0
    assert unwarned["undefined"]["median_lead_s"] == "no failing grasp was warned before its onset"
    # stable grasps too short for a stable stretch: undefined, not 0
    too_short = episode(spans(), spans(), 500, 500 + OFF + H - 50)
    assert too_short.stable_seconds == 0.0 and too_short.false_warnings == 0
    short = summarise_episodes([too_short])
    assert short["undefined"]["false_warnings_per_stable_s"] == (
        "stable grasps have no stable stretch"
    )


class LastForceScorer:
    """Stub scorer: a window's probability is its last frame's first normal force."""

    def __init__(self, window_steps: int) -> None:
        self.constants = MonitorConstants(np.zeros((5, 2)), np.ones((5, 2)), 0.5, window_steps)

    def score_one(self, window: np.ndarray) -> float:
        return float(window[-1, 0, 0])

    def __call__(self, windows: np.ndarray) -> np.ndarray:
        return windows[:, -1, 0, 0].astype(np.float64)


def test_streaming_monitor_warnings_feed_the_episode_score() -> None:
    steps, onset, rise = 40, 2000, 1700  # the score crosses the threshold from frame 1700
    frames = np.zeros((N, 5, 2), dtype=np.float32)
    frames[:, 0, 0] = np.where(spans((rise, N)), 0.9, 0.1)
    out = StreamingMonitor.from_scorer(LastForceScorer(steps), stride=2, debounce=3).run(frames)
    ready = first_scored(out.prob)
    assert ready == steps - 1
    # scored frames 39, 41, ...: unstable from 1701; three in a row at 1701, 1703, 1705
    r = episode(out.warning, spans((onset, onset + H)), start=0, ready=ready)
    assert r.first_warning == 1705
    assert r.lead_time_s == pytest.approx((onset - 1705) * DT) and r.warned_in_time
    assert math.isclose(r.lead_time_s, 0.1475, rel_tol=1e-9)
