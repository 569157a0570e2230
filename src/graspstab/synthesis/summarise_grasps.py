"""Per-object summary of the synthesised grasps: energy distribution and contact diagnostics."""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np
import polars as pl

from graspstab.common.io import read_parquet, write_json
from graspstab.synthesis.anneal_grasps import FINGERS
from graspstab.synthesis.grasp_energy import TERMS

QUANTILES = (0.05, 0.25, 0.5, 0.75, 0.95)
#: "Within a few millimetres" of the surface (issue acceptance): fingertip gap thresholds [m].
TIP_TOLERANCES = (0.002, 0.005)


def read_grasp_tables(paths: Sequence[str | Path]) -> pl.DataFrame:
    """Concatenate shard tables (one row per candidate grasp)."""
    if not paths:
        raise ValueError("no grasp tables given")
    return pl.concat([read_parquet(p) for p in paths])


def _quantiles(values: np.ndarray) -> dict[str, float]:
    q = np.quantile(values, QUANTILES)
    return {f"q{int(round(p * 100)):02d}": float(v) for p, v in zip(QUANTILES, q, strict=True)}


def summarise(table: pl.DataFrame) -> dict[str, Any]:
    """The energy distribution (start and best), fingertip gaps and how deep the hand reaches in."""
    tips = np.stack([table[f"tip_dist_{f}"].to_numpy() for f in FINGERS], axis=1)
    out: dict[str, Any] = {
        "grasps": table.height,
        "energy_start": _quantiles(table["energy_start"].to_numpy()),
        "energy": _quantiles(table["energy"].to_numpy()),
        "terms": {t: _quantiles(table[f"e_{t}"].to_numpy()) for t in TERMS},
        "acceptance_rate": _quantiles(table["acceptance_rate"].to_numpy()),
        "energy_fell_fraction": float(
            np.mean(table["energy"].to_numpy() < table["energy_start"].to_numpy())
        ),
        # fingertip gap: |signed distance| of the distal candidate nearest the surface
        "tip_abs_dist": _quantiles(np.abs(tips).ravel()),
        "min_candidate_dist": _quantiles(table["min_candidate_dist"].to_numpy()),
        # deepest hand surface point inside the object (true mesh), E_hpen's diagnostic
        "max_hand_depth": _quantiles(table["max_hand_depth"].to_numpy()),
    }
    for tol in TIP_TOLERANCES:
        mm = f"{tol * 1000:g}mm"
        out[f"tips_within_{mm}_mean"] = float(np.mean(np.abs(tips) <= tol) * len(FINGERS))
        out[f"grasps_with_3_tips_within_{mm}"] = float(np.mean((np.abs(tips) <= tol).sum(1) >= 3))
    return out


def summarise_grasps(
    object_id: str, shard_paths: Sequence[str | Path], out_path: str | Path
) -> dict[str, Any]:
    """Write the object's ``summary.json`` from its shard tables."""
    table = read_grasp_tables(shard_paths)
    objects = table["object"].unique().to_list()
    if objects != [object_id]:
        raise ValueError(f"grasp tables for {object_id} hold rows of {objects}")
    summary = {"object_id": object_id, "shards": len(shard_paths), **summarise(table)}
    write_json(out_path, summary)
    return summary
