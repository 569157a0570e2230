"""Sensor augmentation for training (our extension): each training window, every epoch, comes
through one sensor condition drawn at random from the robustness study's, so a model sees what a
real sensor would deliver. Validation and test windows stay clean: epochs are selected as in 3.5.2.

Two readings of "trained with the corruption as augmentation" (``sensing.augment.modes``):
``mixture`` draws from every curve's strengths and every preset (one model for all sensors); a
corruption's name draws from that curve's strengths only (one model per corruption)."""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np

from graspstab.labels.trace_windows import trace_map
from graspstab.learning.data import WindowData
from graspstab.sensing.conditions import MIXTURE, conditions
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


def augmentation_sensors(sensing: Mapping[str, Any], mode: str = MIXTURE) -> list[SensorModel]:
    """The conditions a mode draws from: every non-clean one of the study (curves and presets)
    for ``mixture``, else the named corruption's curve."""
    conds = [c for c in conditions(sensing) if c["kind"] != "clean"]
    if mode != MIXTURE:
        conds = [c for c in conds if c["kind"] == "curve" and c["corruption"] == mode]
        if not conds:
            raise ValueError(
                f"sensing.augment.modes: {mode!r} names no curve of sensing.curves (curves: "
                f"{list(sensing['curves'])}); add its strengths there or use {MIXTURE!r}"
            )
    return [c["sensor"] for c in conds]


def attach(data: WindowData, sensing: Mapping[str, Any], trace_paths: Sequence[str],
           trace_keys: Sequence[tuple[str, int]], dt: float, seed: int) -> WindowData:  # fmt: skip
    """``data`` with its training batches augmented by the study's sensors."""
    mode = str(sensing["augment"].get("mode", MIXTURE))
    data.augment = SensorAugmentation(
        data, augmentation_sensors(sensing, mode), trace_map(list(trace_paths), list(trace_keys)),
        dt, seed, float(sensing["augment"]["clean_share"]),
    )  # fmt: skip
    return data
