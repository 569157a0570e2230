"""Unit conversions that name artefacts, shared by config checks, workflow and report."""

from __future__ import annotations


def ms_of(window_s: float) -> int:
    """A window length in whole milliseconds: the wildcard that names a trimmed dataset."""
    return round(1000 * window_s)
