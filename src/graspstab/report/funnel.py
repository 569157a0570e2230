"""The grasp funnel: how many candidate grasps survive each stage (annealed -> replayed ->
usable -> windows), per object and in total, so a reader sees where a run loses its data.

"Usable" is read from the baseline dataset's summary (grasps with at least one labelled window):
the labelling stage records no per-grasp usable interval, so a replay whose interval exists but
is too short for one window, or whose windows are all ambiguous, counts as not usable here.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import polars as pl

from graspstab.common.io import read_parquet
from graspstab.figures.presentation import UNDEFINED
from graspstab.report import html as H

SPLITS = ("train", "val", "test")
COLUMNS = ("annealed", "replayed", "diverged", "held", "usable", "windows", "unstable")


def funnel(
    grasp_summaries: Sequence[Mapping[str, Any]],
    replay_tables: Sequence[Path],
    dataset: Mapping[str, Any] | None,
) -> list[dict[str, Any]]:
    """One row per object plus a final "all objects" row with the counts of :data:`COLUMNS`:
    candidate grasps annealed, replays run, replays that diverged, held to the end, usable
    grasps, labelled windows and unstable windows (baseline dataset)."""
    replays = (
        pl.concat([read_parquet(p, columns=["object", "diverged", "held_at_end"])
                   for p in replay_tables], how="vertical_relaxed")
        if replay_tables else None
    )  # fmt: skip
    per_object = (dataset or {}).get("objects", {})
    objects = sorted(
        {str(s["object_id"]) for s in grasp_summaries}
        | (set(replays["object"].unique()) if replays is not None else set())
        | set(per_object)
    )
    annealed = {str(s["object_id"]): int(s.get("grasps", 0)) for s in grasp_summaries}
    rows = []
    for obj in objects:
        mine = replays.filter(pl.col("object") == obj) if replays is not None else None
        counts = per_object.get(obj, {})
        split = [counts.get(s, {}) for s in SPLITS]
        rows.append({
            "object": obj,
            "annealed": annealed.get(obj),
            "replayed": mine.height if mine is not None else None,
            "diverged": int(mine["diverged"].sum()) if mine is not None else None,
            "held": int(mine["held_at_end"].sum()) if mine is not None else None,
            "usable": sum(c.get("grasps", 0) for c in split) if dataset else None,
            "windows": sum(c.get("stable", 0) + c.get("unstable", 0) for c in split)
            if dataset else None,
            "unstable": sum(c.get("unstable", 0) for c in split) if dataset else None,
        })  # fmt: skip
    total: dict[str, Any] = {"object": "all objects"}
    for col in COLUMNS:
        values = [r[col] for r in rows]
        total[col] = None if any(v is None for v in values) else sum(values)
    return [*rows, total]


def funnel_table(rows: Sequence[Mapping[str, Any]]) -> str:
    """Candidate grasps through each stage, per object and in total."""

    def cell(v: Any) -> str:
        return UNDEFINED if v is None else f"{v:,}"

    def rate(a: Any, b: Any) -> str:
        return f"{a / b:.0%}" if a is not None and b else "—"

    body = [
        [r["object"], cell(r["annealed"]), cell(r["replayed"]), cell(r["diverged"]),
         cell(r["held"]), cell(r["usable"]), rate(r["usable"], r["replayed"]),
         cell(r["windows"]), cell(r["unstable"])]
        for r in rows
    ]  # fmt: skip
    return H.table(
        ["object", "annealed", "replayed", "diverged", "held to the end", "usable",
         "usable / replayed", "windows", "unstable windows"],
        body,
        caption="Grasp funnel: candidate grasps annealed (3.1.4) → replayed (3.2; diverged "
        "replays are dropped) → usable (at least one labelled window in the baseline dataset, "
        "3.3; the labelling stage keeps no per-grasp usable interval, so an interval too short "
        "for one window also counts as not usable) → labelled windows",
    )  # fmt: skip
