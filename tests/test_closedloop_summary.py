"""A protocol's closed-loop summary on planted tables: counts and shares by hand, intervals against
a brute-force bootstrap on the same draws, paired comparisons and the worse-grasp list."""

from __future__ import annotations

import numpy as np
import polars as pl
import pytest

from graspstab.closedloop.summary import (
    aggregate_closed_loop,
    answer,
    bootstrap_weights,
    default_comparisons,
    summarise_policies,
    worse_grasps,
)

N = 12  # grasps; the first 6 drop without a reflex, grasps 0-7 are failing


def planted() -> pl.DataFrame:
    """none: drops 0-5; always: drops none but 11 (pushed out); proxy: drops 0-2 (prevents 3-5),
    fires on 0-5 and on 9 (a false alarm); gru: as none but fires on 10 (a false alarm)."""
    rows = []
    for g in range(N):
        base = dict(
            object="a" if g < 7 else "b",
            grasp_id=g,
            usable=True,
            failing=g < 8,
            baseline_dropped=g < 6,
            lead_s=np.nan,
            latency_s=np.nan,
            slip_mm=np.nan,
            added_normal_mean_n=np.nan,
            added_normal_peak_n=np.nan,
            tightened_s=0.0,
            drop_s=np.nan,
            tighten_s=np.nan,
            warn_s=np.nan,
            peak_offset_rad=0.0,
        )
        for policy, dropped, fired in (
            ("none", g < 6, False),
            ("always", g == 11, True),
            ("proxy", g < 3, g < 6 or g == 9),
            ("gru", g < 6, g == 10),
        ):
            r = dict(
                base,
                policy=policy,
                dropped=dropped,
                fired=fired,
                prevented=(g < 6) and not dropped,
                worse=dropped and not g < 6,
                false_alarm=fired and not g < 8,
            )
            if fired:
                r["added_normal_mean_n"], r["tightened_s"] = 0.5 + 0.1 * g, 1.0
            rows.append(r)
    # an unusable grasp: left out of every figure
    rows.append(dict(rows[0], grasp_id=99, usable=False, dropped=True, worse=True))
    return pl.DataFrame(rows)


def test_counts_and_shares_are_what_the_planted_rows_give() -> None:
    table, _ = summarise_policies(planted(), ["none", "always", "proxy", "gru"], resamples=50)
    r = {row["policy"]: row for row in table.iter_rows(named=True)}
    assert all(row["grasps"] == N and row["baseline_drops"] == 6 for row in r.values())
    assert r["none"]["drop_rate"] == pytest.approx(6 / 12) and r["none"]["prevented"] == 0
    assert r["always"]["drops"] == 1 and r["always"]["worse"] == 1
    assert r["always"]["prevented_share"] == pytest.approx(1.0)
    assert r["always"]["worse_share"] == pytest.approx(1 / 6)
    # always fires on every grasp: the 4 holding ones (8-11) are false alarms
    assert r["always"]["false_alarm_rate"] == pytest.approx(4 / 4)
    assert r["proxy"]["prevented_share"] == pytest.approx(3 / 6)
    assert r["proxy"]["false_alarm_rate"] == pytest.approx(1 / 4)
    assert r["gru"]["false_alarms"] == 1 and r["gru"]["fired_rate"] == pytest.approx(1 / 12)
    # means over the grasps where a figure is defined (fired ones)
    assert r["proxy"]["added_normal_mean_n"] == pytest.approx(
        np.mean([0.5 + 0.1 * g for g in (0, 1, 2, 3, 4, 5, 9)])
    )
    assert np.isnan(r["none"]["added_normal_mean_n"])


def test_false_alarms_per_grasp_second_are_over_the_holding_grasps_armed_seconds() -> None:
    """Holding grasps 8-11 armed for 2 + g/4 s each: always alarms on all four, the proxy on 9,
    the gru on 10; a table without the exposure column gives the figure undefined."""
    t = planted().with_columns(armed_s=2.0 + pl.col("grasp_id") / 4)
    table, _ = summarise_policies(t, ["none", "always", "proxy", "gru"], resamples=50)
    r = {row["policy"]: row for row in table.iter_rows(named=True)}
    seconds = sum(2.0 + g / 4 for g in (8, 9, 10, 11))
    assert r["always"]["false_alarms_per_s"] == pytest.approx(4 / seconds)
    assert r["proxy"]["false_alarms_per_s"] == pytest.approx(1 / seconds)
    assert r["none"]["false_alarms_per_s"] == 0.0
    old, _ = summarise_policies(planted(), ["none", "gru"], resamples=20)
    assert old["false_alarms_per_s"].is_nan().all()


