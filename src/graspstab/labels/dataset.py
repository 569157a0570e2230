"""The window dataset's format, shared by its writer (labelling) and its readers (learning, the
sensing study): the input channels, the training-split normalisation (3.5.2) and the windows'
memory map. A reader imports this module, never the labelling stage's entry point."""

from __future__ import annotations

import os
from pathlib import Path
from typing import Any

import numpy as np
import polars as pl

from graspstab.common.io import load_npy

CHANNELS = ("normal", "shear")
#: Where each channel sits in the windows' last axis (N, W, fingertips, channel).
NORMAL_CHANNEL = CHANNELS.index("normal")
SHEAR_CHANNEL = CHANNELS.index("shear")


def normalisation(windows: np.ndarray, index: pl.DataFrame, eps: float = 1e-6) -> dict[str, Any]:
    """Per fingertip x channel mean and std over the training windows' time steps only (3.5.2),
    the std floored at ``eps``; validation and test windows never enter."""
    train = np.asarray(windows[(index["split"] == "train").to_numpy()])
    flat = train.reshape(-1, 5, 2).astype(np.float64)
    mean = flat.mean(axis=0) if len(flat) else np.zeros((5, 2))
    std = np.maximum(flat.std(axis=0), eps) if len(flat) else np.ones((5, 2))
    return {
        "mean": mean.tolist(), "std": std.tolist(), "eps": eps, "axes": "fingertip x channel",
        "channels": list(CHANNELS), "train_windows": int(len(train)),
    }  # fmt: skip


#: What ``motion.npy`` holds beside the windows (N, W, 2), step by step over each window's
#: observation period: eq. 23's step label u_t and the object's centre-of-mass speed [m/s]. No
#: fingertip sensor sees either, so no model reads them: evaluation does, to tell a window whose
#: object already moves (recognising the present) from one whose object is still (foresight).
MOTION = ("unstable", "speed")


def load_motion(out_dir: str | Path) -> np.ndarray:
    """The dataset's observation-period motion (``MOTION``) as a read-only memory map (N, W, 2)."""
    return load_npy(os.fspath(Path(out_dir) / "motion.npy"), mmap_mode="r")


def load_windows(out_dir: str | Path) -> np.ndarray:
    """The dataset's windows as a read-only memory map (N, W, 5, 2)."""
    return load_npy(os.fspath(Path(out_dir) / "windows.npy"), mmap_mode="r")
