"""Failure-anatomy stage entry point: one protocol's replays, each usable grasp's failure onset
and type (:mod:`graspstab.labels.anatomy`), as a per-grasp table and a summary the report reads.

Writes ``anatomy.parquet`` (object, grasp_id, shard, split and :func:`grasp_anatomy`'s columns;
onset and failure times in seconds after the settle index), ``anatomy.json`` (the protocol, its
counts per type and split, onset quartiles, and the rules used) and, with ``figure_path``, the
onset histogram (:mod:`graspstab.labels.anatomy_figure`).
"""

from __future__ import annotations

import logging
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import polars as pl

from graspstab.common.io import write_json, write_parquet
from graspstab.common.logs import setup_logging
from graspstab.common.provenance import provenance
from graspstab.labels.anatomy import CHANNELS, grasp_anatomy, summarise
from graspstab.labels.anatomy_figure import plot_anatomy
from graspstab.labels.replays import replay_grasps

log = logging.getLogger("graspstab.labels")


def summarise_anatomy(
    replays: Sequence[tuple[str | Path, str | Path]],
    table_path: str | Path,
    summary_path: str | Path,
    labels: Mapping[str, Any],
    splits: Mapping[str, str],
    dt: float,
    protocol: str,
    figure_path: str | Path | None = None,
    log_file: str | Path | None = None,
) -> pl.DataFrame:
    """Anatomy of every usable replay of the (table, traces) pairs."""
    setup_logging(log_file)
    rows = []
    for g in replay_grasps(replays, splits, CHANNELS):
        a = grasp_anatomy(g.traces, dict(labels), dt)
        if a is not None:
            rows.append({"object": g.object, "grasp_id": g.grasp_id, "shard": g.shard,
                         "split": g.split, **a})  # fmt: skip
    table = pl.DataFrame(rows, schema_overrides={"type": pl.String}) if rows else pl.DataFrame()
    summary = {
        "protocol": protocol,
        **summarise(rows),
        "by_split": {s: summarise(r for r in rows if r["split"] == s)
                     for s in ("train", "val", "test")},  # fmt: skip
        "rules": dict(labels["anatomy"]),
        "provenance": provenance("labels", {"labels": dict(labels), "dt": dt}),
    }
    write_parquet(table_path, table, metadata={"protocol": protocol})
    write_json(summary_path, summary)
    if figure_path is not None:
        plot_anatomy(rows, summary, figure_path)
    log.info("%s: %d usable grasps, %d failed after settling (%s); %d leave a still window",
             protocol, summary["usable"], summary["failed"],
             ", ".join(f"{k} {v}" for k, v in summary["types"].items() if v),
             summary["still_window"])  # fmt: skip
    return table
