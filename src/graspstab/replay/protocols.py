"""The replay params each protocol runs under, in one place so the workflow's replay rules and the
closed loop replay the same physics (and hash the same params)."""

from __future__ import annotations

from typing import Any

#: the load protocols (replay.protocol) and the settings group each one reads
PROTOCOLS = {"gravity": None, "ramp": "ramp", "perturb": "perturb"}


def replay_params(replay: dict[str, Any]) -> dict[str, Any]:
    """What a replay depends on: the replay group without the settings of the load protocols it
    does not run (tuning the ramp must not rerun the gravity or perturbation replays)."""
    own = PROTOCOLS[replay["protocol"]]
    return {k: v for k, v in replay.items() if k not in PROTOCOLS.values() or k == own}


def creep_free_replay(config: dict[str, Any]) -> dict[str, Any]:
    """The creep-free benchmark's replay params: the run's replay group under creep_free's load
    (``ramp``: replay.ramp; ``perturb``: replay.perturb) with its contact model, squeeze and
    replay length."""
    cf, replay = config["creep_free"], config["replay"]
    return replay_params({
        **replay,
        "protocol": cf["load"],
        "contact": cf["contact"],
        "squeeze": {**replay["squeeze"], "angle": cf["squeeze"]},
        "steps": round(cf["seconds"] / replay["timestep"]),
    })  # fmt: skip


def creep_free_labels(config: dict[str, Any]) -> dict[str, Any]:
    """The creep-free benchmark's labelling rules: the run's (labels), with its own source when
    creep_free.labels_source names one."""
    source = config["creep_free"]["labels_source"]
    return config["labels"] if source is None else {**config["labels"], "source": source}
