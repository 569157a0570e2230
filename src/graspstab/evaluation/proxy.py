"""Friction-ratio proxy of section 4.7: a threshold-free baseline for the learned models.

For each observation window the proxy scores the ratio of total tangential (shear) to total
normal fingertip load at the final observed timestep. A high ratio means the grasp carries more
sideways load for the same squeezing load, i.e. it is closer to the friction-cone boundary of
section 2.2. Loads are pooled over fingertips and the friction coefficient mu is omitted, so this
is a proxy, not a per-contact friction-cone test. The score is not a probability: it is evaluated
with ranking metrics only (AUPRC, AUROC), which sweep every threshold on the score (fig. 4.10).
"""

from __future__ import annotations

from typing import Any

import numpy as np
from sklearn.metrics import average_precision_score, roc_auc_score

from graspstab.labels.dataset import NORMAL_CHANNEL, SHEAR_CHANNEL
from graspstab.metrics.classification import check_scored


def friction_ratio(windows: Any, eps: float = 1e-9) -> np.ndarray:
    """Shear-to-normal load ratio at each window's last timestep (the 4.7 proxy score).

    ``windows`` are raw (not normalised) forces of shape (N, W, F, 2), F = 5 fingertips in the
    pipeline, channel 0 the normal and channel 1 the shear (tangential) magnitude. The score is
    ``sum_f shear[-1, f] / max(sum_f normal[-1, f], eps)``: the denominator is floored at ``eps``
    so that a window with no normal load gets a large finite score when it carries shear (closest
    to sliding) and 0 when it carries no load at all. Only ``windows[:, -1]`` is read, so a
    memory-mapped array is never loaded whole. Returns float64 of shape (N,).
    """
    if eps <= 0:
        raise ValueError(f"eps must be positive, got {eps}")
    if windows.ndim != 4 or windows.shape[-1] != 2:
        raise ValueError(f"windows must have shape (N, W, F, 2), got {tuple(windows.shape)}")
    last = np.asarray(windows[:, -1], dtype=np.float64)  # (N, F, 2); reads only the last step
    normal = last[..., NORMAL_CHANNEL].sum(axis=1)
    shear = last[..., SHEAR_CHANNEL].sum(axis=1)
    return shear / np.maximum(normal, eps)


def proxy_metrics(scores: Any, labels: Any) -> dict[str, float]:
    """Threshold-free ranking metrics of a proxy score: ``auprc`` and ``auroc`` (fig. 4.10).

    Higher scores mean "more likely unstable" (label 1). AUPRC is scikit-learn's
    average_precision_score, AUROC roc_auc_score; both are NaN when only one class is present.
    Non-finite scores or non-binary labels raise ``ValueError``.
    """
    s, y = check_scored(scores, labels)
    if not 0 < int(y.sum()) < y.size:
        return {"auprc": float("nan"), "auroc": float("nan")}
    return {
        "auprc": float(average_precision_score(y, s)),
        "auroc": float(roc_auc_score(y, s)),
    }
