"""The grip reflex: when the monitor warns, the closing joints' targets move further in.

A controller in the replay's loop (``replay.run.Controller``). It reads the fingertip forces the
way a controller on the hand would: causally, every frame pushed into a streaming monitor after
the step that recorded it. A warning raised at frame ``t`` (the reading of step ``t``) acts from
step ``t + 1 + delay``, ``delay`` being the sensing-to-actuation delay plus the monitor's per-score
latency, in steps. From then on the closing joints' targets move in at ``rate`` up to ``amount``
[rad] past the open-loop targets (never past a joint's upper limit). Release rules: ``never``
(tightened for the rest of the episode) or ``calm`` (once the warning has been down for
``release_s``, the targets return at the same rate; a new warning tightens again).

Causality sets the chunking: every warning from frames before step ``first`` is known when the
chunk from ``first`` is planned, and one from a later frame acts at ``first + 1 + delay`` at the
earliest, so a chunk of ``delay + 1`` steps never needs a decision it has not seen. Python runs
once a chunk, not once a step. Without a monitor (``fire_at`` given) the reflex is a fixed
schedule: the "always tighten" and "oracle" policies. An ``arm_step`` ignores warnings on
earlier frames (the monitor still reads them); with ``fresh``, a warning already up at the arm
step does not count either until it has dropped and risen again (only a warning raised after
arming fires: one the monitor carries over from the settling transient is not a prediction).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np

#: what ends a tightening: nothing, or a warning that has stayed down ``release_s``
RELEASE_RULES = ("never", "calm")


@dataclass(frozen=True)
class ReflexParams:
    """The reflex's parameters (config group ``closed_loop.reflex``)."""

    amount: float  # [rad] how far past the open-loop targets the closing joints move
    rate: float  # [rad/s] how fast they move there (and back, on release)
    delay_s: float  # [s] sensing-to-actuation delay, on top of the monitor's latency
    release: str = "never"
    release_s: float = 0.5  # [s] rule calm: the warning down this long releases the grip

    def __post_init__(self) -> None:
        for name in ("amount", "rate", "delay_s", "release_s"):
            value = getattr(self, name)
            if not np.isfinite(value) or value < 0 or (name == "rate" and value == 0):
                bound = ">= 0" + (" and > 0" if name == "rate" else "")
                raise ValueError(f"closed_loop.reflex.{name} must be finite {bound}, got {value}")
        if self.release not in RELEASE_RULES:
            raise ValueError(f"closed_loop.reflex.release must be one of "
                             f"{', '.join(RELEASE_RULES)}, got {self.release!r}")  # fmt: skip


def delay_steps(delay_s: float, latency_s: float, dt: float) -> int:
    """The delay from a warning's frame to the first step it may act on, in whole steps beyond
    the next one (a delay shorter than a step still acts one step later, never the same step)."""
    return max(0, int(np.ceil((delay_s + latency_s) / dt - 1e-9)))


