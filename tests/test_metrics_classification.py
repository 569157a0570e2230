"""Metrics and threshold selection (thesis 3.5.3, 4.2, 4.6): hand-computed cases, brute-force and
scikit-learn references, the validation-only contract, calibration on synthetic data."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from sklearn.metrics import (
    accuracy_score,
    average_precision_score,
    confusion_matrix,
    f1_score,
    log_loss,
    precision_score,
    recall_score,
    roc_auc_score,
)

from graspstab.metrics.classification import (
    METRIC_KEYS,
    ThresholdChoice,
    binary_metrics,
    per_object_metrics,
    reliability_curve,
    select_threshold,
    threshold_curves,
    threshold_grid,
)

GRID = threshold_grid()

# Case A (recall rule met): 10 unstable, 4 stable windows. Recall >= 0.9 needs >= 9 positives
# flagged, i.e. t <= 0.55. On (0.30, 0.55] the flags are 9 positives + stable 0.90, 0.58:
# precision 9/11; on (0.20, 0.30] 9/12; on (0.10, 0.20] 10/13; below 10/14. Best 9/11, lowest
# grid point of (0.30, 0.55] is 0.305. F1 there = 2*9 / (10 + 11) = 6/7.
# Best F1 overall: (0.10, 0.20] with 2*10 / (10 + 13) = 20/23 > 6/7, lowest grid point 0.105.
CASE_A_POS = [0.91, 0.88, 0.85, 0.80, 0.75, 0.70, 0.65, 0.60, 0.55, 0.20]
CASE_A_NEG = [0.90, 0.58, 0.30, 0.10]
# Case B (fallback): 4 unstable windows, two below the grid (max grid recall 0.5 < 0.9).
# F1 on (0.85, 0.90]: 2/5; (0.80, 0.85]: 2/6; (0.50, 0.80]: 4/7; [0.05, 0.50]: 4/8; above: 0.
# Best 4/7 with precision 2/3 and recall 1/2, lowest grid point of (0.50, 0.80] is 0.505.
CASE_B_POS = [0.90, 0.80, 0.03, 0.02]
CASE_B_NEG = [0.85, 0.50, 0.01]


def _case(pos: list[float], neg: list[float]) -> tuple[np.ndarray, np.ndarray]:
    probs = np.array(pos + neg)
    labels = np.array([1] * len(pos) + [0] * len(neg))
    order = np.random.default_rng(0).permutation(probs.size)  # order must not matter
    return probs[order], labels[order]


def _brute_rows(
    probs: np.ndarray, labels: np.ndarray, grid: np.ndarray
) -> list[tuple[float, float, float, float]]:
    """(threshold, precision, recall, F1) per grid threshold, ascending, from a plain loop with
    scikit-learn's metrics (zero_division=0)."""
    rows = []
    for t in sorted(grid.tolist()):
        pred = (probs >= t).astype(int)
        rows.append(
            (
                t,
                precision_score(labels, pred, zero_division=0),
                recall_score(labels, pred, zero_division=0),
                f1_score(labels, pred, zero_division=0),
            )
        )
    return rows


def _brute_rule(
    rows: list[tuple[float, float, float, float]], min_recall: float, rule: str
) -> tuple[float, str]:
    """The rule of 3.5.3 as a plain loop; strict '>' while scanning ascending thresholds keeps
    the lowest threshold on ties."""
    if rule == "min_recall":
        best = None
        for t, p, r, _ in rows:
            if r >= min_recall and (best is None or p > best[1]):
                best = (t, p)
        if best is not None:
            return best[0], "min_recall"
    best = None
    for t, _, _, f in rows:
        if best is None or f > best[1]:
            best = (t, f)
    return best[0], "best_f1"


def test_threshold_grid_defaults() -> None:
    assert GRID.size == 181
    assert GRID[0] == 0.05
    assert GRID[-1] == 0.95
    assert np.all(np.diff(GRID) > 0)
    assert 0.3 in GRID.tolist() and 0.5 in GRID.tolist()  # exact decimals despite float steps
    np.testing.assert_allclose(np.diff(GRID), 0.005, atol=1e-12)


def test_threshold_grid_other_steps() -> None:
    assert threshold_grid(0.1, 0.3, 0.1).tolist() == [0.1, 0.2, 0.3]
    assert threshold_grid(0.5, 0.5, 0.01).tolist() == [0.5]
    with pytest.raises(ValueError):
        threshold_grid(0.1, 0.3, 0.0)