def test_intervals_match_a_brute_force_bootstrap_on_the_same_draws() -> None:
    resamples, seed = 300, 7
    table, _ = summarise_policies(
        planted(), ["none", "proxy"], resamples=resamples, seed=seed, level=0.9
    )
    proxy = table.filter(pl.col("policy") == "proxy").row(0, named=True)
    rng = np.random.default_rng(seed)
    draws = rng.integers(0, N, (resamples, N))
    prevented = np.array([g in (3, 4, 5) for g in range(N)])
    dropped_base = np.arange(N) < 6
    shares = []
    for d in draws:
        denom = sum(dropped_base[i] for i in d)
        if denom:
            shares.append(sum(prevented[i] for i in d) / denom)
    lo, hi = np.quantile(shares, [0.05, 0.95])
    assert (proxy["prevented_share_lo"], proxy["prevented_share_hi"]) == pytest.approx((lo, hi))
    w = bootstrap_weights(N, resamples, seed)
    assert w.shape == (resamples, N) and np.all(w.sum(axis=1) == N)


def test_the_object_bootstrap_draws_whole_objects_against_brute_force() -> None:
    """Grasps 0-6 are object a, 7-11 object b: each resample counts every grasp of an object as
    often as the object was drawn, and the proxy's prevented share is a ratio of those sums."""
    resamples, seed = 200, 3
    objects = ["a" if g < 7 else "b" for g in range(N)]
    w = bootstrap_weights(N, resamples, seed, objects)
    rng = np.random.default_rng(seed)
    picks = rng.integers(0, 2, (resamples, 2))
    want = np.array([[np.sum(p == (0 if o == "a" else 1)) for o in objects] for p in picks])
    np.testing.assert_array_equal(w, want)
    table, _ = summarise_policies(planted(), ["none", "proxy"], resamples=resamples, seed=seed,
                                  level=0.9, unit="object")  # fmt: skip
    proxy = table.filter(pl.col("policy") == "proxy").row(0, named=True)
    prevented = np.array([g in (3, 4, 5) for g in range(N)], float)
    dropped = (np.arange(N) < 6).astype(float)
    with np.errstate(invalid="ignore", divide="ignore"):
        shares = (want @ prevented) / (want @ dropped)
    lo, hi = np.quantile(shares[np.isfinite(shares)], [0.05, 0.95])
    assert (proxy["prevented_share_lo"], proxy["prevented_share_hi"]) == pytest.approx((lo, hi))
    with pytest.raises(ValueError, match="grasp or object"):
        summarise_policies(planted(), ["none"], resamples=100, unit="fold")


def test_paired_comparisons_resolve_a_clear_gain_and_tie_identical_policies() -> None:
    t = planted()
    t = pl.concat([t, t.filter(pl.col("policy") == "gru").with_columns(policy=pl.lit("twin"))])
    pols = ["none", "always", "proxy", "gru", "twin"]
    _, pairs = summarise_policies(
        t, pols, resamples=500, compare=[("always", "none"), ("twin", "gru")]
    )
    p = {(r["policy"], r["against"], r["figure"]): r for r in pairs.iter_rows(named=True)}
    drop = p[("always", "none", "drop_rate")]
    assert drop["diff"] == pytest.approx(1 / 12 - 6 / 12) and drop["verdict"] == "lower"
    assert p[("always", "none", "false_alarm_rate")]["verdict"] == "higher"
    twin = p[("twin", "gru", "drop_rate")]
    assert twin["diff"] == 0 and twin["lo"] == 0 and twin["hi"] == 0
    assert twin["verdict"] == "not resolved"
    assert default_comparisons(pols) == [
        ("gru", "proxy"),
        ("twin", "proxy"),
        ("always", "none"),
        ("proxy", "none"),
        ("gru", "none"),
        ("twin", "none"),
    ]


