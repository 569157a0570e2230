"""Chapter 4 figures (thesis figs. 4.1-4.10 and the Optuna histories) from the study artefacts.

Every function writes one PNG (matplotlib, Agg) and returns its path. The inputs are the tables
written by :mod:`graspstab.learning.studies`, :mod:`~graspstab.learning.train_model` and
:mod:`~graspstab.learning.tune_model`. Metrics may be NaN (undefined, e.g. validation AUPRC when
the validation split holds no unstable window): such a value is never drawn as a zero-height bar
but marked "undefined", and a panel without any data says so. :func:`plot_learning` writes them
all into one folder.
"""

from __future__ import annotations

import logging
import math
import re
from collections.abc import Callable, Iterable, Mapping, Sequence
from pathlib import Path
from typing import Any

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
import polars as pl  # noqa: E402
from matplotlib.colors import to_rgba  # noqa: E402
from matplotlib.lines import Line2D  # noqa: E402
from matplotlib.patches import Patch  # noqa: E402
from matplotlib.ticker import MaxNLocator  # noqa: E402
from matplotlib.transforms import blended_transform_factory  # noqa: E402

from graspstab.common.io import read_json  # noqa: E402
from graspstab.learning.aggregate import mean_std  # noqa: E402
from graspstab.learning.metrics import (  # noqa: E402
    reliability_curve,
    threshold_curves,
    threshold_grid,
)

log = logging.getLogger("graspstab.learning")

FAMILY_ORDER = ("cnn", "gru", "lstm")
FAMILY_COLOURS = {"cnn": "#1f77b4", "gru": "#ff7f0e", "lstm": "#2ca02c"}
FAMILY_LABELS = {"cnn": "CNN", "gru": "GRU", "lstm": "LSTM"}
METRIC_LABELS = {
    "accuracy": "Accuracy",
    "precision": "Precision",
    "recall": "Recall",
    "f1": "F$_1$",
    "auroc": "AUROC",
    "auprc": "AUPRC",
}
THRESHOLD_METRICS = ("accuracy", "precision", "recall", "f1")
RANKING_METRICS = ("auroc", "auprc")
UNDEFINED = "undefined"
PCT_LABEL = "score [%], mean ± std over seeds"
SPLIT_NAMES = {"val": "validation", "test": "test"}

#: Output file names of :func:`plot_learning` (name -> file), in thesis order.
FIGURES = {
    name: f"{name}.png"
    for name in (
        "benchmark",
        "confusion",
        "objects",
        "splits",
        "sweep",
        "latency",
        "operating_points",
        "threshold_transfer",
        "reliability",
        "proxy",
        "tuning",
    )
}

Stat = tuple[float, float]  # (mean, std) as fractions or raw values


# ---------------------------------------------------------------------------- small helpers


def finite(value: Any) -> bool:
    """True for a real, finite number (None and NaN are undefined)."""
    try:
        return value is not None and math.isfinite(float(value))
    except (TypeError, ValueError):
        return False


def _num(value: Any) -> float:
    return float(value) if finite(value) else float("nan")


def colour(family: str) -> str:
    return FAMILY_COLOURS.get(family, "0.5")


def family_label(family: str) -> str:
    return FAMILY_LABELS.get(family, str(family).upper())


def ordered_families(names: Iterable[str]) -> list[str]:
    """The thesis order (CNN, GRU, LSTM), then any other family alphabetically."""
    present = set(names)
    return [f for f in FAMILY_ORDER if f in present] + sorted(present - set(FAMILY_ORDER))


def object_label(obj: str) -> str:
    """'077_rubiks_cube' -> 'rubiks cube'."""
    return re.sub(r"^\d+_", "", str(obj)).replace("_", " ")


def _rows_by(frame: pl.DataFrame, keys: Sequence[str]) -> dict[tuple, dict[str, Any]]:
    return {tuple(r[k] for k in keys): r for r in frame.iter_rows(named=True)}


