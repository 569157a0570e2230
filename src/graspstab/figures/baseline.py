"""The fixed-task benchmark's figures (thesis 4.3): metrics per family (fig. 4.1), test confusion
matrices (fig. 4.2) and per-object test metrics (fig. 4.3)."""

from __future__ import annotations

from collections.abc import Iterable, Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np
import polars as pl

from graspstab.figures.common import (
    PCT_LABEL,
    grouped_bars,
    legend_and_title,
    no_data,
    plt,
    save,
    seed_note,
    stat,
)
from graspstab.figures.presentation import (
    FAMILY_ORDER,
    METRIC_LABELS,
    RANKING_METRICS,
    THRESHOLD_METRICS,
    UNDEFINED,
    family_label,
    finite,
    object_label,
    ordered_families,
    rows_by,
    undefined_as_nan,
)


def plot_benchmark(summary: pl.DataFrame, out: Path, dpi: int) -> Path:
    """Fig. 4.1: validation/test threshold metrics (A, B) and ranking metrics (C, D) per family."""
    rows = rows_by(summary, ["family", "split"])
    families = ordered_families(summary["family"].to_list())
    fig, axes = plt.subplots(2, 2, figsize=(11, 7.5), gridspec_kw={"width_ratios": [2, 1.2]})
    panels = [
        ("A", "val", THRESHOLD_METRICS, "validation, at the validation-selected threshold"),
        ("C", "val", RANKING_METRICS, "validation ranking metrics"),
        ("B", "test", THRESHOLD_METRICS, "test (unseen objects), same threshold"),
        ("D", "test", RANKING_METRICS, "test ranking metrics"),
    ]
    for ax, (letter, split, metrics, title) in zip(axes.flat, panels, strict=True):
        values = {f: [stat(rows.get((f, split)), m) for m in metrics] for f in families}
        grouped_bars(ax, [METRIC_LABELS[m] for m in metrics], values)
        ax.set_title(f"4.1{letter}  {title}", loc="left", fontsize=10)
        ax.set_ylabel(PCT_LABEL)
    legend_and_title(
        fig,
        families,
        "Figure 4.1: fixed-task benchmark at the baseline observation window"
        f"{seed_note(summary)}, bars = mean, error bars = ±1 std",
    )
    fig.tight_layout(rect=(0, 0, 1, 0.92))
    return save(fig, out, dpi)


def _pick_seed(seeds: Iterable[int], first_seed: int) -> int | None:
    seeds = sorted(int(s) for s in seeds)
    if first_seed in seeds:
        return first_seed
    return seeds[0] if seeds else None


def _confusion_panel(ax: plt.Axes, row: Mapping[str, Any] | None) -> Any:
    if row is None:
        ax.set_axis_off()
        no_data(ax, "no test run for this seed")
        return None
    counts = np.array([[row["tn"], row["fp"]], [row["fn"], row["tp"]]], dtype=float)
    totals = counts.sum(axis=1, keepdims=True)
    with np.errstate(invalid="ignore", divide="ignore"):
        norm = np.where(totals > 0, counts / np.where(totals > 0, totals, 1), np.nan)
    cmap = plt.get_cmap("Blues").with_extremes(bad="0.9")
    im = ax.imshow(np.ma.masked_invalid(norm), vmin=0, vmax=1, cmap=cmap)
    for i in range(2):
        for j in range(2):
            v = norm[i, j]
            text = (
                f"{v:.1%}\n(n = {int(counts[i, j])})" if finite(v) else f"{UNDEFINED}\n(no windows)"
            )
            ax.text(
                j,
                i,
                text,
                ha="center",
                va="center",
                fontsize=9,
                color="white" if finite(v) and v > 0.6 else "black",
            )
    ticks = ["stable", "unstable"]
    ax.set_xticks([0, 1], ticks)
    ax.set_yticks([0, 1], ticks)
    ax.set_xlabel("predicted class")
    return im


def plot_confusion(runs: pl.DataFrame, first_seed: int, out: Path, dpi: int) -> Path:
    """Fig. 4.2: row-normalised test confusion matrices of one seed, one panel per family."""
    test = runs.filter(pl.col("split") == "test")
    seed = _pick_seed(test["seed"].unique().to_list(), first_seed)
    families = ordered_families(test["family"].to_list()) or list(FAMILY_ORDER)
    rows = rows_by(test.filter(pl.col("seed") == seed), ["family"]) if seed is not None else {}
    fig, axes = plt.subplots(
        1, len(families), figsize=(3.7 * len(families) + 1, 3.9), squeeze=False
    )
    im = None
    for k, (ax, fam) in enumerate(zip(axes[0], families, strict=True)):
        im = _confusion_panel(ax, rows.get((fam,))) or im
        ax.set_title(f"4.2{'ABCDEFG'[k]}  {family_label(fam)}", loc="left", fontsize=10)
        if k == 0:
            ax.set_ylabel("true class")
        else:
            ax.tick_params(labelleft=False)  # same classes as the first panel
    if im is not None:
        fig.colorbar(im, ax=axes[0].tolist(), fraction=0.025, label="fraction of the true class")
    note = f"seed {seed}" if seed is not None else "no seed"
    if seed is not None and seed != first_seed:
        note += f" (seed {first_seed} absent)"
    fig.suptitle(
        f"Figure 4.2: test confusion matrices, {note}; rows normalised, counts in brackets",
        x=0.02,
        ha="left",
    )
    return save(fig, out, dpi)


def _object_stats(objects: pl.DataFrame, metrics: Sequence[str]) -> pl.DataFrame:
    aggs = []
    for m in metrics:
        col = pl.col(m).fill_nan(None)
        aggs += [col.mean().alias(f"{m}_mean"), col.std(ddof=1).alias(f"{m}_std")]
    objects = undefined_as_nan(objects)
    return objects.group_by(["family", "object"]).agg(
        pl.col("seed").n_unique().alias("seeds"), *aggs
    )


def plot_objects(objects: pl.DataFrame, out: Path, dpi: int) -> Path:
    """Fig. 4.3: per-object test AUPRC (A) and recall at the chosen threshold (B) per family."""
    test = objects.filter(pl.col("split") == "test")
    stats = _object_stats(test, ("auprc", "recall"))
    rows = rows_by(stats, ["family", "object"])
    families = ordered_families(stats["family"].to_list())
    objs = sorted(stats["object"].unique().to_list())
    fig, axes = plt.subplots(1, 2, figsize=(10, 4.2))
    for ax, letter, metric in zip(axes, "AB", ("auprc", "recall"), strict=True):
        values = {f: [stat(rows.get((f, o)), metric) for o in objs] for f in families}
        grouped_bars(ax, [object_label(o) for o in objs], values)
        what = "AUPRC" if metric == "auprc" else "recall at the validation-selected threshold"
        ax.set_title(f"4.3{letter}  test {what}", loc="left", fontsize=10)
        ax.set_ylabel(PCT_LABEL)
        ax.set_xlabel("unseen test object")
    legend_and_title(fig, families, f"Figure 4.3: per-object test metrics{seed_note(stats)}")
    fig.tight_layout(rect=(0, 0, 1, 0.9))
    return save(fig, out, dpi)