@dataclass
class GripReflex:
    """One episode's reflex. ``monitor``: a ``monitor.stream.StreamingMonitor`` (reset here) or
    None with ``fire_at`` the step the reflex acts at (a fixed schedule; None: never).
    ``closing``: (nu,) 1 on the actuators the reflex moves in, else 0; ``upper``: (nu,) their
    target limits [rad]."""

    params: ReflexParams
    closing: np.ndarray
    upper: np.ndarray
    dt: float
    monitor: Any = None
    latency_s: float = 0.0
    fire_at: int | None = None
    arm_step: int = 0  # warnings on earlier frames are ignored (one up at it rises there)
    fresh: bool = False  # a warning up at arm_step counts only after it drops and rises again
    # what happened: the steps a tightening started and a release started, and the warnings' frames
    on_steps: list[int] = field(default_factory=list)
    off_steps: list[int] = field(default_factory=list)
    warn_frames: list[int] = field(default_factory=list)

    def __post_init__(self) -> None:
        self.closing = np.asarray(self.closing, dtype=np.float64)
        self.upper = np.asarray(self.upper, dtype=np.float64)
        if self.closing.shape != self.upper.shape:
            raise ValueError(f"closing {self.closing.shape} and upper {self.upper.shape} differ")
        if self.monitor is not None and self.fire_at is not None:
            raise ValueError("a reflex is driven by a monitor or by a fixed step, not both")
        self.delay = delay_steps(self.params.delay_s, self.latency_s, self.dt)
        self._step = self.params.rate * self.dt  # target change per step [rad]
        self._events: list[tuple[int, int]] = []  # (step, +1 tighten / -1 release), in order
        self._offset, self._offset_at, self._dir = 0.0, 0, 0  # offset before step _offset_at
        self._warning = False
        self._down_since: int | None = None
        self._stale = self.fresh  # fresh: ignore the warning until it is first seen down
        if self.monitor is not None:
            self.monitor.reset()
        if self.fire_at is not None:
            self._schedule(int(self.fire_at), +1)

    @property
    def live(self) -> bool:
        """Whether a frame not yet seen could still change the targets."""
        if self.monitor is None:
            return False
        return self.params.release == "calm" or not self.on_steps

    def _schedule(self, step: int, direction: int) -> None:
        if step < self._offset_at:  # the chunking guarantees this never happens
            raise RuntimeError(f"reflex event at step {step}, after step {self._offset_at} ran")
        (self.on_steps if direction > 0 else self.off_steps).append(step)
        self._events.append((step, direction))

    def skip_to(self, step: int) -> None:
        """Start at step ``step`` with the targets untouched (a replay continued from a fork):
        only a fixed schedule acting at or after it can, since a monitor would miss the frames
        before it."""
        if self.monitor is not None:
            raise ValueError("a monitor-driven reflex cannot start mid-replay: its monitor would "
                             "miss the earlier frames; fork a fixed schedule instead")
        if self._offset_at != 0 or any(e[0] < step for e in self._events):
            raise ValueError(f"the reflex acts before step {step} or has already run")
        self._offset_at = step

    def chunk_steps(self, first: int, default: int) -> int:
        """``delay + 1`` steps while a warning could still act, else ``default``."""
        return min(default, self.delay + 1) if self.live else default

    def offsets(self, first: int, n: int) -> np.ndarray:
        """The target offset [rad] at steps ``first .. first + n - 1`` (chunks in order): it moves
        by ``rate * dt`` a step (in while tightening, out while releasing), within [0, amount]."""
        if first != self._offset_at:
            raise ValueError(f"offsets asked from step {first}, expected {self._offset_at}")
        out = np.empty(n)
        offset, direction, at = self._offset, self._dir, 0
        inside = [e for e in self._events if first <= e[0] < first + n]
        for step, change in [*inside, (first + n, 0)]:
            end = step - first
            if end > at:
                span = np.arange(1, end - at + 1)
                out[at:end] = np.clip(offset + direction * self._step * span, 0.0,
                                      self.params.amount)  # fmt: skip
                offset = float(out[end - 1])
            at = end
            direction = change or direction
        self._offset, self._offset_at, self._dir = offset, first + n, direction
        return out

    def targets(self, first: int, n: int, ctrl: np.ndarray) -> np.ndarray:
        """The open-loop targets plus the offset along the closing actuators, capped at their
        limits (a target already beyond its limit stays where it was)."""
        base = np.asarray(ctrl, dtype=np.float64)
        moved = base[None] + self.offsets(first, n)[:, None] * self.closing[None]
        return np.where(self.closing[None] > 0, np.minimum(moved, np.maximum(self.upper, base)),
                        base[None])  # fmt: skip

    def observe(self, first: int, normal: np.ndarray, shear: np.ndarray) -> None:
        """Push the chunk's frames into the monitor; schedule what its warnings ask for."""
        if not self.live:
            return
        trace = self.monitor.push_many(np.stack([normal, shear], axis=-1))
        for k, raw in enumerate(trace.warning):
            frame = first + k
            up = bool(raw) and frame >= self.arm_step
            if self._stale and frame >= self.arm_step:
                if up:
                    up = False  # still the warning that was up at arming
                else:
                    self._stale = False
            if up and not self._warning:
                self.warn_frames.append(frame)
                self._down_since = None
                tightened = len(self.on_steps) > len(self.off_steps)
                if not tightened:
                    self._schedule(frame + 1 + self.delay, +1)
            elif not up and self._warning:
                self._down_since = frame
            if (
                self.params.release == "calm"
                and not up
                and self._down_since is not None
                and len(self.on_steps) > len(self.off_steps)
                and frame - self._down_since + 1 >= round(self.params.release_s / self.dt)
            ):
                self._schedule(frame + 1 + self.delay, -1)
                self._down_since = None
            self._warning = bool(up)
            if not self.live:
                return