def _stat(row: Mapping[str, Any] | None, metric: str) -> Stat:
    if row is None:
        return float("nan"), float("nan")
    return _num(row.get(f"{metric}_mean")), _num(row.get(f"{metric}_std"))


def undefined_as_nan(frame: pl.DataFrame) -> pl.DataFrame:
    """Precision, recall and F1 as NaN where scikit-learn's zero_division=0 stored 0 for 0/0:
    recall with no unstable window, precision with none predicted unstable, F1 with neither.
    ``frame`` needs tp, fp, fn and the three metrics (runs or objects table)."""
    pos = pl.col("tp") + pl.col("fn")
    pred = pl.col("tp") + pl.col("fp")
    nan = pl.lit(float("nan"))
    return frame.with_columns(
        pl.when(pos == 0).then(nan).otherwise(pl.col("recall")).alias("recall"),
        pl.when(pred == 0).then(nan).otherwise(pl.col("precision")).alias("precision"),
        pl.when(pos + pred == 0).then(nan).otherwise(pl.col("f1")).alias("f1"),
    )


def defined_summary(runs: pl.DataFrame, by: Sequence[str]) -> pl.DataFrame:
    """Mean ± std over seeds (as the studies' summary.parquet) with 0/0 metrics undefined."""
    return mean_std(undefined_as_nan(runs), by)


def _save(fig: plt.Figure, path: Path, dpi: int) -> Path:
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=dpi, bbox_inches="tight")
    plt.close(fig)
    return path


def no_data(ax: plt.Axes, text: str = "no data") -> None:
    """Say in the panel that there is nothing to draw."""
    ax.text(
        0.5,
        0.5,
        text,
        ha="center",
        va="center",
        transform=ax.transAxes,
        color="0.3",
        fontsize=10,
        wrap=True,
    )


def placeholder(path: Path, title: str, message: str, dpi: int) -> Path:
    """A figure that only states why it could not be drawn (a missing study artefact)."""
    fig, ax = plt.subplots(figsize=(7, 2.2))
    ax.set_axis_off()
    no_data(ax, message)
    fig.suptitle(title)
    return _save(fig, path, dpi)


def _seed_note(frame: pl.DataFrame) -> str:
    if "seeds" not in frame.columns or frame.is_empty():
        return ""
    seeds = sorted({int(s) for s in frame["seeds"].drop_nulls()})
    return f" ({'/'.join(map(str, seeds))} seeds)" if seeds else ""


def _family_legend(fig_or_ax: Any, families: Sequence[str], **kwargs: Any) -> None:
    handles = [Patch(color=colour(f), label=family_label(f)) for f in families]
    fig_or_ax.legend(handles=handles, **kwargs)


def _legend_and_title(fig: plt.Figure, families: Sequence[str], title: str) -> None:
    """A family legend centred under a left-aligned figure title (the multi-panel figures)."""
    _family_legend(fig, families, loc="upper center", bbox_to_anchor=(0.5, 0.955),
                   ncol=len(families), frameon=False)  # fmt: skip
    fig.suptitle(title, x=0.02, ha="left")


# ------------------------------------------------------------------------------------ bars


def _draw_bars(
    ax: plt.Axes,
    positions: Sequence[float],
    stats: Sequence[Stat],
    colours: Sequence[Any],
    width: float,
    scale: float,
    **bar_kw: Any,
) -> tuple[list[float], list[float], list[tuple[float, str]]]:
    """Bars with ±std error bars for defined means; returns the low and high ends of the drawn
    bars (mean ∓ std) and markers (position, text) for undefined and zero-height bars, which
    would otherwise be invisible."""
    lows, highs, marks = [], [], []
    for p, (mean, std), c in zip(positions, stats, colours, strict=True):
        if not finite(mean):
            marks.append((p, UNDEFINED))
            continue
        if mean == 0:
            marks.append((p, "0"))
        err = std * scale if finite(std) else None
        ax.bar(
            p,
            mean * scale,
            width,
            color=c,
            yerr=err,
            capsize=2.5,
            error_kw={"ecolor": "0.15", "lw": 0.9},
            **bar_kw,
        )
        lows.append(mean * scale - (err or 0.0))
        highs.append(mean * scale + (err or 0.0))
    return lows, highs, marks


