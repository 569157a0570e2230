"""The friction-ratio proxy (4.7) as a monitor, with its own validation-selected threshold.

The proxy scores a window by the shear-to-normal load ratio at its last frame
(``evaluation.proxy.friction_ratio``), so as a monitor it needs a window of one frame. Its ratio is
unbounded; the monitor's decision rule (``prob >= threshold``, a threshold in [0, 1]) takes it
through the monotone map ``p = r / (1 + r)``, which changes no ranking. The threshold is chosen
the way the models' are (3.5.3, ``metrics.classification.select_threshold`` with the run's rule and
recall target), on the validation windows' scores, over every distinct validation score rather
than the models' 0.05-0.95 grid (a ratio of a few tenths maps to p ~ 0.1-0.3, where that grid is
coarse). It is reported in ratio units too.
"""

from __future__ import annotations

import logging
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np

from graspstab.evaluation.proxy import friction_ratio
from graspstab.learning.data import load_window_data
from graspstab.metrics.classification import select_threshold
from graspstab.monitor.constants import FRAME_SHAPE, MonitorConstants
from graspstab.monitor.scoring import check_windows

log = logging.getLogger("graspstab.monitor")

PROXY = "proxy"


def bounded(ratio: Any) -> np.ndarray:
    """``r / (1 + r)``: the friction ratio mapped monotonically onto [0, 1)."""
    r = np.asarray(ratio, dtype=np.float64)
    return r / (1.0 + r)


def ratio_of(p: float) -> float:
    """The friction ratio of a bounded score (the inverse of :func:`bounded`)."""
    return float(p / (1.0 - p)) if p < 1.0 else float("inf")


def proxy_constants(threshold: float) -> MonitorConstants:
    """The proxy's monitor constants: a one-frame window, no normalisation, its threshold."""
    return MonitorConstants(
        mean=np.zeros(FRAME_SHAPE), std=np.ones(FRAME_SHAPE), threshold=threshold,
        window_steps=1, family=PROXY, model={"family": PROXY, "score": "r / (1 + r)"},
    )  # fmt: skip


class ProxyScorer:
    """The proxy as a :class:`~graspstab.monitor.scoring.WindowScorer` (raw one-frame windows)."""

    def __init__(self, threshold: float) -> None:
        self.constants = proxy_constants(threshold)

    def score_one(self, window: np.ndarray) -> float:
        """Bounded friction ratio of one raw window ``(1, 5, 2)``."""
        return float(bounded(friction_ratio(np.asarray(window)[None]))[0])

    def __call__(self, windows: np.ndarray) -> np.ndarray:
        """Bounded friction ratios of raw windows ``(B, 1, 5, 2)``."""
        return bounded(friction_ratio(check_windows(windows, 1)))


def select_proxy_threshold(
    windows: Any, labels: Any, threshold: Mapping[str, Any]
) -> dict[str, Any]:
    """The proxy's threshold chosen on validation windows ``(N, W, 5, 2)`` (raw; only the last
    frame is read) and their labels, by the train group's rule (``threshold``: rule, min_recall).
    Returns the choice (``threshold`` bounded, ``ratio``, rule, precision, recall, f1)."""
    y = np.asarray(labels)
    if len(y) == 0:
        raise ValueError("no validation window: the proxy's threshold cannot be chosen")
    p = bounded(friction_ratio(windows))
    choice = select_threshold(p, y, np.unique(p), min_recall=threshold["min_recall"],
                              rule=threshold["rule"])  # fmt: skip
    return {**vars(choice), "ratio": ratio_of(choice.threshold), "grid": "validation scores",
            "windows": int(len(y)), "unstable": int(y.sum())}  # fmt: skip


def proxy_scorer(dataset_dir: str | Path, threshold: Mapping[str, Any],
                 val_objects: Sequence[str] | None = None) -> tuple[ProxyScorer, dict]:  # fmt: skip
    """The proxy with its threshold chosen on the dataset's validation windows (or, with
    ``val_objects``, on those objects' windows: a cross-validation fold's validation objects)."""
    data = load_window_data(dataset_dir)
    if val_objects is None:
        rows = data.rows("val")
    else:
        rows = np.flatnonzero(np.isin(data.index["object"].to_numpy(), list(val_objects)))
    choice = select_proxy_threshold(data.windows[rows], data.labels(rows), threshold)
    log.info("proxy threshold %.4f (friction ratio %.4f, rule %s) on %d validation windows",
             choice["threshold"], choice["ratio"], choice["rule"], choice["windows"])  # fmt: skip
    return ProxyScorer(choice["threshold"]), choice
