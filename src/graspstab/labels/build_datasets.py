"""Dataset stage entry points: baseline dataset, sweep reference and its trims (3.3, 3.5.4).

The baseline dataset (``labels.window_s``) is built from the replays independently of the sweep,
as the reference did; the sweep's reference dataset is built at the longest sweep window and every
shorter sweep window is trimmed from it (same end, label, split and sample count).
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np
import polars as pl

from graspstab.common.io import read_parquet, save_npy, write_json, write_parquet
from graspstab.common.logs import setup_logging
from graspstab.labels.dataset import load_motion, load_windows, normalisation
from graspstab.labels.label_windows import label_windows
from graspstab.labels.trim import trim_same_end
from graspstab.labels.windows import step_counts


def dataset_summary(index: pl.DataFrame) -> dict[str, Any]:
    """Windows per split and class, overall and per object (cf. section 4.1.1)."""
    def counts(frame: pl.DataFrame) -> dict[str, dict[str, int]]:
        out: dict[str, dict[str, int]] = {}
        for split in ("train", "val", "test"):
            part = frame.filter(pl.col("split") == split)
            out[split] = {
                "stable": int((part["label"] == 0).sum()),
                "unstable": int((part["label"] == 1).sum()),
                "grasps": int(part.select("object", "grasp_id").unique().height),
            }
        return out

    return {
        "windows": index.height,
        "splits": counts(index),
        "objects": {o: counts(index.filter(pl.col("object") == o))
                    for o in sorted(index["object"].unique().to_list())},
    }  # fmt: skip


def build_dataset(
    replays: list[tuple[str, str]], out_dir: str | Path, labels: dict[str, Any],
    splits: dict[str, str], window_s: float, dt: float, seed: int,
    log_file: str | Path | None = None,
) -> dict[str, Any]:  # fmt: skip
    """Build one dataset from the replays ((table, traces) pairs) and write its ``summary.json``
    beside it."""
    setup_logging(log_file)
    index = label_windows(replays, out_dir, labels, splits, window_s, dt, seed)
    summary = {"window_s": window_s, **dataset_summary(index)}
    write_json(Path(out_dir) / "summary.json", summary)
    return summary


def trim_dataset(
    reference_dir: str | Path, out_dir: str | Path, window_s: float, dt: float,
    log_file: str | Path | None = None,
) -> dict[str, Any]:  # fmt: skip
    """The sweep dataset of ``window_s`` trimmed from the reference dataset (same end)."""
    setup_logging(log_file)
    ref, out = Path(reference_dir), Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    index = read_parquet(ref / "index.parquet")
    steps = step_counts(window_s, 0.0, 0.0, dt)[0]
    trimmed, windows = trim_same_end(index, load_windows(ref), steps)
    save_npy(out / "windows.npy", np.ascontiguousarray(windows, dtype=np.float32))
    _, motion = trim_same_end(index, load_motion(ref), steps)  # the same tail of each window
    save_npy(out / "motion.npy", np.ascontiguousarray(motion))
    write_json(out / "normalisation.json", normalisation(windows, trimmed))
    write_parquet(out / "index.parquet", trimmed, metadata={
        "window_steps": steps, "dt": dt, "window_s": window_s, "trimmed_from": str(ref),
    })  # fmt: skip
    summary = {"window_s": window_s, **dataset_summary(trimmed)}
    write_json(out / "summary.json", summary)
    return summary
