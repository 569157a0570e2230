"""benchmarks/label_sources.py: eq. 23's labels against the displacement label, on constructed
object paths against hand-computed references."""

from __future__ import annotations

import importlib.util
import math

import numpy as np
import pytest

from tests.conftest import REPO

spec = importlib.util.spec_from_file_location(
    "label_sources", REPO / "benchmarks" / "label_sources.py"
)
ls = importlib.util.module_from_spec(spec)
spec.loader.exec_module(ls)


def test_displacement_and_onset_of_an_object_leaving_after_a_still_period() -> None:
    # still for 10 steps after settle (index 2), then 1 mm per step along x
    x = np.concatenate([np.zeros(12), np.arange(1, 11) * 1e-3])
    pos = np.stack([x, np.zeros_like(x), np.zeros_like(x)], axis=1) + [0.1, 0.2, 0.3]
    d = ls.displacement_labels(pos, 2, 0.0045)
    assert d[:16].sum() == 0 and d[16:].all()  # 5 mm > 4.5 mm from step 16 on
    assert ls.failure_onset(pos, 2, len(x), 0.0045) == 16
    assert ls.failure_onset(pos, 2, 15, 0.0045) is None  # contact ended first
    assert ls.failure_onset(pos, 2, len(x), 0.05) is None


def test_confusion_and_kappa_against_hand_counts() -> None:
    a = np.array([1, 1, 0, 0, 1, 0, 0, 0])
    b = np.array([1, 0, 1, 0, 1, 0, 0, 0])
    c = ls.confusion(a, b)
    assert c == {"both": 2, "first_only": 1, "second_only": 1, "neither": 4}
    # agreement 6/8, chance (3/8)^2 + (5/8)^2 = 34/64
    assert ls.kappa(c) == pytest.approx((6 / 8 - 34 / 64) / (1 - 34 / 64))
    assert ls.kappa(ls.confusion(a, a)) == pytest.approx(1.0)
    assert math.isnan(ls.kappa(ls.confusion(np.zeros(4), np.zeros(4))))


def test_still_windows_need_every_observed_step_below_v_slip() -> None:
    u = np.zeros(20, dtype=np.uint8)
    u[7] = 1
    starts = np.array([0, 3, 8, 12])
    # windows [0, 5), [3, 8) holds step 7, [8, 13), [12, 17)
    assert ls.still_windows(u, starts, 5).tolist() == [True, False, True, True]
    assert ls.still_windows(u, np.array([7]), 1).tolist() == [False]


def test_slip_rows_count_eq23_steps_without_contact_slip(tmp_path) -> None:
    """A replay still for 1 s, then moving at 3 mm/s with its fingertip contacts sliding at
    2 mm/s for 1 s, then at 20 mm/s with them sliding at 20 mm/s: at a 5 mm/s slip speed the
    first moving second is eq. 23 unstable with no contact slip."""
    import polars as pl
    import yaml

    from graspstab.common.io import save_npz
    from graspstab.replay.traces import trace_key

    dt, n = 0.0005, 6000
    vel = np.zeros((n, 3))
    vel[2000:4000, 0], vel[4000:, 0] = 0.003, 0.02
    tip = np.zeros((n, 5))
    tip[2000:4000, 1], tip[4000:, 1] = 0.002, 0.02
    tr = {"velocity": vel, "position": np.cumsum(vel, axis=0) * dt,
          "min_distance": np.full(n, -0.001), "tip_slip": tip, "link_slip": np.zeros(n)}
    folder = tmp_path / "replay" / "obj"
    folder.mkdir(parents=True)
    pl.DataFrame({"grasp_id": [0], "object": ["obj"], "diverged": [False]}).write_parquet(
        folder / "replays_0.parquet")  # fmt: skip
    save_npz(folder / "traces_0.npz", **{trace_key(0, c): v for c, v in tr.items()})
    lab = yaml.safe_load((REPO / "config" / "labels" / "default.yaml").read_text())
    assert ls.records_slip(tmp_path / "replay")
    row = ls.slip_rows(tmp_path / "replay", lab, dt, [0.005])[0]
    assert row["steps"] == n  # settled at step 0, in contact throughout
    assert row["eq23 unstable"] == pytest.approx(4000 / n)
    assert row["contact slip"] == pytest.approx(2000 / n)
    assert row["eq23 unstable, no slip"] == pytest.approx(0.5)