def _finish_bars(
    ax: plt.Axes,
    lows: list[float],
    highs: list[float],
    marks: list[tuple[float, str]],
    zoom: bool,
    positions: Sequence[float] = (),
) -> None:
    """Y limits (zoomed to the drawn values when ``zoom``; the axis label states the range) and
    the markers of :func:`_draw_bars` ('undefined', '0') at their bars' positions."""
    if len(positions):
        ax.set_xlim(min(positions) - 0.5, max(positions) + 0.5)
    if highs:
        top = max(highs)
        bottom = 0.0
        if zoom:
            bottom = max(0.0, 5.0 * math.floor((min(lows) - 3.0) / 5.0))
        if top <= bottom:  # every bar is 0: show a readable range, not a degenerate one
            top = bottom + (100.0 if zoom else 1.0)
        ax.set_ylim(bottom, top + 0.1 * (top - bottom))
    elif not marks:
        no_data(ax)
        return
    else:
        ax.set_ylim(0, 100)
        no_data(ax, "all values undefined")
    lo, hi = ax.get_ylim()
    for p, text in marks:
        ax.text(
            p,
            lo + 0.03 * (hi - lo),
            text,
            rotation=90,
            ha="center",
            va="bottom",
            fontsize=7,
            color="0.25",
            style="italic",
        )


def grouped_bars(
    ax: plt.Axes,
    groups: Sequence[str],
    values: Mapping[str, Sequence[Stat]],
    scale: float = 100.0,
    zoom: bool = True,
    annotate: bool = False,
) -> None:
    """One bar per (group, family), mean ± std; NaN means get an 'undefined' marker, no bar."""
    families = list(values)
    if not families or not groups:
        no_data(ax)
        return
    width = 0.8 / len(families)
    x = np.arange(len(groups), dtype=float)
    lows, highs, undefined, positions = [], [], [], []
    for i, fam in enumerate(families):
        pos = x - 0.4 + width * (i + 0.5)
        lo, hi, und = _draw_bars(ax, pos, values[fam], [colour(fam)] * len(pos), width, scale)
        lows += lo
        highs += hi
        undefined += und
        positions += list(pos)
        if annotate:
            _annotate(ax, pos, values[fam], scale)
    _finish_bars(ax, lows, highs, undefined, zoom, positions)
    ax.set_xticks(x, groups)
    ax.grid(axis="y", alpha=0.3)
    ax.set_axisbelow(True)


def _annotate(
    ax: plt.Axes,
    positions: Sequence[float],
    stats: Sequence[Stat],
    scale: float,
    fmt: str = "{:.2f}",
) -> None:
    """The mean above each defined bar (above its error bar, if any)."""
    for p, (mean, std) in zip(positions, stats, strict=True):
        if finite(mean):
            top = mean * scale + (std * scale if finite(std) else 0.0)
            ax.annotate(
                fmt.format(mean * scale),
                (p, top),
                xytext=(0, 3),
                textcoords="offset points",
                ha="center",
                va="bottom",
                fontsize=7,
            )


# ------------------------------------------------------------------------------ the figures


