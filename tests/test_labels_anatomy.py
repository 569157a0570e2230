"""Failure anatomy and the label sources on planted traces: the onset run, the still window
against a brute-force scan, each failure type from the channel that marks it, and each source's
u_t from the quantity it names."""

from __future__ import annotations

import numpy as np
import pytest
import yaml
from conftest import CONFIG_DIR

from graspstab.labels.anatomy import grasp_anatomy, motion_onset, still_window_before, summarise
from graspstab.labels.sources import source_channels, unstable_steps
from graspstab.labels.windows import event_windows, step_counts, timestep_labels, window_starts

DT = 0.0005
T = 8000  # 4 s
SETTLE = 0  # 3.3.1 settles a grasp still and in contact from its first step at step 0


@pytest.fixture(scope="module")
def labels() -> dict:
    return yaml.safe_load((CONFIG_DIR / "labels" / "default.yaml").read_text())


def planted(slide_at: int | None = None, speed: float = 0.02, **extra: dict) -> dict:
    """A grasp at rest in contact (d = -1 mm), sliding along x at ``speed`` from ``slide_at``;
    ``extra`` channels replace the quiet defaults from ``slide_at`` (step index -> value)."""
    vel = np.zeros((T, 3))
    if slide_at is not None:
        vel[slide_at:, 0] = speed
    pos = np.cumsum(vel, axis=0) * DT
    tr = {"position": pos, "velocity": vel, "min_distance": np.full(T, -0.001),
          "tip_slip": np.zeros((T, 5)), "link_slip": np.zeros(T), "servo_load": np.full(T, 0.3),
          "spin": np.zeros(T)}  # fmt: skip
    for name, (at, value) in extra.items():
        tr[name][at:] = value
    return tr


def test_motion_onset_bridges_short_gaps_only() -> None:
    u = np.zeros(100, np.uint8)
    u[20:40] = 1
    u[43:60] = 1  # a 3-step gap
    assert motion_onset(u, 0, 60, gap=3) == 20
    assert motion_onset(u, 0, 60, gap=2) == 43
    assert motion_onset(u, 30, 60, gap=3) == 30  # never before settle
    assert motion_onset(np.zeros(100, np.uint8), 0, 60, gap=3) == 60


@pytest.mark.parametrize("seed", range(20))
def test_still_window_matches_a_brute_force_scan(seed: int) -> None:
    rng = np.random.default_rng(seed)
    u = (rng.random(200) < 0.08).astype(np.uint8)
    settle, onset = int(rng.integers(0, 50)), int(rng.integers(50, 200))
    w = int(rng.integers(1, 30))
    brute = any(not u[s : s + w].any() for s in range(settle, onset - w + 1))
    assert still_window_before(u, settle, onset, w) == brute


def test_a_held_grasp_has_no_failure(labels) -> None:
    a = grasp_anatomy(planted(), labels, DT)
    assert a["outcome"] == "held" and a["type"] is None


@pytest.mark.parametrize(("extra", "kind"), [
    ({"tip_slip": (3000, 0.02)}, "fingertip_slip"),
    ({"link_slip": (3000, 0.02), "tip_slip": (3100, 0.02)}, "link_slip"),
    ({"link_slip": (3100, 0.02), "tip_slip": (3000, 0.02)}, "fingertip_slip"),
    ({"spin": (3000, 2.0), "servo_load": (3000, 1.0)}, "rotation"),
    ({"servo_load": (3000, 1.0)}, "servo_saturation"),
    ({}, "compliance"),
])  # fmt: skip
def test_each_failure_type_comes_from_the_channel_that_marks_it(labels, extra, kind) -> None:
    """Still 1.4 s after settle, then sliding at 20 mm/s: 10 mm after 0.5 s, the failure."""
    a = grasp_anatomy(planted(3000, **extra), labels, DT)
    assert a["settle_s"] == SETTLE * DT
    assert a["outcome"] == "failed" and a["type"] == kind
    assert a["onset_s"] == pytest.approx((3000 - SETTLE) * DT)
    assert a["fail_s"] == pytest.approx((3000 - SETTLE) * DT + 0.5, abs=2 * DT)
    assert a["still_window"] and not a["moving_at_settle"]


