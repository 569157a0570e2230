"""Object-level k-fold cross-validation: fold invariants, the vectorised metrics against
scikit-learn, bootstrap and paired-comparison behaviour on constructed cases, the fairness
variants' features against brute force, and the study's config checks."""

from __future__ import annotations

import numpy as np
import polars as pl
import pytest
from sklearn.metrics import average_precision_score, roc_auc_score

from graspstab.config import ConfigError, load_config
from graspstab.evaluation import crossval as cv
from graspstab.evaluation.folds import deal_folds, kfold_assignments
from graspstab.learning.data import transformed_statistics
from graspstab.learning.features import gain_normalise, ratio_channel, window_transform
from tests.conftest import CONFIG_DIR, SCHEMA

OBJECTS = [f"{i:03d}_obj" for i in range(44)]


@pytest.mark.parametrize("k", [3, 4, 11, 44])
def test_every_object_is_a_test_object_exactly_once(k):
    folds = kfold_assignments(OBJECTS, k, seed=0)
    assert len(folds) == k
    tested = [o for a in folds for o, s in a.items() if s == "test"]
    assert sorted(tested) == sorted(OBJECTS)
    for a in folds:
        assert set(a) == set(OBJECTS)  # every object has one role in every fold
        n_test = sum(s == "test" for s in a.values())
        n_val = sum(s == "val" for s in a.values())
        assert n_test in (len(OBJECTS) // k, -(-len(OBJECTS) // k))
        assert n_val >= 1 and sum(s == "train" for s in a.values()) >= 1


def test_validation_is_the_next_fold_and_never_the_test_fold():
    folds = deal_folds(OBJECTS, 11, seed=3)
    for i, a in enumerate(kfold_assignments(OBJECTS, 11, seed=3)):
        assert sorted(o for o, s in a.items() if s == "test") == folds[i]
        assert sorted(o for o, s in a.items() if s == "val") == folds[(i + 1) % 11]


def test_folds_depend_on_the_seed_only():
    assert kfold_assignments(OBJECTS, 11, 0) == kfold_assignments(list(reversed(OBJECTS)), 11, 0)
    assert kfold_assignments(OBJECTS, 11, 0) != kfold_assignments(OBJECTS, 11, 1)


@pytest.mark.parametrize("k, val_folds", [(2, 1), (45, 1), (5, 4)])
def test_impossible_folds_are_refused(k, val_folds):
    with pytest.raises(ValueError):
        kfold_assignments(OBJECTS, k, 0, val_folds)


@pytest.mark.parametrize("seed", range(5))
def test_metrics_match_scikit_learn_with_ties(seed):
    rng = np.random.default_rng(seed)
    y = rng.integers(0, 2, 300)
    s = np.round(rng.normal(size=300) + y, 1)  # rounding makes many ties
    assert cv.average_precision(s, y) == pytest.approx(average_precision_score(y, s), abs=1e-12)
    assert cv.roc_auc(s, y) == pytest.approx(roc_auc_score(y, s), abs=1e-12)
    assert np.isnan(cv.average_precision(s, np.zeros(300)))


def test_grasp_bootstrap_of_a_perfect_scorer_is_exact_and_of_noise_brackets_it():
    rng = np.random.default_rng(0)
    grasps = np.repeat(np.arange(40), 5)
    y = (grasps % 2).astype(int)
    perfect = cv.grasp_bootstrap(y.astype(float), y, grasps, 200, rng)
    assert perfect["auprc"] == perfect["auprc_lo"] == perfect["auprc_hi"] == 1.0
    noisy = cv.grasp_bootstrap(y + rng.normal(0, 1.0, y.size), y, grasps, 300, rng)
    assert noisy["auroc_lo"] < noisy["auroc"] < noisy["auroc_hi"]
    assert noisy["auroc_hi"] - noisy["auroc_lo"] > 0.02


def test_paired_comparison_finds_a_consistent_gain_and_not_a_null_one():
    rng = np.random.default_rng(1)
    proxy = {f"o{i}": float(v) for i, v in enumerate(rng.uniform(0.5, 0.8, 30))}
    better = {o: v + 0.1 for o, v in proxy.items()}
    r = cv.paired_comparison(better, proxy, 1000, rng)
    assert r["mean_diff"] == pytest.approx(0.1)
    assert r["lo"] > 0 and r["wins"] == 30 and r["verdict"] == "learned better"
    assert r["sign_p"] < 1e-6
    null = {o: v + rng.normal(0, 0.05) for o, v in proxy.items()}
    n = cv.paired_comparison(null, proxy, 1000, rng)
    assert n["lo"] < n["mean_diff"] < n["hi"]
    worse = cv.paired_comparison(proxy, better, 1000, rng)
    assert worse["verdict"] == "proxy better"
    proxy["o0"] = float("nan")  # an object with one class only is left out of the pairing
    assert cv.paired_comparison(better, proxy, 100, rng)["objects"] == 29


def _index(objects, grasps_per_object=3, windows=2):
    rows = [(o, g, w) for o in objects for g in range(grasps_per_object) for w in range(windows)]
    return pl.DataFrame(
        {
            "sample_id": list(range(len(rows))),
            "object": [r[0] for r in rows],
            "shard": [0] * len(rows),
            "grasp_id": [r[1] for r in rows],
            "label": [(r[1] + r[2]) % 2 for r in rows],
        }
    )


def test_scored_windows_refuses_an_object_tested_in_two_folds():
    index = _index(["a", "b"])
    preds = index.select(
        "sample_id",
        "object",
        pl.lit("test").alias("split"),
        pl.col("label").cast(pl.Float64).alias("prob"),
    )
    proxy = index.select("sample_id", pl.col("label").cast(pl.Float64).alias("score"))
    one = {"family": "gru", "variant": "forces", "seed": 42}
    ok = cv.scored_windows(
        [
            {**one, "fold": 0, "predictions": preds.filter(pl.col("object") == "a")},
            {**one, "fold": 1, "predictions": preds.filter(pl.col("object") == "b")},
        ],
        index,
        proxy,
    )
    assert ok.filter(pl.col("scorer") == "proxy").height == index.height
    assert sorted(ok["scorer"].unique()) == ["gru", "proxy"]
    with pytest.raises(ValueError, match="more than one fold"):
        cv.scored_windows(
            [{**one, "fold": 0, "predictions": preds}, {**one, "fold": 1, "predictions": preds}],
            index,
            proxy,
        )


def test_ratio_channel_is_the_per_fingertip_shear_over_floored_normal():
    raw = np.zeros((1, 2, 5, 2), dtype=np.float32)
    raw[0, :, 0] = [2.0, 1.0]  # tip 0: normal 2, shear 1
    raw[0, :, 1] = [0.0, 0.3]  # tip 1: unloaded normal, some shear
    out = ratio_channel(raw, eps=0.05)
    assert out.shape == (1, 2, 5, 3)
    assert out[0, 0, 0, 2] == pytest.approx(0.5)
    assert out[0, 0, 1, 2] == pytest.approx(0.3 / 0.05)
    assert out[0, 0, 2, 2] == 0.0


def test_gain_normalisation_is_gain_invariant():
    rng = np.random.default_rng(2)
    raw = rng.uniform(0.1, 3.0, (8, 20, 5, 2)).astype(np.float32)
    np.testing.assert_allclose(
        gain_normalise(3.7 * raw, 0.01), gain_normalise(raw, 0.01), rtol=1e-5
    )
    # the window's mean total normal force becomes one
    np.testing.assert_allclose(gain_normalise(raw, 0.01)[..., 0].sum(-1).mean(-1), 1.0, rtol=1e-5)
    t = window_transform(
        {"ratio_channel": True, "window_norm": "gain", "ratio_eps": 0.05, "gain_eps": 0.01}
    )
    np.testing.assert_allclose(t(2.0 * raw), t(raw), rtol=1e-4)
    assert window_transform({"ratio_eps": 0.05, "gain_eps": 0.01}) is None


def test_transformed_statistics_match_brute_force():
    rng = np.random.default_rng(3)
    raw = rng.uniform(0.0, 2.0, (50, 6, 5, 2)).astype(np.float32)
    index = pl.DataFrame({"split": ["train"] * 30 + ["val"] * 20})
    t = window_transform({"ratio_channel": True, "ratio_eps": 0.05, "gain_eps": 0.01})
    mean, std = transformed_statistics(raw, index, t, 1e-6, chunk=7)
    flat = t(raw[:30]).reshape(-1, 5, 3).astype(np.float64)
    np.testing.assert_allclose(mean, flat.mean(0), rtol=1e-6)
    np.testing.assert_allclose(std, flat.std(0), rtol=1e-5)


def test_the_wide_object_set_and_its_study_are_valid():
    cfg = load_config(CONFIG_DIR, SCHEMA, {"profile": "wide"}, check_files=False)
    items = cfg["objects"]["items"]
    assert len(items) == 44 and all(e.get("shape") for e in items.values())
    assert all(e.get("sha256") for e in items.values())
    assert cfg["crossval"]["enabled"] and cfg["creep_free"]["enabled"]


@pytest.mark.parametrize(
    "override, message",
    [
        ({"crossval": {"k": 45}}, "crossval.k = 45"),
        ({"creep_free": {"enabled": False}}, "creep_free.enabled is false"),
        ({"crossval": {"window_s": 0.03}}, "not a sweep window"),
        ({"crossval": {"val_folds": 10, "k": 11}}, "leaves no training fold"),
    ],
)
def test_impossible_studies_are_refused_at_load_time(override, message):
    with pytest.raises(ConfigError, match=message):
        load_config(CONFIG_DIR, SCHEMA, {"profile": "wide", **override}, check_files=False)


def test_the_study_from_fold_predictions_to_the_report_section(tmp_path):
    """aggregate_crossval on a small dataset whose learned scores are the labels plus noise and
    whose windows carry a weak friction-ratio signal: the learned scorer must beat the proxy, the
    figure and the report section must be written from the files alone."""
    from graspstab.common.io import read_json, read_parquet, save_npy, write_json, write_parquet
    from graspstab.evaluation import studies
    from graspstab.figures.crossval import plot_crossval
    from graspstab.report.crossval import crossval_section

    rng = np.random.default_rng(5)
    objects = [f"{i:03d}_obj" for i in range(9)]
    index = _index(objects, grasps_per_object=6, windows=4).with_columns(
        pl.lit("train").alias("split")
    )
    y = index["label"].to_numpy()
    windows = rng.uniform(1.0, 2.0, (index.height, 3, 5, 2)).astype(np.float32)
    windows[:, -1, :, 1] *= 0.5 + 0.3 * y[:, None] + rng.normal(0, 0.4, (index.height, 1))
    data = tmp_path / "dataset"
    data.mkdir()
    write_parquet(data / "index.parquet", index)
    save_npy(data / "windows.npy", windows)
    # half the windows' objects move over their observation period (those are moving-now)
    moving = (np.arange(index.height) % 2 == 0).astype(np.float32)[:, None] * np.ones((1, 3))
    save_npy(data / "motion.npy", np.stack([moving, 0.01 * moving], -1).astype(np.float32))
    write_json(
        data / "normalisation.json",
        {"mean": np.zeros((5, 2)).tolist(), "std": np.ones((5, 2)).tolist(), "eps": 1e-6},
    )
    folds = kfold_assignments(objects, 3, seed=0)
    keys, paths, metric_paths = [], [], []
    grid = [0.05, 0.95, 0.005]
    alarms = {"forces": np.zeros(4, dtype=np.int64)}
    for k, a in enumerate(folds):
        test = index.filter(pl.col("object").is_in([o for o, s in a.items() if s == "test"]))
        label = test["label"].to_numpy()
        # the plain run separates the classes; the "gain" variant here scores noise, and its
        # threshold sits on the grid's floor, so it alarms on every window
        probs = {
            "forces": np.clip(label * 0.6 + rng.uniform(0, 0.5, test.height), 0, 1),
            "gain": rng.uniform(0.1, 1.0, test.height),
        }
        for variant, prob in probs.items():
            p = tmp_path / f"{variant}_f{k}.parquet"
            write_parquet(
                p,
                test.select(
                    "sample_id",
                    "object",
                    "label",
                    pl.lit("test").alias("split"),
                    pl.Series("prob", prob),
                ),
            )
            t = 0.5 if variant == "forces" else grid[0]
            if variant == "forces":
                pred = prob >= t
                alarms["forces"] += [
                    np.sum(pred & (label == 1)), np.sum(pred & (label == 0)),
                    np.sum(~pred & (label == 1)), np.sum(~pred & (label == 0)),
                ]  # fmt: skip
            m = tmp_path / f"{variant}_f{k}.json"
            write_json(
                m,
                {
                    "threshold": {"threshold": t},
                    "params": {
                        "train": {
                            "threshold": {
                                "rule": "min_recall",
                                "min_recall": 0.9,
                                "grid": grid,
                            }
                        }
                    },
                },  # fmt: skip
            )
            keys.append({"family": "gru", "variant": variant, "fold": k, "seed": 42})
            paths.append(p)
            metric_paths.append(m)
    props = {
        o: {"mass": 0.1 * (i + 1), "shape": "box", "size": 0.05} for i, o in enumerate(objects)
    }
    out = tmp_path / "study"
    summary = studies.aggregate_crossval(
        paths,
        metric_paths,
        keys,
        data,
        props,
        "reference",
        {"resamples": 200, "level": 0.95, "seed": 0},
        out,
    )
    assert summary["tested_objects"] == objects and summary["folds"] == 3
    assert summary["pooled"]["gru"]["windows"] == index.height
    # the still-now windows (odd sample ids), the persistence oracle beside the scorers
    still = summary["pooled_still"]
    assert still["gru"]["windows"] == index.height // 2 and "persistence" in still
    assert still["gru"]["chance"] == pytest.approx(y[1::2].mean())
    assert still["persistence"]["auroc"] == pytest.approx(0.5)  # it scores every one 0
    assert summary["oracle"]["windows"] == index.height
    assert {r["scorer"] for r in summary["paired_still"]} >= {"gru"}
    assert summary["answer_still"].startswith(
        "Under the reference protocol, on the still-now test windows of unseen objects")
    paired = {(r["scorer"], r["metric"]): r for r in summary["paired"]}
    assert paired[("gru", "auprc")]["verdict"] == "learned better"
    assert "beats the friction-ratio proxy" in summary["answer"]
    # the answer sentence is about the plain families; the noise variant loses to its family
    assert "gru+gain" not in summary["answer"]
    change = {(r["scorer"], r["metric"]): r for r in summary["variants"]}
    assert change[("gru+gain", "auprc")]["against"] == "gru"
    assert change[("gru+gain", "auprc")]["verdict"] == "plain better"
    assert change[("gru+gain", "auprc")]["objects"] == len(objects)
    # thresholded metrics pooled over folds, against the confusion counts computed here
    thr = {r["scorer"]: r for r in summary["thresholds"]}
    tp, fp, fn, tn = (int(x) for x in alarms["forces"])
    assert thr["gru"]["precision"] == pytest.approx(tp / (tp + fp))
    assert thr["gru"]["recall"] == pytest.approx(tp / (tp + fn))
    assert thr["gru"]["fpr"] == pytest.approx(fp / (fp + tn))
    assert thr["gru"]["at_floor"] == 0 and thr["gru+gain"]["at_floor"] == 3
    assert thr["gru+gain"]["recall"] == 1.0 and thr["gru+gain"]["fpr"] == 1.0
    assert thr["gru"]["rule"] == "recall >= 0.9" and thr["gru"]["runs"] == 3
    per_object = read_parquet(out / "per_object.parquet")
    assert set(per_object["scorer"]) == {"gru", "gru+gain", "proxy"}
    assert per_object.height == 27
    figure = plot_crossval(per_object, read_json(out / "summary.json"), tmp_path / "f.png", 60)
    files = {f"reference_{n}": out / f"{n}.parquet" for n in ("per_object", "pooled", "paired")}
    files |= {"reference_summary": out / "summary.json", "reference_figure": figure}
    config = {
        "crossval": {
            "enabled": True,
            "k": 3,
            "variants": [],
            "variant_families": ["gru"],
            "window_s": 0.01,
            "seeds": [42],
            "protocols": ["reference"],
        },
        "objects": {"items": dict.fromkeys(objects, {})},
    }
    html = crossval_section(files, config)
    assert "Generalisation across objects" in html and summary["answer"].split(",")[0] in html
    assert "undefined" not in html.split("Per-object")[0]
