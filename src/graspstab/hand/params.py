"""Default hand-stage parameters (the config/hand slice) and their merge with a given slice."""

from __future__ import annotations

import copy
from typing import Any

from graspstab.hand import names

DEFAULT_PARAMS: dict[str, Any] = {
    "fingertips": dict(names.FINGERTIP_BODIES),
    "palm_body": names.PALM_BODY,
    "drop_bodies": list(names.DROP_BODIES),
    "drop_joints": list(names.DROP_JOINTS),
    "actuator": {"kp": 2.0, "forcerange": 1.0},  # None: keep the file's value
    "capsules": {"coverage": 0.95, "max_slack": 0.003},
    "candidates": {
        "points_per_region": 12,
        "palm_facing_min_cos": 0.3,
        "surface_samples": 4000,
        "seed": 0,
    },
    "surface_points": {"cover_radius": 0.005, "samples_per_cm2": 50, "seed": 0},
    "grasp_focus_offset": 0.04,
}


def resolve_params(params: dict[str, Any] | None) -> dict[str, Any]:
    """Defaults overlaid with ``params`` (one level of nested dicts merged; extra keys kept)."""
    out = copy.deepcopy(DEFAULT_PARAMS)
    for key, value in (params or {}).items():
        if isinstance(value, dict) and isinstance(out.get(key), dict) and key != "fingertips":
            out[key] = {**out[key], **value}
        else:
            out[key] = copy.deepcopy(value)
    return out
