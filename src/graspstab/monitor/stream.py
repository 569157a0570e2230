"""The streaming monitor: one raw force frame in at a time, a probability and a warning out.

This is how a controller runs a window model: frames arrive at the replay rate (2 kHz), the last
``window_steps`` of them are kept in a preallocated ring buffer, and once it is full the window is
scored every ``stride`` frames (the first score comes with the frame that fills the buffer). A
score is unstable when ``prob >= threshold`` (the learning stage's rule); the warning is raised
while the last ``debounce`` scores were all unstable and dropped by the first stable score. On
frames that are not scored it keeps its value. Scoring a window here gives the same probability
as scoring that window in a batch with the learning stage's normalisation (tests).

A scorer with per-frame state of its own (``monitor.incremental.IncrementalCNNScorer``: a CNN
whose layers' shift-invariant parts are cached) is handed every frame and asked for the current
window's probability instead.

The ring holds every frame twice (slots ``i`` and ``i + W``), so the window is always the one
contiguous slice ``ring[s : s + W]``: no per-frame copy or allocation of the window.
"""

from __future__ import annotations

from typing import Any, NamedTuple

import numpy as np
from torch import nn

from graspstab.monitor.constants import (
    FRAME_SHAPE,
    MonitorConstants,
    MonitorError,
    check_positive,
    check_threshold,
)
from graspstab.monitor.scoring import TorchScorer, WindowScorer


class MonitorStep(NamedTuple):
    """One frame's outcome: the probability (None on a frame that was not scored), the warning."""

    prob: float | None
    warning: bool


class MonitorTrace(NamedTuple):
    """A whole trace's outcome per frame: probability (NaN where not scored), warning."""

    prob: np.ndarray  # (T,) float64
    warning: np.ndarray  # (T,) bool


def check_trace(frames: Any, first: int = 0) -> np.ndarray:
    """A raw trace as float32 (T, 5, 2), or an error naming the shape or the first non-finite
    frame (numbered from ``first``, the frames already seen)."""
    x = np.asarray(frames, dtype=np.float32)
    if x.ndim != 3 or x.shape[1:] != FRAME_SHAPE:
        raise MonitorError(
            f"a trace is (T, {FRAME_SHAPE[0]}, {FRAME_SHAPE[1]}) raw forces (time, fingertips,"
            f" (normal, shear)); got shape {x.shape}"
        )
    bad = np.flatnonzero(~np.isfinite(x).all(axis=(1, 2)))
    if len(bad):
        raise MonitorError(f"frame {first + int(bad[0])} has a non-finite force")
    return x


class StreamingMonitor:
    """Frame-by-frame instability monitor around a trained model (any family, any format)."""

    def __init__(
        self,
        model: nn.Module,
        mean: Any,
        std: Any,
        threshold: float,
        window_steps: int,
        *,
        stride: int = 1,
        debounce: int = 1,
    ) -> None:
        """``model``: a learning-stage classifier (normalised windows in, logits out); ``mean``
        and ``std``: its training normalisation (5, 2); ``threshold``: its validation-selected
        decision threshold; ``window_steps``: the window it was trained on, in frames."""
        constants = MonitorConstants(mean, std, threshold, window_steps)
        self._setup(TorchScorer(model, constants), constants.threshold, stride, debounce)

    @classmethod
    def from_scorer(
        cls,
        scorer: WindowScorer,
        *,
        threshold: float | None = None,
        stride: int = 1,
        debounce: int = 1,
    ) -> StreamingMonitor:
        """A monitor on any scorer (an exported model, see ``monitor.export``); the threshold is
        the scorer's own unless given."""
        monitor = cls.__new__(cls)
        chosen = scorer.constants.threshold if threshold is None else threshold
        monitor._setup(scorer, chosen, stride, debounce)
        return monitor

    def _setup(self, scorer: WindowScorer, threshold: float, stride: int, debounce: int) -> None:
        self.scorer = scorer
        self.threshold = check_threshold(threshold)
        self.window_steps = scorer.constants.window_steps
        self.stride = check_positive("stride", stride)
        self.debounce = check_positive("debounce", debounce)
        self._ring = np.zeros((2 * self.window_steps, *FRAME_SHAPE), dtype=np.float32)
        # a scorer that keeps its own per-frame state (monitor.incremental) sees every frame
        self._incremental = callable(getattr(scorer, "push_frame", None))
        self.reset()

    @property
    def constants(self) -> MonitorConstants:
        """The scorer's normalisation, threshold and window."""
        return self.scorer.constants

    @property
    def frames_seen(self) -> int:
        """Frames pushed since the last reset."""
        return self._count

    @property
    def warning(self) -> bool:
        """The debounced warning as of the last frame."""
        return self._warning

    def reset(self) -> None:
        """Forget every frame (a new grasp episode)."""
        self._ring.fill(0.0)
        if self._incremental:
            self.scorer.reset()
        self._count = 0
        self._wait = 0  # frames until the next score once the buffer is full
        self._above = 0  # consecutive scores at or above the threshold
        self._warning = False

    def push(self, frame: Any) -> MonitorStep:
        """Take one raw frame (5, 2) [N]: (normal, shear) per fingertip in eq. 19's order."""
        x = np.asarray(frame, dtype=np.float32)
        if x.shape != FRAME_SHAPE:
            raise MonitorError(
                f"a frame is one time step of forces with shape {FRAME_SHAPE} (fingertips in eq. "
                f"19's order x (normal, shear), newtons); got shape {x.shape}"
            )
        if not np.isfinite(x).all():
            raise MonitorError(f"frame {self._count} has a non-finite force: {x.tolist()}")
        return self._step(x)

    def _step(self, x: np.ndarray) -> MonitorStep:
        w = self.window_steps
        if self._incremental:
            self.scorer.push_frame(x)
        else:
            slot = self._count % w
            self._ring[slot] = x
            self._ring[slot + w] = x
        self._count += 1
        if self._count < w:
            return MonitorStep(None, False)
        if self._wait:
            self._wait -= 1
            return MonitorStep(None, self._warning)
        self._wait = self.stride - 1
        if self._incremental:
            prob = self.scorer.score_window()
        else:
            start = self._count % w
            prob = self.scorer.score_one(self._ring[start : start + w])
        self._above = self._above + 1 if prob >= self.threshold else 0
        self._warning = self._above >= self.debounce
        return MonitorStep(prob, self._warning)

    def push_many(self, frames: Any) -> MonitorTrace:
        """Push a run of raw frames (T, 5, 2), continuing from the current state."""
        x = check_trace(frames, first=self._count)
        prob = np.full(len(x), np.nan)
        warning = np.zeros(len(x), dtype=bool)
        for t in range(len(x)):
            step = self._step(x[t])
            if step.prob is not None:
                prob[t] = step.prob
            warning[t] = step.warning
        return MonitorTrace(prob, warning)

    def run(self, trace: Any) -> MonitorTrace:
        """Monitor a whole trace (T, 5, 2) from an empty buffer (resets first)."""
        self.reset()
        return self.push_many(trace)


