"""Entry point of rule aggregate_fold_warning: every fold's early-warning rows pooled over the
unseen objects, with intervals by bootstrap over objects (``monitor.fold_warning``)."""

from __future__ import annotations

import logging
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import polars as pl

from graspstab.common.io import read_json, read_parquet, write_json, write_parquet
from graspstab.common.logs import setup_logging
from graspstab.monitor.fold_warning import pooled_warning, warning_answer

log = logging.getLogger("graspstab.monitor")


def aggregate_fold_warning(
    grasps: Sequence[str | Path],
    thresholds: Sequence[str | Path],
    protocol: str,
    bootstrap: Mapping[str, Any],
    out_rows: str | Path,
    out_summary: str | Path,
    log_file: str | Path | None = None,
) -> dict[str, Any]:
    """Pool the folds' rows (``grasps``: each fold's grasps.parquet; ``thresholds``: its
    thresholds.json, in the same order)."""
    setup_logging(log_file)
    rows = pl.concat([read_parquet(p) for p in grasps])
    folds = [read_json(p) for p in thresholds]
    summary = pooled_warning(rows, int(bootstrap["resamples"]), int(bootstrap["seed"]),
                             float(bootstrap["level"]))  # fmt: skip
    first = folds[0] if folds else {}
    summary.update({
        "protocol": protocol, "folds": len(folds),
        "budget_per_s": first.get("budget_per_s"), "ahead_s": first.get("ahead_s"),
        "thresholds": {
            name: {"at_floor": sum(f["thresholds"][name]["at_floor"] for f in folds),
                   "never_warns": sum(f["thresholds"][name]["never_warns"] for f in folds),
                   "val_false_per_s": [f["thresholds"][name]["false_per_s"] for f in folds]}
            for name in summary["monitors"]
        },
    })  # fmt: skip
    summary["answer"] = warning_answer(summary, protocol.replace("_", "-"))
    log.info("%s", summary["answer"])
    write_parquet(out_rows, rows)
    write_json(out_summary, summary)
    return summary
