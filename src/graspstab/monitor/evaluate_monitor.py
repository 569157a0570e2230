"""Entry point of rule evaluate_monitor: each family's monitor and the proxy, grasp by grasp.

Each family's model (the window sweep's first-seed checkpoint at ``monitor.window_s``, with its
validation-selected threshold) and the friction-ratio proxy (its threshold chosen on the same
dataset's validation windows, ``monitor.proxy``) run over every validation and test replay
(``monitor.grasp_level``). Writes the per-grasp table, a JSON summary per monitor and split
(``monitor.episodes.summarise_episodes``) and the timeline grasp's traces for the figure.
"""

from __future__ import annotations

import logging
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np
import polars as pl
import torch

from graspstab.common.io import save_npz, write_json, write_parquet
from graspstab.common.logs import setup_logging
from graspstab.monitor.checkpoint import read_trained
from graspstab.monitor.early_warning import early_warning
from graspstab.monitor.episodes import summarise_episodes
from graspstab.monitor.grasp_level import (
    SPLITS,
    evaluate_monitors,
    read_episodes,
    results_of,
    timeline_grasp,
)
from graspstab.monitor.proxy import PROXY, proxy_scorer
from graspstab.monitor.scoring import TorchScorer, WindowScorer

log = logging.getLogger("graspstab.monitor")

TIMELINE_LEAD_S = 4.0  # the timeline figure shows up to this long before the onset (or the end)


def timeline_record(kept: Mapping[str, Any], scorers: Mapping[str, WindowScorer],
                    onset: int | None, dt: float) -> dict[str, np.ndarray]:  # fmt: skip
    """The timeline grasp's arrays, cut to at most TIMELINE_LEAD_S before the onset (or end)."""
    ep = kept["episode"]
    lo = max(0, (ep.end if onset is None else onset) - round(TIMELINE_LEAD_S / dt))
    out: dict[str, np.ndarray] = {
        "t": np.arange(lo, ep.end) * dt, "forces": ep.forces[lo:], "speed": ep.speed[lo:],
        "u": ep.u[lo:], "frames": np.array([lo, ep.start, ep.end, -1 if onset is None else onset]),
    }  # fmt: skip
    for name, trace in kept["traces"].items():
        out[f"prob_{name}"] = trace.prob[lo:]
        out[f"warning_{name}"] = trace.warning[lo:]
        out[f"threshold_{name}"] = np.array(scorers[name].constants.threshold)
    return out


