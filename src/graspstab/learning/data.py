"""Window datasets for training: memory-mapped windows, object splits, train-only normalisation.

Training never loads the whole ``windows.npy``: batches are gathered from the memory map by
sample index and normalised on the fly with the training split's statistics (eq. 32, 3.5.2).
A split assignment other than the dataset's own (the split-robustness study, 4.4) recomputes
those statistics from the new training objects, so no validation or test window ever enters them.
"""

from __future__ import annotations

from collections.abc import Callable, Iterator, Mapping
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import polars as pl
import torch

from graspstab.common.errors import GraspstabError
from graspstab.common.io import read_json, read_parquet
from graspstab.labels.dataset import load_windows, normalisation

SPLITS = ("train", "val", "test")


class DatasetError(ValueError, GraspstabError):
    """A dataset that cannot be trained on (missing split, unknown object in an assignment)."""


@dataclass
class WindowData:
    """One window dataset with a split assignment and its normalisation statistics."""

    windows: np.ndarray  # (N, W, 5, C) float32, memory-mapped
    index: pl.DataFrame  # sample_id, object, grasp_id, ..., label, split (the assignment's)
    mean: np.ndarray  # (5, C) training-split mean per fingertip x channel
    std: np.ndarray  # (5, C) training-split std, floored
    source: Path
    # raw training windows of the given rows in place of the stored ones (sensor augmentation,
    # graspstab.learning.augmentation); None: the stored windows
    augment: Callable[[np.ndarray], np.ndarray] | None = None
    # raw windows -> model features before normalisation (graspstab.learning.features); None:
    # the forces as stored
    transform: Callable[[np.ndarray], np.ndarray] | None = None

    @property
    def channels(self) -> int:
        """Input channels per fingertip the model sees (after ``transform``)."""
        return int(self.mean.shape[-1])

    @property
    def window_steps(self) -> int:
        """W, the number of timesteps per window."""
        return int(self.windows.shape[1])

    def rows(self, split: str) -> np.ndarray:
        """Sample rows (positions in ``windows``) of one split, in dataset order."""
        return np.flatnonzero((self.index["split"] == split).to_numpy())

    def labels(self, rows: np.ndarray) -> np.ndarray:
        """Labels (0 stable, 1 unstable) of the given rows."""
        return self.index["label"].to_numpy()[rows].astype(np.float32)

    def objects(self, rows: np.ndarray) -> np.ndarray:
        """Object ids of the given rows."""
        return self.index["object"].to_numpy()[rows]

    def batch(self, rows: np.ndarray) -> torch.Tensor:
        """Normalised windows of ``rows`` as a float32 tensor (B, W, 5, C); reads only those rows
        from the memory map (sorted, so the page cache is read forwards)."""
        order = np.argsort(rows, kind="stable")
        raw = np.empty((len(rows), *self.windows.shape[1:]), dtype=np.float32)
        raw[order] = self.windows[rows[order]]
        if self.transform is not None:
            raw = self.transform(raw)
        raw -= self.mean.astype(np.float32)
        raw /= self.std.astype(np.float32)
        return torch.from_numpy(raw)

    def train_batch(self, rows: np.ndarray) -> torch.Tensor:
        """A training batch: ``batch``, or the augmentation's windows of ``rows`` normalised."""
        if self.augment is None:
            return self.batch(rows)
        raw = self.augment(rows)
        if self.transform is not None:
            raw = self.transform(raw)
        raw -= self.mean.astype(np.float32)
        raw /= self.std.astype(np.float32)
        return torch.from_numpy(raw)

    def batches(
        self, rows: np.ndarray, batch_size: int
    ) -> Iterator[tuple[np.ndarray, torch.Tensor]]:
        """Consecutive batches of ``rows`` (evaluation order), with their row numbers."""
        for i in range(0, len(rows), batch_size):
            chunk = rows[i : i + batch_size]
            yield chunk, self.batch(chunk)

    def class_counts(self, split: str) -> tuple[int, int]:
        """(stable, unstable) window counts of one split."""
        y = self.labels(self.rows(split))
        return int((y == 0).sum()), int((y == 1).sum())


