"""Sensor augmentation for training (our extension): each training window, every epoch, comes
through one sensor condition drawn at random from the robustness study's (a corruption at one of
its strengths, or a preset), so a model sees what a real sensor would deliver. Validation and
test windows stay clean: epochs are selected as in 3.5.2."""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np

from graspstab.labels.trace_windows import trace_map
from graspstab.learning.data import WindowData
from graspstab.sensing.conditions import conditions
from graspstab.sensing.segments import window_segments
from graspstab.sensing.sensor_model import SensorModel, sense


class SensorAugmentation:
    """Raw training windows through randomly drawn sensors (``WindowData.augment``)."""

    def __init__(
        self,
        data: WindowData,
        sensors: Sequence[SensorModel],
        traces: Mapping[tuple[str, int], str],
        dt: float,
        seed: int,
        clean_share: float = 0.0,
    ) -> None:
        if not sensors:
            raise ValueError("sensor augmentation needs at least one sensor condition")
        if not 0 <= clean_share < 1:
            raise ValueError(f"clean_share {clean_share} must be in [0, 1)")
        self.sensors = list(sensors)
        self.clean_share = float(clean_share)
        self.dt = float(dt)
        self.scale = np.asarray(data.std)
        self.window_steps = data.window_steps
        rows = data.rows("train")
        context = max(s.context_frames(dt) for s in self.sensors)
        self.position = np.full(len(data.index), -1, dtype=np.int64)
        self.position[rows] = np.arange(len(rows))
        self.segments = window_segments(data.index[rows], traces, data.window_steps, context)
        self.rng = np.random.default_rng(np.random.SeedSequence([int(seed), 0xA06]))

    def __call__(self, rows: np.ndarray) -> np.ndarray:
        """Raw (un-normalised) windows of training ``rows``, each through its own drawn sensor
        (or clean with probability ``clean_share``)."""
        pos = self.position[rows]
        if (pos < 0).any():
            raise ValueError("sensor augmentation applies to training rows only")
        seg = self.segments[pos]
        out = np.array(seg[:, -self.window_steps :], dtype=np.float32)
        draw = self.rng.integers(0, len(self.sensors), size=len(rows))
        clean = self.rng.random(len(rows)) < self.clean_share
        for k in np.unique(draw[~clean]):
            pick = np.flatnonzero((draw == k) & ~clean)
            out[pick] = sense(self.sensors[k], seg[pick], self.window_steps, self.scale,
                              self.dt, self.rng)  # fmt: skip
        return out


def augmentation_sensors(sensing: Mapping[str, Any]) -> list[SensorModel]:
    """Every non-clean condition of the robustness study (curves and presets)."""
    return [c["sensor"] for c in conditions(sensing) if c["kind"] != "clean"]


def attach(data: WindowData, sensing: Mapping[str, Any], trace_paths: Sequence[str],
           trace_keys: Sequence[tuple[str, int]], dt: float, seed: int) -> WindowData:  # fmt: skip
    """``data`` with its training batches augmented by the study's sensors."""
    data.augment = SensorAugmentation(
        data, augmentation_sensors(sensing), trace_map(list(trace_paths), list(trace_keys)), dt,
        seed, float(sensing["augment"]["clean_share"]),
    )  # fmt: skip
    return data
