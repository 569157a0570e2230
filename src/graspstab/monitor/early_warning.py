"""Early warning at a false-warning budget: does a monitor warn ahead of failures that begin after
a still period, at a threshold a robot could live with?

The window metrics rank windows; a controller runs one threshold. Here each monitor's threshold
is chosen on the validation grasps that hold: the lowest threshold from which on their false
warnings (rising edges of the debounced warning, as ``monitor.episodes`` counts them) stay within
``budget_per_s`` per stable grasp-second (default one per 50 s). It is chosen from a grid of the
validation scores' quantiles, and a threshold at the grid's floor is reported as such (it means
the budget did not bind). At that threshold, on the test grasps:

* **failing after a still period**: grasps whose failing motion (``labels.anatomy``'s onset)
  begins after at least one still observation window (no eq. 23 step) following the settle
  index: the only failures a warning can foresee;
* **lead time**: onset minus the first warning raised at or after the settle index (armed at
  settle; a warning already up then counts as raised then), when it precedes the onset;
* **warned ahead**: the share of those grasps whose lead is at least ``ahead_s`` (50 ms), and the
  test holding grasps' false warnings per stable grasp-second at the same threshold (does the
  budget transfer?).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from graspstab.monitor.episodes import rises
from graspstab.monitor.stream import debounced, held


@dataclass(frozen=True)
class ScoredGrasp:
    """One grasp's scores as a monitor produced them, and what the budget needs of it."""

    split: str
    frames: np.ndarray  # the scored frames (trace rows), ascending
    scores: np.ndarray  # the score at each scored frame
    start: int  # settle index: the monitor is armed here
    end: int  # contact end (exclusive)
    stable_end: int | None  # holding grasps: end of the stable stretch; None for failing ones
    onset: int | None  # failing after a still period: the onset; else None
    failing: bool  # the grasp fails (after a still period or not)
    object: str = ""  # the grasp's object and id (the fold-wide tables cluster by object)
    grasp_id: int = -1


def warnings_at(g: ScoredGrasp, threshold: float, debounce: int, length: int) -> np.ndarray:
    """The per-frame warning of ``g`` at ``threshold`` (held between scores), over ``length``
    frames."""
    return held(g.frames, debounced(g.scores >= threshold, debounce), length)


def false_rate(grasps: Sequence[ScoredGrasp], threshold: float, debounce: int,
               dt: float) -> tuple[int, float]:  # fmt: skip
    """False warnings and stable grasp-seconds of the holding grasps at ``threshold``."""
    edges, seconds = 0, 0.0
    for g in grasps:
        if g.stable_end is None or g.stable_end <= g.start:
            continue
        w = warnings_at(g, threshold, debounce, g.stable_end)
        edges += len(rises(w, g.start, g.stable_end))
        seconds += (g.stable_end - g.start) * dt
    return edges, seconds


def grid_of(grasps: Sequence[ScoredGrasp], points: int = 201) -> np.ndarray:
    """Candidate thresholds: quantiles of every score of the grasps, ascending and unique, with
    one above the largest (a monitor that never warns)."""
    every = np.concatenate([g.scores for g in grasps]) if grasps else np.zeros(0)
    every = every[np.isfinite(every)]
    if not len(every):
        return np.array([np.inf])
    q = np.unique(np.quantile(every, np.linspace(0.0, 1.0, points)))
    return np.append(q, np.nextafter(q[-1], np.inf))


def budget_threshold(grasps: Sequence[ScoredGrasp], budget_per_s: float, debounce: int,
                     dt: float, points: int = 201) -> dict[str, Any]:  # fmt: skip
    """The lowest grid threshold from which on the holding grasps' false warnings stay within
    ``budget_per_s`` per stable grasp-second, its rate, and whether it is the grid's floor."""
    grid = grid_of(grasps, points)
    rates = []
    for t in grid:
        edges, seconds = false_rate(grasps, float(t), debounce, dt)
        rates.append(edges / seconds if seconds > 0 else 0.0)
    ok = np.asarray(rates) <= budget_per_s
    # from the top down: the lowest threshold with every higher one within budget too
    bad = np.flatnonzero(~ok)
    i = int(bad[-1]) + 1 if len(bad) else 0
    i = min(i, len(grid) - 1)
    edges, seconds = false_rate(grasps, float(grid[i]), debounce, dt)
    return {"threshold": float(grid[i]), "at_floor": i == 0, "never_warns": i == len(grid) - 1,
            "false_warnings": edges, "stable_seconds": seconds,
            "false_per_s": edges / seconds if seconds > 0 else None}  # fmt: skip


def grasp_outcomes(grasps: Sequence[ScoredGrasp], threshold: float, debounce: int, dt: float,
                   ahead_s: float) -> list[dict[str, Any]]:  # fmt: skip
    """Per grasp at ``threshold``: for one failing after a still period, its lead (onset minus
    the first warning at or after the settle index [s], when that precedes the onset, else None)
    and whether it is at least ``ahead_s``; for one that holds, its false warnings and stable
    seconds (0 for the others)."""
    rows: list[dict[str, Any]] = []
    for g in grasps:
        lead = None
        if g.onset is not None:
            first = rises(warnings_at(g, threshold, debounce, g.end), g.start, g.end)
            if len(first) and first[0] < g.onset:
                lead = (g.onset - int(first[0])) * dt
        edges, seconds = 0, 0.0
        if g.stable_end is not None and g.stable_end > g.start:
            w = warnings_at(g, threshold, debounce, g.stable_end)
            edges = len(rises(w, g.start, g.stable_end))
            seconds = (g.stable_end - g.start) * dt
        rows.append({
            "object": g.object, "grasp_id": g.grasp_id, "failing": g.failing,
            "after_still": g.onset is not None, "lead_s": lead,
            "warned_ahead": None if g.onset is None else lead is not None
            and lead >= ahead_s - 1e-12,
            "false_warnings": edges, "stable_seconds": seconds,
        })  # fmt: skip
    return rows


def lead_times(grasps: Sequence[ScoredGrasp], threshold: float, debounce: int,
               dt: float) -> list[float | None]:  # fmt: skip
    """Per grasp failing after a still period: its lead [s] (:func:`grasp_outcomes`), or None."""
    return [r["lead_s"] for r in grasp_outcomes(grasps, threshold, debounce, dt, 0.0)
            if r["after_still"]]  # fmt: skip


def early_warning(val: Sequence[ScoredGrasp], test: Sequence[ScoredGrasp], *,
                  budget_per_s: float, ahead_s: float, debounce: int,
                  dt: float) -> dict[str, Any]:  # fmt: skip
    """One monitor's early-warning figures (module docstring)."""
    choice = budget_threshold(val, budget_per_s, debounce, dt)
    rows = grasp_outcomes(test, choice["threshold"], debounce, dt, ahead_s)
    leads = [r["lead_s"] for r in rows if r["after_still"]]
    defined = [x for x in leads if x is not None]
    ahead = sum(bool(r["warned_ahead"]) for r in rows)
    edges = sum(r["false_warnings"] for r in rows)
    seconds = sum(r["stable_seconds"] for r in rows)
    return {
        "threshold": choice,
        "test": {
            "grasps": len(test),
            "failing": sum(g.failing for g in test),
            "failing_after_still": len(leads),
            "warned_before_onset": len(defined),
            "warned_ahead": ahead,
            "warned_ahead_share": ahead / len(leads) if leads else None,
            "median_lead_s": float(np.median(defined)) if defined else None,
            "false_warnings": edges,
            "stable_seconds": seconds,
            "false_per_s": edges / seconds if seconds > 0 else None,
        },
    }
