"""The failure-anatomy figure: when failing grasps begin to fail after settling, stacked by
failure type, with the grasps already moving at settle apart, so a reader sees at a glance
whether an early warning had a still period to work with."""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

from graspstab.common.plotting import no_data, plt, save
from graspstab.labels.anatomy import TYPES

COLOURS = dict(zip(TYPES, ("tab:red", "tab:orange", "tab:purple", "tab:blue", "tab:grey"),
                   strict=True))  # fmt: skip


def plot_anatomy(rows: Sequence[dict[str, Any]], summary: dict[str, Any], out: str | Path) -> None:
    """Histogram of onset times [s after settle] of the failing grasps, stacked by type."""
    failed = [r for r in rows if r["outcome"] == "failed"]
    fig, ax = plt.subplots(figsize=(7.5, 3.6))
    title = (f"Failure anatomy, {summary['protocol']}: {summary['failed']} of "
             f"{summary['usable']} usable grasps fail; {summary['moving_at_settle']} already "
             f"moving at settle, {summary['still_window']} leave a still window")  # fmt: skip
    if not failed:
        no_data(ax, "no usable grasp fails after settling")
    else:
        onsets = np.array([r["onset_s"] for r in failed], dtype=np.float64)
        bins = np.linspace(0.0, max(float(onsets.max()), 0.1) * 1.02, 31)
        stacks = [onsets[[r["type"] == t for r in failed]] for t in TYPES]
        labels = [f"{t.replace('_', ' ')} ({len(s)})" for t, s in zip(TYPES, stacks, strict=True)]
        ax.hist(stacks, bins=bins, stacked=True, color=[COLOURS[t] for t in TYPES],
                label=labels)  # fmt: skip
        ax.set_xlabel("onset of the failing motion [s after the settle index]")
        ax.set_ylabel("failing grasps")
        ax.legend(fontsize=7, loc="upper right")
    ax.set_title(title, fontsize=8)
    fig.tight_layout()
    save(fig, out, 110)
