"""Evaluation metrics and decision-threshold selection (thesis 3.5.3, 4.2, 4.6).

Everything here works on plain 1-D numpy arrays of predicted instability probabilities (the
sigmoid of the model's raw score z_s) and binary labels (1 = unstable future, the positive class).
A window is predicted unstable when ``prob >= threshold``.

Conventions for undefined values (each public function repeats the ones it uses):

* precision, recall and F1 follow scikit-learn's ``zero_division=0``: precision is 0 when nothing
  is predicted unstable, recall is 0 when no window is unstable, F1 is 0 when both are 0;
* AUROC and AUPRC are NaN when only one class is present (a ranking metric needs both);
* the false-positive rate (fp / stable windows) and miss rate (fn / unstable windows) are NaN when
  their denominator is 0;
* threshold ties are broken towards the lowest threshold (at equal precision or F1 a lower
  threshold never has lower recall, so it is the more conservative warning).

Empty inputs, non-binary labels and non-finite probabilities raise ``ValueError``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any, Literal

import numpy as np
from sklearn.metrics import (
    accuracy_score,
    average_precision_score,
    confusion_matrix,
    precision_recall_fscore_support,
    roc_auc_score,
)

ThresholdRule = Literal["min_recall", "best_f1"]

#: Keys of :func:`binary_metrics`, in the order they are returned.
METRIC_KEYS: tuple[str, ...] = (
    "n",
    "n_unstable",
    "loss",
    "accuracy",
    "precision",
    "recall",
    "f1",
    "auroc",
    "auprc",
    "tp",
    "fp",
    "tn",
    "fn",
    "false_positive_rate",
    "miss_rate",
    "threshold",
)

#: Threshold used when the labels contain no unstable window (rule "undefined").
UNDEFINED_THRESHOLD = 0.5


def threshold_grid(start: float = 0.05, stop: float = 0.95, step: float = 0.005) -> np.ndarray:
    """The candidate decision thresholds of 3.5.3 (181 values, 0.05 to 0.95 inclusive by default).

    Built from integer step counts and rounded to 10 decimals, so the end point is included and
    the values are exact decimals (0.3 rather than 0.30000000000000004) despite float rounding.
    """
    if step <= 0:
        raise ValueError(f"step must be positive, got {step}")
    if stop < start:
        raise ValueError(f"stop ({stop}) must be >= start ({start})")
    count = int(math.floor((stop - start) / step + 1e-9)) + 1
    return np.round(start + step * np.arange(count, dtype=np.float64), 10)


@dataclass(frozen=True)
class ThresholdChoice:
    """The validation-selected decision threshold and its validation operating point.

    ``rule`` is "min_recall" when some grid threshold reaches the recall target (the most precise
    of those is chosen), "best_f1" when none does or the best-F1 rule was requested, and
    "undefined" when the validation labels contain no unstable window (threshold 0.5).
    """

    threshold: float
    rule: str
    precision: float
    recall: float
    f1: float


def check_scored(scores: Any, labels: Any, name: str = "scores") -> tuple[np.ndarray, np.ndarray]:
    """Validated finite float64 scores and int8 labels in {0, 1}, 1-D, equal length, non-empty
    (shared by the models' probabilities and the friction-ratio proxy's scores)."""
    s = np.asarray(scores, dtype=np.float64).reshape(-1)
    y_raw = np.asarray(labels).reshape(-1)
    if s.shape != y_raw.shape:
        raise ValueError(f"{name} and labels differ in length: {s.shape[0]} vs {y_raw.shape[0]}")
    if s.size == 0:
        raise ValueError(f"empty {name}/labels")
    if not np.all(np.isfinite(s)):
        raise ValueError(f"{name} contain NaN or infinite values")
    if not np.all((y_raw == 0) | (y_raw == 1)):
        raise ValueError("labels must be 0 (stable) or 1 (unstable)")
    return s, y_raw.astype(np.int8)


def _check_binary(probs: Any, labels: Any) -> tuple[np.ndarray, np.ndarray]:
    """Validated float64 probabilities in [0, 1] and int8 labels in {0, 1}, 1-D and equal length."""
    p, y = check_scored(probs, labels, "probs")
    if np.any((p < 0.0) | (p > 1.0)):
        raise ValueError("probs must lie in [0, 1]")
    return p, y


def _grid_counts(
    p: np.ndarray, y: np.ndarray, grid: np.ndarray
) -> tuple[np.ndarray, np.ndarray, int]:
    """Predicted positives and true positives of ``p >= t`` for every t in ``grid``, and the
    number of positives; one sort plus a binary search per threshold (no loop over the grid)."""
    sorted_all = np.sort(p)
    sorted_pos = np.sort(p[y == 1])
    pred_pos = p.size - np.searchsorted(sorted_all, grid, side="left")
    true_pos = sorted_pos.size - np.searchsorted(sorted_pos, grid, side="left")
    return pred_pos.astype(np.int64), true_pos.astype(np.int64), int(sorted_pos.size)


def _prf(
    pred_pos: np.ndarray, true_pos: np.ndarray, n_pos: int
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Precision, recall and F1 from counts, with scikit-learn's zero_division=0 convention.

    F1 = 2 tp / (positives + predicted positives), the formula scikit-learn uses, so the floats
    match it exactly (mathematically equal ratios give equal floats, which keeps ties exact).
    """
    tp = true_pos.astype(np.float64)
    pp = pred_pos.astype(np.float64)
    with np.errstate(divide="ignore", invalid="ignore"):
        precision = np.where(pp > 0, tp / np.where(pp > 0, pp, 1.0), 0.0)
        recall = tp / n_pos if n_pos > 0 else np.zeros_like(tp)
        denom = n_pos + pp
        f1 = np.where(denom > 0, 2.0 * tp / np.where(denom > 0, denom, 1.0), 0.0)
    return precision, recall, f1


