"""The replay trace figure (cf. thesis fig. 3.7): motion, contact distance and fingertip forces.

Panels: (A) object position, (B) displacement from the start, (C) velocity, (D) speed, (E) the
time derivative of speed, (F) d_t, (G) fingertip normal and (H) shear forces (eq. 18). The
stable/unstable shading is the labelling stage's (``graspstab.labels.figure``), drawn through
``decorate``: this stage knows nothing of labels.
"""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np
import polars as pl

from graspstab.common.io import read_parquet
from graspstab.common.plotting import plt, save
from graspstab.hand.names import FINGERS
from graspstab.replay.traces import CHANNELS, read_traces


def pick_example(summary: pl.DataFrame) -> int:
    """A replay worth showing: the longest one that ends in contact loss (it held, then failed),
    else the longest one."""
    lost = summary.filter(pl.col("stop_reason") == "contact_lost")
    pool = lost if lost.height and lost["steps"].max() > 2000 else summary
    return int(pool.sort(["steps", "grasp_id"], descending=[True, False])["grasp_id"][0])


def plot_replay_trace(
    traces: dict[str, np.ndarray],
    dt: float,
    out_path: str | Path,
    title: str,
    decorate: Callable[[list[Any], np.ndarray], None] | None = None,
) -> None:
    """Eight stacked panels over time (seconds); units in the axis labels. The free fall after
    the last hand-object contact is cut at 0.1 s past it (it would set every motion axis).
    ``decorate(axes, t)`` draws on top (the labelling stage's shading)."""
    defined = np.flatnonzero(np.isfinite(traces["min_distance"]))
    if len(defined):
        end = min(len(traces["min_distance"]), int(defined[-1]) + 1 + round(0.1 / dt))
        traces = {k: v[:end] for k, v in traces.items()}
    t = np.arange(len(traces["position"])) * dt
    pos = traces["position"].astype(np.float64) * 1000
    vel = traces["velocity"].astype(np.float64) * 1000
    speed = np.linalg.norm(vel, axis=1)
    fig, axes = plt.subplots(8, 1, figsize=(8, 13), sharex=True)
    panels = [
        ("A  position [mm]", [(pos[:, k], a) for k, a in enumerate("xyz")]),
        ("B  displacement [mm]", [(np.linalg.norm(pos - pos[0], axis=1), "|p - p0|")]),
        ("C  velocity [mm/s]", [(vel[:, k], a) for k, a in enumerate("xyz")]),
        ("D  speed [mm/s]", [(speed, "|v|")]),
        ("E  d|v|/dt [mm/s²]", [(np.gradient(speed, dt) if len(t) > 1 else speed, "")]),
        ("F  d_t [mm]", [(traces["min_distance"].astype(np.float64) * 1000, "d_t")]),
        ("G  normal force [N]", [(traces["normal"][:, k], f) for k, f in enumerate(FINGERS)]),
        ("H  shear force [N]", [(traces["shear"][:, k], f) for k, f in enumerate(FINGERS)]),
    ]
    for ax, (label, lines) in zip(axes, panels, strict=True):
        for y, name in lines:
            ax.plot(t, y, lw=0.8, label=name or None)
        ax.set_ylabel(label, fontsize=8)
        ax.tick_params(labelsize=7)
        if len(lines) > 1:
            ax.legend(fontsize=6, ncol=5, loc="upper right")
    axes[3].axhline(1.2, color="k", ls="--", lw=0.6)  # 3.3.2's instability threshold
    if decorate is not None:
        decorate(list(axes), t)
    axes[-1].set_xlabel("time [s]")
    fig.suptitle(title, fontsize=10)
    fig.tight_layout()
    save(fig, out_path, 110)


def example_traces(
    summary_path: str | Path, traces_path: str | Path, extra: tuple[str, ...] = ()
) -> tuple[str, int, dict[str, np.ndarray]]:
    """:func:`pick_example`'s replay of one shard: its object, grasp id and traces (the
    recorded channels and any ``extra`` ones)."""
    summary = read_parquet(summary_path)
    gid = pick_example(summary)
    channels = tuple(dict.fromkeys((*CHANNELS, *extra)))
    return summary["object"][0], gid, read_traces(traces_path, gid, channels)


def plot_replay_example(
    summary_path: str | Path, traces_path: str | Path, dt: float, out_path: str | Path
) -> int:
    """Draw :func:`pick_example`'s replay of one shard, unlabelled; returns its grasp id."""
    obj, gid, traces = example_traces(summary_path, traces_path)
    plot_replay_trace(traces, dt, out_path, f"{obj}, grasp {gid} (cf. thesis fig. 3.7)")
    return gid
