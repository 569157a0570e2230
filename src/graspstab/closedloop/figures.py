"""The closed loop's figures: the reflex's trade-off (drops prevented against false alarms and
against added grip force, one point per swept setting) and one grasp's timeline with and without
the reflex."""

from __future__ import annotations

import json
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np
import polars as pl

from graspstab.common.io import load_npz, read_parquet
from graspstab.common.plotting import no_data, plt, save

PROTOCOLS = {"reference": "reference protocol", "creep_free": "creep-free load ramp"}
BOUNDS = {"always": ("k", "s"), "oracle": ("tab:green", "*"), "oracle-0ms": ("tab:green", "*"),
          "oracle-150ms": ("tab:olive", "*"),
          "load_onset": ("tab:purple", "D")}  # colour and marker  # fmt: skip
FLOOR = 1e-4  # [mm/s] speeds below this are drawn at it (log axis)


def _errors(frame: pl.DataFrame, key: str) -> np.ndarray:
    v, lo, hi = (frame[c].to_numpy().astype(float) for c in (key, f"{key}_lo", f"{key}_hi"))
    return np.nan_to_num(np.vstack([v - lo, hi - v]) * 100, nan=0.0)


def _nothing_to_draw(axes: Sequence[Any], text: str) -> None:
    """Every panel hidden, ``text`` in the first (a run without a sweep or a closed loop)."""
    for ax in axes[1:]:
        ax.set_axis_off()
    no_data(axes[0], text, color=None, fontsize=None, va="baseline", wrap=False, axis_off=True)


def plot_tradeoff(tradeoff: pl.DataFrame, policies: pl.DataFrame, protocol: str, out: str | Path,
                  dpi: int = 110) -> None:  # fmt: skip
    """Drops prevented (share of the no-reflex drops) against the false-alarm rate and against the
    mean added normal force, for every swept setting of every swept policy, with the bounds
    (``always``, ``oracle``) for scale; bars are the bootstrap intervals."""
    fig, axes = plt.subplots(1, 2, figsize=(10.0, 4.4), sharey=True)
    name = PROTOCOLS.get(protocol, protocol)
    if tradeoff.is_empty():
        _nothing_to_draw(axes, "no sweep in this run (closed_loop.sweep)")
        save(fig, out, dpi)
        return
    panels = (("false_alarm_rate", 100.0, "false alarms [% of grasps that hold]"),
              ("added_normal_mean_n", 1.0, "added normal force, mean [N]"))  # fmt: skip
    bases = list(dict.fromkeys(tradeoff["base"].to_list()))
    for ax, (key, scale, label) in zip(axes, panels, strict=True):
        for i, base in enumerate(bases):
            part = tradeoff.filter(pl.col("base") == base)
            x = part[key].to_numpy().astype(float) * scale
            y = part["prevented_share"].to_numpy().astype(float) * 100
            err = _errors(part, key) * (scale / 100.0)
            ax.errorbar(x, y, xerr=err, yerr=_errors(part, "prevented_share"), fmt="o",
                        color=f"C{i}", ms=5, lw=0.8, capsize=2, label=base)  # fmt: skip
            for xi, yi, p, v in zip(x, y, part["parameter"], part["value"], strict=True):
                text = "default" if p == "default" else f"{p}={v:g}"
                if np.isfinite(xi) and np.isfinite(yi):
                    ax.annotate(text, (xi, yi), fontsize=6, xytext=(3, 3),
                                textcoords="offset points", color=f"C{i}")  # fmt: skip
        for bound, (colour, marker) in BOUNDS.items():
            row = policies.filter(pl.col("policy") == bound)
            if row.height:
                r = row.row(0, named=True)
                ax.plot(r[key] * scale, r["prevented_share"] * 100, marker=marker, color=colour,
                        ls="none", ms=9, label=bound)  # fmt: skip
        ax.set_xlabel(label)
        ax.grid(alpha=0.3)
    axes[0].set_ylabel("drops prevented [% of no-reflex drops]")
    axes[0].legend(fontsize=7, loc="best")
    fig.suptitle(f"The reflex's trade-off, {name}: one setting changed at a time", fontsize=10)
    fig.tight_layout()
    save(fig, out, dpi)


