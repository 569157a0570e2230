"""Labelling rules (3.3) on synthetic traces with hand-computed answers, plus window properties."""

from __future__ import annotations

import numpy as np
import pytest
import yaml
from conftest import CONFIG_DIR
from hypothesis import given, settings
from hypothesis import strategies as st

from graspstab.labels.interval import (
    distance_tolerance,
    earliest_run,
    settle_by_distance,
    settle_by_speed,
    usable_interval,
)
from graspstab.labels.windows import predictive_labels, step_counts, timestep_labels, window_starts

LABELS = yaml.safe_load((CONFIG_DIR / "labels" / "default.yaml").read_text())
P = LABELS["settle"]
DT = 0.0005
N = 8000  # 4 s of rows


def _quiet_after(i: int, fast: float = 0.05) -> np.ndarray:
    """Speed 50 mm/s before row i, 1 mm/s after."""
    speed = np.full(N, 0.001)
    speed[:i] = fast
    return speed


def _dist_settles_at(i: int) -> np.ndarray:
    """d_t wandering by 3 mm before row i, constant -1 mm after (with 0.01 mm jitter)."""
    rng = np.random.default_rng(0)
    dist = -0.001 + rng.normal(scale=1e-5, size=N)
    dist[:i] = -0.001 + 0.003 * np.sin(np.arange(i) / 20.0)
    return dist


def test_step_counts_are_the_references() -> None:
    assert step_counts(0.2, 0.1, 0.15, DT) == (400, 200, 300)  # 3.3.3
    assert step_counts(LABELS["window_s"], LABELS["offset_s"], LABELS["horizon_s"], DT) == (
        400, 200, 300,
    )  # fmt: skip
    assert step_counts(0.01, 0.1, 0.15, DT) == (20, 200, 300)  # the sweep's shortest window


def test_earliest_run_by_hand() -> None:
    ok = np.array([1, 1, 0, 1, 1, 1, 0, 1, 1, 1, 1], dtype=bool)
    assert earliest_run(ok, 3, 11) == 3
    assert earliest_run(ok, 4, 11) == 7
    assert earliest_run(ok, 4, 10) is None  # the run must end within the limit
    assert earliest_run(ok, 5, 11) is None


def test_settle_by_speed_only() -> None:
    speed, dist = _quiet_after(1000), np.full(N, np.nan)  # no contact: distance check fails
    assert settle_by_speed(speed, DT, P) == 1000
    assert settle_by_distance(dist, DT, P) is None
    got = usable_interval(speed, dist, DT, P, LABELS["contact_loss_s"])
    assert (got.settle_index, got.settle_rule) == (1000, "speed")


def test_settle_by_distance_only() -> None:
    speed, dist = np.full(N, 0.05), _dist_settles_at(1500)  # always fast
    assert settle_by_speed(speed, DT, P) is None
    ref, tol = distance_tolerance(dist, DT, P)
    assert ref == pytest.approx(-0.001, abs=1e-5) and tol == P["distance_tol_min"]  # 0.5 mm floor
    got = usable_interval(speed, dist, DT, P, LABELS["contact_loss_s"])
    # the sine stays within 0.5 mm of -1 mm only near its zero crossings, for far less than 0.1 s
    assert got.settle_rule == "distance" and 1400 <= got.settle_index <= 1500


def test_settle_by_both_takes_the_later() -> None:
    got = usable_interval(_quiet_after(2000), _dist_settles_at(1500), DT, P, 0.1)
    assert got.settle_rule == "both" and got.settle_index == 2000
    got = usable_interval(_quiet_after(500), _dist_settles_at(1500), DT, P, 0.1)
    assert got.settle_rule == "both" and 1400 <= got.settle_index <= 1500


def test_settle_by_neither_falls_back_to_3_s() -> None:
    got = usable_interval(np.full(N, 0.05), np.full(N, np.nan), DT, P, 0.1)
    assert (got.settle_index, got.settle_rule) == (6000, "fallback")


def test_settle_reading_both_requires_both_checks() -> None:
    """settle.require = both: one successful check is not enough, the 3 s fallback applies; when
    both succeed the two readings agree."""
    both = dict(P, require="both")
    assert P["require"] == "either"
    cases = [(_quiet_after(1000), np.full(N, np.nan)), (np.full(N, 0.05), _dist_settles_at(1500))]
    for speed, dist in cases:
        assert usable_interval(speed, dist, DT, P, 0.1).settle_rule in ("speed", "distance")
        got = usable_interval(speed, dist, DT, both, 0.1)
        assert (got.settle_index, got.settle_rule) == (6000, "fallback")
    speed, dist = _quiet_after(2000), _dist_settles_at(1500)
    assert usable_interval(speed, dist, DT, both, 0.1) == usable_interval(speed, dist, DT, P, 0.1)
    with pytest.raises(ValueError, match="require"):
        usable_interval(speed, dist, DT, dict(P, require="one"), 0.1)


def test_settle_interval_must_lie_within_the_search() -> None:
    # quiet only from 2.95 s: the 0.1 s interval would end after 3 s
    assert settle_by_speed(_quiet_after(5900), DT, P) is None
    assert settle_by_speed(_quiet_after(5800), DT, P) == 5800