def test_select_threshold_recall_rule_by_hand() -> None:
    probs, labels = _case(CASE_A_POS, CASE_A_NEG)
    choice = select_threshold(probs, labels, GRID)
    assert choice.rule == "min_recall"
    assert choice.threshold == 0.305
    assert choice.precision == pytest.approx(9 / 11)
    assert choice.recall == pytest.approx(0.9)
    assert choice.f1 == pytest.approx(6 / 7)


def test_select_threshold_best_f1_rule_requested_by_hand() -> None:
    probs, labels = _case(CASE_A_POS, CASE_A_NEG)
    choice = select_threshold(probs, labels, GRID, rule="best_f1")
    assert choice == ThresholdChoice(0.105, "best_f1", 10 / 13, 1.0, 20 / 23)


def test_select_threshold_fallback_by_hand() -> None:
    probs, labels = _case(CASE_B_POS, CASE_B_NEG)
    choice = select_threshold(probs, labels, GRID, min_recall=0.9)
    assert choice.rule == "best_f1"
    assert choice.threshold == 0.505
    assert choice.precision == pytest.approx(2 / 3)
    assert choice.recall == pytest.approx(0.5)
    assert choice.f1 == pytest.approx(4 / 7)


def test_select_threshold_no_unstable_window_is_undefined() -> None:
    probs = np.array([0.1, 0.6, 0.9])
    choice = select_threshold(probs, np.zeros(3, dtype=int), GRID)
    assert choice == ThresholdChoice(0.5, "undefined", 0.0, 0.0, 0.0)


def test_select_threshold_ties_go_to_lowest_threshold_for_any_grid_order() -> None:
    # Every threshold in (0.2, 0.8] flags exactly the one positive: precision 1 everywhere.
    probs = np.array([0.9, 0.2, 0.1])
    labels = np.array([1, 0, 0])
    grid = np.array([0.7, 0.3, 0.5, 0.25])
    choice = select_threshold(probs, labels, grid, min_recall=1.0)
    assert (choice.threshold, choice.rule, choice.precision) == (0.25, "min_recall", 1.0)
    assert select_threshold(probs, labels, grid, rule="best_f1").threshold == 0.25


def test_select_threshold_prediction_is_inclusive() -> None:
    # A probability exactly on a grid value is flagged at that threshold (prob >= threshold).
    probs = np.array([0.5, 0.4])
    labels = np.array([1, 0])
    choice = select_threshold(probs, labels, GRID, min_recall=1.0)
    assert choice.threshold == 0.405 and choice.precision == 1.0 and choice.recall == 1.0
    curves = threshold_curves(probs, labels, np.array([0.5, 0.505]))
    assert curves["recall"].tolist() == [1.0, 0.0]


def test_select_threshold_rejects_bad_input() -> None:
    with pytest.raises(ValueError):
        select_threshold(np.array([0.2, 0.3]), np.array([0, 2]), GRID)
    with pytest.raises(ValueError):
        select_threshold(np.array([0.2, np.nan]), np.array([0, 1]), GRID)
    with pytest.raises(ValueError):
        select_threshold(np.array([0.2]), np.array([0, 1]), GRID)
    with pytest.raises(ValueError):
        select_threshold(np.array([0.2, 0.3]), np.array([0, 1]), GRID, rule="youden")  # type: ignore[arg-type]


@pytest.mark.parametrize("seed", [1, 2])
def test_select_threshold_matches_brute_force_on_full_grid(seed: int) -> None:
    rng = np.random.default_rng(seed)
    n = 400
    labels = rng.integers(0, 2, n)
    # Probabilities on the grid itself (ties with thresholds) plus continuous noise.
    probs = np.where(rng.random(n) < 0.5, rng.choice(GRID, n), rng.random(n))
    probs = np.clip(probs + 0.15 * labels * rng.random(n), 0.0, 1.0)
    rows = _brute_rows(probs, labels, GRID)
    rules_seen = set()
    for min_recall in (0.9, 0.999):
        for rule in ("min_recall", "best_f1"):
            choice = select_threshold(probs, labels, GRID, min_recall=min_recall, rule=rule)
            assert (choice.threshold, choice.rule) == _brute_rule(rows, min_recall, rule)
            rules_seen.add(choice.rule)
            t, p, r, f = rows[GRID.tolist().index(choice.threshold)]
            assert (choice.precision, choice.recall) == (p, r)
            assert choice.f1 == pytest.approx(f, abs=1e-12)
    assert rules_seen == {"min_recall", "best_f1"}


