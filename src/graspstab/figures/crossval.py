"""The k-fold study's figure (our extension): per-object test AUPRC of each plain family and the
friction-ratio proxy against object mass, size and shape class, and the paired differences."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np
import polars as pl

from graspstab.figures.common import colour, plt, save

SHAPES = ["box", "cylinder", "round", "flat", "irregular", "unclassified"]


def _colour(scorer: str) -> str:
    return "0.35" if scorer == "proxy" else colour(scorer)


def plot_crossval(per_object: pl.DataFrame, summary: dict[str, Any], out: Path, dpi: int) -> Path:
    """Four panels: AUPRC against mass (log), against largest extent, by shape class (jittered),
    and learned-minus-proxy per object with the paired-bootstrap interval of the mean."""
    scorers = [s for s in summary["scorers"] if "+" not in s]
    fig, axes = plt.subplots(1, 4, figsize=(16, 4.2), gridspec_kw={"width_ratios": [1, 1, 1, 1.2]})
    rng = np.random.default_rng(0)
    for i, scorer in enumerate(scorers):
        d = per_object.filter(pl.col("scorer") == scorer).drop_nulls("auprc")
        d = d.filter(pl.col("auprc").is_not_nan())
        kw = {"color": _colour(scorer), "s": 18, "alpha": 0.8, "label": scorer}
        axes[0].scatter(d["mass"], 100 * d["auprc"], **kw)
        axes[1].scatter(100 * d["size"], 100 * d["auprc"], **kw)
        xs = np.array([SHAPES.index(s) if s in SHAPES else len(SHAPES) - 1 for s in d["shape"]])
        off = (i - (len(scorers) - 1) / 2) * 0.15
        axes[2].scatter(xs + off + rng.uniform(-0.04, 0.04, xs.size), 100 * d["auprc"], **kw)
    axes[0].set_xscale("log")
    axes[0].set_xlabel("object mass [kg]")
    axes[1].set_xlabel("largest extent [cm]")
    axes[2].set_xticks(range(len(SHAPES)), SHAPES, rotation=30)
    axes[2].set_xlabel("shape class")
    for ax in axes[:3]:
        ax.set_ylabel("test AUPRC per object [%]")
        ax.grid(alpha=0.3)
    axes[0].legend(fontsize=8, frameon=False)
    ax = axes[3]
    paired = {r["scorer"]: r for r in summary["paired"] if r["metric"] == "auprc"}
    proxy = per_object.filter(pl.col("scorer") == "proxy")
    base = dict(zip(proxy["object"], proxy["auprc"], strict=True))
    learned = [s for s in scorers if s != "proxy"]
    for j, scorer in enumerate(learned):
        d = per_object.filter(pl.col("scorer") == scorer)
        diff = np.array(
            [a - base.get(o, np.nan) for o, a in zip(d["object"], d["auprc"], strict=True)]
        )
        diff = diff[np.isfinite(diff)]
        ax.scatter(
            j + rng.uniform(-0.12, 0.12, diff.size),
            100 * diff,
            s=14,
            alpha=0.7,
            color=_colour(scorer),
        )
        p = paired.get(scorer)
        if p and np.isfinite(p["mean_diff"]):
            ax.errorbar(
                j + 0.3,
                100 * p["mean_diff"],
                color="k",
                capsize=4,
                fmt="o",
                yerr=[[100 * (p["mean_diff"] - p["lo"])], [100 * (p["hi"] - p["mean_diff"])]],
            )
    ax.axhline(0, color="0.3", lw=1, ls="--")
    ax.set_xticks(range(len(learned)), learned)
    ax.set_ylabel("AUPRC learned - proxy per object [points]")
    ax.set_title("paired: mean and interval (black)", fontsize=9)
    ax.grid(alpha=0.3)
    fig.suptitle(
        f"Object-level {summary['folds']}-fold cross-validation, {summary['protocol']} protocol: "
        f"{len(summary['tested_objects'])} test objects",
        fontsize=10,
    )
    fig.tight_layout()
    return save(fig, out, dpi)
