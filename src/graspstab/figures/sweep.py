"""The window-length sweep's figures (thesis 4.5): test metrics per window (fig. 4.5), baseline
inference latency (fig. 4.6) and validation AUPRC against total decision latency (fig. 4.7)."""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np
import polars as pl
from matplotlib.lines import Line2D
from matplotlib.transforms import blended_transform_factory

from graspstab.figures.common import (
    PCT_LABEL,
    annotate,
    colour,
    draw_bars,
    finish_bars,
    grouped_bars,
    legend_and_title,
    no_data,
    plt,
    save,
    seed_note,
    stat,
)
from graspstab.figures.presentation import (
    METRIC_LABELS,
    RANKING_METRICS,
    THRESHOLD_METRICS,
    as_float,
    family_label,
    finite,
    ordered_families,
    rows_by,
)


def plot_sweep(summary: pl.DataFrame, out: Path, dpi: int) -> Path:
    """Fig. 4.5: test metrics vs observation-window length (A-F), mean ± std per family."""
    test = summary.filter(pl.col("split") == "test")
    rows = rows_by(test, ["family", "window_s"])
    families = ordered_families(test["family"].to_list())
    windows = sorted(test["window_s"].unique().to_list())
    groups = [f"{w * 1000:g}" for w in windows]
    fig, axes = plt.subplots(2, 3, figsize=(15, 7.5))
    metrics = (*THRESHOLD_METRICS, *RANKING_METRICS)
    for k, (ax, metric) in enumerate(zip(axes.flat, metrics, strict=True)):
        values = {f: [stat(rows.get((f, w)), metric) for w in windows] for f in families}
        grouped_bars(ax, groups, values)
        ax.set_title(f"4.5{'ABCDEF'[k]}  test {METRIC_LABELS[metric]}", loc="left", fontsize=10)
        ax.set_xlabel("observation window [ms]")
        ax.set_ylabel(PCT_LABEL)
    legend_and_title(
        fig,
        families,
        f"Figure 4.5: test metrics across observation-window length{seed_note(test)}; "
        "offset and horizon fixed",
    )
    fig.tight_layout(rect=(0, 0, 1, 0.95))
    return save(fig, out, dpi)


def plot_latency(latency: pl.DataFrame, out: Path, dpi: int) -> Path:
    """Fig. 4.6: CPU batch-1 forward-pass latency (median ± std, A) and throughput (B) per family
    at the baseline window."""
    base = latency.filter(pl.col("study") == "baseline")
    rows = rows_by(base, ["family"])
    families = ordered_families(base["family"].to_list())
    fig, axes = plt.subplots(1, 2, figsize=(9, 3.8))
    x = np.arange(len(families), dtype=float)
    specs = [
        ("A", "median forward-pass latency [ms] (± std)", "median_ms", "std_ms", "{:.3f}"),
        ("B", "throughput [windows/s]", "throughput_per_s", None, "{:.0f}"),
    ]
    for ax, (letter, ylabel, key, err, fmt) in zip(axes, specs, strict=True):
        stats = [
            (as_float(rows[(f,)][key]), as_float(rows[(f,)][err]) if err else float("nan"))
            for f in families
        ]
        lows, highs, undefined = draw_bars(ax, x, stats, [colour(f) for f in families], 0.6, 1.0)
        annotate(ax, x, stats, 1.0, fmt)
        finish_bars(ax, lows, highs, undefined, zoom=False, positions=x)
        ax.set_xticks(x, [family_label(f) for f in families])
        ax.set_ylabel(ylabel)
        ax.set_title(f"4.6{letter}", loc="left", fontsize=10)
        ax.grid(axis="y", alpha=0.3)
        ax.set_axisbelow(True)
    window = base["window_s"].drop_nulls().unique().to_list() if "window_s" in base.columns else []
    at = f" at the {window[0]:g} s window" if len(window) == 1 else " at the baseline window"
    fig.suptitle(
        f"Figure 4.6: CPU batch-1 inference latency of the baseline checkpoints{at}",
        x=0.02,
        ha="left",
    )
    fig.tight_layout(rect=(0, 0, 1, 0.93))
    return save(fig, out, dpi)


def _mark_choice(ax: plt.Axes, choice: Mapping[str, Any]) -> None:
    if not choice.get("defined"):
        reason = choice.get("reason", "no defined validation AUPRC")
        ax.text(
            0.02,
            0.95,
            f"latency-aware choice undefined: {reason}",
            va="top",
            transform=ax.transAxes,
            fontsize=8,
            color="0.25",
            style="italic",
        )
        return
    pick = choice["pick"]
    x, y = as_float(pick.get("total_latency_ms")), as_float(pick.get("val_auprc_mean")) * 100
    if not (finite(x) and finite(y)):
        return
    ax.scatter([x], [y], s=420, facecolors="none", edgecolors="black", linewidths=1.8, zorder=5)
    text = (
        f"latency-aware pick: {family_label(pick['family'])}, "
        f"{pick['window_s'] * 1000:g} ms window\n{y:.3f} % at {x:.2f} ms"
    )
    ax.annotate(
        text,
        (x, y),
        xytext=(0.3, 0.06),
        textcoords="axes fraction",
        fontsize=8,
        arrowprops={"arrowstyle": "-", "color": "0.3"},
        bbox={"boxstyle": "round", "fc": "white", "ec": "0.6"},
    )