def load_window_data(
    dataset_dir: str | Path,
    assignment: Mapping[str, str] | None = None,
    eps: float | None = None,
    transform: Callable[[np.ndarray], np.ndarray] | None = None,
) -> WindowData:
    """Open a dataset directory written by ``label_windows``/``trim_sweep_window``.

    ``assignment`` maps object id to split; objects it does not name are dropped (an assignment
    over a subset of objects). None keeps the dataset's own splits and stored statistics."""
    root = Path(dataset_dir)
    index = read_parquet(root / "index.parquet")
    windows = load_windows(root)
    if len(index) != len(windows):
        raise DatasetError(
            f"{root}: index.parquet has {len(index)} rows but windows.npy {len(windows)} windows; "
            "rebuild the dataset"
        )
    stored = read_json(root / "normalisation.json")
    eps = float(stored.get("eps", 1e-6) if eps is None else eps)
    if assignment is None:
        mean, std = np.asarray(stored["mean"]), np.asarray(stored["std"])
    else:
        unknown = sorted(set(assignment) - set(index["object"].unique().to_list()))
        bad = sorted({s for s in assignment.values() if s not in SPLITS})
        if bad:
            raise DatasetError(f"split assignment uses unknown split(s) {bad}; valid: {SPLITS}")
        mapping = pl.DataFrame({"object": list(assignment), "split": list(assignment.values())})
        if unknown:
            # An object with no usable windows is legal (it contributes nothing); note it only.
            mapping = mapping.filter(~pl.col("object").is_in(unknown))
        index = index.drop("split").join(mapping, on="object", how="left", maintain_order="left")
        keep = index["split"].is_not_null().to_numpy()
        index = index.filter(pl.Series(keep))
        rows = np.flatnonzero(keep)
        if not keep.all():
            windows = _RowView(windows, rows)
        stats = normalisation(windows, index, eps)
        mean, std = np.asarray(stats["mean"]), np.asarray(stats["std"])
    if transform is not None:
        mean, std = transformed_statistics(windows, index, transform, eps)
    return WindowData(windows=windows, index=index, mean=mean, std=std, source=root,
                      transform=transform)  # fmt: skip


def transformed_statistics(
    windows: np.ndarray, index: pl.DataFrame, transform: Callable[[np.ndarray], np.ndarray],
    eps: float, chunk: int = 4096,
) -> tuple[np.ndarray, np.ndarray]:
    """Per fingertip x channel mean and std (floored at ``eps``) of the transformed training
    windows over all their timesteps (3.5.2 on the model's features), read in chunks."""
    rows = np.flatnonzero((index["split"] == "train").to_numpy())
    total = total_sq = None
    count = 0
    for i in range(0, len(rows), chunk):
        x = transform(np.asarray(windows[rows[i : i + chunk]], dtype=np.float32))
        flat = x.reshape(-1, *x.shape[2:]).astype(np.float64)
        total = flat.sum(axis=0) if total is None else total + flat.sum(axis=0)
        sq = (flat**2).sum(axis=0)
        total_sq = sq if total_sq is None else total_sq + sq
        count += flat.shape[0]
    if total is None or count == 0:
        probe = transform(np.zeros((1, *windows.shape[1:]), dtype=np.float32))
        return np.zeros(probe.shape[2:]), np.ones(probe.shape[2:])
    mean = total / count
    std = np.sqrt(np.maximum(total_sq / count - mean**2, 0.0))
    return mean, np.maximum(std, eps)


class _RowView:
    """A row subset of a memory map that still reads lazily (``view[rows]`` -> base rows)."""

    def __init__(self, base: np.ndarray, rows: np.ndarray) -> None:
        self.base, self.rows = base, rows
        self.shape = (len(rows), *base.shape[1:])
        self.dtype = base.dtype

    def __len__(self) -> int:
        return len(self.rows)

    def __getitem__(self, item: np.ndarray) -> np.ndarray:
        return np.asarray(self.base[self.rows[item]])

    def __array__(self, dtype: object = None, copy: object = None) -> np.ndarray:
        out = np.asarray(self.base[self.rows])
        return out if dtype is None else out.astype(dtype)
