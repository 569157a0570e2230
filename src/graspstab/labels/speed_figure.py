"""The speeds behind the labels: a histogram of target-interval object speed per class, with the
instability threshold (eq. 23) and the contact model's creep, so a reader sees what "unstable"
means under the model in use (written beside its JSON summary)."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from graspstab.common.io import read_parquet, write_json
from graspstab.common.plotting import plt, save
from graspstab.labels.speeds import summarise_speeds

FLOOR = 1e-6  # [m/s] speeds below 1 um/s are drawn in the first bin (log axis)


def plot_speeds(summary: dict[str, Any], speeds: dict[str, np.ndarray], out: str | Path) -> None:
    """Histogram (log speed) of the stable and unstable windows' target-interval speeds."""
    fig, ax = plt.subplots(figsize=(7.5, 3.6))
    finite = [np.maximum(v[np.isfinite(v)], FLOOR) for v in speeds.values()]
    top = max([float(v.max()) for v in finite if len(v)] + [1.0])
    bins = np.logspace(np.log10(FLOOR), np.log10(top * 1.5), 50)
    for (name, v), colour in zip(speeds.items(), ("tab:green", "tab:red"), strict=True):
        v = np.maximum(v[np.isfinite(v)], FLOOR)
        ax.hist(v * 1e3, bins=bins * 1e3, color=colour, alpha=0.6, label=f"{name} ({len(v)})")
    ax.axvline(summary["v_slip"] * 1e3, color="k", ls="--", lw=1,
               label=f"v_slip {summary['v_slip'] * 1e3:g} mm/s (eq. 23)")  # fmt: skip
    box = summary["box_creep"]["speed"]
    ax.axvline(max(box, FLOOR) * 1e3, color="tab:blue", ls=":", lw=1.5,
               label=f"creep of a held box {box * 1e3:.3g} mm/s")  # fmt: skip
    held = summary["held_creep"]["q50"]
    if held is not None:
        ax.axvline(max(held, FLOOR) * 1e3, color="tab:purple", ls="-.", lw=1.2,
                   label=f"creep of held grasps (median) {held * 1e3:.3g} mm/s")  # fmt: skip
    ax.set_xscale("log")
    ax.set_xlabel("median object speed over the target interval [mm/s]")
    ax.set_ylabel("windows")
    ax.set_title(f"What the labels mean under the '{summary['contact_model']}' contact model")
    ax.legend(fontsize=7, loc="upper left")
    fig.tight_layout()
    save(fig, out, 110)


def plot_unstable_speeds(
    index_path: str | Path,
    replay_tables: list[str | Path],
    trace_files: list[str | Path],
    contact: dict[str, Any],
    labels: dict[str, Any],
    dt: float,
    out_json: str | Path,
    out_png: str | Path,
) -> dict[str, Any]:
    """Entry point of rule plot_unstable_speeds: the summary JSON and the histogram."""
    index = read_parquet(index_path)
    summary, speeds = summarise_speeds(
        index, [Path(p) for p in replay_tables], [Path(p) for p in trace_files], contact,
        labels, float(labels["window_s"]), dt,
    )  # fmt: skip
    plot_speeds(summary, speeds, out_png)
    write_json(out_json, summary)
    return summary
