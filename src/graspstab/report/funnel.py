"""The report's grasp funnel table: how many candidate grasps survive each stage (annealed ->
replayed -> usable -> windows), per object and in total, as rule ``summarise_funnel`` wrote it.

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

#: How the table names its last row, the one over all objects (a null ``object``).
ALL_OBJECTS = "all objects"


def read_funnel(path: Path) -> list[dict[str, Any]]:
    """The funnel table's rows, the one over all objects last and named :data:`ALL_OBJECTS`."""
    table = read_parquet(path).with_columns(pl.col("object").fill_null(ALL_OBJECTS))
    return table.to_dicts()


def funnel_total(rows: Sequence[Mapping[str, Any]] | None) -> Mapping[str, Any] | None:
    """The row over all objects (None without a funnel)."""
    return next((r for r in rows or [] if r["object"] == ALL_OBJECTS), None)


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
