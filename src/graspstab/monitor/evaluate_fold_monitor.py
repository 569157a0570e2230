"""Entry point of rule evaluate_fold_monitor: one cross-validation fold's monitors on its own
validation and test replays, for the fold-wide early warning (``monitor.fold_warning``).

The fold's models (each family's plain-forces run at ``crossval.window_s``) and the
friction-ratio proxy score every replay of the fold's validation and test objects as the
streaming monitor would (``monitor.grasp_level``); each monitor's threshold is then chosen on the
validation grasps for the false-warning budget and applied to the test grasps. The window-level
threshold a monitor carries is not used: the budget chooses.
"""

from __future__ import annotations

import logging
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import torch

from graspstab.common.io import write_json, write_parquet
from graspstab.common.logs import setup_logging
from graspstab.monitor.checkpoint import read_trained
from graspstab.monitor.fold_warning import fold_rows
from graspstab.monitor.grasp_level import evaluate_monitors, read_episodes
from graspstab.monitor.proxy import PROXY, ProxyScorer
from graspstab.monitor.scoring import TorchScorer, WindowScorer

log = logging.getLogger("graspstab.monitor")


def evaluate_fold_monitor(
    replays: Sequence[tuple[str | Path, str | Path]],
    runs: Mapping[str, tuple[str | Path, str | Path]],
    assignment: Mapping[str, str],
    fold: int,
    labels: Mapping[str, Any],
    dt: float,
    monitor: Mapping[str, Any],
    out_grasps: str | Path,
    out_thresholds: str | Path,
    log_file: str | Path | None = None,
) -> dict[str, Any]:
    """Score the fold. ``runs``: family -> (checkpoint, metrics.json) of the fold's models;
    ``assignment``: object -> split of this fold; ``monitor``: the monitor group (stride,
    debounce, batch_size, early_warning)."""
    setup_logging(log_file)
    torch.set_num_threads(1)
    scorers: dict[str, WindowScorer] = {}
    for family, (checkpoint, metrics) in runs.items():
        model, constants = read_trained(checkpoint, metrics)
        scorers[family] = TorchScorer(model, constants)
    scorers[PROXY] = ProxyScorer(0.5)  # its window-level threshold is unused (module docstring)
    stride, debounce = int(monitor["stride"]), int(monitor["debounce"])
    episodes = read_episodes(replays, assignment, labels, dt, keep=("val", "test"))
    scored: dict[str, list[Any]] = {}
    evaluate_monitors(episodes, scorers, labels, dt, stride=stride, debounce=debounce,
                      batch_size=int(monitor["batch_size"]), scored=scored)  # fmt: skip
    ew = monitor["early_warning"]
    rows, choices = fold_rows(scored, fold, budget_per_s=float(ew["budget_per_s"]),
                              ahead_s=float(ew["ahead_s"]), debounce=debounce, dt=dt)  # fmt: skip
    for name, c in choices.items():
        mine = rows.filter(rows["monitor"] == name)
        log.info("fold %d, %s: threshold %.4g%s on %d validation grasps; %d of %d test grasps "
                 "failing after a still period warned ahead", fold, name, c["threshold"],
                 " (grid floor)" if c["at_floor"] else "", c["val_grasps"],
                 int(mine["warned_ahead"].fill_null(False).sum()),
                 int(mine["after_still"].sum()))  # fmt: skip
    write_parquet(out_grasps, rows)
    summary = {"fold": fold, "budget_per_s": float(ew["budget_per_s"]),
               "ahead_s": float(ew["ahead_s"]), "stride": stride, "debounce": debounce,
               "thresholds": choices}  # fmt: skip
    write_json(out_thresholds, summary)
    return summary