def scored_frames(frames: int, window_steps: int, stride: int) -> np.ndarray:
    """The frames a monitor scores on a trace of ``frames`` frames: the one that fills the buffer
    (``window_steps - 1``) and every ``stride``-th after it."""
    w, s = check_positive("window_steps", window_steps), check_positive("stride", stride)
    return np.arange(w - 1, frames, s, dtype=np.int64)


def debounced(unstable: np.ndarray, debounce: int) -> np.ndarray:
    """The warning after each score: up while the last ``debounce`` scores were all unstable."""
    flags = np.asarray(unstable, dtype=bool)
    steps = np.arange(len(flags))
    last_stable = np.maximum.accumulate(np.where(flags, -1, steps)) if len(flags) else steps
    run = steps - last_stable  # consecutive unstable scores up to and including each one
    return run >= check_positive("debounce", debounce)


def held(frames: np.ndarray, state: np.ndarray, length: int) -> np.ndarray:
    """Per-frame warning over ``length`` frames from the warning ``state`` after each scored frame
    (``frames``, ascending): it keeps its value on the frames between two scores, False before
    the first."""
    if not len(frames):
        return np.zeros(length, dtype=bool)
    last = np.searchsorted(frames, np.arange(length), side="right") - 1
    return np.where(last >= 0, state[np.maximum(last, 0)], False)


def score_trace(
    scorer: WindowScorer,
    trace: Any,
    *,
    threshold: float | None = None,
    stride: int = 1,
    debounce: int = 1,
    batch_size: int = 4096,
) -> MonitorTrace:
    """What :meth:`StreamingMonitor.run` gives on ``trace`` (T, 5, 2), scored in batches: the same
    frames scored, the same windows, the same warning rule (tests), at a fraction of the cost of
    one call per frame. For evaluating many replays offline; a controller pushes frames."""
    x = check_trace(trace)
    cut = check_threshold(scorer.constants.threshold if threshold is None else threshold)
    w = scorer.constants.window_steps
    frames = scored_frames(len(x), w, stride)
    probs = np.zeros(len(frames), dtype=np.float64)
    size = check_positive("batch_size", batch_size)
    # (T - W + 1, 5, 2, W) views of every full window, no copy (none when T < W)
    views = np.lib.stride_tricks.sliding_window_view(x, w, axis=0) if len(frames) else x
    for lo in range(0, len(frames), size):
        rows = frames[lo : lo + size] - (w - 1)
        probs[lo : lo + size] = scorer(np.moveaxis(views[rows], -1, 1))
    prob = np.full(len(x), np.nan)
    prob[frames] = probs
    warning = held(frames, debounced(probs >= cut, debounce), len(x))
    return MonitorTrace(prob, warning)
