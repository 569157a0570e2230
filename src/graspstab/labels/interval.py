"""The usable replay interval (thesis 3.3.1): settle index, depth rejection and contact end.

All indices are trace rows (row t = the state before step t, dt apart). ``dist`` is d_t with NaN
where no hand-object contact exists; ``speed`` is ||v_t||.

Where only one of the two settle checks succeeds, the reference is silent. Two readings, chosen
by ``settle.require``: ``either`` takes the one that succeeded (it has found a quiet interval, and
the 3 s fallback is meant for replays where neither check finds one); ``both`` requires both and
otherwise falls back to 3 s (the later of two indices exists only when both do).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from graspstab.common.runs import earliest_run

__all__ = ["earliest_run", "settle_by_distance", "settle_by_speed", "usable_interval"]


def steps_of(seconds: float, dt: float) -> int:
    """Whole steps in ``seconds`` (rounded to the nearest step: 0.1 s / 0.5 ms = 200)."""
    return int(round(seconds / dt))


def settle_by_speed(speed: np.ndarray, dt: float, p: dict[str, Any]) -> int | None:
    """Eq. 20: the earliest 0.1 s interval within the first 3 s with ||v|| <= 5 mm/s throughout."""
    return earliest_run(
        np.asarray(speed) <= p["speed_max"],
        steps_of(p["interval_s"], dt),
        steps_of(p["search_s"], dt),
    )


def distance_tolerance(dist: np.ndarray, dt: float, p: dict[str, Any]) -> tuple[float, float]:
    """Eq. 21: d~ = median of finite d_t in the last 0.2 s of the 3 s search, and tau_d."""
    search = steps_of(p["search_s"], dt)
    tail = np.asarray(dist[max(0, search - steps_of(p["distance_tail_s"], dt)) : search])
    tail = tail[np.isfinite(tail)]
    if len(tail) == 0:
        return math.nan, math.nan
    ref = float(np.median(tail))
    mad = float(np.median(np.abs(tail - ref)))
    return ref, max(p["distance_tol_min"], p["distance_mad_factor"] * 1.4826 * mad)


def settle_by_distance(dist: np.ndarray, dt: float, p: dict[str, Any]) -> int | None:
    """Eq. 22: the earliest 0.1 s interval within 3 s with |d_t - d~| <= tau_d throughout."""
    ref, tol = distance_tolerance(dist, dt, p)
    if not math.isfinite(ref):
        return None
    with np.errstate(invalid="ignore"):
        ok = np.abs(np.asarray(dist) - ref) <= tol  # NaN (no contact) is never settled
    return earliest_run(ok, steps_of(p["interval_s"], dt), steps_of(p["search_s"], dt))


@dataclass(frozen=True)
class UsableInterval:
    """Where a replay's usable interval lies, and why it may be rejected."""

    settle_index: int
    settle_rule: str  # both | speed | distance | fallback
    contact_end: int  # exclusive end of the usable interval
    rejected: str | None  # None, or why: "depth" (d_t < -8 mm for >= 1 s after settling)


def usable_interval(speed: np.ndarray, dist: np.ndarray, dt: float, p: dict[str, Any],
                    contact_loss_s: float) -> UsableInterval:  # fmt: skip
    """Settle index (the later of the two checks; the 3 s fallback when neither succeeds),
    depth rejection and contact end (3.3.1) of one replay."""
    by_speed, by_dist = settle_by_speed(speed, dt, p), settle_by_distance(dist, dt, p)
    require = p["require"]
    if require not in ("either", "both"):
        raise ValueError(f"labels.settle.require must be 'either' or 'both', got {require!r}")
    if by_speed is not None and by_dist is not None:
        settle, rule = max(by_speed, by_dist), "both"
    elif require == "both" and (by_speed is not None or by_dist is not None):
        settle, rule = steps_of(p["search_s"], dt), "fallback"
    elif by_speed is not None:
        settle, rule = by_speed, "speed"
    elif by_dist is not None:
        settle, rule = by_dist, "distance"
    else:
        settle, rule = steps_of(p["search_s"], dt), "fallback"
    dist = np.asarray(dist)
    after = dist[settle:]
    # contact end: first step of the first run of undefined d_t lasting >= 0.1 s after settling
    loss = earliest_run(np.isnan(after), steps_of(contact_loss_s, dt), len(after))
    end = len(dist) if loss is None else settle + loss
    with np.errstate(invalid="ignore"):
        deep = after < p["penetration_reject"]
    too_deep = earliest_run(deep, steps_of(p["penetration_reject_s"], dt), len(after))
    return UsableInterval(settle, rule, end, None if too_deep is None else "depth")
