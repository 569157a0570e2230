"""Runs of consecutive true values in a boolean trace (settling, contact loss, depth rules)."""

from __future__ import annotations

import numpy as np


def earliest_run(ok: np.ndarray, length: int, limit: int) -> int | None:
    """First index i with ``ok[i : i + length]`` all true and ``i + length <= limit``."""
    n = min(len(ok), limit)
    if length < 1 or n < length:
        return None
    run = np.convolve(ok[:n].astype(np.int64), np.ones(length, dtype=np.int64), mode="valid")
    hits = np.flatnonzero(run == length)
    return int(hits[0]) if len(hits) else None