def test_worse_lists_every_grasp_a_policy_pushes_out_and_missing_rows_are_named() -> None:
    worse = worse_grasps(planted())
    assert worse.select("policy", "grasp_id").rows() == [("always", 11)]  # unusable 99 left out
    t = planted().filter(~((pl.col("policy") == "gru") & (pl.col("grasp_id") == 4)))
    with pytest.raises(ValueError, match="policy 'gru' has no row for object 'a' grasp 4"):
        summarise_policies(t, ["none", "gru"], resamples=10)


def test_aggregate_writes_the_tables_and_states_the_answer(tmp_path) -> None:
    t = planted()
    paths = []
    for obj in ("a", "b"):
        paths.append(tmp_path / f"{obj}.parquet")
        t.filter(pl.col("object") == obj).write_parquet(paths[-1])
    pols = ["none", "always", "proxy", "gru"]
    summary = aggregate_closed_loop([str(p) for p in paths], pols, "creep_free",
                                    {"resamples": 400, "level": 0.95, "seed": 0},
                                    str(tmp_path / "out"))  # fmt: skip
    assert summary["grasps"] == N and summary["unusable"] == 1 and summary["objects"] == ["a", "b"]
    assert summary["worse_by_policy"] == {"none": 0, "always": 1, "proxy": 0, "gru": 0}
    text = summary["answer"]
    assert text.startswith("Under the creep-free benchmark, over 12 test grasps (6 dropped")
    assert (
        "gru drops 50.0 % against the proxy's 25.0 % (no resolved difference from the proxy: +25.0 "
        "points [+0.0, +50.0]" in text
    )
    assert "Always (the force-hungry bound) prevents 6 of 6." in text and "oracle" not in text
    for name in ("policies", "comparisons", "worse"):
        assert pl.read_parquet(tmp_path / "out" / f"{name}.parquet").height > 0


def test_tradeoff_sets_each_variant_beside_its_policys_defaults(tmp_path) -> None:
    t = planted().with_columns(parameter=pl.lit(""), value=pl.lit(float("nan")))
    variant = t.filter(pl.col("policy") == "gru").with_columns(
        policy=pl.lit("proxy@amount=0.1"), parameter=pl.lit("amount"), value=pl.lit(0.1)
    )
    t.vstack(variant).write_parquet(tmp_path / "a.parquet")
    pols = ["none", "always", "proxy", "gru"]
    summary = aggregate_closed_loop([str(tmp_path / "a.parquet")], pols, "reference",
                                    {"resamples": 200, "level": 0.95, "seed": 0},
                                    str(tmp_path / "out"))  # fmt: skip
    assert summary["swept"] == 1
    assert pl.read_parquet(tmp_path / "out/policies.parquet")["policy"].to_list() == pols
    trade = pl.read_parquet(tmp_path / "out/tradeoff.parquet")
    assert trade.select("policy", "base", "parameter").rows() == [
        ("proxy", "proxy", "default"), ("proxy@amount=0.1", "proxy", "amount")
    ]  # fmt: skip
    # the variant is gru's rows: its figures are gru's, on the same grasps
    assert trade["prevented_share"].to_list() == pytest.approx([0.5, 0.0])
    assert trade["false_alarm_rate"].to_list() == pytest.approx([0.25, 0.25])


def test_the_answer_says_when_false_alarms_are_undefined() -> None:
    t = planted().filter(pl.col("grasp_id") < 8)  # every grasp fails without a reflex
    pols = ["none", "proxy", "gru"]
    p, c = summarise_policies(t, pols, resamples=100, compare=default_comparisons(pols))
    text = answer("creep_free", p, c, 0.95)
    assert "false alarms undefined: no grasp holds without a reflex" in text and "nan" not in text


def test_the_answer_states_each_monitor_against_its_shuffled_timing() -> None:
    """A shuffled control identical to its monitor: the comparison is zero with a zero interval,
    and the answer says so in its own clause."""
    t = planted()
    t = pl.concat([t, t.filter(pl.col("policy") == "gru").with_columns(
        policy=pl.lit("gru~shuffled"))])  # fmt: skip
    pols = ["none", "always", "proxy", "gru", "gru~shuffled"]
    table, pairs = summarise_policies(t, pols, resamples=100, compare=default_comparisons(pols))
    text = answer("reference", table, pairs, 0.95)
    assert ("Against its own tightening times dealt to other grasps (the shuffled control), "
            "drop rate: gru +0.0 points [+0.0, +0.0].") in text