def plot_benchmark(summary: pl.DataFrame, out: Path, dpi: int) -> Path:
    """Fig. 4.1: validation/test threshold metrics (A, B) and ranking metrics (C, D) per family."""
    rows = _rows_by(summary, ["family", "split"])
    families = ordered_families(summary["family"].to_list())
    fig, axes = plt.subplots(2, 2, figsize=(11, 7.5), gridspec_kw={"width_ratios": [2, 1.2]})
    panels = [
        ("A", "val", THRESHOLD_METRICS, "validation, at the validation-selected threshold"),
        ("C", "val", RANKING_METRICS, "validation ranking metrics"),
        ("B", "test", THRESHOLD_METRICS, "test (unseen objects), same threshold"),
        ("D", "test", RANKING_METRICS, "test ranking metrics"),
    ]
    for ax, (letter, split, metrics, title) in zip(axes.flat, panels, strict=True):
        values = {f: [_stat(rows.get((f, split)), m) for m in metrics] for f in families}
        grouped_bars(ax, [METRIC_LABELS[m] for m in metrics], values)
        ax.set_title(f"4.1{letter}  {title}", loc="left", fontsize=10)
        ax.set_ylabel(PCT_LABEL)
    _legend_and_title(
        fig,
        families,
        "Figure 4.1: fixed-task benchmark at the baseline observation window"
        f"{_seed_note(summary)}, bars = mean, error bars = ±1 std",
    )
    fig.tight_layout(rect=(0, 0, 1, 0.92))
    return _save(fig, out, dpi)


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
    rows = _rows_by(test.filter(pl.col("seed") == seed), ["family"]) if seed is not None else {}
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
    return _save(fig, out, dpi)


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
    rows = _rows_by(stats, ["family", "object"])
    families = ordered_families(stats["family"].to_list())
    objs = sorted(stats["object"].unique().to_list())
    fig, axes = plt.subplots(1, 2, figsize=(10, 4.2))
    for ax, letter, metric in zip(axes, "AB", ("auprc", "recall"), strict=True):
        values = {f: [_stat(rows.get((f, o)), metric) for o in objs] for f in families}
        grouped_bars(ax, [object_label(o) for o in objs], values)
        what = "AUPRC" if metric == "auprc" else "recall at the validation-selected threshold"
        ax.set_title(f"4.3{letter}  test {what}", loc="left", fontsize=10)
        ax.set_ylabel(PCT_LABEL)
        ax.set_xlabel("unseen test object")
    _legend_and_title(fig, families, f"Figure 4.3: per-object test metrics{_seed_note(stats)}")
    fig.tight_layout(rect=(0, 0, 1, 0.9))
    return _save(fig, out, dpi)


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
        stats = [(_num(r.get("auprc")), _num(r.get("auprc_std"))) for r in per]
        colours = [c if int(r["assignment"]) == 0 else to_rgba(c, 0.45) for r in per]
        lows, highs, undefined = _draw_bars(ax, x, stats, colours, 0.75, 100.0, edgecolor="none")
        mean = _num(summary.get("mean"))
        if finite(mean):
            ax.axhline(mean * 100, ls="--", color="0.2", lw=1.2)
            lows.append(mean * 100)
        _finish_bars(ax, lows, highs, undefined, zoom=True, positions=x)
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
    return _save(fig, out, dpi)


def plot_sweep(summary: pl.DataFrame, out: Path, dpi: int) -> Path:
    """Fig. 4.5: test metrics vs observation-window length (A-F), mean ± std per family."""
    test = summary.filter(pl.col("split") == "test")
    rows = _rows_by(test, ["family", "window_s"])
    families = ordered_families(test["family"].to_list())
    windows = sorted(test["window_s"].unique().to_list())
    groups = [f"{w * 1000:g}" for w in windows]
    fig, axes = plt.subplots(2, 3, figsize=(15, 7.5))
    metrics = (*THRESHOLD_METRICS, *RANKING_METRICS)
    for k, (ax, metric) in enumerate(zip(axes.flat, metrics, strict=True)):
        values = {f: [_stat(rows.get((f, w)), metric) for w in windows] for f in families}
        grouped_bars(ax, groups, values)
        ax.set_title(f"4.5{'ABCDEF'[k]}  test {METRIC_LABELS[metric]}", loc="left", fontsize=10)
        ax.set_xlabel("observation window [ms]")
        ax.set_ylabel(PCT_LABEL)
    _legend_and_title(
        fig,
        families,
        f"Figure 4.5: test metrics across observation-window length{_seed_note(test)}; "
        "offset and horizon fixed",
    )
    fig.tight_layout(rect=(0, 0, 1, 0.95))
    return _save(fig, out, dpi)