def threshold_curves(probs: Any, labels: Any, grid: Any) -> dict[str, np.ndarray]:
    """Precision, recall and F1 at every grid threshold, for the threshold-transfer plot (fig. 4.8).

    Returns ``threshold``, ``precision``, ``recall``, ``f1`` (float arrays aligned with ``grid``)
    and ``tp``, ``predicted_positive`` (int arrays). Conventions: scikit-learn's zero_division=0
    (precision 0 with no predicted positives, recall 0 with no unstable window).
    """
    p, y = _check_binary(probs, labels)
    g = np.asarray(grid, dtype=np.float64).reshape(-1)
    pred_pos, true_pos, n_pos = _grid_counts(p, y, g)
    precision, recall, f1 = _prf(pred_pos, true_pos, n_pos)
    return {
        "threshold": g.copy(),
        "precision": precision,
        "recall": recall,
        "f1": f1,
        "tp": true_pos,
        "predicted_positive": pred_pos,
    }


def _lowest_at_max(values: np.ndarray, grid: np.ndarray, mask: np.ndarray) -> int:
    """Index of the lowest threshold among ``mask`` entries attaining the maximum of ``values``."""
    best = values[mask].max()
    candidates = np.flatnonzero(mask & (values == best))
    return int(candidates[np.argmin(grid[candidates])])


