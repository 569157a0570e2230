"""Same-end trimming for the window-length sweep (thesis 3.5.4).

Every shorter window is the tail of a reference window (built at the longest sweep length): the
first ``W_ref - W`` frames are dropped, so the end time, the predictive offset, the target
interval, the label, the split and the sample count all stay those of the reference dataset.
"""

from __future__ import annotations

import numpy as np
import polars as pl


def trim_same_end(
    index: pl.DataFrame, windows: np.ndarray, window_steps: int
) -> tuple[pl.DataFrame, np.ndarray]:
    """The dataset of ``window_steps`` frames trimmed from the reference (``windows (N, W_ref,
    ...)``: the windows, or their motion); ``index`` rows keep their ids, ends, labels and
    splits, starts move forward."""
    w_ref = windows.shape[1]
    if not 1 <= window_steps <= w_ref:
        raise ValueError(f"a trimmed window needs 1 <= W <= {w_ref} frames, got {window_steps}")
    if index.height != len(windows):
        raise ValueError(f"index has {index.height} rows for {len(windows)} windows")
    cut = w_ref - window_steps
    trimmed = index.with_columns(pl.col("start") + cut)
    return trimmed, windows[:, cut:]
