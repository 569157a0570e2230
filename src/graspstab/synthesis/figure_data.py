"""Inputs of the synthesis figures, checked and selected: grasp-table columns, pre-grasp entries.

Apart from the drawing (:mod:`graspstab.synthesis.figure`) because it needs no matplotlib and is
where bad input is caught: every check raises :class:`FigureInputError` naming the missing field.
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping, Sequence
from typing import Any, Literal

import numpy as np
import polars as pl

from graspstab.common.errors import GraspstabError

#: Grasp-table pose columns (object frame): palm position [m], quaternion w-x-y-z, 16 joints [rad].
WRIST_COLUMNS: tuple[str, ...] = ("wrist_x", "wrist_y", "wrist_z")
QUAT_COLUMNS: tuple[str, ...] = ("quat_w", "quat_x", "quat_y", "quat_z")
JOINT_COLUMNS: tuple[str, ...] = tuple(f"theta_{k:02d}" for k in range(16))
POSE_COLUMNS: tuple[str, ...] = WRIST_COLUMNS + QUAT_COLUMNS + JOINT_COLUMNS
#: Keys of a pre-grasp batch (3.1.3): arrays with a leading grasp dimension n.
PREGRASP_KEYS: tuple[str, ...] = (
    "wrist_pos",
    "quat",
    "joints",
    "anchor",
    "surface_point",
    "direction",
    "direction_raw",
    "standoff",
    "roll",
)


class FigureInputError(ValueError, GraspstabError):
    """A figure's input table or pre-grasp batch lacks a field or has the wrong shape."""


def require_columns(columns: Iterable[str], required: Iterable[str], what: str) -> None:
    """Raise :class:`FigureInputError` naming every column of ``required`` not in ``columns``."""
    present = list(columns)
    missing = [c for c in required if c not in present]
    if missing:
        raise FigureInputError(
            f"{what} is missing column(s) {', '.join(repr(c) for c in missing)}; it has "
            f"{', '.join(present) if present else 'no columns'}. Pass a grasp table written by "
            "the synthesis stage (anneal_grasps)."
        )


def grasp_arrays(
    grasps: pl.DataFrame | Mapping[str, Any],
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Hand poses of grasp-table rows: wrist position (n, 3), quaternion w-x-y-z (n, 4) and
    joints (n, 16) as float64; ``grasps`` is a table or one row (``frame.row(i, named=True)``)."""
    columns = grasps.columns if isinstance(grasps, pl.DataFrame) else list(grasps)
    require_columns(columns, POSE_COLUMNS, "grasp table")

    def block(names: Sequence[str]) -> np.ndarray:
        if isinstance(grasps, pl.DataFrame):
            return grasps.select(names).to_numpy().astype(np.float64).reshape(-1, len(names))
        cols = [np.atleast_1d(np.asarray(grasps[c], dtype=np.float64)) for c in names]
        return np.stack(cols, axis=1)

    return block(WRIST_COLUMNS), block(QUAT_COLUMNS), block(JOINT_COLUMNS)


def select_gallery_grasps(
    grasps: pl.DataFrame,
    per_object: int = 2,
    max_objects: int = 6,
    seed: int = 0,
    choose: Literal["best", "random"] = "best",
) -> pl.DataFrame:
    """Rows for the gallery: the first ``max_objects`` objects in table order, and of each its
    ``per_object`` lowest-``energy`` grasps (``choose="best"``, ties by grasp_id) or a seeded
    random sample of them (``"random"``, as the caption of fig. 3.6 says). Non-finite energies are
    never shown. Returned in object order, then energy order."""
    if per_object < 1 or max_objects < 1:
        raise ValueError(
            f"per_object and max_objects must be >= 1, got {per_object}, {max_objects}"
        )
    if choose not in ("best", "random"):
        raise ValueError(f"choose must be 'best' or 'random', got {choose!r}")
    require_columns(grasps.columns, ("object", "energy", "grasp_id", *POSE_COLUMNS), "grasp table")
    finite = grasps.filter(pl.col("energy").is_finite())
    objects = finite["object"].unique(maintain_order=True).to_list()[:max_objects]
    rng = np.random.default_rng(seed)
    parts = []
    for obj in objects:
        rows = finite.filter(pl.col("object") == obj).sort(["energy", "grasp_id"])
        if choose == "random" and rows.height > per_object:
            pick = np.sort(rng.choice(rows.height, size=per_object, replace=False))
            rows = rows[pick.tolist()]
        parts.append(rows.head(per_object))
    if not parts:
        return grasps.clear()
    return pl.concat(parts)


def pregrasp_entry(pregrasp: Mapping[str, Any], index: int) -> dict[str, np.ndarray]:
    """Entry ``index`` of a pre-grasp batch as float64 arrays, checking keys and shapes."""
    missing = [k for k in PREGRASP_KEYS if k not in pregrasp]
    if missing:
        raise FigureInputError(
            f"pre-grasp batch is missing key(s) {', '.join(repr(k) for k in missing)}; it has "
            f"{', '.join(pregrasp)}. Pass the dict returned by sample_pregrasps (3.1.3)."
        )
    shapes = {"quat": 4, "joints": 16, "standoff": 0, "roll": 0}
    n = len(np.asarray(pregrasp["wrist_pos"]))
    if not -n <= index < n:
        raise IndexError(f"pre-grasp index {index} out of range for a batch of {n}")
    out = {}
    for key in PREGRASP_KEYS:
        arr = np.asarray(pregrasp[key], dtype=np.float64)
        width = shapes.get(key, 3)
        expected = (n,) if width == 0 else (n, width)
        if arr.shape != expected:
            raise FigureInputError(f"pre-grasp {key!r} must have shape {expected}, got {arr.shape}")
        out[key] = arr[index]
    return out


def energy_floor(values: np.ndarray) -> float:
    """The smallest energy drawn on the log axis: half the smallest positive value (1e-6 if
    none); zeros (and any non-positive value) are drawn at this floor."""
    positive = values[np.isfinite(values) & (values > 0)]
    return 0.5 * float(positive.min()) if positive.size else 1e-6