def select_threshold(
    probs: Any,
    labels: Any,
    grid: Any,
    min_recall: float = 0.9,
    rule: ThresholdRule = "min_recall",
) -> ThresholdChoice:
    """Choose the decision threshold on validation predictions only (thesis 3.5.3, 4.2).

    rule="min_recall": among grid thresholds whose recall is >= ``min_recall``, the one with the
    highest precision; if none reaches the target, the one with the highest F1 (rule "best_f1").
    rule="best_f1": the highest-F1 threshold directly (an Optuna-searchable alternative).

    Ties (equal precision, or equal F1) go to the lowest threshold, deterministically, whatever the
    order of ``grid``. Precision with no predicted positives counts as 0. When ``labels`` contain
    no unstable window the choice is undefined: threshold 0.5, rule "undefined", and the reported
    precision/recall/F1 at 0.5 follow zero_division=0 (so all 0). Vectorised: one sort of
    ``probs`` and a binary search per threshold, fast for N ~ 15,000 and 181 thresholds.
    """
    if rule not in ("min_recall", "best_f1"):
        raise ValueError(f"unknown threshold rule {rule!r}; use 'min_recall' or 'best_f1'")
    p, y = _check_binary(probs, labels)
    g = np.asarray(grid, dtype=np.float64).reshape(-1)
    if g.size == 0:
        raise ValueError("empty threshold grid")
    if not np.all(np.isfinite(g)):
        raise ValueError("threshold grid contains NaN or infinite values")

    if not np.any(y == 1):
        pred_pos, true_pos, n_pos = _grid_counts(p, y, np.array([UNDEFINED_THRESHOLD]))
        precision, recall, f1 = _prf(pred_pos, true_pos, n_pos)
        return ThresholdChoice(
            UNDEFINED_THRESHOLD, "undefined", float(precision[0]), float(recall[0]), float(f1[0])
        )

    pred_pos, true_pos, n_pos = _grid_counts(p, y, g)
    precision, recall, f1 = _prf(pred_pos, true_pos, n_pos)
    everywhere = np.ones(g.size, dtype=bool)
    meets = recall >= min_recall
    if rule == "min_recall" and np.any(meets):
        i, chosen_rule = _lowest_at_max(precision, g, meets), "min_recall"
    else:
        i, chosen_rule = _lowest_at_max(f1, g, everywhere), "best_f1"
    return ThresholdChoice(
        float(g[i]), chosen_rule, float(precision[i]), float(recall[i]), float(f1[i])
    )


def _bce(y: np.ndarray, p: np.ndarray, logits: Any | None) -> float:
    """Mean binary cross-entropy: stable softplus form from logits when given, else clipped probs.

    From logits z: mean(max(z, 0) - y z + log1p(exp(-|z|))), the BCEWithLogits of eq. 33 (finite
    for any finite z). From probabilities: clipped to [eps, 1 - eps] with eps the float64 machine
    epsilon, as scikit-learn's log_loss does for float64 input.
    """
    yf = y.astype(np.float64)
    if logits is not None:
        z = np.asarray(logits, dtype=np.float64).reshape(-1)
        if z.shape != y.shape:
            raise ValueError(f"logits and labels differ in length: {z.shape[0]} vs {y.shape[0]}")
        if not np.all(np.isfinite(z)):
            raise ValueError("logits contain NaN or infinite values")
        return float(np.mean(np.maximum(z, 0.0) - yf * z + np.log1p(np.exp(-np.abs(z)))))
    eps = np.finfo(np.float64).eps
    q = np.clip(p, eps, 1.0 - eps)
    return float(-np.mean(yf * np.log(q) + (1.0 - yf) * np.log1p(-q)))


def _ratio(num: int, den: int) -> float:
    """num / den, NaN for an empty denominator."""
    return float(num) / den if den > 0 else float("nan")


