"""The replay params each protocol runs under, in one place so the workflow's replay rules and the
closed loop replay the same physics (and hash the same params)."""

from __future__ import annotations

from typing import Any


def replay_params(replay: dict[str, Any]) -> dict[str, Any]:
    """What a replay depends on: the replay group, without the load ramp's settings under the
    gravity protocol (tuning the ramp must not rerun the gravity replays)."""
    if replay["protocol"] == "gravity":
        return {k: v for k, v in replay.items() if k != "ramp"}
    return replay


def creep_free_replay(config: dict[str, Any]) -> dict[str, Any]:
    """The creep-free benchmark's replay params: the run's replay group under the load ramp
    (replay.ramp) with creep_free's contact model, squeeze and replay length."""
    cf, replay = config["creep_free"], config["replay"]
    return replay_params({
        **replay,
        "protocol": "ramp",
        "contact": cf["contact"],
        "squeeze": {**replay["squeeze"], "angle": cf["squeeze"]},
        "steps": round(cf["seconds"] / replay["timestep"]),
    })  # fmt: skip