def _best_points(points: pl.DataFrame, best: Sequence[Mapping[str, Any]] | None) -> list[tuple]:
    if best is None:
        valid = points.filter(pl.col("val_auprc_mean").fill_nan(None).is_not_null())
        best = (
            valid.sort("val_auprc_mean", descending=True)
            .group_by("family", maintain_order=True)
            .first()
            .to_dicts()
        )
    return [(b["family"], b["window_s"]) for b in best]


def _family_points(
    ax: plt.Axes, fam: str, rows: Sequence[Mapping[str, Any]], stars: set[tuple]
) -> list[float]:
    """One family's defined (latency, validation AUPRC) points with window labels and its star;
    returns their latencies."""
    if not rows:
        return []
    x = np.array([r["total_latency_ms"] for r in rows])
    y = np.array([r["val_auprc_mean"] for r in rows]) * 100
    e = np.array([as_float(r["val_auprc_std"]) for r in rows]) * 100
    ax.errorbar(
        x,
        y,
        yerr=np.where(np.isfinite(e), e, 0),
        color=colour(fam),
        marker="o",
        ms=5,
        capsize=2.5,
        lw=1.2,
    )
    for r, xi, yi in zip(rows, x, y, strict=True):
        ax.annotate(
            f"{r['window_s'] * 1000:g} ms",
            (xi, yi),
            xytext=(4, 4),
            textcoords="offset points",
            fontsize=7,
            color=colour(fam),
        )
        if (fam, r["window_s"]) in stars:
            ax.scatter(
                [xi],
                [yi],
                marker="*",
                s=260,
                color=colour(fam),
                edgecolors="black",
                linewidths=0.8,
                zorder=6,
            )
    return list(x)


def _undefined_points(ax: plt.Axes, fam: str, rows: Sequence[Mapping[str, Any]]) -> list[float]:
    """Configurations without a defined validation AUPRC: open circles in a band along the
    bottom at their total latency (the latency is still known)."""
    if not rows:
        return []
    trans = blended_transform_factory(ax.transData, ax.transAxes)
    x = [r["total_latency_ms"] for r in rows]
    ax.scatter(
        x,
        [0.04] * len(x),
        transform=trans,
        marker="o",
        s=40,
        facecolors="none",
        edgecolors=colour(fam),
        linewidths=1.3,
        clip_on=False,
    )
    for r, xi in zip(rows, x, strict=True):
        ax.annotate(
            f"{r['window_s'] * 1000:g} ms",
            (xi, 0.04),
            xycoords=trans,
            xytext=(0, 7),
            textcoords="offset points",
            fontsize=6,
            rotation=90,
            ha="center",
            color=colour(fam),
        )
    return x


def _latency_axis(ax: plt.Axes, xs: Sequence[float]) -> None:
    """Log scale for a wide latency range; explicit limits, because points drawn in the bottom
    band (axes coordinates) do not take part in autoscaling."""
    lo, hi = min(xs), max(xs)
    if lo > 0 and hi / lo > 8:
        ax.set_xscale("log")
        ax.set_xlim(lo / 1.25, hi * 1.25)
    else:
        pad = 0.06 * (hi - lo) if hi > lo else max(abs(lo) * 0.1, 1.0)
        ax.set_xlim(lo - pad, hi + pad)


def _operating_legend(ax: plt.Axes, families: Sequence[str], undefined: int) -> None:
    handles: list[Any] = [
        Line2D([], [], marker="o", color=colour(f), label=family_label(f)) for f in families
    ]
    handles.append(
        Line2D(
            [],
            [],
            marker="*",
            ls="",
            ms=12,
            color="0.5",
            mec="black",
            label="family's best validation AUPRC",
        )
    )
    if undefined:
        handles.append(
            Line2D(
                [],
                [],
                marker="o",
                ls="",
                mfc="none",
                color="0.4",
                label=f"validation AUPRC undefined ({undefined})",
            )
        )
    # the bottom band holds the undefined configurations and their labels
    ax.legend(handles=handles, loc="upper right" if undefined else "lower right", fontsize=8)


def plot_operating_points(
    points: pl.DataFrame, overview: Mapping[str, Any], out: Path, dpi: int
) -> Path:
    """Fig. 4.7: validation AUPRC vs total decision latency of every family x window; stars
    mark each family's best window, the circle the latency-aware pick. Configurations whose
    validation AUPRC is undefined sit as open circles along the bottom."""
    fig, ax = plt.subplots(figsize=(9, 5.5))
    families = ordered_families(points["family"].to_list())
    stars = set(_best_points(points, overview.get("best_windows")))
    defined, xs, undefined = 0, [], 0
    for fam in families:
        part = points.filter(pl.col("family") == fam).sort("window_s").to_dicts()
        part = [r for r in part if finite(r["total_latency_ms"])]
        ok = [r for r in part if finite(r["val_auprc_mean"])]
        bad = [r for r in part if not finite(r["val_auprc_mean"])]
        xs += _family_points(ax, fam, ok, stars) + _undefined_points(ax, fam, bad)
        defined, undefined = defined + len(ok), undefined + len(bad)
    if not defined:
        no_data(ax, "no configuration has a defined validation AUPRC")
        ax.set_yticks([])
    if xs:
        _latency_axis(ax, xs)
        _mark_choice(ax, overview.get("choice", {}))
        _operating_legend(ax, families, undefined)
    else:
        no_data(ax)
    ax.set_xlabel("total decision latency [ms] = window duration + median forward pass")
    ax.set_ylabel("validation AUPRC [%], mean ± std over seeds")
    ax.grid(alpha=0.3)
    ax.set_title(
        "Figure 4.7: validation AUPRC against total decision latency across the "
        "window-length sweep",
        loc="left",
    )
    fig.tight_layout()
    return save(fig, out, dpi)