def binary_metrics(
    probs: Any, labels: Any, threshold: float, logits: Any | None = None
) -> dict[str, float | int]:
    """All metrics the evaluation records (3.5.4, 4.2, table 4.3) at one decision threshold.

    Keys (exactly): n, n_unstable, loss, accuracy, precision, recall, f1, auroc, auprc, tp, fp,
    tn, fn, false_positive_rate, miss_rate, threshold. Counts are ints, the rest floats.

    * prediction: unstable when ``prob >= threshold``;
    * loss: mean binary cross-entropy, computed stably from ``logits`` when given (the thresholded
      metrics and AUCs always use ``probs``), else from probabilities clipped to [eps, 1 - eps];
    * precision, recall, F1: scikit-learn with zero_division=0 (0, not NaN, when undefined);
    * auroc (roc_auc_score), auprc (average_precision_score): NaN when only one class is present;
    * false_positive_rate = fp / stable windows, miss_rate = fn / unstable windows: NaN when the
      denominator is 0.
    """
    p, y = _check_binary(probs, labels)
    loss = _bce(y, p, logits)
    pred = (p >= threshold).astype(np.int8)
    tn, fp, fn, tp = (int(v) for v in confusion_matrix(y, pred, labels=[0, 1]).ravel())
    precision, recall, f1, _ = precision_recall_fscore_support(
        y, pred, average="binary", pos_label=1, zero_division=0
    )
    both_classes = 0 < int(y.sum()) < y.size
    auroc = float(roc_auc_score(y, p)) if both_classes else float("nan")
    auprc = float(average_precision_score(y, p)) if both_classes else float("nan")
    n_unstable = tp + fn
    n_stable = tn + fp
    return {
        "n": int(y.size),
        "n_unstable": int(n_unstable),
        "loss": loss,
        "accuracy": float(accuracy_score(y, pred)),
        "precision": float(precision),
        "recall": float(recall),
        "f1": float(f1),
        "auroc": auroc,
        "auprc": auprc,
        "tp": tp,
        "fp": fp,
        "tn": tn,
        "fn": fn,
        "false_positive_rate": _ratio(fp, n_stable),
        "miss_rate": _ratio(fn, n_unstable),
        "threshold": float(threshold),
    }


def per_object_metrics(
    probs: Any, labels: Any, objects: Any, threshold: float, logits: Any | None = None
) -> dict[str, dict[str, float | int]]:
    """:func:`binary_metrics` per object id, to see which unseen objects the errors come from.

    Keys are ``str(object_id)`` in sorted order; each value uses the same threshold and the
    conventions of :func:`binary_metrics` (so AUROC/AUPRC are NaN for a one-class object).
    """
    p, y = _check_binary(probs, labels)
    obj = np.asarray(objects).reshape(-1)
    if obj.shape != y.shape:
        raise ValueError(f"objects and labels differ in length: {obj.shape[0]} vs {y.shape[0]}")
    z = None if logits is None else np.asarray(logits, dtype=np.float64).reshape(-1)
    if z is not None and z.shape != y.shape:
        raise ValueError(f"logits and labels differ in length: {z.shape[0]} vs {y.shape[0]}")
    keys = obj.astype(str)
    out: dict[str, dict[str, float | int]] = {}
    for key in sorted(set(keys.tolist())):
        m = keys == key
        out[key] = binary_metrics(p[m], y[m], threshold, None if z is None else z[m])
    return out


def reliability_curve(probs: Any, labels: Any, n_bins: int = 10) -> dict[str, np.ndarray]:
    """Binned calibration (fig. 4.9): mean predicted probability vs observed unstable fraction.

    Equal-width bins on [0, 1]; bin k holds probabilities in [edge_k, edge_k+1), the last bin
    also holds 1.0. Returns ``bin_edges`` (n_bins + 1), ``mean_predicted``, ``observed_fraction``
    (floats, NaN for an empty bin) and ``count`` (ints), the last three of length n_bins.
    """
    if n_bins < 1:
        raise ValueError(f"n_bins must be >= 1, got {n_bins}")
    p, y = _check_binary(probs, labels)
    edges = np.linspace(0.0, 1.0, n_bins + 1)
    idx = np.searchsorted(edges[1:-1], p, side="right")
    count = np.bincount(idx, minlength=n_bins).astype(np.int64)
    sum_p = np.bincount(idx, weights=p, minlength=n_bins)
    sum_y = np.bincount(idx, weights=y.astype(np.float64), minlength=n_bins)
    with np.errstate(divide="ignore", invalid="ignore"):
        mean_predicted = np.where(count > 0, sum_p / np.maximum(count, 1), np.nan)
        observed = np.where(count > 0, sum_y / np.maximum(count, 1), np.nan)
    return {
        "bin_edges": edges,
        "mean_predicted": mean_predicted,
        "observed_fraction": observed,
        "count": count,
    }
