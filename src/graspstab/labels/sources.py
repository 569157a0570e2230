"""What makes a time step unstable (3.3.2), one reading per named source (``labels.source``).

* ``object_speed`` (eq. 23, the reference): u_t = 1[||v_t|| >= v_slip]. Under the reference's
  contact model a held object creeps at millimetres per second, so this marks creep as well as
  slip.
* ``contact_slip``: u_t = 1 when any hand-object contact slides faster than ``slip_speed``
  (the fastest of the replay's ``tip_slip`` and ``link_slip`` channels): the contact gives way,
  whatever the object's centre does.
* ``displacement``: u_t = 1 once the object is farther than ``displacement`` from its pose at
  the settle index (hand frame: the hand is fixed): the grasp has failed, not drifted; 0 before
  the settle index.

Every stage that labels (windows, the figures, the grasp-level monitor, the closed loop) takes
its u_t from :func:`unstable_steps`, so a source changes every label at once.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from graspstab.labels.windows import timestep_labels

SOURCES = ("object_speed", "contact_slip", "displacement")


def source_channels(labels: dict[str, Any]) -> tuple[str, ...]:
    """The trace channels :func:`unstable_steps` reads under ``labels["source"]``."""
    source = labels.get("source", "object_speed")
    if source == "object_speed":
        return ("velocity",)
    if source == "contact_slip":
        return ("tip_slip", "link_slip")
    if source == "displacement":
        return ("position",)
    raise ValueError(f"unknown labels.source {source!r}; valid: {', '.join(SOURCES)}")


def displacement(position: np.ndarray, settle: int) -> np.ndarray:
    """Distance [m] of the object's centre from where it was at step ``settle``."""
    pos = np.asarray(position, dtype=np.float64)
    return np.linalg.norm(pos - pos[min(max(settle, 0), len(pos) - 1)], axis=1)


def contact_slip_speed(traces: dict[str, np.ndarray]) -> np.ndarray:
    """The fastest contact slip [m/s] at each step, fingertips and other links together."""
    tips = np.asarray(traces["tip_slip"], dtype=np.float64)
    return np.maximum(tips.max(axis=1, initial=0.0), np.asarray(traces["link_slip"], np.float64))


def unstable_steps(
    traces: dict[str, np.ndarray], labels: dict[str, Any], settle: int
) -> np.ndarray:
    """u_t (uint8) of one replay under ``labels["source"]`` (``settle``: its settle index)."""
    source_channels(labels)  # validates the name
    source = labels.get("source", "object_speed")
    if source == "object_speed":
        speed = np.linalg.norm(np.asarray(traces["velocity"], dtype=np.float64), axis=1)
        return timestep_labels(speed, labels["v_slip"])
    if source == "contact_slip":
        return (contact_slip_speed(traces) >= float(labels["slip_speed"])).astype(np.uint8)
    moved = displacement(traces["position"], settle) >= float(labels["displacement"])
    moved[: max(settle, 0)] = False
    return moved.astype(np.uint8)
