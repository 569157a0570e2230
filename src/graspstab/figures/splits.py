"""The split-robustness figure (thesis 4.4, fig. 4.4): test AUPRC per sampled object-to-split
assignment."""

from __future__ import annotations

from collections.abc import Mapping
from pathlib import Path
from typing import Any

import numpy as np
from matplotlib.colors import to_rgba
from matplotlib.lines import Line2D
from matplotlib.patches import Patch

from graspstab.figures.common import colour, draw_bars, finish_bars, no_data, plt, save
from graspstab.figures.presentation import as_float, family_label, finite, object_label


def _assignment_label(row: Mapping[str, Any]) -> str:
    test = ", ".join(object_label(o) for o in str(row.get("test_objects", "")).split(", ") if o)
    return f"{row['assignment']}: {test}" if test else str(row["assignment"])


def plot_splits(summary: Mapping[str, Any], family: str | None, out: Path, dpi: int) -> Path:
    """Fig. 4.4: test AUPRC per sampled assignment (mean ± std over seeds), fixed split
    (assignment 0) highlighted, dashed line at the mean across assignments."""
    per = sorted(summary.get("per_assignment", []), key=lambda r: int(r["assignment"]))
    c = colour(family or "")
    fig, ax = plt.subplots(figsize=(max(6.0, 0.38 * len(per) + 2.5), 5.6))
    if not per:
        no_data(ax)
    else:
        x = np.arange(len(per), dtype=float)
        stats = [(as_float(r.get("auprc")), as_float(r.get("auprc_std"))) for r in per]
        colours = [c if int(r["assignment"]) == 0 else to_rgba(c, 0.45) for r in per]
        lows, highs, undefined = draw_bars(ax, x, stats, colours, 0.75, 100.0, edgecolor="none")
        mean = as_float(summary.get("mean"))
        if finite(mean):
            ax.axhline(mean * 100, ls="--", color="0.2", lw=1.2)
            lows.append(mean * 100)
        finish_bars(ax, lows, highs, undefined, zoom=True, positions=x)
        ax.set_xticks(x, [_assignment_label(r) for r in per], rotation=90, fontsize=7)
        fixed = [i for i, r in enumerate(per) if int(r["assignment"]) == 0]
        for i in fixed:
            ax.get_xticklabels()[i].set_fontweight("bold")
        handles = [
            Patch(color=c, label="fixed split (assignment 0)"),
            Patch(color=to_rgba(c, 0.45), label="sampled assignment"),
            Line2D(
                [],
                [],
                ls="--",
                color="0.2",
                label=f"mean {mean * 100:.2f} %" if finite(mean) else "mean undefined",
            ),
        ]
        ax.legend(
            handles=handles,
            loc="lower left",
            bbox_to_anchor=(0, 1.0),
            ncol=3,
            fontsize=8,
            frameon=False,
        )
        ax.grid(axis="y", alpha=0.3)
        ax.set_axisbelow(True)
    ax.set_xlabel("split assignment: number and its test objects")
    ax.set_ylabel("test AUPRC [%], mean ± std over seeds")
    name = family_label(family) if family else "model"
    fig.suptitle(
        f"Figure 4.4: split robustness of the {name}, "
        f"{summary.get('assignments', len(per))} sampled assignments",
        x=0.02,
        ha="left",
    )
    fig.tight_layout()
    return save(fig, out, dpi)