def best_timeline(paths: Sequence[str | Path]) -> tuple[dict[str, np.ndarray], dict[str, Any]]:
    """The timeline with the highest rank (``closed_loop.timeline_rank``) over the objects' files;
    ({}, {}) when none holds a run."""
    best: tuple[dict[str, np.ndarray], dict[str, Any]] = ({}, {})
    for path in paths:
        arrays = load_npz(path)
        meta = json.loads(str(arrays.pop("meta")))
        if meta and meta.get("rank", -1) > best[1].get("rank", -1):
            best = (arrays, meta)
    return best


def plot_timeline(arrays: dict[str, np.ndarray], meta: dict[str, Any], protocol: str,
                  v_slip: float, dt: float, out: str | Path, dpi: int = 110) -> None:  # fmt: skip
    """One grasp with and without the reflex: total fingertip normal force, object speed against
    eq. 23's threshold, and the reflex's target offset, with the no-reflex onset, the first
    warning and the first tightened step marked."""
    fig, axes = plt.subplots(3, 1, figsize=(8.0, 7.0), sharex=True)
    name = PROTOCOLS.get(protocol, protocol)
    if not meta:
        _nothing_to_draw(axes, "no closed-loop run to draw")
        save(fig, out, dpi)
        return
    policy = meta["policy"]
    for side, colour, label in (("none", "0.4", "no reflex"), ("reflex", "tab:blue", policy)):
        normal = arrays[f"{side}/normal"].astype(float)
        t = np.arange(len(normal)) * dt
        axes[0].plot(t, normal.sum(axis=1), color=colour, lw=1, label=label)
        speed = np.linalg.norm(arrays[f"{side}/velocity"].astype(float), axis=1) * 1e3
        axes[1].semilogy(t, np.maximum(speed, FLOOR), color=colour, lw=0.8, label=label)
        if f"{side}/reflex" in arrays:
            axes[2].plot(t, arrays[f"{side}/reflex"], color=colour, lw=1.2, label=label)
    axes[1].axhline(v_slip * 1e3, color="tab:red", ls="--", lw=1,
                    label=f"v_slip {v_slip * 1e3:g} mm/s (eq. 23)")  # fmt: skip
    marks = (("onset_s", "tab:red", "no-reflex onset"), ("warn_s", "tab:orange", "first warning"),
             ("tighten_s", "tab:blue", "first tightened step"))  # fmt: skip
    for key, colour, label in marks:
        if meta.get(key) is not None:
            for ax in axes:
                ax.axvline(meta[key], color=colour, lw=1, ls=":", label=label if ax is axes[2]
                           else None)  # fmt: skip
    axes[0].set_ylabel("total normal force [N]")
    axes[1].set_ylabel("object speed [mm/s]")
    axes[2].set_ylabel("target offset [rad]")
    axes[2].set_xlabel("time [s]")
    for ax in axes:
        ax.legend(fontsize=7, loc="upper left")
    what = ("prevented the drop" if meta.get("prevented") else
            "dropped anyway" if meta.get("dropped") else "held")  # fmt: skip
    base = "dropped" if meta.get("baseline_dropped") else "held"
    axes[0].set_title(f"{meta['object']} grasp {meta['grasp_id']}, {name}: {policy} {what} "
                      f"(no reflex: {base})", fontsize=9)  # fmt: skip
    fig.tight_layout()
    save(fig, out, dpi)


def plot_closed_loop(summary_dir: str | Path, timelines: Sequence[str | Path], protocol: str,
                     v_slip: float, dt: float, out_tradeoff: str | Path,
                     out_timeline: str | Path, dpi: int = 110) -> None:  # fmt: skip
    """Both figures of one protocol from its summary folder and its objects' timelines."""
    folder = Path(summary_dir)
    tradeoff, policies = (read_parquet(folder / f"{n}.parquet") for n in ("tradeoff", "policies"))
    plot_tradeoff(tradeoff, policies, protocol, out_tradeoff, dpi)
    arrays, meta = best_timeline(timelines)
    plot_timeline(arrays, meta, protocol, v_slip, dt, out_timeline, dpi)