@settings(max_examples=30, deadline=None)
@given(
    data=st.lists(st.tuples(st.integers(0, 20), st.booleans()), min_size=1, max_size=40).filter(
        lambda rows: any(label for _, label in rows)
    )
)
def test_select_threshold_matches_brute_force_property(data: list[tuple[int, bool]]) -> None:
    # Coarse grid 0.05..0.95 by 0.05 and probabilities on a 0.05 lattice: many exact ties.
    grid = threshold_grid(0.05, 0.95, 0.05)
    probs = np.array([round(k * 0.05, 10) for k, _ in data])
    labels = np.array([int(label) for _, label in data])
    rows = _brute_rows(probs, labels, grid)
    for min_recall in (0.5, 0.9, 1.0):
        for rule in ("min_recall", "best_f1"):
            choice = select_threshold(probs, labels, grid, min_recall=min_recall, rule=rule)
            assert (choice.threshold, choice.rule) == _brute_rule(rows, min_recall, rule)


def test_threshold_curves_match_sklearn() -> None:
    rng = np.random.default_rng(3)
    labels = rng.integers(0, 2, 300)
    probs = rng.random(300)
    curves = threshold_curves(probs, labels, GRID)
    assert set(curves) >= {"threshold", "precision", "recall", "f1"}
    for i in range(0, GRID.size, 20):
        pred = (probs >= GRID[i]).astype(int)
        assert curves["precision"][i] == precision_score(labels, pred, zero_division=0)
        assert curves["recall"][i] == recall_score(labels, pred, zero_division=0)
        assert curves["f1"][i] == pytest.approx(f1_score(labels, pred, zero_division=0), abs=1e-12)
    # No predicted positives above every probability: precision 0 by zero_division=0.
    top = threshold_curves(np.array([0.1, 0.2]), np.array([1, 0]), np.array([0.9]))
    assert top["precision"].tolist() == [0.0] and top["recall"].tolist() == [0.0]


@pytest.mark.parametrize("seed", [0, 1, 2, 3])
def test_binary_metrics_match_sklearn(seed: int) -> None:
    rng = np.random.default_rng(seed)
    n = 500
    labels = rng.integers(0, 2, n)
    logits = rng.normal(0.0, 2.0, n) + 1.5 * labels
    probs = 1.0 / (1.0 + np.exp(-logits))
    threshold = float(rng.choice(GRID))
    pred = (probs >= threshold).astype(int)
    tn, fp, fn, tp = confusion_matrix(labels, pred, labels=[0, 1]).ravel()
    for with_logits in (False, True):
        m = binary_metrics(probs, labels, threshold, logits=logits if with_logits else None)
        assert tuple(m) == METRIC_KEYS
        assert (m["tp"], m["fp"], m["tn"], m["fn"]) == (tp, fp, tn, fn)
        assert m["n"] == n and m["n_unstable"] == int(labels.sum())
        expected = {
            "accuracy": accuracy_score(labels, pred),
            "precision": precision_score(labels, pred, zero_division=0),
            "recall": recall_score(labels, pred, zero_division=0),
            "f1": f1_score(labels, pred, zero_division=0),
            "auroc": roc_auc_score(labels, probs),
            "auprc": average_precision_score(labels, probs),
            "loss": log_loss(labels, probs, labels=[0, 1]),
            "false_positive_rate": fp / (fp + tn),
            "miss_rate": fn / (fn + tp),
        }
        for key, value in expected.items():
            assert m[key] == pytest.approx(value, abs=1e-9), key
        assert m["threshold"] == threshold
        for key in ("n", "n_unstable", "tp", "fp", "tn", "fn"):
            assert isinstance(m[key], int)


def test_binary_metrics_undefined_values() -> None:
    # One class only: AUROC/AUPRC and the stable-denominator rate are NaN.
    m = binary_metrics(np.array([0.2, 0.7, 0.9]), np.array([1, 1, 1]), 0.5)
    assert math.isnan(m["auroc"]) and math.isnan(m["auprc"])
    assert math.isnan(m["false_positive_rate"])
    assert m["miss_rate"] == pytest.approx(1 / 3)
    m = binary_metrics(np.array([0.2, 0.7]), np.array([0, 0]), 0.5)
    assert math.isnan(m["miss_rate"]) and m["false_positive_rate"] == 0.5
    assert (m["precision"], m["recall"], m["f1"]) == (0.0, 0.0, 0.0)
    # Nothing predicted unstable: precision 0 (zero_division=0), not NaN.
    m = binary_metrics(np.array([0.2, 0.3]), np.array([0, 1]), 0.95)
    assert (m["precision"], m["recall"], m["f1"]) == (0.0, 0.0, 0.0)
    assert m["auroc"] == 1.0 and m["auprc"] == 1.0


