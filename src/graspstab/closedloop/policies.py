"""The policies the closed loop compares on the same grasps, and the reflex each one drives.

``none``: no reflex (the open-loop replay). ``always``: tighten at arming (the force-hungry upper
bound on holding). ``oracle``: tighten ``lead_s`` before the no-reflex run's failure onset (the
labelling horizon when None; never on a grasp that holds): one per lead of
``closed_loop.oracle_leads_s``, named ``oracle-<ms>ms``, the best a warning that early can do.
``load_onset``: tighten when the protocol's load starts (a controller that knows the
disturbance: the bound of a perfect detector of the load, not of slip; never under gravity
alone). ``monitor``: a streaming monitor (a learned family, the learned pick or the
friction-ratio proxy) warns and the reflex acts after the delay plus the monitor's latency.
``shuffled`` (``<monitor>~shuffled``): that monitor's own tightening times, counted from
arming, dealt to other grasps of the same run: what its timing alone would buy.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from graspstab.closedloop.reflex import GripReflex, ReflexParams
from graspstab.monitor.scoring import WindowScorer
from graspstab.monitor.stream import StreamingMonitor

KINDS = ("none", "always", "oracle", "monitor", "load_onset", "shuffled")
#: the policy names that are not monitors (closed_loop.policies)
FIXED = ("none", "always", "oracle", "load_onset")
SHUFFLED = "~shuffled"  # suffix of a monitor's shuffled-timing control
BUDGET = "-budget"  # suffix of a monitor at its false-warning budget threshold
#: the monitors with a budget threshold (the grasp-level evaluation's: the families and the
#: proxy at monitor.window_s; the pick is an export it does not score)
BUDGETED = ("proxy", "cnn", "gru", "lstm")


def oracle_name(lead_s: float) -> str:
    """The row label of the oracle tightening ``lead_s`` before the onset."""
    return f"oracle-{round(1000 * lead_s)}ms"


def policy_names(names: list[str], oracle_leads_s: list[float] | None = None,
                 shuffled: bool = False,
                 thresholds: tuple[str, ...] | list[str] = ("recall",)) -> list[str]:  # fmt: skip
    """The row labels a run's ``closed_loop.policies`` give: ``oracle`` one per lead (kept as
    ``oracle`` without leads); each monitor at each of ``thresholds`` (``recall``: its own name;
    ``budget``: ``<name>-budget``, for the monitors in ``BUDGETED``); and with ``shuffled`` each
    monitor's shuffled control after them."""
    out: list[str] = []
    monitors: list[str] = []
    for name in names:
        if name == "oracle" and oracle_leads_s:
            out += [oracle_name(x) for x in oracle_leads_s]
        elif name in FIXED:
            out.append(name)
        else:
            mine = ([name] if "recall" in thresholds else []) + (
                [f"{name}{BUDGET}"] if "budget" in thresholds and name in BUDGETED else [])
            out += mine
            monitors += mine
    if shuffled:
        out += [f"{n}{SHUFFLED}" for n in monitors]
    return out


@dataclass(frozen=True)
class Policy:
    """One policy: its name in the tables, its kind and, for a monitor, the scorer, the
    validation-selected threshold and the measured per-score latency [s]."""

    name: str
    kind: str
    scorer: WindowScorer | None = None
    threshold: float | None = None
    latency_s: float = 0.0
    lead_s: float | None = None  # oracle: how long before the onset (None: the horizon)
    of: str | None = None  # shuffled: the monitor policy whose tightening times it deals out
    at_floor: bool = False  # a budget threshold at its grid's floor (the budget did not bind)
    never_warns: bool = False  # a budget threshold above every validation score

    def __post_init__(self) -> None:
        if self.kind not in KINDS:
            raise ValueError(f"policy {self.name!r}: kind {self.kind!r} is not one of "
                             f"{', '.join(KINDS)}")  # fmt: skip
        if (self.kind == "monitor") != (self.scorer is not None):
            raise ValueError(f"policy {self.name!r}: a monitor policy needs a scorer, "
                             "and only a monitor policy takes one")  # fmt: skip
        if (self.kind == "shuffled") != (self.of is not None):
            raise ValueError(f"policy {self.name!r}: a shuffled control names the monitor it "
                             "shuffles, and only a shuffled control does")  # fmt: skip


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
    fresh: bool = False,
    load_step: int | None = None,
    fire_step: int | None = None,
) -> GripReflex | None:
    """The reflex ``policy`` drives on one grasp (None for no reflex, and for a schedule with
    nothing to fire at: the oracle on a grasp without an onset, the load-onset control without a
    load, a shuffled control dealt a grasp whose monitor never tightened). ``onset``: the
    no-reflex run's failure onset (the oracles' cue; ``oracle_lead_steps`` their lead when the
    policy has none); ``arm_step``: where every monitor is armed and ``always`` fires;
    ``fresh``: a monitor's warning up at arming counts only once it has dropped;
    ``load_step``: the load's first step; ``fire_step``: the shuffled control's step."""
    common = {"params": params, "closing": closing, "upper": upper, "dt": dt}
    if policy.kind == "none":
        return None
    if policy.kind == "always":
        return GripReflex(**common, fire_at=arm_step)
    if policy.kind == "oracle":
        lead = oracle_lead_steps if policy.lead_s is None else round(policy.lead_s / dt)
        return None if onset is None else GripReflex(
            **common, fire_at=max(0, onset - lead))  # fmt: skip
    if policy.kind == "load_onset":
        return None if load_step is None else GripReflex(**common, fire_at=load_step)
    if policy.kind == "shuffled":
        return None if fire_step is None else GripReflex(**common, fire_at=fire_step)
    monitor = StreamingMonitor.from_scorer(policy.scorer, threshold=policy.threshold,
                                           stride=stride, debounce=debounce)  # fmt: skip
    return GripReflex(**common, monitor=monitor, latency_s=policy.latency_s, arm_step=arm_step,
                      fresh=fresh)  # fmt: skip
