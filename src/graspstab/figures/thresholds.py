"""The decision threshold and calibration figures (thesis 4.6): threshold transfer from validation
to test (fig. 4.8) and reliability curves (fig. 4.9) of the first seed's checkpoints."""

from __future__ import annotations

from collections.abc import Mapping
from pathlib import Path
from typing import Any

import numpy as np
import polars as pl

from graspstab.figures.common import colour, no_data, plt, save
from graspstab.figures.presentation import (
    FAMILY_ORDER,
    SPLIT_NAMES,
    as_float,
    family_label,
    finite,
    ordered_families,
)
from graspstab.metrics.classification import reliability_curve, threshold_curves, threshold_grid

Predictions = Mapping[str, tuple[pl.DataFrame, Mapping[str, Any]]]


def _split_arrays(frame: pl.DataFrame, split: str) -> tuple[np.ndarray, np.ndarray]:
    part = frame.filter(pl.col("split") == split)
    return part["prob"].to_numpy().astype(float), part["label"].to_numpy().astype(int)


def _transfer_curves(ax_r: plt.Axes, ax_p: plt.Axes, frame: pl.DataFrame, fam: str) -> list[str]:
    """Draw the recall and precision curves; return notes on splits that have none."""
    grid = threshold_grid()
    notes = []
    for split, ls in (("val", "-"), ("test", "--")):
        probs, labels = _split_arrays(frame, split)
        if labels.size == 0 or labels.sum() == 0:
            why = "no windows" if labels.size == 0 else "no unstable window"
            notes.append(f"{SPLIT_NAMES[split]}: {why}, curves undefined")
            continue
        c = threshold_curves(probs, labels, grid)
        precision = np.where(c["predicted_positive"] > 0, c["precision"], np.nan)
        label = SPLIT_NAMES[split]
        ax_r.plot(grid, c["recall"] * 100, ls=ls, color=colour(fam), label=label)
        ax_p.plot(grid, precision * 100, ls=ls, color=colour(fam), label=label)
        if not np.isfinite(precision).any():
            notes.append(f"{SPLIT_NAMES[split]}: nothing predicted unstable, precision undefined")
    for ax in (ax_r, ax_p):
        ax.set_xlim(grid[0], grid[-1])
        ax.set_ylim(-3, 103)
        ax.grid(alpha=0.3)
    return notes


def plot_threshold_transfer(predictions: Predictions, out: Path, dpi: int) -> Path:
    """Fig. 4.8: recall (top) and precision (bottom) vs threshold on validation and test; the
    dotted line is the validation-selected threshold applied to test."""
    families = ordered_families([*FAMILY_ORDER, *predictions])
    fig, axes = plt.subplots(
        2, len(families), figsize=(4.2 * len(families), 6.6), squeeze=False, sharex=True
    )
    for k, fam in enumerate(families):
        ax_r, ax_p = axes[0, k], axes[1, k]
        if fam not in predictions:
            no_data(ax_r, "no predictions for the first seed")
            no_data(ax_p, "no predictions for the first seed")
            ax_r.set_title(family_label(fam), fontsize=9)
            continue
        frame, thr = predictions[fam]
        notes = _transfer_curves(ax_r, ax_p, frame, fam)
        t, rule = as_float(thr.get("threshold")), thr.get("rule", "?")
        for ax in (ax_r, ax_p):
            if finite(t):
                ax.axvline(t, ls=":", color="black", lw=1.3, label=f"threshold {t:.3f} ({rule})")
        ax_r.set_title("\n".join([family_label(fam), *notes]), fontsize=9)
        ax_r.legend(fontsize=7, loc="lower left")
        ax_p.set_xlabel("decision threshold")
    axes[0, 0].set_ylabel("recall [%]")
    axes[1, 0].set_ylabel("precision [%]")
    fig.suptitle(
        "Figure 4.8: transfer of the validation-selected decision threshold (first seed); "
        "solid = validation, dashed = test",
        x=0.02,
        ha="left",
    )
    fig.tight_layout(rect=(0, 0, 1, 0.95))
    return save(fig, out, dpi)


def plot_reliability(predictions: Predictions, out: Path, dpi: int, n_bins: int = 10) -> Path:
    """Fig. 4.9: reliability curves (mean predicted probability vs observed unstable fraction,
    equal-width bins) on validation and test; the diagonal is perfect calibration."""
    families = ordered_families([*FAMILY_ORDER, *predictions])
    fig, axes = plt.subplots(1, len(families), figsize=(4 * len(families), 4.3), squeeze=False)
    for ax, fam in zip(axes[0], families, strict=True):
        ax.plot([0, 1], [0, 1], ls="--", color="0.5", lw=1, label="perfect calibration")
        frame = predictions[fam][0] if fam in predictions else None
        drawn = False
        for split, marker, ls in (("val", "o", "-"), ("test", "s", "--")):
            probs, labels = _split_arrays(frame, split) if frame is not None else ([], [])
            if len(labels) == 0:
                continue
            rc = reliability_curve(probs, labels, n_bins)
            m = rc["count"] > 0
            ax.plot(
                rc["mean_predicted"][m],
                rc["observed_fraction"][m],
                marker=marker,
                ls=ls,
                ms=4,
                color=colour(fam),
                label=f"{SPLIT_NAMES[split]} (n = {len(labels)}, {int(np.sum(labels))} unstable)",
            )
            drawn = True
        if not drawn:
            no_data(ax)
        ax.set_xlim(-0.02, 1.02)
        ax.set_ylim(-0.02, 1.02)
        ax.set_aspect("equal")
        ax.grid(alpha=0.3)
        ax.set_title(family_label(fam), fontsize=10)
        ax.set_xlabel("mean predicted instability probability")
        ax.legend(fontsize=7, loc="upper left")
    axes[0, 0].set_ylabel("observed unstable fraction")
    fig.suptitle(
        f"Figure 4.9: reliability of the first-seed checkpoints ({n_bins} equal-width bins)",
        x=0.02,
        ha="left",
    )
    fig.tight_layout(rect=(0, 0, 1, 0.93))
    return save(fig, out, dpi)
