"""How the chapter-4 results are named and shown, in one place for the figures and the report.

No plotting here (no matplotlib import), so the report reads its names, orders and undefined-value
rules without pulling in a plotting backend: family names and order, split and metric names, the
"undefined" marker, the 0/0-as-undefined summary of runs, and the learning figures' names (the one
list that rule ``plot_learning``, :mod:`graspstab.figures` and the report share).
"""

from __future__ import annotations

import math
import re
from collections.abc import Iterable, Sequence
from typing import Any

import polars as pl

# undefined_as_nan (precision, recall and F1 as NaN for 0/0) is the studies'; re-exported here
from graspstab.evaluation.aggregate import mean_std, undefined_as_nan  # noqa: F401
from graspstab.evaluation.detection import ORACLE  # noqa: F401  (re-exported for the report)

#: Every learning figure of rule ``plot_learning`` (name -> ``<name>.png``), in thesis order.
LEARNING_FIGURES = (
    "benchmark",
    "confusion",
    "objects",
    "splits",
    "sweep",
    "latency",
    "operating_points",
    "threshold_transfer",
    "reliability",
    "proxy",
    "tuning",
)
#: Output file name of each learning figure.
FIGURES = {name: f"{name}.png" for name in LEARNING_FIGURES}

FAMILY_ORDER = ("cnn", "gru", "lstm")
FAMILY_LABELS = {"cnn": "CNN", "gru": "GRU", "lstm": "LSTM"}

UNDEFINED = "undefined"
SPLITS = ("val", "test")
SPLIT_NAMES = {"val": "validation", "test": "test"}

THRESHOLD_METRICS = ("accuracy", "precision", "recall", "f1")
RANKING_METRICS = ("auroc", "auprc")
METRICS = (*THRESHOLD_METRICS, *RANKING_METRICS)
#: Metric names in running text and tables.
METRIC_NAMES = {
    "accuracy": "accuracy",
    "precision": "precision",
    "recall": "recall",
    "f1": "F1",
    "auroc": "AUROC",
    "auprc": "AUPRC",
}
#: Metric names on figure axes and titles (matplotlib mathtext).
METRIC_LABELS = {
    "accuracy": "Accuracy",
    "precision": "Precision",
    "recall": "Recall",
    "f1": "F$_1$",
    "auroc": "AUROC",
    "auprc": "AUPRC",
}


#: Prediction, not detection (``graspstab.evaluation.detection``): every ranking metric is also
#: given on the windows whose object is still over the whole observation period (``still``: the
#: columns ``still_<metric>`` of the studies' tables, the keys ``<split>_still`` of the records)
#: and on those where it already moves (``moving``).
MOTION_PARTS = ("still", "moving")
MOTION_NAMES = {"all": "all windows", "still": "still now", "moving": "moving now"}
#: The persistence oracle (its name in the records is evaluation.detection.ORACLE): it reads
#: object motion, a reference line, never a monitor.
ORACLE_LABEL = "persistence oracle"


def motion_reason(n: Any, n_unstable: Any, split: str = "test", part: str = "still") -> str:
    """Why a ranking metric of a split's still-now (``part`` "still") or moving-now windows is
    undefined, from their count and positives: none recorded (an artefact written before these
    metrics), no such window, no unstable one, no stable one."""
    name, kind = SPLIT_NAMES.get(split, split), f"{part}-now"
    if not finite(n):
        return f"no {kind} metrics recorded (an artefact written before them)"
    if float(n) == 0:
        return f"the {name} split holds no {kind} window"
    if finite(n_unstable) and float(n_unstable) == 0:
        return f"no {kind} {name} window becomes unstable"
    if finite(n_unstable) and float(n_unstable) == float(n):
        return f"every {kind} {name} window becomes unstable"
    return "no seed gave a defined value"


def finite(value: Any) -> bool:
    """True for a real, finite number: None (strict JSON's undefined) and NaN are not."""
    try:
        return value is not None and math.isfinite(float(value))
    except (TypeError, ValueError):
        return False


def as_float(value: Any) -> float:
    """``value`` as a float, NaN when it is undefined (None, NaN, not a number)."""
    return float(value) if finite(value) else float("nan")


def family_label(family: str) -> str:
    """'gru' -> 'GRU' (an unknown family in upper case)."""
    return FAMILY_LABELS.get(family, str(family).upper())


def ordered_families(names: Iterable[str]) -> list[str]:
    """The thesis order (CNN, GRU, LSTM), then any other family alphabetically."""
    present = set(names)
    return [f for f in FAMILY_ORDER if f in present] + sorted(present - set(FAMILY_ORDER))


def object_label(obj: str) -> str:
    """'077_rubiks_cube' -> 'rubiks cube'."""
    return re.sub(r"^\d+_", "", str(obj)).replace("_", " ")


def rows_by(frame: pl.DataFrame, keys: Sequence[str]) -> dict[tuple, dict[str, Any]]:
    """The rows of ``frame`` keyed by their values of ``keys`` (a tuple, also for one key)."""
    return {tuple(r[k] for k in keys): r for r in frame.iter_rows(named=True)}


def defined_summary(runs: pl.DataFrame, by: Sequence[str]) -> pl.DataFrame:
    """Mean ± std over seeds (as the studies' summary.parquet) with 0/0 metrics undefined (the
    figures' view; the report reads the same numbers from the studies' summary_defined.parquet,
    written by :func:`graspstab.evaluation.aggregate.seed_summary`)."""
    return mean_std(undefined_as_nan(runs), by)
