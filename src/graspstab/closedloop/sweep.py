"""The reflex's settings swept one at a time around the defaults, for the trade-off between drops
prevented and false alarms or added force: each setting is a *variant*, one row label in the
closed-loop tables."""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

from graspstab.closedloop.policies import Policy
from graspstab.closedloop.reflex import ReflexParams

#: the swept parameters: the reflex's own, the monitor's debounce and threshold, the arming time
PARAMETERS = ("amount", "rate", "delay_s", "debounce", "threshold_scale", "arm_s")


@dataclass(frozen=True)
class Variant:
    """One policy under one reflex setting; ``parameter`` and ``value`` name the setting that
    differs from the defaults ("" and NaN: the defaults themselves)."""

    label: str
    policy: Policy
    reflex: ReflexParams
    debounce: int
    arm_s: float
    parameter: str = ""
    value: float = math.nan


def default_variant(policy: Policy, reflex: ReflexParams, debounce: int, arm_s: float) -> Variant:
    """The policy under the run's own settings, labelled with the policy's name."""
    return Variant(policy.name, policy, reflex, debounce, arm_s)


def sweep_variants(
    policies: Sequence[Policy],
    sweep: Mapping[str, Sequence[float]],
    reflex: ReflexParams,
    debounce: int,
    arm_s: float,
) -> list[Variant]:
    """Every policy under every swept value, one parameter away from the defaults, labelled
    ``<policy>@<parameter>=<value>``. ``threshold_scale`` multiplies the policy's validation
    threshold (capped at 1)."""
    unknown = sorted(set(sweep) - set(PARAMETERS))
    if unknown:
        raise ValueError(f"closed_loop.sweep: unknown parameter(s) {', '.join(unknown)}; "
                         f"valid: {', '.join(PARAMETERS)}")  # fmt: skip
    out = []
    for policy in policies:
        if policy.kind != "monitor" and any(sweep.get(p) for p in ("debounce", "threshold_scale")):
            raise ValueError(
                f"closed_loop.sweep: policy {policy.name!r} has no monitor, so its debounce and "
                "threshold cannot be swept; sweep monitors only"
            )
        for parameter in PARAMETERS:
            for value in sweep.get(parameter, ()):
                v: dict[str, Any] = {"policy": policy, "reflex": reflex, "debounce": debounce,
                                     "arm_s": arm_s}  # fmt: skip
                if parameter in ("amount", "rate", "delay_s"):
                    v["reflex"] = dataclasses.replace(reflex, **{parameter: float(value)})
                elif parameter == "debounce":
                    v["debounce"] = int(value)
                elif parameter == "arm_s":
                    v["arm_s"] = float(value)
                else:
                    scaled = min(1.0, float(policy.threshold) * float(value))
                    v["policy"] = dataclasses.replace(policy, threshold=scaled)
                out.append(Variant(f"{policy.name}@{parameter}={value:g}", parameter=parameter,
                                   value=float(value), **v))  # fmt: skip
    return out
