"""The grasp-level figures: how early warnings come (lead times), and one replay as a controller
would see it (forces in, probability and warning out, the failure onset from eq. 23's labels)."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np
import polars as pl

from graspstab.common.io import load_npz, read_json, read_parquet
from graspstab.common.plotting import no_data, plt, save
from graspstab.hand.names import FINGERS
from graspstab.monitor.proxy import PROXY

COLOURS = {"cnn": "tab:blue", "gru": "tab:orange", "lstm": "tab:green", PROXY: "tab:gray"}
FLOOR = 1e-6  # [m/s] speeds below 1 um/s are drawn at the floor (log axis)


def plot_lead_times(frame: pl.DataFrame, summary: dict[str, Any], out: str | Path,
                    split: str = "test", dpi: int = 110) -> None:  # fmt: skip
    """Histogram of lead times (onset - first warning) of each monitor's failing grasps in
    ``split``, with the offset that counts a warning as in time."""
    offset = summary["settings"]["offset_s"]
    rows = frame.filter((pl.col("split") == split) & pl.col("lead_time_s").is_not_null())
    fig, ax = plt.subplots(figsize=(7.5, 3.6))
    leads = rows["lead_time_s"].to_numpy()
    top = max(float(leads.max()) if len(leads) else 0.0, 2 * offset)
    bins = np.linspace(0.0, top * 1.02, 31)
    for name, info in summary["monitors"].items():
        mine = rows.filter(pl.col("monitor") == name)["lead_time_s"].to_numpy()
        s = info["splits"][split]
        label = (f"{name}: {s['warned_in_time']} of {s['failing_grasps']} failing grasps "
                 f"warned >= {offset:g} s ahead")  # fmt: skip
        ax.hist(mine, bins=bins, histtype="step", lw=1.8, color=COLOURS.get(name), label=label)
    ax.axvline(offset, color="k", ls="--", lw=1, label=f"offset {offset:g} s (3.3.3)")
    ax.set_xlabel("lead time: failure onset - first warning [s]")
    ax.set_ylabel("failing grasps")
    ax.set_title(f"How early the monitors warn ({split} replays, grasps warned before onset)")
    ax.legend(fontsize=7, loc="upper right")
    fig.tight_layout()
    save(fig, out, dpi)


def plot_timeline(arrays: dict[str, np.ndarray], summary: dict[str, Any], out: str | Path,
                  dpi: int = 110) -> None:  # fmt: skip
    """One replay: fingertip forces, object speed against eq. 23's threshold, and the monitors'
    probabilities against their thresholds, with warnings shaded and the onset marked."""
    info = summary["timeline"]
    fig, axes = plt.subplots(3, 1, figsize=(8.0, 7.0), sharex=True)
    if info.get("object") is None or not len(arrays.get("t", [])):
        for ax in axes[1:]:
            ax.set_axis_off()
        no_data(axes[0], "no validation or test replay to draw", color=None, fontsize=None,
                va="baseline", wrap=False, axis_off=True)  # fmt: skip
        save(fig, out, dpi)
        return
    t, forces = arrays["t"], arrays["forces"]
    lo, start, end, onset = (int(v) for v in arrays["frames"])
    dt = summary["settings"]["dt"]
    for f, finger in enumerate(FINGERS):
        colour = f"C{f}"
        axes[0].plot(t, forces[:, f, 0], color=colour, lw=1, label=f"{finger} normal")
        axes[0].plot(t, forces[:, f, 1], color=colour, lw=1, ls="--")
    axes[0].set_ylabel("force [N]\n(solid normal, dashed shear)")
    axes[0].legend(fontsize=6, ncol=5, loc="upper left")
    axes[1].semilogy(t, np.maximum(arrays["speed"], FLOOR) * 1e3, color="k", lw=0.8)
    v_slip = summary["settings"]["v_slip"] * 1e3
    axes[1].axhline(v_slip, color="tab:red", ls="--", lw=1,
                    label=f"v_slip {v_slip:g} mm/s (eq. 23)")  # fmt: skip
    axes[1].set_ylabel("object speed [mm/s]")
    axes[1].legend(fontsize=7, loc="upper left")
    focus = info["monitor"]
    for name in (focus, PROXY) if focus != PROXY else (PROXY,):
        if f"prob_{name}" not in arrays:
            continue
        prob, warn = arrays[f"prob_{name}"], arrays[f"warning_{name}"]
        thr = float(arrays[f"threshold_{name}"])
        ok = np.isfinite(prob)
        colour = COLOURS.get(name, "tab:purple")
        axes[2].plot(t[ok], prob[ok], color=colour, lw=1, label=f"{name} score")
        axes[2].axhline(thr, color=colour, ls=":", lw=1, label=f"{name} threshold {thr:.3f}")
        axes[2].fill_between(t, 0, 1, where=warn, color=colour, alpha=0.12, step="post",
                             transform=axes[2].get_xaxis_transform())  # fmt: skip
    axes[2].set_ylim(-0.02, 1.02)
    axes[2].set_ylabel("score (shaded: warning)")
    axes[2].set_xlabel("time [s]")
    axes[2].legend(fontsize=7, loc="upper left")
    for ax in axes:
        ax.axvspan(t[0], start * dt, color="0.85", alpha=0.5, lw=0)  # before the settle index
        if onset >= 0:
            ax.axvline(onset * dt, color="tab:red", lw=1.5)
    lead = info.get("lead_time_s")
    if onset < 0:
        what = "no onset"
    elif lead is None:
        what = f"onset at {onset * dt:.2f} s, no warning before it"
    else:
        what = f"onset at {onset * dt:.2f} s, {focus}'s first warning {lead:.2f} s ahead"
    axes[0].set_title(f"{info['object']} grasp {info['grasp_id']} ({info['split']}): {what}; "
                      f"grey: before settling", fontsize=9)  # fmt: skip
    axes[2].set_xlim(t[0], max(t[-1], lo * dt + dt))
    fig.tight_layout()
    save(fig, out, dpi)


def plot_monitor(
    episodes: str | Path, summary_json: str | Path, timeline: str | Path,
    out_leads: str | Path, out_timeline: str | Path, dpi: int = 110,
) -> None:  # fmt: skip
    """Entry point of rule plot_monitor: both figures from evaluate_monitor's outputs."""
    summary = read_json(summary_json)
    plot_lead_times(read_parquet(episodes), summary, out_leads, dpi=dpi)
    plot_timeline(load_npz(timeline), summary, out_timeline, dpi=dpi)
