"""Per-grasp replay settings shared by the replay job and the closed loop, so both replay the
same physics: the grasp's load ramp (or none under gravity alone, 3.2) and the stop rule for
deep penetration. The closed loop imports this module, never the replay stage's entry point."""

from __future__ import annotations

import zlib
from typing import Any

import numpy as np

from graspstab.replay.ramp import RampLoad, ramp_direction, ramp_load
from graspstab.replay.run import DeepStop
from graspstab.replay.slip import SlipSampler


def grasp_stream(seed: int, object_id: str, grasp_id: int) -> np.random.Generator:
    """The random stream of one grasp's load (SeedSequence of seed, object, grasp)."""
    return np.random.default_rng(
        np.random.SeedSequence([int(seed), zlib.crc32(object_id.encode()), int(grasp_id)])
    )


def grasp_load(
    params: dict[str, Any], scene: Any, gravity_hand: np.ndarray, object_id: str, grasp_id: int
) -> RampLoad | None:
    """The load of one grasp (simulation frame = hand frame), or None under gravity alone (3.2,
    the reference's protocol): the load ramp (``ramp``) or the hidden-onset disturbance
    (``perturb``), drawn from the grasp's own stream and never from anything the replay does."""
    if params["protocol"] == "gravity":
        return None
    weight = float(scene.model.body_subtreemass[scene.object_body]) * float(
        np.linalg.norm(gravity_hand)
    )
    dt = float(params["timestep"])
    if params["protocol"] == "perturb":
        return perturb_load(params["perturb"], gravity_hand, weight, dt, object_id, grasp_id)
    ramp = params["ramp"]
    rng = grasp_stream(ramp["seed"], object_id, grasp_id)
    direction = ramp_direction(ramp["directions"], gravity_hand, rng)
    return ramp_load(ramp, direction, weight, dt)


def perturb_load(
    perturb: dict[str, Any], gravity_hand: np.ndarray, weight: float, dt: float, object_id: str,
    grasp_id: int,
) -> RampLoad:  # fmt: skip
    """The hidden-onset disturbance of one grasp: still until a delay drawn uniformly from
    ``delay_s``, then a load rising open-loop at a rate drawn uniformly from ``rate`` [m g/s] up
    to ``ceiling`` [m g], along a direction drawn from ``directions``; direction, delay and rate
    are drawn in that order from the grasp's stream."""
    rng = grasp_stream(perturb["seed"], object_id, grasp_id)
    direction = ramp_direction(perturb["directions"], gravity_hand, rng)
    delay = float(rng.uniform(*map(float, perturb["delay_s"])))
    rate = float(rng.uniform(*map(float, perturb["rate"])))
    return RampLoad(direction=direction, weight=weight, dt=dt, start_s=delay, rate=rate,
                    ceiling=float(perturb["ceiling"]), path="linear")  # fmt: skip


def deep_stop(params: dict[str, Any]) -> DeepStop | None:
    """The ``too_deep`` stop rule of ``params["deep_stop"]`` in steps (None when disabled)."""
    rule, dt = params["deep_stop"], float(params["timestep"])
    if not rule["enabled"]:
        return None
    return DeepStop(float(rule["depth"]), max(1, round(float(rule["seconds"]) / dt)),
                    round(float(rule["after_s"]) / dt))  # fmt: skip


def slip_sampler(scene: Any, params: dict[str, Any]) -> SlipSampler:
    """The contact slip sampler of a replay scene, every ``params["slip_every_s"]`` (at least one
    step): one per scene, passed to each of its replays."""
    every = max(1, round(float(params["slip_every_s"]) / float(params["timestep"])))
    return SlipSampler(scene.model, scene.layout, every)
