"""The robustness study's sensor conditions from the sensing config group: the clean sensor, each
curve's strengths and each preset, in that order (the study and the augmentation share them)."""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

from graspstab.sensing.sensor_model import CORRUPTIONS, SensorModel

#: The augmentation mode that draws from every curve and preset (sensing.augment.modes).
MIXTURE = "mixture"


def training_label(mode: str) -> str:
    """The ``training`` value an augmentation mode's runs carry in the robustness tables:
    ``augmented`` for the mixture, ``augmented:<corruption>`` for one corruption's curve."""
    return "augmented" if mode == MIXTURE else f"augmented:{mode}"


def conditions(sensing: Mapping[str, Any]) -> list[dict[str, Any]]:
    """The study's conditions in order: the clean sensor, each curve's strengths, the presets.
    Each is {kind: "clean" | "curve" | "preset", corruption, strength, sensor}."""
    base = {"full_scale_n": float(sensing["full_scale_n"])}
    out = [{"kind": "clean", "corruption": "none", "strength": 0.0,
            "sensor": SensorModel.from_config(base)}]  # fmt: skip
    for corruption, strengths in sensing["curves"].items():
        if corruption not in CORRUPTIONS:
            raise ValueError(f"sensing.curves: unknown corruption {corruption!r}; "
                             f"valid: {list(CORRUPTIONS)}")  # fmt: skip
        for value in strengths:
            sensor = SensorModel.from_config(base).with_strength(corruption, value)
            out.append({"kind": "curve", "corruption": corruption, "strength": float(value),
                        "sensor": sensor})  # fmt: skip
    for name, values in sensing["presets"].items():
        out.append({"kind": "preset", "corruption": str(name), "strength": float("nan"),
                    "sensor": SensorModel.from_config({**base, **values})})  # fmt: skip
    return out
