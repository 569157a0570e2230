"""A fingertip force sensor between the simulator and the models (our extension; the reference's
5.3 names noise, calibration drift and latency as what its clean features lack).

The sensor reads a force segment ``x`` of shape ``(B, T, F, C)`` on the simulator's grid (``dt``)
and reports, on the same grid, what a real sensor would have delivered:

1. a fixed delay of ``round(delay_s / dt)`` frames (the reading at ``t`` is the force at
   ``t - d``);
2. a gain error per window, fingertip and channel, ``1 + gain * N(0, 1)`` (calibration);
3. a bias drift starting at zero at the segment's first frame (the sensor was tared there), its
   rate ``drift * scale * N(0, 1)`` per second per fingertip and channel;
4. white noise of std ``noise * scale``, drawn per sensor sample;
5. quantisation by a ``bits``-bit converter over ``[-full_scale_n, full_scale_n]``: rounded to
   the nearest multiple of ``2 full_scale_n / 2**bits``, clipped to the range;
6. sampling at ``rate_hz`` with a random phase per window and a zero-order hold back onto the
   simulator's grid, so the models, the window lengths and the labels stay as they are and only
   information is lost (feeding the models at the sensor's rate would change their input length
   and, at 60 Hz, leave the 0.01 s window without a sample);
7. dropped samples, each lost with probability ``drop``: the previous delivered sample is held
   (the segment's first frame, its oldest reading, when every earlier sample was lost).

``scale`` is the per fingertip x channel training std of the dataset (its normalisation
statistics), so noise and drift are stated relative to each channel's spread. Every strength
zero (the default) is the identity. All draws come from the generator passed in.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import asdict, dataclass, fields
from typing import Any

import numpy as np

from graspstab.common.errors import GraspstabError

#: The corruptions, each with the field that sets its strength (its "off" value is the default).
CORRUPTIONS = {
    "noise": "noise",
    "gain": "gain",
    "drift": "drift",
    "quantisation": "bits",
    "rate": "rate_hz",
    "delay": "delay_s",
    "drop": "drop",
}


class SensorModelError(ValueError, GraspstabError):
    """A sensor setting out of its range (names the field and how to fix it)."""


@dataclass(frozen=True)
class SensorModel:
    """One sensor's corruptions; every default is "off"."""

    noise: float = 0.0  # additive white noise std, fraction of each channel's training std
    gain: float = 0.0  # std of the relative gain error per fingertip and channel
    drift: float = 0.0  # std of the bias drift rate, channel training stds per second
    bits: int | None = None  # converter resolution; None: no quantisation
    full_scale_n: float = 100.0  # converter range [-full_scale_n, full_scale_n] in newtons
    rate_hz: float | None = None  # sampling rate; None: every simulator frame
    delay_s: float = 0.0  # fixed delay
    drop: float = 0.0  # probability that a sample is lost

    def __post_init__(self) -> None:
        for name in ("noise", "gain", "drift", "delay_s"):
            if not getattr(self, name) >= 0:
                raise SensorModelError(f"sensor {name} = {getattr(self, name)} must be >= 0")
        if not 0 <= self.drop < 1:
            raise SensorModelError(f"sensor drop = {self.drop} must be in [0, 1)")
        if self.bits is not None and (
            isinstance(self.bits, bool)
            or not isinstance(self.bits, int)
            or not 1 <= self.bits <= 32
        ):
            raise SensorModelError(f"sensor bits = {self.bits!r} must be an integer in 1..32 "
                                   "or null (no quantisation)")  # fmt: skip
        if not self.full_scale_n > 0:
            raise SensorModelError(f"sensor full_scale_n = {self.full_scale_n} must be > 0")
        if self.rate_hz is not None and not self.rate_hz > 0:
            raise SensorModelError(f"sensor rate_hz = {self.rate_hz} must be > 0 or null")

    @classmethod
    def from_config(cls, values: Mapping[str, Any] | None) -> SensorModel:
        """A sensor from a config mapping; unknown keys are refused by name."""
        values = dict(values or {})
        known = {f.name for f in fields(cls)}
        unknown = sorted(set(values) - known)
        if unknown:
            raise SensorModelError(f"unknown sensor setting(s) {unknown}; valid: {sorted(known)}")
        bits = values.get("bits")
        if isinstance(bits, float) and bits.is_integer():
            values["bits"] = int(bits)  # a YAML or override "8.0"
        return cls(**values)

    def with_strength(self, corruption: str, value: Any) -> SensorModel:
        """This sensor with one corruption's strength set (``CORRUPTIONS`` names them)."""
        if corruption not in CORRUPTIONS:
            raise SensorModelError(f"unknown corruption {corruption!r}; valid: {list(CORRUPTIONS)}")
        return SensorModel.from_config({**asdict(self), CORRUPTIONS[corruption]: value})

    @property
    def is_identity(self) -> bool:
        """True when the sensor changes nothing (every corruption off)."""
        return (self.noise == 0 and self.gain == 0 and self.drift == 0 and self.bits is None
                and self.rate_hz is None and self.delay_s == 0 and self.drop == 0)  # fmt: skip

    def delay_frames(self, dt: float) -> int:
        """The delay in simulator frames."""
        return int(round(self.delay_s / dt))

    def period_frames(self, dt: float) -> float:
        """Simulator frames per sensor sample (at least 1)."""
        return 1.0 if self.rate_hz is None else max(1.0, 1.0 / (self.rate_hz * dt))

    def context_frames(self, dt: float) -> int:
        """Frames a segment needs before the window so that the delay and two sample periods of
        hold (or of dropped samples) read recorded forces."""
        hold = 2 * math.ceil(self.period_frames(dt)) if self.rate_hz or self.drop else 0
        return self.delay_frames(dt) + hold


