"""Prediction, not detection, as the report shows it: the cells of a ranking metric on the
still-now windows (the object still over the whole observation period; ``evaluation.detection``)
beside the all-windows figure, with their count, positives and chance level.

Every value is read from a summary a job wrote: a record's ``<split>_still`` block (``n``,
``n_unstable``, ``chance``, ``auprc``, ``auroc``) or a seed summary's ``still_<metric>_mean`` /
``_std`` columns; an undefined metric prints ``undefined: <reason>`` (e.g. "undefined: no
still-now test window becomes unstable"), never 0. An artefact written before these metrics has
neither, and the tables leave the still-now part out (:func:`has_motion`).
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping
from typing import Any

from graspstab.figures.presentation import UNDEFINED, finite, motion_reason

#: What each window set means, for the sections' notes (HTML).
ALL_WINDOWS_TEXT = (
    "<b>All windows</b> is the reference's protocol: every test window, including those whose "
    "object already moves during its observation period, so it also rewards recognising motion "
    "already under way."
)
STILL_NOW_TEXT = (
    "<b>Still now</b> keeps only the windows whose object is still over the whole observation "
    "period (no step at or above v_slip, eq. 23): a scorer can rank them only by foresight, so "
    "this is early warning proper. Read its AUPRC against its own chance level, the still-now "
    "windows' unstable share."
)
ORACLE_TEXT = (
    "The <b>persistence oracle</b> scores a window by the share of its observation period in "
    "which the object moves: it reads object motion, which no fingertip sensor sees, so it is a "
    "reference line for 'it moves now, so it will move', never a monitor. It scores every "
    "still-now window 0, so it cannot rank them."
)


def undefined(reason: str) -> str:
    """An undefined still-now (moving-now) value with its reason."""
    return f"{UNDEFINED}: {reason}"


def has_motion(columns: Iterable[str], part: str = "still") -> bool:
    """Whether a seed summary (its columns, or a row's keys) holds the ``part``-now metrics."""
    return f"{part}_auprc_mean" in set(columns)


def count(value: Any) -> str:
    """A window count (a mean over seeds of one split's count: whole) as text."""
    if not finite(value):
        return UNDEFINED
    v = float(value)
    return f"{int(round(v)):,}" if abs(v - round(v)) < 1e-9 else f"{v:,.1f}"


def percent(value: Any, std: Any = None, digits: int = 2, sign: bool = True) -> str | None:
    """A fraction in percent ('mean ± std %'; std left out when None), None when undefined."""
    if not finite(value):
        return None
    unit = " %" if sign else ""
    m = f"{100 * float(value):.{digits}f}"
    if std is None:
        return f"{m}{unit}"
    s = f"{100 * float(std):.{digits}f}" if finite(std) else UNDEFINED
    return f"{m} ± {s}{unit}"


def block_metric(
    block: Mapping[str, Any] | None,
    metric: str,
    split: str = "test",
    part: str = "still",
    digits: int = 2,
    sign: bool = True,
) -> str:
    """``metric`` (auprc, auroc) of a record's ``<split>_<part>`` block in percent, or
    'undefined: <reason>' (no block: not recorded)."""
    b = block or {}
    got = percent(b.get(metric), None, digits, sign)
    return got if got is not None else undefined(
        motion_reason(b.get("n"), b.get("n_unstable"), split, part)
    )


def block_counts(
    block: Mapping[str, Any] | None, split: str = "test", part: str = "still", digits: int = 2,
    sign: bool = True,
) -> list[str]:
    """[windows, unstable, chance AUPRC] of a record's ``<split>_<part>`` block."""
    b = block or {}
    n = b.get("n")
    chance = percent(b.get("chance"), None, digits, sign)
    if chance is None:  # no window (or none recorded): no share
        empty = not finite(n) or float(n) == 0
        chance = undefined(motion_reason(n, None, split, part) if empty else "no value")
    return [count(n), count(b.get("n_unstable")), chance]


def summary_metric(
    row: Mapping[str, Any] | None,
    metric: str,
    split: str = "test",
    part: str = "still",
    digits: int = 2,
    std: bool = True,
    sign: bool = True,
) -> str:
    """Mean ± std over seeds of ``<part>_<metric>`` from a row of a seed summary (a study's
    summary.parquet or summary_defined.parquet) in percent, or 'undefined: <reason>'."""
    r = row or {}
    mean = r.get(f"{part}_{metric}_mean")
    sd = r.get(f"{part}_{metric}_std") if std else None
    got = percent(mean, sd, digits, sign)
    if got is not None:
        return got
    return undefined(motion_reason(r.get(f"{part}_n_mean"), r.get(f"{part}_n_unstable_mean"),
                                   split, part))  # fmt: skip


def summary_counts(
    row: Mapping[str, Any] | None, split: str = "test", part: str = "still", digits: int = 2,
    sign: bool = True,
) -> list[str]:
    """[windows, unstable, chance AUPRC] of a seed summary's row (each the mean over seeds of one
    split's count or share: the same windows in every seed)."""
    r = row or {}
    return block_counts(
        {"n": r.get(f"{part}_n_mean"), "n_unstable": r.get(f"{part}_n_unstable_mean"),
         "chance": r.get(f"{part}_chance_mean")},
        split, part, digits, sign,
    )  # fmt: skip
