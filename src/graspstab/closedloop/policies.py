"""The policies the closed loop compares on the same grasps, and the reflex each one drives.

``none``: no reflex (the open-loop replay). ``always``: tighten from the first step (the
force-hungry upper bound on holding). ``oracle``: tighten at the no-reflex run's failure onset
minus ``oracle_lead_s`` (the labelling horizon by default; never on a grasp that holds), the best
any warning can do. ``monitor``: a streaming monitor (a learned family, the learned pick or the
friction-ratio proxy) warns and the reflex acts after the delay plus the monitor's latency.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from graspstab.closedloop.reflex import GripReflex, ReflexParams
from graspstab.monitor.scoring import WindowScorer
from graspstab.monitor.stream import StreamingMonitor

KINDS = ("none", "always", "oracle", "monitor")


@dataclass(frozen=True)
class Policy:
    """One policy: its name in the tables, its kind and, for a monitor, the scorer, the
    validation-selected threshold and the measured per-score latency [s]."""

    name: str
    kind: str
    scorer: WindowScorer | None = None
    threshold: float | None = None
    latency_s: float = 0.0

    def __post_init__(self) -> None:
        if self.kind not in KINDS:
            raise ValueError(f"policy {self.name!r}: kind {self.kind!r} is not one of "
                             f"{', '.join(KINDS)}")  # fmt: skip
        if (self.kind == "monitor") != (self.scorer is not None):
            raise ValueError(f"policy {self.name!r}: a monitor policy needs a scorer, "
                             "and only a monitor policy takes one")  # fmt: skip


def actuator_axes(scene: Any, nu: int) -> tuple[np.ndarray, np.ndarray]:
    """(nu,) 1 on the actuators of the closing joints (``replay.squeeze.joints``), else 0, and
    (nu,) every actuator's upper target limit (inf where it has none)."""
    closing, upper = np.zeros(nu), np.full(nu, np.inf)
    closing[scene.finger_ctrl] = scene.closing
    upper[scene.finger_ctrl] = scene.ctrl_range[:, 1]
    return closing, upper


def make_reflex(
    policy: Policy,
    params: ReflexParams,
    closing: np.ndarray,
    upper: np.ndarray,
    dt: float,
    *,
    onset: int | None = None,
    oracle_lead_steps: int = 0,
    arm_step: int = 0,
    stride: int = 1,
    debounce: int = 1,
) -> GripReflex | None:
    """The reflex ``policy`` drives on one grasp (None for no reflex, and for the oracle on a
    grasp without an onset). ``onset``: the no-reflex run's failure onset (the oracle's cue)."""
    common = {"params": params, "closing": closing, "upper": upper, "dt": dt}
    if policy.kind == "none":
        return None
    if policy.kind == "always":
        return GripReflex(**common, fire_at=0)
    if policy.kind == "oracle":
        return None if onset is None else GripReflex(
            **common, fire_at=max(0, onset - oracle_lead_steps))  # fmt: skip
    monitor = StreamingMonitor.from_scorer(policy.scorer, threshold=policy.threshold,
                                           stride=stride, debounce=debounce)  # fmt: skip
    return GripReflex(**common, monitor=monitor, latency_s=policy.latency_s, arm_step=arm_step)
