"""The grasp funnel: how many candidate grasps survive each stage (annealed -> replayed -> usable
-> windows), per object and in total: the table job ``summarise_funnel`` writes, so a reader of
the report sees where a run loses its data without the report counting anything.

"Usable" is read from the baseline dataset's summary (grasps with at least one labelled window):
the labelling stage records no per-grasp usable interval, so a replay whose interval exists but
is too short for one window, or whose windows are all ambiguous, counts as not usable here.
"""

from __future__ import annotations

import logging
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import polars as pl

from graspstab.common.io import read_json, read_parquet, write_parquet
from graspstab.common.logs import setup_logging
from graspstab.common.provenance import provenance

log = logging.getLogger("graspstab.labels")

SPLITS = ("train", "val", "test")
#: The counts of each row, in order (after ``object``, null on the last row: all objects).
COLUMNS = ("annealed", "replayed", "diverged", "held", "usable", "windows", "unstable")


def funnel(
    grasp_summaries: Sequence[Mapping[str, Any]],
    outcomes: pl.DataFrame | None,
    dataset: Mapping[str, Any] | None,
) -> list[dict[str, Any]]:
    """One row per object plus a final row over all objects (``object`` None) with the counts of
    :data:`COLUMNS`: candidate grasps annealed (the grasp summaries), replays run, replays that
    diverged, held to the end (``outcomes``: the replay outcome table's per-object rows), usable
    grasps, labelled windows and unstable windows (``dataset``: the baseline dataset's summary).
    A count whose source is not given is None, and so is its total."""
    replays = (
        {r["object"]: r for r in outcomes.iter_rows(named=True) if r["object"] is not None}
        if outcomes is not None else None
    )  # fmt: skip
    per_object = (dataset or {}).get("objects", {})
    objects = sorted(
        {str(s["object_id"]) for s in grasp_summaries} | set(replays or {}) | set(per_object)
    )
    annealed = {str(s["object_id"]): int(s.get("grasps", 0)) for s in grasp_summaries}
    rows = []
    for obj in objects:
        mine = replays.get(obj) if replays is not None else None
        counts = per_object.get(obj, {})
        split = [counts.get(s, {}) for s in SPLITS]
        rows.append({
            "object": obj,
            "annealed": annealed.get(obj),
            "replayed": mine["replays"] if mine is not None else None,
            "diverged": mine["diverged"] if mine is not None else None,
            "held": mine["held"] if mine is not None else None,
            "usable": sum(c.get("grasps", 0) for c in split) if dataset else None,
            "windows": sum(c.get("stable", 0) + c.get("unstable", 0) for c in split)
            if dataset else None,
            "unstable": sum(c.get("unstable", 0) for c in split) if dataset else None,
        })  # fmt: skip
    total: dict[str, Any] = {"object": None}
    for col in COLUMNS:
        values = [r[col] for r in rows]
        total[col] = None if any(v is None for v in values) else sum(values)
    return [*rows, total]


def funnel_frame(rows: Sequence[Mapping[str, Any]]) -> pl.DataFrame:
    """The rows of :func:`funnel` as a table (counts as nullable integers)."""
    schema = {"object": pl.String, **{c: pl.Int64 for c in COLUMNS}}
    return pl.DataFrame([dict(r) for r in rows], schema=schema)


def summarise_funnel(
    grasp_summaries: Sequence[str | Path],
    replay_outcomes_table: str | Path,
    dataset_summary: str | Path,
    out_path: str | Path,
    log_file: str | Path | None = None,
) -> pl.DataFrame:
    """The grasp funnel (:func:`funnel`) of one run, from its grasp
    summaries, its replay outcome table and its baseline dataset's summary, written to
    ``out_path`` with the job's provenance in the Parquet metadata."""
    setup_logging(log_file)
    rows = funnel(
        [read_json(p) for p in grasp_summaries],
        read_parquet(replay_outcomes_table),
        read_json(dataset_summary),
    )
    frame = funnel_frame(rows)
    write_parquet(out_path, frame, metadata={"provenance": provenance("labels", {})})
    total = rows[-1]
    log.info("funnel: %s annealed, %s replayed, %s usable, %s windows", total["annealed"],
             total["replayed"], total["usable"], total["windows"])  # fmt: skip
    return frame
