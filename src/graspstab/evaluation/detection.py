"""Prediction against detection: what a window's observation period already shows. A window
whose object moves during its observation period (any step unstable by eq. 23) is labelled by a
future that mostly looks like its present, so scoring it well can be recognition; a window whose
object is still ("still now") can only be scored well by foresight. Every evaluation gives its
ranking metrics on all windows (the reference's protocol) and on the still-now ones.

The persistence oracle scores a window by its observation period's unstable share: it reads the
object's motion, which no fingertip sensor sees, so it is a reference line (how far "it moves now,
so it will move" goes), never a monitor. It cannot rank still-now windows (all score 0).
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import numpy as np

from graspstab.evaluation.proxy import proxy_metrics
from graspstab.labels.dataset import MOTION

#: The span over which a window's end speed is averaged: the last 10 ms of its observation.
END_SPEED_S = 0.01
UNSTABLE, SPEED = MOTION.index("unstable"), MOTION.index("speed")
#: The name of the persistence oracle's rows and records, beside the proxy's.
ORACLE = "persistence"


def unstable_share(motion: np.ndarray) -> np.ndarray:
    """Each window's share of unstable steps (eq. 23) over its observation period (N,)."""
    m = np.asarray(motion)
    if m.shape[1] == 0:
        return np.zeros(len(m))
    return m[:, :, UNSTABLE].astype(np.float64).mean(axis=1)


def still_now(motion: np.ndarray) -> np.ndarray:
    """Whether each window's object is still over its whole observation period (no step at or
    above v_slip): the windows where a warning can only be foresight."""
    return unstable_share(motion) == 0.0


def end_speed(motion: np.ndarray, dt: float) -> np.ndarray:
    """Each window's mean object speed [m/s] over the last ``END_SPEED_S`` of its observation."""
    m = np.asarray(motion)
    k = min(m.shape[1], max(1, round(END_SPEED_S / dt)))
    return m[:, -k:, SPEED].astype(np.float64).mean(axis=1) if k else np.zeros(len(m))


def ranked(scores: np.ndarray, labels: np.ndarray) -> dict[str, Any]:
    """AUPRC and AUROC of ``scores`` (NaN where one class is missing) with the count, the
    positives and the chance level of AUPRC (the positive share; NaN without windows)."""
    s = np.asarray(scores, dtype=np.float64).reshape(-1)
    y = np.asarray(labels).reshape(-1).astype(np.int8)
    n, pos = int(y.size), int(y.sum())
    out = {"n": n, "n_unstable": pos, "chance": pos / n if n else float("nan")}
    if n == 0:
        return {**out, "auprc": float("nan"), "auroc": float("nan")}
    return {**out, **proxy_metrics(s, y)}


def split_by_motion(
    scores: np.ndarray, labels: np.ndarray, still: np.ndarray
) -> dict[str, dict[str, Any]]:
    """:func:`ranked` on the still-now windows (``still``) and on the moving-now ones
    (``moving``)."""
    still = np.asarray(still, dtype=bool)
    s, y = np.asarray(scores), np.asarray(labels)
    return {"still": ranked(s[still], y[still]), "moving": ranked(s[~still], y[~still])}


def motion_blocks(
    scores: np.ndarray, labels: np.ndarray, still: np.ndarray, split: str
) -> Mapping[str, dict[str, Any]]:
    """The record keys ``<split>_still`` and ``<split>_moving`` of :func:`split_by_motion`."""
    parts = split_by_motion(scores, labels, still)
    return {f"{split}_still": parts["still"], f"{split}_moving": parts["moving"]}