def plot_latency(latency: pl.DataFrame, out: Path, dpi: int) -> Path:
    """Fig. 4.6: CPU batch-1 forward-pass latency (median ± std, A) and throughput (B) per family
    at the baseline window."""
    base = latency.filter(pl.col("study") == "baseline")
    rows = _rows_by(base, ["family"])
    families = ordered_families(base["family"].to_list())
    fig, axes = plt.subplots(1, 2, figsize=(9, 3.8))
    x = np.arange(len(families), dtype=float)
    specs = [
        ("A", "median forward-pass latency [ms] (± std)", "median_ms", "std_ms", "{:.3f}"),
        ("B", "throughput [windows/s]", "throughput_per_s", None, "{:.0f}"),
    ]
    for ax, (letter, ylabel, key, err, fmt) in zip(axes, specs, strict=True):
        stats = [
            (_num(rows[(f,)][key]), _num(rows[(f,)][err]) if err else float("nan"))
            for f in families
        ]
        lows, highs, undefined = _draw_bars(ax, x, stats, [colour(f) for f in families], 0.6, 1.0)
        _annotate(ax, x, stats, 1.0, fmt)
        _finish_bars(ax, lows, highs, undefined, zoom=False, positions=x)
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
    return _save(fig, out, dpi)


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
    x, y = _num(pick.get("total_latency_ms")), _num(pick.get("val_auprc_mean")) * 100
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
    e = np.array([_num(r["val_auprc_std"]) for r in rows]) * 100
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
    return _save(fig, out, dpi)


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
        t, rule = _num(thr.get("threshold")), thr.get("rule", "?")
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
    return _save(fig, out, dpi)


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
    return _save(fig, out, dpi)


def plot_proxy(proxy: Mapping[str, Any], summary: pl.DataFrame, out: Path, dpi: int) -> Path:
    """Fig. 4.10: test AUPRC of the friction-ratio proxy beside the models' mean test AUPRC; the
    dashed line is chance level (the test set's unstable fraction)."""
    rows = _rows_by(summary.filter(pl.col("split") == "test"), ["family"])
    families = ordered_families(f for (f,) in rows)
    labels = ["friction-ratio\nproxy", *[family_label(f) for f in families]]
    stats = [(_num(proxy.get("test", {}).get("auprc")), float("nan"))]
    stats += [_stat(rows[(f,)], "auprc") for f in families]
    colours = ["0.55", *[colour(f) for f in families]]
    fig, ax = plt.subplots(figsize=(6.5, 4.3))
    x = np.arange(len(labels), dtype=float)
    lows, highs, undefined = _draw_bars(ax, x, stats, colours, 0.6, 100.0)
    _annotate(ax, x, stats, 100.0)
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
    _finish_bars(ax, lows, highs, undefined, zoom=False, positions=x)
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
    return _save(fig, out, dpi)


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
    return _save(fig, out, dpi)


# -------------------------------------------------------------------------------- the entry


def _read(path: Path, reader: Callable[[Path], Any]) -> Any:
    if not Path(path).exists():
        log.warning("learning figures: %s is missing", path)
        return None
    return reader(path)


def load_predictions(results: Path, first_seed: int) -> dict[str, tuple[pl.DataFrame, dict]]:
    """family -> (predictions, threshold record) of the baseline runs of ``first_seed``."""
    out = {}
    base = Path(results) / "train" / "baseline"
    for fam in ordered_families(p.name for p in base.iterdir()) if base.is_dir() else []:
        run = base / fam / f"seed{first_seed}"
        if (run / "predictions.parquet").exists() and (run / "metrics.json").exists():
            thr = read_json(run / "metrics.json").get("threshold", {})
            out[fam] = (pl.read_parquet(run / "predictions.parquet"), thr)
    return out


def load_tuning(results: Path) -> dict[str, tuple[pl.DataFrame, dict | None]]:
    """family -> (trials table, best.json or None) of every tuned family."""
    out = {}
    base = Path(results) / "tune"
    for fam in ordered_families(p.name for p in base.iterdir()) if base.is_dir() else []:
        trials = base / fam / "trials.parquet"
        if trials.exists():
            out[fam] = (pl.read_parquet(trials), _read(base / fam / "best.json", read_json))
    return out


