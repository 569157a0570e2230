"""MuJoCo sensors that record the replay's per-step quantities in C (thesis 3.2, eqs. 18-19).

Reading contacts in Python every step would cost more than the step itself, so the replay adds
sensors to the model and lets ``mujoco.rollout`` fill ``sensordata``:

* per fingertip, a contact sensor between the fingertip body and the object with ``slots``
  contact slots of (count, normal, tangent 1, tangent 2), the contact-frame force that
  ``mj_contactForce`` returns (normal first);
* one contact sensor between the whole hand (subtree of its root) and the object, reduced to the
  smallest signed distance (count, dist): d_t of 3.2, undefined when the count is 0;
* the object's position and linear velocity (body origin = centre of mass, 3.1.1).

:func:`features` turns a block of sensordata rows into the trace channels: eq. (18) sums
``|N|`` and ``sqrt(A^2 + B^2)`` over a fingertip's contacts.
"""

from __future__ import annotations

from dataclasses import dataclass

import mujoco
import numpy as np

# dataspec bits of the contact sensor (MuJoCo's mjtConDataField order) and its reductions
_FOUND, _FORCE, _DIST = 1, 2, 8
_REDUCE_NONE, _REDUCE_MINDIST = 0, 1


@dataclass(frozen=True)
class SensorLayout:
    """Where each recorded quantity sits in a ``sensordata`` row."""

    fingertips: tuple[str, ...]  # finger names, eq. (19) order
    slots: int  # contact slots per fingertip sensor
    tip_start: tuple[int, ...]  # first column of each fingertip sensor (slots x 4 values)
    dist_start: int  # (count, dist) of the hand-object sensor
    pos_start: int  # object position (3)
    vel_start: int  # object linear velocity (3)


def add_replay_sensors(
    spec: mujoco.MjSpec,
    fingertip_bodies: dict[str, str],
    hand_root: str,
    object_body: str,
    slots: int,
) -> None:
    """Add the replay's sensors to ``spec`` (names prefixed ``replay_``)."""
    for finger, body in fingertip_bodies.items():
        spec.add_sensor(
            name=f"replay_tip_{finger}",
            type=mujoco.mjtSensor.mjSENS_CONTACT,
            objtype=mujoco.mjtObj.mjOBJ_BODY,
            objname=body,
            reftype=mujoco.mjtObj.mjOBJ_BODY,
            refname=object_body,
            intprm=[_FOUND | _FORCE, _REDUCE_NONE, int(slots)],
        )
    spec.add_sensor(
        name="replay_hand_dist",
        type=mujoco.mjtSensor.mjSENS_CONTACT,
        objtype=mujoco.mjtObj.mjOBJ_XBODY,  # the subtree of the hand's root
        objname=hand_root,
        reftype=mujoco.mjtObj.mjOBJ_BODY,
        refname=object_body,
        intprm=[_FOUND | _DIST, _REDUCE_MINDIST, 1],
    )
    for name, kind in (
        ("replay_object_pos", mujoco.mjtSensor.mjSENS_FRAMEPOS),
        ("replay_object_vel", mujoco.mjtSensor.mjSENS_FRAMELINVEL),
    ):
        spec.add_sensor(name=name, type=kind, objtype=mujoco.mjtObj.mjOBJ_BODY, objname=object_body)


def sensor_layout(model: mujoco.MjModel, fingers: tuple[str, ...], slots: int) -> SensorLayout:
    """Column offsets of the sensors :func:`add_replay_sensors` added to the compiled ``model``."""

    def start(name: str, dim: int) -> int:
        sid = model.sensor(name).id
        if model.sensor_dim[sid] != dim:
            raise ValueError(f"sensor {name!r} has dimension {model.sensor_dim[sid]}, not {dim}")
        return int(model.sensor_adr[sid])

    return SensorLayout(
        fingertips=tuple(fingers),
        slots=int(slots),
        tip_start=tuple(start(f"replay_tip_{f}", 4 * slots) for f in fingers),
        dist_start=start("replay_hand_dist", 2),
        pos_start=start("replay_object_pos", 3),
        vel_start=start("replay_object_vel", 3),
    )


def features(sensordata: np.ndarray, layout: SensorLayout) -> dict[str, np.ndarray]:
    """Trace channels of sensordata rows ``(T, nsensordata)``.

    Returns ``position (T, 3)``, ``velocity (T, 3)``, ``min_distance (T,)`` (NaN without any
    hand-object contact), ``normal`` and ``shear (T, 5)`` (eq. 18, fingertip order of eq. 19) and
    ``overflow (T,)``: the largest number of a fingertip's contacts that did not fit the slots.
    """
    rows = np.asarray(sensordata, dtype=np.float64)
    n = len(rows)
    normal = np.empty((n, len(layout.fingertips)))
    shear = np.empty_like(normal)
    overflow = np.zeros(n, dtype=np.int64)
    for k, a in enumerate(layout.tip_start):
        block = rows[:, a : a + 4 * layout.slots].reshape(n, layout.slots, 4)
        normal[:, k] = np.abs(block[..., 1]).sum(axis=1)
        shear[:, k] = np.hypot(block[..., 2], block[..., 3]).sum(axis=1)
        overflow = np.maximum(overflow, block[:, 0, 0].astype(np.int64) - layout.slots)
    count = rows[:, layout.dist_start]
    dist = np.where(count > 0, rows[:, layout.dist_start + 1], np.nan)
    return {
        "position": rows[:, layout.pos_start : layout.pos_start + 3],
        "velocity": rows[:, layout.vel_start : layout.vel_start + 3],
        "min_distance": dist,
        "normal": normal,
        "shear": shear,
        "overflow": np.maximum(overflow, 0),
    }