def test_a_grasp_moving_from_its_settle_index_leaves_no_still_window(labels) -> None:
    """Creeping at 3 mm/s (above v_slip, below the 5 mm/s settle bound) from the start."""
    tr = planted(0, speed=0.003)
    a = grasp_anatomy(tr, labels, DT)
    assert a["outcome"] == "failed" and a["moving_at_settle"] and not a["still_window"]
    assert a["onset_s"] == 0.0
    s = summarise([a, grasp_anatomy(planted(), labels, DT)])
    assert (s["usable"], s["held"], s["failed"], s["still_window"]) == (2, 1, 1, 0)
    assert s["types"]["compliance"] == 1


def test_losing_contact_is_a_failure_however_short_the_slide(labels) -> None:
    tr = planted(3000, speed=0.002)
    tr["min_distance"][3100:] = np.nan
    a = grasp_anatomy(tr, labels, DT)
    assert a["outcome"] == "failed" and a["contact_lost"]
    assert a["fail_s"] == pytest.approx((3100 - SETTLE) * DT)


def test_each_label_source_reads_the_quantity_it_names(labels) -> None:
    tr = planted(3000, speed=0.002, tip_slip=(3500, 0.006))
    speed = np.linalg.norm(tr["velocity"], axis=1)
    np.testing.assert_array_equal(unstable_steps(tr, labels, SETTLE),
                                  timestep_labels(speed, labels["v_slip"]))  # fmt: skip
    slip = unstable_steps(tr, {**labels, "source": "contact_slip"}, SETTLE)
    assert slip[:3500].sum() == 0 and slip[3500:].all()
    # 2 mm/s from step 3000 covers 5 mm only at the trace's end (2.5 s = 5000 steps); 20 mm/s
    # in 0.25 s
    assert not unstable_steps(tr, {**labels, "source": "displacement"}, SETTLE)[:-2].any()
    tr2 = planted(3000, speed=0.02)
    moved = unstable_steps(tr2, {**labels, "source": "displacement"}, SETTLE)
    assert np.flatnonzero(moved)[0] == pytest.approx(3000 + 500, abs=2)
    assert source_channels({"source": "contact_slip"}) == ("tip_slip", "link_slip")
    with pytest.raises(ValueError, match="labels.source"):
        unstable_steps(tr, {**labels, "source": "vibes"}, SETTLE)


def test_event_windows_stop_at_the_onset_and_mark_the_onset_in_the_target() -> None:
    """Starts as eq. 26 draws them up to onset - W - O; positive exactly when the onset lies in
    [s + W + O, s + W + O + H); a grasp that holds gets eq. 26's starts, all negative."""
    w, o, h = 40, 20, 30
    rng = np.random.default_rng(0)
    starts, y = event_windows(100, 2000, 700, w, o, h, 1000, rng)
    assert starts.min() == 100 and starts.max() == 700 - w - o
    assert len(starts) == 700 - w - o - 100 + 1  # every start drawn when count allows
    first = starts + w + o
    np.testing.assert_array_equal(y == 1, (first <= 700) & (700 < first + h))
    assert y.sum() == h
    held, y0 = event_windows(100, 2000, None, w, o, h, 20, np.random.default_rng(0))
    want = window_starts(100, 2000, w, o, h, 20, np.random.default_rng(0))
    np.testing.assert_array_equal(held, want)
    assert not y0.any()
    none, _ = event_windows(100, 2000, 150, w, o, h, 20, rng)  # onset too early for a window
    assert len(none) == 0


def test_the_event_form_labels_a_planted_failure(labels) -> None:
    """A grasp still for 1.5 s that then slides away: its positive windows are those whose target
    interval holds the onset; a held grasp's are all negative."""
    from graspstab.labels.label_windows import grasp_windows

    ev = {**labels, "form": "event"}
    starts, r, y, rejected = grasp_windows(planted(3000), "obj", 1, {**ev, "windows_per_grasp":
                                           10_000}, 0.2, DT, 0)  # fmt: skip
    w, o, h = step_counts(0.2, ev["offset_s"], ev["horizon_s"], DT)
    assert rejected is None and starts.max() == 3000 - w - o
    np.testing.assert_array_equal(y == 1, starts + w + o + h > 3000)
    np.testing.assert_array_equal(r, y)
    _, _, y_held, _ = grasp_windows(planted(), "obj", 1, ev, 0.2, DT, 0)
    assert len(y_held) and not y_held.any()
