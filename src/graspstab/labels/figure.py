"""The labelling stage's figures: the replay trace shaded by eq. 23's timestep labels (cf. thesis
fig. 3.7) and the window illustration (fig. 3.8: observation window, offset and horizon of one
sample drawn on its replay's fingertip forces)."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np
import polars as pl

from graspstab.common.io import read_parquet
from graspstab.common.plotting import no_data, plt, save
from graspstab.hand.names import FINGERS
from graspstab.labels.interval import usable_interval
from graspstab.labels.sources import source_channels, unstable_steps
from graspstab.labels.windows import step_counts
from graspstab.replay.figure import example_traces, plot_replay_trace
from graspstab.replay.traces import read_traces

DPI = 110


def shade_periods(axes: list[Any], t: np.ndarray, u: np.ndarray, start: int, end: int) -> None:
    """Shade rows [start, end) of every axis red where u_t = 1 and green where u_t = 0."""
    seg = np.asarray(u[start:end], dtype=np.int8)
    if len(seg) == 0:
        return
    edges = np.concatenate([[0], np.flatnonzero(np.diff(seg)) + 1, [len(seg)]])
    for a, b in zip(edges[:-1], edges[1:], strict=True):
        colour = "tab:red" if seg[a] else "tab:green"
        for ax in axes:
            ax.axvspan(t[start + a], t[start + b - 1], color=colour, alpha=0.15, lw=0)


def plot_labelled_replay(
    summary_path: str | Path, traces_path: str | Path, dt: float, labels: dict[str, Any],
    out_path: str | Path,
) -> int:  # fmt: skip
    """The replay trace figure of one shard's example grasp (graspstab.replay.figure), its
    usable interval shaded red where u_t = 1 and green where u_t = 0; returns its grasp id."""
    obj, gid, traces = example_traces(summary_path, traces_path, source_channels(labels))
    speed = np.linalg.norm(traces["velocity"].astype(np.float64), axis=1)
    ui = usable_interval(speed, traces["min_distance"].astype(np.float64), dt,
                         labels["settle"], labels["contact_loss_s"])  # fmt: skip
    u = unstable_steps(traces, labels, ui.settle_index)

    def shade(axes: list[Any], t: np.ndarray) -> None:
        shade_periods(axes, t, u, ui.settle_index, min(ui.contact_end, len(t)))

    plot_replay_trace(traces, dt, out_path, f"{obj}, grasp {gid} (cf. thesis fig. 3.7)", shade)
    return gid


def trace_files_by_shard(
    tables: list[str | Path], traces: list[str | Path]
) -> dict[tuple[str, int], Path]:
    """(object, shard) -> trace file, from the declared replay tables and their trace files
    (pairwise, in the same order), read from the tables' own rows rather than their paths."""
    out: dict[tuple[str, int], Path] = {}
    for table, trace in zip(tables, traces, strict=True):
        rows = read_parquet(table, columns=["object", "shard"]).unique()
        for obj, shard in rows.iter_rows():
            out[(obj, int(shard))] = Path(trace)
    return out


def pick_window(index: pl.DataFrame) -> dict[str, Any]:
    """A sample worth showing: a mixed future (0 < r < 1) if any, else an unstable one, else the
    first."""
    for cond in ((pl.col("r") > 0) & (pl.col("r") < 1), pl.col("label") == 1, pl.lit(True)):
        part = index.filter(cond)
        if part.height:
            return part.sort("sample_id").row(0, named=True)
    raise ValueError("the dataset has no windows to illustrate")


def plot_window(
    index_path: str | Path, tables: list[str | Path], traces: list[str | Path],
    labels: dict[str, Any], dt: float, out_path: str | Path,
) -> None:  # fmt: skip
    """Draw :func:`pick_window`'s sample of a dataset on its replay (full span and a zoom), read
    from the declared replay ``tables`` and ``traces``; an empty dataset gives a figure that says
    so."""
    index = read_parquet(index_path)
    if index.height == 0:
        fig, ax = plt.subplots(figsize=(6, 1.5))
        no_data(ax, "no labelled window in this run", color=None, fontsize=None, wrap=False,
                axis_off=True)  # fmt: skip
        save(fig, out_path, DPI)
        return
    sample = pick_window(index)
    w = sample["end"] - sample["start"]
    _, o, h = step_counts(labels["window_s"], labels["offset_s"], labels["horizon_s"], dt)
    gid, obj, shard = sample["grasp_id"], sample["object"], sample["shard"]
    files = trace_files_by_shard(tables, traces)
    if (obj, int(shard)) not in files:
        raise KeyError(f"{index_path}: window of {obj} shard {shard} has no declared trace file")
    wanted = dict.fromkeys(("velocity", "min_distance", "normal", "shear",
                            *source_channels(labels)))  # fmt: skip
    tr = read_traces(files[(obj, int(shard))], gid, tuple(wanted))
    speed = np.linalg.norm(tr["velocity"].astype(np.float64), axis=1)
    ui = usable_interval(speed, tr["min_distance"].astype(np.float64), dt, labels["settle"],
                         labels["contact_loss_s"])  # fmt: skip
    u = unstable_steps(tr, labels, ui.settle_index)
    t = np.arange(len(speed)) * dt
    s = sample["start"]
    marks = [s, s + w, s + w + o, min(s + w + o + h, ui.contact_end)]
    fig, axes = plt.subplots(2, 2, figsize=(11, 6), sharex="col")
    lo, hi = max(0, marks[0] - w), min(len(t), marks[3] + w)
    for col, (a, b) in enumerate(((ui.settle_index, ui.contact_end), (lo, hi))):
        for row, channel in enumerate(("normal", "shear")):
            ax = axes[row, col]
            for k, f in enumerate(FINGERS):
                ax.plot(t[a:b], tr[channel][a:b, k], lw=0.8, label=f)
            shade_periods([ax], t, u, a, b)
            for m in marks:
                ax.axvline(t[min(m, len(t) - 1)], color="k", ls="--", lw=0.7)
            ax.set_ylabel(f"{'ABCD'[2 * col + row]}  {channel} force [N]", fontsize=8)
            ax.tick_params(labelsize=7)
        axes[1, col].set_xlabel("time [s]")
    axes[0, 0].legend(fontsize=6, ncol=5)
    fig.suptitle(
        f"{obj}, grasp {gid}: window [{marks[0]}, {marks[1]}), offset {o}, horizon to {marks[3]}; "
        f"r = {sample['r']:.2%} unstable, label {sample['label']} (cf. thesis fig. 3.8)",
        fontsize=9,
    )
    fig.tight_layout()
    save(fig, out_path, DPI)
