"""The Optuna optimisation histories of the tuning study (table 4.1; the thesis has no figure)."""

from __future__ import annotations

from collections.abc import Mapping
from pathlib import Path
from typing import Any

import numpy as np
import polars as pl
from matplotlib.ticker import MaxNLocator
from matplotlib.transforms import blended_transform_factory

from graspstab.figures.common import no_data, plt, save
from graspstab.figures.presentation import (
    FAMILY_ORDER,
    METRIC_LABELS,
    family_label,
    ordered_families,
)


def _tuning_panel(ax: plt.Axes, trials: pl.DataFrame) -> None:
    """Complete trials and the running best; pruned trials at their last reported value; trials
    without a value (failed, running, pruned before any report) along the bottom."""
    trials = trials.sort("number")
    values = trials["value"].cast(pl.Float64).to_numpy()
    numbers = trials["number"].to_numpy()
    states = np.array(trials["state"].to_list(), dtype=object)
    has = np.isfinite(values)
    ok = (states == "complete") & has
    if ok.any():
        ax.scatter(numbers[ok], values[ok], s=22, color="0.2", zorder=3, label="complete trial")
        running = np.maximum.accumulate(np.where(ok, values, -np.inf))
        keep = np.isfinite(running)
        ax.step(
            numbers[keep], running[keep], where="post", color="tab:red", lw=1.3, label="best so far"
        )
    else:
        no_data(ax, "no completed trial with a finite value")
    pruned = (states == "pruned") & has
    if pruned.any():
        ax.scatter(
            numbers[pruned],
            values[pruned],
            marker="x",
            color="0.45",
            s=30,
            label=f"pruned, last reported value ({int(pruned.sum())})",
        )
    marks = {"pruned": "x", "fail": "v", "running": "s", "complete": "D"}
    trans = blended_transform_factory(ax.transData, ax.transAxes)
    for state in sorted(set(states[~has])):
        sel = (states == state) & ~has
        ax.scatter(
            numbers[sel],
            np.full(sel.sum(), 0.04),
            marker=marks.get(state, "o"),
            color="tab:red" if state == "fail" else "0.45",
            s=30,
            transform=trans,
            clip_on=False,
            label=f"{state}, no value ({int(sel.sum())})",
        )
    if (~has).any():
        lo, hi = ax.get_ylim()
        ax.set_ylim(lo - 0.15 * (hi - lo), hi)  # a band along the bottom for valueless trials
    ax.xaxis.set_major_locator(MaxNLocator(integer=True))
    ax.set_xlabel("trial number")
    ax.grid(alpha=0.3)
    ax.legend(fontsize=7, loc="best")


def plot_tuning(
    tuning: Mapping[str, tuple[pl.DataFrame, Mapping[str, Any] | None]], out: Path, dpi: int
) -> Path:
    """Optuna optimisation history per family: trial value by trial number, the running best,
    pruned / failed trials marked along the bottom (they have no value)."""
    families = ordered_families(tuning) or list(FAMILY_ORDER)
    fig, axes = plt.subplots(1, len(families), figsize=(4.3 * len(families), 4), squeeze=False)
    for ax, fam in zip(axes[0], families, strict=True):
        if fam not in tuning:
            no_data(ax)
            continue
        trials, best = tuning[fam]
        _tuning_panel(ax, trials)
        obj = (best or {}).get("objective", "value")
        extra = f", best trial {best['best_trial']}" if best and "best_trial" in best else ""
        ax.set_title(f"{family_label(fam)}{extra}", fontsize=10)
        ax.set_ylabel(
            "trial value: "
            + ("−validation loss" if obj == "loss" else f"validation {METRIC_LABELS.get(obj, obj)}")
        )
    fig.suptitle(
        "Optuna optimisation history per family (tuning of table 4.1; no thesis figure)",
        x=0.02,
        ha="left",
    )
    fig.tight_layout(rect=(0, 0, 1, 0.92))
    return save(fig, out, dpi)
