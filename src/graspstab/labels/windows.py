"""Timestep labels, window starts and predictive labels (thesis 3.3.2-3.3.4, eqs. 23-30)."""

from __future__ import annotations

import math

import numpy as np


def step_counts(
    window_s: float, offset_s: float, horizon_s: float, dt: float
) -> tuple[int, int, int]:
    """W, O, H of eq. 24 in steps.

    W = ceil(tau_w / dt) and H = ceil(tau_h / dt) as printed (a relative 1e-9 guard keeps 0.2 /
    5e-4 at 400 despite floating point). For O the reference prints ceil(tau_o / dt + 1/2) but
    states O = 200 for tau_o = 0.1 s, dt = 5e-4 s, which is floor(tau_o / dt + 1/2), the nearest
    step (the ceiling would give 201); we follow the stated value.
    """

    def ceil(x: float) -> int:
        return math.ceil(x - 1e-9 * max(1.0, abs(x)))

    return ceil(window_s / dt), math.floor(offset_s / dt + 0.5 + 1e-9), ceil(horizon_s / dt)


def timestep_labels(speed: np.ndarray, v_slip: float) -> np.ndarray:
    """Eq. 23: u_t = 1[||v_t|| >= v_slip] (uint8)."""
    return (np.asarray(speed) >= v_slip).astype(np.uint8)


def window_starts(
    settle: int, contact_end: int, w: int, o: int, h: int, count: int, rng: np.random.Generator
) -> np.ndarray:
    """Up to ``count`` distinct starts s with settle <= s <= contact_end - W - O - H (eq. 26):
    the settle index whenever valid, the rest drawn without replacement; sorted."""
    last = contact_end - w - o - h
    if last < settle or count < 1:
        return np.zeros(0, dtype=np.int64)
    pool = np.arange(settle + 1, last + 1)
    extra = rng.choice(pool, size=min(count - 1, len(pool)), replace=False) if len(pool) else []
    return np.sort(np.concatenate([[settle], np.asarray(extra, dtype=np.int64)])).astype(np.int64)


def predictive_labels(
    u: np.ndarray,
    starts: np.ndarray,
    contact_end: int,
    w: int,
    o: int,
    h: int,
    low: float,
    high: float,
) -> tuple[np.ndarray, np.ndarray]:
    """Eqs. 29-30 for each start: r_s over [s + W + O, min(s + W + O + H, contact_end)), and the
    label 1 (r >= high), 0 (r <= low) or -1 (discarded: ambiguous, or an empty target)."""
    csum = np.concatenate([[0], np.cumsum(np.asarray(u, dtype=np.int64))])
    n = len(csum) - 1
    first = np.clip(np.asarray(starts, dtype=np.int64) + w + o, 0, n)
    stop = np.clip(np.minimum(first + h, contact_end), first, n)
    size = stop - first
    with np.errstate(invalid="ignore", divide="ignore"):
        r = np.where(size > 0, (csum[stop] - csum[first]) / np.maximum(size, 1), np.nan)
    label = np.full(len(r), -1, dtype=np.int8)
    label[r >= high] = 1
    label[r <= low] = 0
    return r, label


def event_windows(
    settle: int, contact_end: int, onset: int | None, w: int, o: int, h: int, count: int,
    rng: np.random.Generator,
) -> tuple[np.ndarray, np.ndarray]:  # fmt: skip
    """The event form of 3.3.3-3.3.4 (our option, ``labels.form: event``): starts and labels of
    up to ``count`` windows. A grasp that fails (``onset``: the step its failing motion begins)
    has its starts drawn as eq. 26 draws them, but up to ``onset - W - O`` (no window looks past
    the onset), and a window is positive when the onset lies in its target interval
    [s + W + O, s + W + O + H); a grasp that holds has eq. 26's starts, all negative."""
    if onset is None:
        starts = window_starts(settle, contact_end, w, o, h, count, rng)
        return starts, np.zeros(len(starts), dtype=np.int8)
    starts = window_starts(settle, onset + h, w, o, h, count, rng)  # last start onset - W - O
    first = starts + w + o
    label = ((first <= onset) & (onset < first + h)).astype(np.int8)
    return starts, label