def test_binary_metrics_loss_from_logits_is_stable() -> None:
    logits = np.array([1000.0, -1000.0])
    probs = np.array([1.0, 0.0])
    assert binary_metrics(probs, np.array([1, 0]), 0.5, logits=logits)["loss"] == 0.0
    wrong = binary_metrics(probs, np.array([0, 1]), 0.5, logits=logits)["loss"]
    assert wrong == pytest.approx(1000.0)
    clipped = binary_metrics(probs, np.array([0, 1]), 0.5)["loss"]
    assert math.isfinite(clipped) and clipped > 30.0  # -log(machine eps) ~ 36


def test_per_object_metrics_equal_subset_metrics() -> None:
    rng = np.random.default_rng(5)
    n = 300
    labels = rng.integers(0, 2, n)
    probs = rng.random(n)
    logits = np.log(probs / (1 - probs))
    objects = rng.choice(np.array(["pear", "rubiks_cube", "apple"]), n)
    out = per_object_metrics(probs, labels, objects, 0.4, logits=logits)
    assert list(out) == ["apple", "pear", "rubiks_cube"]
    for name, metrics in out.items():
        m = objects == name
        ref = binary_metrics(probs[m], labels[m], 0.4, logits=logits[m])
        assert metrics == pytest.approx(ref, nan_ok=True)
    assert sum(v["n"] for v in out.values()) == n


def test_threshold_depends_only_on_validation_arrays() -> None:
    """API contract of 3.5.3: select_threshold receives validation arrays only, so whatever the
    test split holds (permuted, flipped or resampled labels) the transferred threshold is the
    same; only the test metrics computed at that fixed threshold change."""
    rng = np.random.default_rng(7)
    val_labels = rng.integers(0, 2, 1000)
    val_probs = np.clip(0.35 * val_labels + 0.65 * rng.random(1000), 0, 1)
    test_labels = rng.integers(0, 2, 800)
    test_probs = np.clip(0.35 * test_labels + 0.65 * rng.random(800), 0, 1)

    def protocol(test_y: np.ndarray) -> tuple[ThresholdChoice, dict[str, float | int]]:
        choice = select_threshold(val_probs, val_labels, GRID)
        return choice, binary_metrics(test_probs, test_y, choice.threshold)

    reference, reference_test = protocol(test_labels)
    for test_y in (rng.permutation(test_labels), 1 - test_labels, np.zeros_like(test_labels)):
        choice, test_metrics = protocol(test_y)
        assert choice == reference
        assert test_metrics["threshold"] == reference.threshold
    assert protocol(1 - test_labels)[1]["recall"] != reference_test["recall"]
    # Sanity: the choice does react to the validation arrays.
    assert select_threshold(val_probs, 1 - val_labels, GRID) != reference


def test_reliability_curve_calibrated_data_on_diagonal() -> None:
    rng = np.random.default_rng(11)
    probs = rng.random(200_000)
    labels = (rng.random(probs.size) < probs).astype(int)
    curve = reliability_curve(probs, labels, n_bins=10)
    np.testing.assert_allclose(curve["bin_edges"], np.linspace(0, 1, 11))
    assert curve["count"].sum() == probs.size and np.all(curve["count"] > 0)
    np.testing.assert_allclose(curve["observed_fraction"], curve["mean_predicted"], atol=0.015)
    np.testing.assert_allclose(curve["mean_predicted"], np.arange(10) / 10 + 0.05, atol=0.01)


def test_reliability_curve_bins_and_empty_bins() -> None:
    probs = np.array([0.0, 0.05, 0.1, 0.35, 1.0])
    labels = np.array([0, 1, 0, 1, 1])
    curve = reliability_curve(probs, labels, n_bins=4)
    assert curve["count"].tolist() == [3, 1, 0, 1]  # [0, .25), [.25, .5), [.5, .75), [.75, 1]
    assert math.isnan(curve["mean_predicted"][2]) and math.isnan(curve["observed_fraction"][2])
    assert curve["mean_predicted"][0] == pytest.approx(0.05)
    assert curve["observed_fraction"][0] == pytest.approx(1 / 3)
    assert curve["observed_fraction"][3] == 1.0