def _study_inputs(results: Path, first_seed: int) -> dict[str, Any]:
    s = Path(results) / "studies"
    pq = pl.read_parquet
    splits_runs = _read(s / "splits" / "runs.parquet", pq)
    return {
        "summary": _read(s / "baseline" / "summary.parquet", pq),
        "runs": _read(s / "baseline" / "runs.parquet", pq),
        "objects": _read(s / "baseline" / "objects.parquet", pq),
        "splits": _read(s / "splits" / "summary.json", read_json),
        "splits_family": (
            splits_runs["family"][0] if splits_runs is not None and splits_runs.height else None
        ),
        "sweep": _read(s / "sweep" / "summary.parquet", pq),
        "sweep_runs": _read(s / "sweep" / "runs.parquet", pq),
        "points": _read(s / "sweep" / "operating_points.parquet", pq),
        "sweep_json": _read(s / "sweep" / "summary.json", read_json),
        "latency": _read(s / "latency.parquet", pq),
        "proxy": _read(s / "proxy.json", read_json),
        "predictions": load_predictions(results, first_seed) or None,
        "tuning": load_tuning(results) or None,
    }


def plot_learning(results_dir: Path, out_dir: Path, dpi: int, first_seed: int) -> dict[str, Path]:
    """Write every chapter-4 figure into ``out_dir`` (file names :data:`FIGURES`); a figure whose
    inputs are missing becomes a placeholder that says which. Returns name -> path."""
    d = _study_inputs(Path(results_dir), int(first_seed))
    if d["runs"] is not None:
        d["summary_defined"] = defined_summary(d["runs"], ["family", "split"])
    else:
        d["summary_defined"] = d["summary"]
    if d["sweep_runs"] is not None:
        d["sweep"] = defined_summary(d["sweep_runs"], ["family", "window_s", "split"])
    out = {name: Path(out_dir) / file for name, file in FIGURES.items()}
    jobs: dict[str, tuple[tuple[str, ...], Callable[[], Path]]] = {
        "benchmark": (
            ("summary_defined",),
            lambda: plot_benchmark(d["summary_defined"], out["benchmark"], dpi),
        ),
        "confusion": (
            ("runs",),
            lambda: plot_confusion(d["runs"], first_seed, out["confusion"], dpi),
        ),
        "objects": (("objects",), lambda: plot_objects(d["objects"], out["objects"], dpi)),
        "splits": (
            ("splits",),
            lambda: plot_splits(d["splits"], d["splits_family"], out["splits"], dpi),
        ),
        "sweep": (("sweep",), lambda: plot_sweep(d["sweep"], out["sweep"], dpi)),
        "latency": (("latency",), lambda: plot_latency(d["latency"], out["latency"], dpi)),
        "operating_points": (
            ("points", "sweep_json"),
            lambda: plot_operating_points(
                d["points"], d["sweep_json"], out["operating_points"], dpi
            ),
        ),
        "threshold_transfer": (
            ("predictions",),
            lambda: plot_threshold_transfer(d["predictions"], out["threshold_transfer"], dpi),
        ),
        "reliability": (
            ("predictions",),
            lambda: plot_reliability(d["predictions"], out["reliability"], dpi),
        ),
        "proxy": (
            ("proxy", "summary"),
            lambda: plot_proxy(d["proxy"], d["summary"], out["proxy"], dpi),
        ),
        "tuning": (("tuning",), lambda: plot_tuning(d["tuning"], out["tuning"], dpi)),
    }
    for name, (needs, draw) in jobs.items():
        missing = [k for k in needs if d[k] is None]
        if missing:
            placeholder(
                out[name],
                f"{name}: not drawn",
                f"missing study artefact(s): {', '.join(missing)}",
                dpi,
            )
        else:
            draw()
        log.info("wrote %s", out[name])
    return out
