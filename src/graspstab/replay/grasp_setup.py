"""Per-grasp replay settings shared by the replay job and the closed loop, so both replay the
same physics: the grasp's load ramp (or none under gravity alone, 3.2) and the stop rule for
deep penetration. The closed loop imports this module, never the replay stage's entry point."""

from __future__ import annotations

import zlib
from typing import Any

import numpy as np

from graspstab.replay.ramp import RampLoad, ramp_direction, ramp_load
from graspstab.replay.run import DeepStop


def grasp_load(
    params: dict[str, Any], scene: Any, gravity_hand: np.ndarray, object_id: str, grasp_id: int
) -> RampLoad | None:
    """The load ramp of one grasp (simulation frame = hand frame), or None under gravity alone
    (3.2, the reference's protocol). The direction is drawn from the grasp's own stream."""
    if params["protocol"] == "gravity":
        return None
    ramp = params["ramp"]
    seq = np.random.SeedSequence([int(ramp["seed"]), zlib.crc32(object_id.encode()), grasp_id])
    direction = ramp_direction(ramp["directions"], gravity_hand, np.random.default_rng(seq))
    weight = float(scene.model.body_subtreemass[scene.object_body]) * float(
        np.linalg.norm(gravity_hand)
    )
    return ramp_load(ramp, direction, weight, float(params["timestep"]))


def deep_stop(params: dict[str, Any]) -> DeepStop | None:
    """The ``too_deep`` stop rule of ``params["deep_stop"]`` in steps (None when disabled)."""
    rule, dt = params["deep_stop"], float(params["timestep"])
    if not rule["enabled"]:
        return None
    return DeepStop(float(rule["depth"]), max(1, round(float(rule["seconds"]) / dt)),
                    round(float(rule["after_s"]) / dt))  # fmt: skip