def test_contact_end_and_depth_rejection() -> None:
    speed, dist = _quiet_after(1000), np.full(N, -0.001)
    dist[3000:3150] = np.nan  # a 75 ms gap: not a contact end
    dist[5000:] = np.nan  # the real loss
    got = usable_interval(speed, dist, DT, P, 0.1)
    assert got.contact_end == 5000 and got.rejected is None
    deep = np.full(N, -0.001)
    deep[2000:3999] = -0.009  # 0.9995 s below -8 mm: kept
    assert usable_interval(speed, deep, DT, P, 0.1).rejected is None
    deep[3999] = -0.009  # exactly 1 s: rejected
    assert usable_interval(speed, deep, DT, P, 0.1).rejected == "depth"
    early = np.full(N, -0.001)
    early[:900] = -0.009  # deep only before settling: kept
    assert usable_interval(speed, early, DT, P, 0.1).rejected is None


def test_timestep_labels_threshold() -> None:
    u = timestep_labels(np.array([0.0, 0.0011999, 0.0012, 0.01]), LABELS["v_slip"])
    assert u.tolist() == [0, 0, 1, 1]


def test_predictive_labels_by_hand_including_the_band_edges() -> None:
    w, o, h = 4, 2, 20
    u = np.zeros(100, dtype=np.uint8)
    starts = np.array([0, 30])
    # the target of start s is [s + 6, s + 26)
    u[6:13] = 1  # start 0: 7 of 20 = 0.35 exactly: label 0 (r <= 0.35)
    u[43:56] = 1  # start 30: [36, 56) holds 13 of 20 = 0.65 exactly: label 1 (r >= 0.65)
    r, y = predictive_labels(u, starts, 100, w, o, h, 0.35, 0.65)
    assert r[0] == 0.35 and y[0] == 0
    assert r[1] == 0.65 and y[1] == 1
    u[13] = 1  # 8 of 20 = 0.4: inside the band, discarded
    assert predictive_labels(u, starts, 100, w, o, h, 0.35, 0.65)[1][0] == -1
    # start 40 with contact ending at 56: target [46, 56) truncated to 10 rows
    u2 = np.zeros(100, dtype=np.uint8)
    u2[46:51] = 1  # 5 of 10 = 0.5: ambiguous, discarded
    r, y = predictive_labels(u2, np.array([40, 60]), 56, w, o, h, 0.35, 0.65)
    assert r[0] == pytest.approx(0.5) and y[0] == -1
    assert np.isnan(r[1]) and y[1] == -1  # no target left: discarded


@settings(max_examples=200, deadline=None)
@given(
    settle=st.integers(0, 3000),
    length=st.integers(0, 4000),
    count=st.integers(1, 30),
    seed=st.integers(0, 2**32 - 1),
)
def test_window_starts_properties(settle: int, length: int, count: int, seed: int) -> None:
    w, o, h = 400, 200, 300
    end = settle + length
    starts = window_starts(settle, end, w, o, h, count, np.random.default_rng(seed))
    valid = end - w - o - h >= settle
    assert len(starts) == (min(count, end - w - o - h - settle + 1) if valid else 0)
    assert len(np.unique(starts)) == len(starts)  # distinct
    if valid:
        assert starts[0] == settle  # the settle window is always in
        assert starts.min() >= settle and starts.max() + w + o + h <= end
        # every target interval is whole, so no window is discarded for being empty
        _, y = predictive_labels(np.zeros(end + 1, np.uint8), starts, end, w, o, h, 0.35, 0.65)
        assert (y == 0).all()
    again = window_starts(settle, end, w, o, h, count, np.random.default_rng(seed))
    assert np.array_equal(starts, again)  # seeded


@settings(max_examples=100, deadline=None)
@given(
    n=st.integers(0, 30),
    w_ref=st.integers(1, 60),
    frac=st.floats(0.0, 1.0),
    seed=st.integers(0, 2**32 - 1),
)
def test_same_end_trimming_invariants(n: int, w_ref: int, frac: float, seed: int) -> None:
    import polars as pl

    from graspstab.labels.trim import trim_same_end

    rng = np.random.default_rng(seed)
    w = max(1, int(round(frac * w_ref)))
    starts = rng.integers(0, 1000, n)
    index = pl.DataFrame({
        "sample_id": np.arange(n), "start": starts, "end": starts + w_ref,
        "r": rng.random(n), "label": rng.integers(0, 2, n).astype(np.int8),
        "split": rng.choice(["train", "val", "test"], n),
    })  # fmt: skip
    windows = rng.random((n, w_ref, 5, 2)).astype(np.float32)
    got, cut = trim_same_end(index, windows, w)
    offset, horizon = 200, 300
    assert got.height == index.height and cut.shape == (n, w, 5, 2)  # sample count, length
    assert got["end"].to_list() == index["end"].to_list()  # same end time ...
    assert ((got["end"] - got["start"]) == w).all()
    # ... the same offset and target interval: first target step s + W + O (eq. 29) agrees
    first_trimmed = got["start"].to_numpy() + w + offset
    first_reference = index["start"].to_numpy() + w_ref + offset
    assert np.array_equal(first_trimmed, first_reference)
    assert np.array_equal(first_trimmed + horizon, first_reference + horizon)
    for col in ("sample_id", "r", "label", "split"):  # same samples, labels and splits
        assert got[col].to_list() == index[col].to_list()
    np.testing.assert_array_equal(cut, windows[:, w_ref - w :])  # the reference's last frames


def test_trimming_rejects_longer_windows() -> None:
    import polars as pl

    from graspstab.labels.trim import trim_same_end

    index = pl.DataFrame({"start": [0], "end": [10]})
    with pytest.raises(ValueError, match="1 <= W <= 10"):
        trim_same_end(index, np.zeros((1, 10, 5, 2), np.float32), 11)