def evaluate_monitor(
    replays: Sequence[tuple[str | Path, str | Path]],
    runs: Mapping[str, tuple[str | Path, str | Path]],
    dataset_dir: str | Path,
    splits: Mapping[str, str],
    labels: Mapping[str, Any],
    dt: float,
    monitor: Mapping[str, Any],
    threshold: Mapping[str, Any],
    out_episodes: str | Path,
    out_summary: str | Path,
    out_timeline: str | Path,
    log_file: str | Path | None = None,
) -> dict[str, Any]:
    """Run the monitors. ``runs``: family -> (checkpoint, metrics.json) of the monitored models;
    ``monitor``: the monitor group (stride, debounce, batch_size, window_s, timeline_family)."""
    setup_logging(log_file)
    torch.set_num_threads(1)
    scorers: dict[str, WindowScorer] = {}
    models: dict[str, Any] = {}
    for family, (checkpoint, metrics) in runs.items():
        model, constants = read_trained(checkpoint, metrics)
        scorers[family] = TorchScorer(model, constants)
        models[family] = {
            "family": family, "window_steps": constants.window_steps,
            "threshold": constants.threshold, "checkpoint": str(checkpoint),
        }  # fmt: skip
    scorers[PROXY], proxy_choice = proxy_scorer(dataset_dir, threshold)
    models[PROXY] = {"family": PROXY, "window_steps": 1, "threshold": proxy_choice["threshold"],
                     "threshold_choice": proxy_choice}  # fmt: skip
    stride, debounce = int(monitor["stride"]), int(monitor["debounce"])
    episodes = read_episodes(replays, splits, labels, dt)  # one replay in memory at a time
    batch = int(monitor["batch_size"])
    scored: dict[str, list[Any]] = {}
    frame, _ = evaluate_monitors(episodes, scorers, labels, dt, stride=stride, debounce=debounce,
                                 batch_size=batch, scored=scored)  # fmt: skip
    focus = monitor["timeline_family"] if monitor["timeline_family"] in scorers else PROXY
    chosen = timeline_grasp(frame, focus)
    timeline: dict[str, Any] = {"monitor": focus, "object": None, "grasp_id": None}
    arrays: dict[str, np.ndarray] = {"frames": np.zeros(0, dtype=np.int64)}
    if chosen is not None:
        one = read_episodes(replays, splits, labels, dt, grasp=chosen)  # again: none kept
        _, kept = evaluate_monitors(one, scorers, labels, dt, stride=stride, debounce=debounce,
                                    keep_traces={chosen})  # fmt: skip
        row = frame.filter((pl.col("monitor") == focus) & (pl.col("object") == chosen[0])
                           & (pl.col("grasp_id") == chosen[1])).row(0, named=True)  # fmt: skip
        arrays = timeline_record(kept[chosen], scorers, row["onset"], dt)
        timeline = {"monitor": focus, "object": chosen[0], "grasp_id": chosen[1],
                    "split": row["split"], "onset": row["onset"], "lead_time_s": row["lead_time_s"],
                    "warned_in_time": row["warned_in_time"]}  # fmt: skip
    summary: dict[str, Any] = {
        "settings": {"stride": stride, "stride_s": stride * dt, "debounce": debounce, "dt": dt,
                     "window_s": monitor["window_s"], "offset_s": labels["offset_s"],
                     "horizon_s": labels["horizon_s"], "v_slip": labels["v_slip"]},
        "replays": {s: frame.filter((pl.col("monitor") == PROXY) & (pl.col("split") == s)).height
                    for s in SPLITS},
        "monitors": {},
        "timeline": timeline,
    }  # fmt: skip
    for name, info in models.items():
        rows = frame.filter(pl.col("monitor") == name)
        per_split = {s: summarise_episodes(results_of(rows.filter(pl.col("split") == s)))
                     for s in SPLITS}  # fmt: skip
        summary["monitors"][name] = {**info, "splits": per_split}
        test = per_split["test"]
        log.info("%s: test %d failing grasps, %s warned in time, median lead %s s, %s false "
                 "warnings per stable grasp-second", name, test["failing_grasps"],
                 test["warned_in_time"], test["median_lead_s"],
                 test["false_warnings_per_stable_s"])  # fmt: skip
    ew = monitor["early_warning"]
    summary["early_warning"] = {
        "budget_per_s": float(ew["budget_per_s"]), "ahead_s": float(ew["ahead_s"]),
        "monitors": {
            name: early_warning([g for g in grasps if g.split == "val"],
                                [g for g in grasps if g.split == "test"],
                                budget_per_s=float(ew["budget_per_s"]),
                                ahead_s=float(ew["ahead_s"]), debounce=debounce, dt=dt)
            for name, grasps in scored.items()
        },
    }  # fmt: skip
    for name, e in summary["early_warning"]["monitors"].items():
        log.info("%s at a budget of %g false warnings per stable second: threshold %.4g%s; test "
                 "%s of %s grasps failing after a still period warned >= %g s ahead", name,
                 ew["budget_per_s"], e["threshold"]["threshold"],
                 " (grid floor)" if e["threshold"]["at_floor"] else "", e["test"]["warned_ahead"],
                 e["test"]["failing_after_still"], ew["ahead_s"])  # fmt: skip
    write_parquet(out_episodes, frame)
    save_npz(out_timeline, **arrays)
    write_json(out_summary, summary)
    return summary