def sense(
    sensor: SensorModel,
    segments: np.ndarray,
    window_steps: int,
    scale: np.ndarray,
    dt: float,
    rng: np.random.Generator,
) -> np.ndarray:
    """What the sensor reports over the last ``window_steps`` frames of each segment.

    ``segments`` (B, T, F, C) raw forces on the simulator grid, T >= window_steps (frames before
    the window give the delay and the hold something to read; see ``context_frames``); ``scale``
    (F, C) the channel stds. Returns float32 (B, window_steps, F, C)."""
    x = np.asarray(segments, dtype=np.float64)
    if x.ndim != 4 or x.shape[1] < window_steps:
        raise SensorModelError(
            f"segments must have shape (B, T >= {window_steps}, F, C), got {tuple(x.shape)}"
        )
    b, t, f, c = x.shape
    scale = np.broadcast_to(np.asarray(scale, dtype=np.float64), (f, c))
    if sensor.is_identity:
        return x[:, t - window_steps :].astype(np.float32)
    d = sensor.delay_frames(dt)
    if d:
        x = np.concatenate([np.repeat(x[:, :1], min(d, t), axis=1), x[:, : max(t - d, 0)]], axis=1)
    if sensor.gain:
        x = x * (1.0 + sensor.gain * rng.standard_normal((b, 1, f, c)))
    if sensor.drift:
        rate = sensor.drift * scale * rng.standard_normal((b, 1, f, c))
        x = x + rate * (np.arange(t) * dt)[None, :, None, None]
    if sensor.noise:
        x = x + sensor.noise * scale * rng.standard_normal(x.shape)
    if sensor.bits is not None:
        step = 2.0 * sensor.full_scale_n / 2**sensor.bits
        x = np.clip(np.round(x / step) * step, -sensor.full_scale_n, sensor.full_scale_n)
    if sensor.rate_hz is not None or sensor.drop:
        x = np.take_along_axis(x, _held_frames(sensor, b, t, dt, rng)[:, :, None, None], axis=1)
    return x[:, t - window_steps :].astype(np.float32)


def _held_frames(
    sensor: SensorModel, b: int, t: int, dt: float, rng: np.random.Generator
) -> np.ndarray:
    """(B, T) index of the sample each frame holds: the latest delivered sample instant at or
    before it; frame 0 (the oldest reading the segment has) before any, never a later one."""
    period = sensor.period_frames(dt)
    phase = (
        rng.uniform(0.0, period, size=(b, 1)) if sensor.rate_hz is not None else np.zeros((b, 1))
    )
    instants = np.floor(phase + period * np.arange(math.ceil(t / period) + 1)[None]).astype(int)
    delivered = rng.random(instants.shape) >= sensor.drop
    mask = np.zeros((b, t + 1), dtype=bool)
    rows = np.broadcast_to(np.arange(b)[:, None], instants.shape)
    ok = delivered & (instants < t)
    mask[rows[ok], instants[ok]] = True
    held = np.where(mask[:, :t], np.arange(t)[None], -1)
    return np.maximum(np.maximum.accumulate(held, axis=1), 0)
