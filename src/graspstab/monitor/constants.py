"""The numbers a deployed model needs beside its weights: normalisation, threshold, window.

A model of the learning stage scores *normalised* windows; a controller has raw forces. These
constants turn one into the other and a probability into a decision, so they travel with every
monitor and every exported file (as a JSON sidecar and embedded in the file itself).
"""

from __future__ import annotations

import json
import math
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from graspstab.common.errors import GraspstabError
from graspstab.common.io import read_json, write_json

FINGERTIPS = 5
CHANNELS = ("normal", "shear")  # the window tensor's last axis (labels.dataset.CHANNELS)
FRAME_SHAPE = (FINGERTIPS, len(CHANNELS))
FORMAT = "graspstab.monitor/1"


class MonitorError(ValueError, GraspstabError):
    """Inputs a monitor cannot be built from or fed (wrong shapes, contradicting files)."""


def as_stat(name: str, value: Any) -> np.ndarray:
    """A (5, 2) per fingertip x channel statistic as float64, checked (shape, finite)."""
    arr = np.asarray(value, dtype=np.float64)
    if arr.shape != FRAME_SHAPE:
        raise MonitorError(
            f"{name} must have shape {FRAME_SHAPE} (fingertips x (normal, shear)), the shape of "
            f"normalisation.json's mean/std; got {arr.shape}"
        )
    if not np.isfinite(arr).all():
        raise MonitorError(f"{name} must be finite; got {arr.tolist()}")
    return arr


def check_threshold(threshold: Any) -> float:
    """A decision threshold in [0, 1] (None or NaN means the run left it undefined)."""
    if threshold is None or not math.isfinite(float(threshold)):
        raise MonitorError(
            f"the decision threshold is undefined ({threshold!r}); pass threshold= explicitly"
        )
    value = float(threshold)
    if not 0.0 <= value <= 1.0:
        raise MonitorError(f"the decision threshold must lie in [0, 1]; got {value}")
    return value


def check_positive(name: str, value: Any) -> int:
    """A positive integer parameter (window steps, stride, debounce)."""
    try:
        ok = not isinstance(value, bool) and int(value) == value and int(value) >= 1
    except (TypeError, ValueError):
        ok = False
    if not ok:
        raise MonitorError(f"{name} must be a positive integer; got {value!r}")
    return int(value)


@dataclass(frozen=True, eq=False)
class MonitorConstants:
    """Normalisation (eq. 32's training mean/std, (5, 2)), threshold and window of one model."""

    mean: np.ndarray
    std: np.ndarray
    threshold: float
    window_steps: int
    family: str | None = None
    model: Mapping[str, Any] = field(default_factory=dict)  # the model spec, for provenance

    def __post_init__(self) -> None:
        std = as_stat("std", self.std)
        if (std <= 0).any():
            raise MonitorError(f"std must be positive (it divides); got {std.tolist()}")
        object.__setattr__(self, "mean", as_stat("mean", self.mean))
        object.__setattr__(self, "std", std)
        object.__setattr__(self, "threshold", check_threshold(self.threshold))
        object.__setattr__(self, "window_steps", check_positive("window_steps", self.window_steps))
        object.__setattr__(self, "model", dict(self.model))

    def to_dict(self) -> dict[str, Any]:
        """Plain JSON-ready form (what the sidecar and the embedded metadata hold)."""
        return {
            "format": FORMAT,
            "family": self.family,
            "model": dict(self.model),
            "window_steps": self.window_steps,
            "threshold": self.threshold,
            "mean": self.mean.tolist(),
            "std": self.std.tolist(),
            "axes": "fingertip (eq. 19 order) x channel",
            "channels": list(CHANNELS),
            "units": "N",
            "input": "raw forces (B, window_steps, 5, 2), float32; normalised inside the model",
            "output": "instability probability (B,); unstable when prob >= threshold",
        }

    @classmethod
    def from_dict(cls, data: Mapping[str, Any], source: str = "constants") -> MonitorConstants:
        """Rebuild from :meth:`to_dict`'s form; a missing key or other format names ``source``."""
        if data.get("format") != FORMAT:
            raise MonitorError(f"{source}: not a {FORMAT} record (format {data.get('format')!r})")
        missing = [k for k in ("mean", "std", "threshold", "window_steps") if k not in data]
        if missing:
            raise MonitorError(f"{source}: missing {missing}")
        return cls(
            mean=data["mean"], std=data["std"], threshold=data["threshold"],
            window_steps=data["window_steps"], family=data.get("family"),
            model=data.get("model") or {},
        )  # fmt: skip

    def to_json(self) -> str:
        """Compact JSON text (for embedding in a model file)."""
        return json.dumps(self.to_dict(), sort_keys=True)


def write_constants(
    path: str | Path, constants: MonitorConstants, extra: Mapping[str, Any] | None = None
) -> None:
    """Write the JSON sidecar atomically (``extra``, e.g. provenance, is stored beside)."""
    write_json(path, {**dict(extra or {}), **constants.to_dict()})


def read_constants(path: str | Path) -> MonitorConstants:
    """Read a sidecar written by :func:`write_constants`."""
    return MonitorConstants.from_dict(read_json(path), source=str(path))
