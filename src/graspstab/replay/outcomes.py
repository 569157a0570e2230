"""How one protocol's replays ended, per object and over all objects (thesis 3.2): the table job
``summarise_replays`` writes, so the report shows counts and medians instead of aggregating the
per-shard replay tables."""

from __future__ import annotations

import logging
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import polars as pl

from graspstab.common.io import read_parquet, write_parquet
from graspstab.common.logs import setup_logging
from graspstab.common.provenance import provenance

log = logging.getLogger("graspstab.replay")

#: The table's columns in order; ``object`` is null on the last row, the one over all objects.
#: Counts are of replays; the medians are over the replays of the row (deepest contact:
#: ``max_penetration`` in m); ``simulated_s`` sums their durations. The last three are the load
#: ramp's (null when the protocol has none): replays that slid under the load while in contact,
#: the median time from that slip to the end of contact (over those that lost contact; null when
#: none did) and the median peak load in m g.
COLUMNS = {
    "object": pl.String,
    "replays": pl.Int64,
    "held": pl.Int64,
    "contact_lost": pl.Int64,
    "too_deep": pl.Int64,
    "diverged": pl.Int64,
    "median_max_penetration_m": pl.Float64,
    "simulated_s": pl.Float64,
    "slid": pl.Int64,
    "median_slip_to_loss_s": pl.Float64,
    "median_peak_load_mg": pl.Float64,
}


def _median(series: pl.Series) -> float | None:
    value = series.median()
    return None if value is None else float(value)


def outcome_row(replays: pl.DataFrame) -> dict[str, Any]:
    """The outcome columns of :data:`COLUMNS` (all but ``object``) over the rows of ``replays``
    (replay tables as ``replay_grasps`` writes them)."""
    row: dict[str, Any] = {
        "replays": replays.height,
        "held": int(replays["held_at_end"].sum()),
        "contact_lost": int((replays["stop_reason"] == "contact_lost").sum()),
        "too_deep": int((replays["stop_reason"] == "too_deep").sum()),
        "diverged": int(replays["diverged"].sum()),
        "median_max_penetration_m": _median(replays["max_penetration"]),
        "simulated_s": float(replays["duration_s"].sum()),
        "slid": None,
        "median_slip_to_loss_s": None,
        "median_peak_load_mg": None,
    }
    if "ramp_slip_s" in replays.columns:
        slid = replays.filter(pl.col("ramp_slip_s").is_not_nan())
        lost = slid.filter(pl.col("contact_loss_s").is_not_nan())
        row["slid"] = slid.height
        row["median_slip_to_loss_s"] = (
            _median(lost["contact_loss_s"] - lost["ramp_slip_s"]) if lost.height else None
        )
        row["median_peak_load_mg"] = _median(replays["ramp_peak_load_mg"])
    return row


def replay_outcomes(replays: pl.DataFrame) -> pl.DataFrame:
    """One row per object (sorted by id), then one over all objects (``object`` null), with the
    columns of :data:`COLUMNS`."""
    objects = sorted(replays["object"].unique().to_list()) if replays.height else []
    rows = [
        {"object": obj, **outcome_row(replays.filter(pl.col("object") == obj))} for obj in objects
    ]
    rows.append({"object": None, **outcome_row(replays)})
    return pl.DataFrame(rows, schema=COLUMNS)


def read_replay_tables(paths: Sequence[str | Path]) -> pl.DataFrame:
    """The per-shard replay tables as one (columns a protocol lacks filled with null)."""
    if not paths:
        raise ValueError("no replay tables given")
    return pl.concat([read_parquet(p) for p in paths], how="diagonal_relaxed")


def summarise_replays(
    tables: Sequence[str | Path],
    out_path: str | Path,
    protocol: str,
    log_file: str | Path | None = None,
) -> pl.DataFrame:
    """How one protocol's replays ended (3.2), per object and over all objects
    (:func:`replay_outcomes` of its per-shard replay tables), written to ``out_path`` with the
    job's provenance in the Parquet metadata."""
    setup_logging(log_file)
    outcomes = replay_outcomes(read_replay_tables(tables))
    meta = {"protocol": protocol, "provenance": provenance("replay", {"protocol": protocol})}
    write_parquet(out_path, outcomes, metadata=meta)
    total = outcomes.row(-1, named=True)
    log.info("%s replays: %d of %d objects, %d held to the end, %d diverged", protocol,
             total["replays"], outcomes.height - 1, total["held"], total["diverged"])  # fmt: skip
    return outcomes
