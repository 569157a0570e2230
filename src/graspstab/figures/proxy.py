"""The friction-ratio proxy figure (thesis 4.7, fig. 4.10): its test AUPRC beside the models'."""

from __future__ import annotations

from collections.abc import Mapping
from pathlib import Path
from typing import Any

import numpy as np
import polars as pl

from graspstab.figures.common import (
    annotate,
    colour,
    draw_bars,
    finish_bars,
    plt,
    save,
    stat,
)
from graspstab.figures.presentation import as_float, family_label, ordered_families, rows_by


def plot_proxy(proxy: Mapping[str, Any], summary: pl.DataFrame, out: Path, dpi: int) -> Path:
    """Fig. 4.10: test AUPRC of the friction-ratio proxy beside the models' mean test AUPRC; the
    dashed line is chance level (the test set's unstable fraction)."""
    rows = rows_by(summary.filter(pl.col("split") == "test"), ["family"])
    families = ordered_families(f for (f,) in rows)
    labels = ["friction-ratio\nproxy", *[family_label(f) for f in families]]
    stats = [(as_float(proxy.get("test", {}).get("auprc")), float("nan"))]
    stats += [stat(rows[(f,)], "auprc") for f in families]
    colours = ["0.55", *[colour(f) for f in families]]
    fig, ax = plt.subplots(figsize=(6.5, 4.3))
    x = np.arange(len(labels), dtype=float)
    lows, highs, undefined = draw_bars(ax, x, stats, colours, 0.6, 100.0)
    annotate(ax, x, stats, 100.0)
    test = proxy.get("test", {})
    n, n_unstable = test.get("n", 0), test.get("n_unstable", 0)
    if n:
        chance = 100.0 * n_unstable / n
        ax.axhline(
            chance,
            ls="--",
            color="0.3",
            lw=1.1,
            label=f"chance level {chance:.1f} % (test unstable fraction, {n_unstable}/{n})",
        )
        highs.append(chance)
        ax.legend(loc="lower left", bbox_to_anchor=(0, 1.0), fontsize=8, frameon=False)
    finish_bars(ax, lows, highs, undefined, zoom=False, positions=x)
    ax.set_ylim(0, max(ax.get_ylim()[1], 100))
    ax.set_xticks(x, labels)
    ax.set_ylabel("test AUPRC [%] (models: mean ± std over seeds)")
    ax.grid(axis="y", alpha=0.3)
    ax.set_axisbelow(True)
    fig.suptitle(
        "Figure 4.10: friction-ratio proxy vs learned models, unseen-object test split",
        x=0.02,
        ha="left",
        fontsize=11,
    )
    fig.tight_layout()
    return save(fig, out, dpi)
