"""Alternative model inputs for the input audit (our extension): the baseline dataset's
windows with other channels, read from the replay traces at the same starts, labels and splits.

Table 4.2's parameter counts are exactly what the three architectures give with 16 inputs per
timestep, not the 10 of the text (docs/extensions.md "Input audit"), so the audit trains the
baseline configurations on:

* ``forces``: eq. 19's 5 fingertips x (normal, shear), 10 inputs (the baseline dataset itself);
* ``normal`` and ``shear``: one of the two channels, 5 inputs;
* ``tangential``: the normal force and the shear's two fingertip-frame components instead of its
  magnitude (``shear_distal``, ``shear_lateral``; graspstab.replay.sensors), 15 inputs;
* ``object_state``: the forces plus the object's position and linear velocity, 16 inputs. The
  labels are computed from that velocity (eq. 23), so this set is a leakage control: a model
  that sees it should do better than any force-only model, and by how much says how much of
  the label the object's own motion gives away.

Windows are ``(N, W, 1, F)``: one "fingertip" holding the F features in the order of
``features``, which every model flattens to F inputs per timestep like the baseline's 5 x 2.
"""

from __future__ import annotations

from collections.abc import Mapping
from pathlib import Path
from typing import Any

import numpy as np
import polars as pl

from graspstab.common.errors import GraspstabError
from graspstab.common.io import (
    read_parquet,
    read_parquet_metadata,
    save_npy,
    write_json,
    write_parquet,
)
from graspstab.labels.build_datasets import dataset_summary
from graspstab.labels.dataset import load_motion
from graspstab.labels.trace_windows import grasps_of

FINGERTIPS = 5
#: Each input set's trace channels: per-fingertip (T, 5) ones, then per-object (T, 3) ones.
INPUT_SETS: dict[str, tuple[tuple[str, ...], tuple[str, ...]]] = {
    "forces": (("normal", "shear"), ()),
    "normal": (("normal",), ()),
    "shear": (("shear",), ()),
    "tangential": (("normal", "shear_distal", "shear_lateral"), ()),
    "object_state": (("normal", "shear"), ("position", "velocity")),
}


class InputSetError(ValueError, GraspstabError):
    """An unknown input set, or a dataset and traces that disagree."""


def features(input_set: str) -> list[str]:
    """The feature names of one input set, in the window's order."""
    tips, objects = _channels(input_set)
    return [f"{c}_{f}" for f in range(FINGERTIPS) for c in tips] + [
        f"{c}_{a}" for c in objects for a in "xyz"
    ]


def _channels(input_set: str) -> tuple[tuple[str, ...], tuple[str, ...]]:
    if input_set not in INPUT_SETS:
        raise InputSetError(f"unknown input set {input_set!r}; valid: {list(INPUT_SETS)}")
    return INPUT_SETS[input_set]


def input_windows(
    index: pl.DataFrame, traces: Mapping[tuple[str, int], str | Path], window_steps: int,
    input_set: str,
) -> np.ndarray:  # fmt: skip
    """``(N, W, 1, F)`` float32 windows of ``input_set`` at the index's starts, in its order."""
    tips, objects = _channels(input_set)
    width = FINGERTIPS * len(tips) + 3 * len(objects)
    out = np.empty((len(index), window_steps, 1, width), dtype=np.float32)
    for rows, starts, tr, name in grasps_of(index, traces, (*tips, *objects), InputSetError):
        parts = [np.stack([tr[c] for c in tips], axis=-1).reshape(-1, FINGERTIPS * len(tips))]
        parts += [tr[c].reshape(-1, 3) for c in objects]
        feats = np.concatenate(parts, axis=1)  # (T, F), fingertip-major like eq. 19
        idx = starts[:, None] + np.arange(window_steps)[None]
        if idx.max() >= len(feats):
            raise InputSetError(f"{name}: a window ends after the trace; rebuild the dataset")
        out[rows, :, 0] = feats[idx]
    return out


def build_input_dataset(
    dataset_dir: str | Path, traces: Mapping[tuple[str, int], str | Path], input_set: str,
    out_dir: str | Path, eps: float = 1e-6,
) -> dict[str, Any]:  # fmt: skip
    """Write the dataset of ``input_set`` beside the baseline's (same index, labels and splits):
    ``windows.npy``, ``index.parquet``, ``normalisation.json`` (training windows only, 3.5.2)
    and ``summary.json``."""
    src, out = Path(dataset_dir), Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    index = read_parquet(src / "index.parquet")
    w = int(index["end"][0] - index["start"][0]) if len(index) else 0
    windows = input_windows(index, traces, w, input_set)
    train = windows[(index["split"] == "train").to_numpy()].reshape(-1, 1, windows.shape[-1])
    mean = train.astype(np.float64).mean(axis=0) if len(train) else np.zeros((1, windows.shape[-1]))
    std = (
        np.maximum(train.astype(np.float64).std(axis=0), eps) if len(train) else np.ones_like(mean)
    )
    save_npy(out / "windows.npy", np.ascontiguousarray(windows))
    save_npy(out / "motion.npy", np.ascontiguousarray(load_motion(src)))  # the same windows
    write_json(out / "normalisation.json", {
        "mean": mean.tolist(), "std": std.tolist(), "eps": eps, "axes": "1 x feature",
        "channels": features(input_set), "train_windows": int((index["split"] == "train").sum()),
    })  # fmt: skip
    write_parquet(
        out / "index.parquet",
        index,
        metadata={**read_parquet_metadata(src / "index.parquet"), "input_set": input_set},
    )
    summary = {"input_set": input_set, "features": features(input_set), **dataset_summary(index)}
    write_json(out / "summary.json", summary)
    return summary
