"""What the chapter-4 figures share on top of :mod:`graspstab.common.plotting` (the Agg backend,
the "no data" panel, the atomic PNG save, re-exported here): family colours, figures cropped to
their content, placeholder panels, and bars that mark an undefined (NaN) value instead of drawing
it.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np
import polars as pl
from matplotlib.patches import Patch

from graspstab.common import plotting
from graspstab.common.plotting import no_data, plt  # the figure modules import them from here
from graspstab.figures.presentation import UNDEFINED, as_float, family_label, finite

FAMILY_COLOURS = {"cnn": "#1f77b4", "gru": "#ff7f0e", "lstm": "#2ca02c"}
PCT_LABEL = "score [%], mean ± std over seeds"

Stat = tuple[float, float]  # (mean, std) as fractions or raw values


def colour(family: str) -> str:
    """The family's colour in every figure (grey for an unknown family)."""
    return FAMILY_COLOURS.get(family, "0.5")


def stat(row: Mapping[str, Any] | None, metric: str) -> Stat:
    """(mean, std) of ``metric`` in a summary row (NaN for a missing row or value)."""
    if row is None:
        return float("nan"), float("nan")
    return as_float(row.get(f"{metric}_mean")), as_float(row.get(f"{metric}_std"))


def save(fig: plt.Figure, path: Path, dpi: int) -> Path:
    """Write ``fig`` as a PNG cropped to its content, atomically, and close it."""
    plotting.save(fig, path, dpi, tight=True)
    return Path(path)


def placeholder(path: Path, title: str, message: str, dpi: int) -> Path:
    """A figure that only states why it could not be drawn (a missing study artefact)."""
    fig, ax = plt.subplots(figsize=(7, 2.2))
    no_data(ax, message, axis_off=True)
    fig.suptitle(title)
    return save(fig, path, dpi)


def seed_note(frame: pl.DataFrame) -> str:
    """' (2/3 seeds)': the seed counts behind a summary's means, for a figure title."""
    if "seeds" not in frame.columns or frame.is_empty():
        return ""
    seeds = sorted({int(s) for s in frame["seeds"].drop_nulls()})
    return f" ({'/'.join(map(str, seeds))} seeds)" if seeds else ""


def family_legend(fig_or_ax: Any, families: Sequence[str], **kwargs: Any) -> None:
    """A legend of one colour patch per family."""
    handles = [Patch(color=colour(f), label=family_label(f)) for f in families]
    fig_or_ax.legend(handles=handles, **kwargs)


def legend_and_title(fig: plt.Figure, families: Sequence[str], title: str) -> None:
    """A family legend centred under a left-aligned figure title (the multi-panel figures)."""
    family_legend(fig, families, loc="upper center", bbox_to_anchor=(0.5, 0.955),
                   ncol=len(families), frameon=False)  # fmt: skip
    fig.suptitle(title, x=0.02, ha="left")


# ------------------------------------------------------------------------------------ bars


def draw_bars(
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


def finish_bars(
    ax: plt.Axes,
    lows: list[float],
    highs: list[float],
    marks: list[tuple[float, str]],
    zoom: bool,
    positions: Sequence[float] = (),
) -> None:
    """Y limits (zoomed to the drawn values when ``zoom``; the axis label states the range) and
    the markers of :func:`draw_bars` ('undefined', '0') at their bars' positions."""
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
        lo, hi, und = draw_bars(ax, pos, values[fam], [colour(fam)] * len(pos), width, scale)
        lows += lo
        highs += hi
        undefined += und
        positions += list(pos)
        if annotate:
            annotate(ax, pos, values[fam], scale)
    finish_bars(ax, lows, highs, undefined, zoom, positions)
    ax.set_xticks(x, groups)
    ax.grid(axis="y", alpha=0.3)
    ax.set_axisbelow(True)


def annotate(
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
