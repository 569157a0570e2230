"""Which model spec a study trains: the config's, or the tuned best, with the sweep's pooling."""

from __future__ import annotations

from collections.abc import Mapping
from pathlib import Path
from typing import Any

from graspstab.common.io import read_json


def study_spec(
    spec: Mapping[str, Any] | None,
    tuned_best: str | Path | None = None,
    recurrent_pooling: str | None = None,
) -> dict[str, Any]:
    """The spec from ``tuned_best`` (tune_model's best.json) when given, else ``spec``; recurrent
    pooling forced to ``recurrent_pooling`` when set (3.4.3: the sweep fixes mean pooling)."""
    if tuned_best:
        out = dict(read_json(tuned_best)["spec"])
    elif spec is not None:
        out = dict(spec)
    else:
        raise ValueError("study_spec needs a spec or a tuned best.json")
    if recurrent_pooling and out["family"] in ("gru", "lstm"):
        out["pooling"] = recurrent_pooling
    return out
