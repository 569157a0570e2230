"""Sensor robustness figure (our extension): test AUPRC of each family and the proxy against each
corruption's strength, one panel per corruption, the chance level dotted."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import polars as pl

from graspstab.figures.common import colour, no_data, plt, save
from graspstab.figures.presentation import family_label

#: Axis label of each corruption's strength (config group sensing, curves).
STRENGTH_LABELS = {
    "noise": "noise std (x channel std)",
    "gain": "gain error std",
    "drift": "drift rate std (x channel std / s)",
    "quantisation": "converter bits",
    "rate": "sampling rate (Hz)",
    "delay": "delay (s)",
    "drop": "dropped-sample probability",
}


def plot_robustness(runs: pl.DataFrame, chance: float, path: Path, dpi: int = 110) -> Path:
    """One panel per corruption of ``runs`` (evaluate_robustness's table): mean +- std over seeds
    per family and training, the clean point at each curve's "off" end (4 bits above the finest
    converter, 2 kHz for the rate); a panel whose AUPRC is undefined says so."""
    curves = runs.filter(pl.col("kind") == "curve")
    clean = runs.filter(pl.col("kind") == "clean")
    names = list(dict.fromkeys(curves["corruption"].to_list()))
    cols = min(4, max(1, len(names)))
    rows = max(1, math.ceil(len(names) / cols))
    fig, axes = plt.subplots(rows, cols, figsize=(3.6 * cols, 2.9 * rows), squeeze=False)
    for ax in axes.flat[len(names) :]:
        ax.set_visible(False)
    # a model trained through one corruption only (training "augmented:<name>") in its panel
    own = pl.col("training").str.starts_with("augmented:")
    for ax, name in zip(axes.flat, names, strict=False):
        mine = ~own | (pl.col("training") == f"augmented:{name}")
        part = curves.filter((pl.col("corruption") == name) & mine)
        # the clean point sits where the strength is "off": 0, or above the strongest for
        # bits and rate (more bits, faster sampling is cleaner)
        off = {"quantisation": part["strength"].max() + 4, "rate": 2000.0}.get(name, 0.0)
        drawn = 0
        for (family, training), group in pl.concat([part, clean.filter(mine).with_columns(
                pl.lit(name).alias("corruption"), pl.lit(off).alias("strength"))]).group_by(
                ["family", "training"], maintain_order=True):  # fmt: skip
            stats = group.group_by("strength").agg(
                pl.col("auprc").mean().alias("m"), pl.col("auprc").std(ddof=0).alias("s")
            )
            stats = stats.sort("strength")
            x, m = stats["strength"].to_numpy(), stats["m"].to_numpy()
            s = np.nan_to_num(stats["s"].to_numpy())
            if not np.isfinite(m).any():  # AUPRC undefined (a class missing from the split)
                continue
            drawn += 1
            style = {"clean": "-", "none": "-", "augmented": "--"}.get(training, "-.")
            label = "proxy" if family == "proxy" else family_label(family)
            if training == "augmented":
                label += " (through sensors)"
            elif training not in ("clean", "none"):
                label += " (this corruption)"
            ax.errorbar(
                x,
                100 * m,
                yerr=100 * s,
                fmt=style + "o",
                ms=3,
                capsize=2,
                color=colour(family) if family != "proxy" else "0.35",
                label=label,
            )
        if not drawn:
            no_data(ax, "AUPRC undefined")
            ax.set_title(name)
            continue
        if math.isfinite(chance):
            ax.axhline(100 * chance, color="0.5", ls=":", lw=1, label="chance")
        if name in ("rate",):
            ax.set_xscale("log")
        ax.set_xlabel(STRENGTH_LABELS.get(name, name))
        ax.set_ylabel("test AUPRC (%)")
        ax.set_title(name)
        ax.grid(alpha=0.3)
    if axes.flat[0].get_legend_handles_labels()[0]:
        axes.flat[0].legend(fontsize=7)
    fig.tight_layout()
    return save(fig, path, dpi)
