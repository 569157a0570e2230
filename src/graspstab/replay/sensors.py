"""MuJoCo sensors that record the replay's per-step quantities in C (thesis 3.2, eqs. 18-19).

Reading contacts in Python every step would cost more than the step itself, so the replay adds
sensors to the model and lets ``mujoco.rollout`` fill ``sensordata``:

* per fingertip, a contact sensor between the fingertip body and the object with ``slots``
  contact slots of (count, contact-frame force, normal, first tangent axis): the force is what
  ``mj_contactForce`` returns (normal first), the two axes place it in the world frame;
* per fingertip, the body frame's orientation (quaternion), for the fingertip-fixed tangent
  basis of the shear's two components (below);
* one contact sensor between the whole hand (subtree of its root) and the object, reduced to the
  smallest signed distance (count, dist): d_t of 3.2, undefined when the count is 0;
* the object's position and linear velocity (body origin = centre of mass, 3.1.1);
* the object's angular velocity and, per finger actuator, its force: what the failure anatomy
  reads (``spin``, ``servo_load``), never a model input.

:func:`features` turns a block of sensordata rows into the trace channels (the replay computes
the force channels, :func:`force_features`, over many chunks at once): eq. (18) sums
``|N|`` and ``sqrt(A^2 + B^2)`` over a fingertip's contacts. It also resolves each fingertip's
shear *vector* into two components (``shear_distal``, ``shear_lateral``; the input audit's
15-input set, our extension): a contact's (A, B) are in its own contact frame, whose tangent axes
MuJoCo picks per contact, so summing A and B across contacts means nothing. Instead each contact's
tangential force goes to the world frame and is summed; the sum is projected on a basis of the
plane normal to the fingertip's force-weighted mean contact normal, the first axis the finger's
long (distal) axis in that plane, the second ``normal x distal``. That is what a fingertip-fixed
three-axis sensor reports, and its magnitude equals eq. (18)'s shear when the contacts' shears
are parallel.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field

import mujoco
import numpy as np

# dataspec bits of the contact sensor (MuJoCo's mjtConDataField order) and its reductions
_FOUND, _FORCE, _DIST, _NORMAL, _TANGENT = 1, 2, 8, 32, 64
_SLOT = 10  # count, force (3), normal (3), tangent (3): the bits' order
_REDUCE_NONE, _REDUCE_MINDIST = 0, 1


@dataclass(frozen=True)
class SensorLayout:
    """Where each recorded quantity sits in a ``sensordata`` row."""

    fingertips: tuple[str, ...]  # finger names, eq. (19) order
    slots: int  # contact slots per fingertip sensor
    tip_start: tuple[int, ...]  # first column of each fingertip sensor (slots x 10 values)
    quat_start: tuple[int, ...]  # each fingertip body's orientation (w, x, y, z)
    distal: np.ndarray  # (fingertips, 3) each fingertip's long axis, its body frame, unit
    lateral: np.ndarray  # (fingertips, 3) a body-frame unit axis normal to ``distal``
    dist_start: int  # (count, dist) of the hand-object sensor
    pos_start: int  # object position (3)
    vel_start: int  # object linear velocity (3)
    angvel_start: int  # object angular velocity (3)
    act_start: int  # the finger actuators' forces (one each), -1 without actuator sensors
    # per actuator sensor: 1 / force range for the closing joints, 0 for the rest (servo_load)
    servo_weight: np.ndarray = field(default_factory=lambda: np.zeros(0))
    tip_bodies: tuple[int, ...] = ()  # each fingertip's body id, eq. (19) order
    hand_bodies: tuple[int, ...] = ()  # every body of the hand's subtree
    object_body: int = -1


def add_replay_sensors(
    spec: mujoco.MjSpec,
    fingertip_bodies: dict[str, str],
    hand_root: str,
    object_body: str,
    slots: int,
    actuators: Sequence[str] = (),
) -> None:
    """Add the replay's sensors to ``spec`` (names prefixed ``replay_``), with one force sensor
    per named actuator."""
    for finger, body in fingertip_bodies.items():
        spec.add_sensor(
            name=f"replay_tip_{finger}",
            type=mujoco.mjtSensor.mjSENS_CONTACT,
            objtype=mujoco.mjtObj.mjOBJ_BODY,
            objname=body,
            reftype=mujoco.mjtObj.mjOBJ_BODY,
            refname=object_body,
            intprm=[_FOUND | _FORCE | _NORMAL | _TANGENT, _REDUCE_NONE, int(slots)],
        )
        spec.add_sensor(
            name=f"replay_quat_{finger}",
            type=mujoco.mjtSensor.mjSENS_FRAMEQUAT,
            objtype=mujoco.mjtObj.mjOBJ_XBODY,
            objname=body,
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
        ("replay_object_angvel", mujoco.mjtSensor.mjSENS_FRAMEANGVEL),
    ):
        spec.add_sensor(name=name, type=kind, objtype=mujoco.mjtObj.mjOBJ_BODY, objname=object_body)
    for i, actuator in enumerate(actuators):
        spec.add_sensor(name=f"replay_act_{i}", type=mujoco.mjtSensor.mjSENS_ACTUATORFRC,
                        objtype=mujoco.mjtObj.mjOBJ_ACTUATOR, objname=actuator)  # fmt: skip


def finger_axes(model: mujoco.MjModel, body: int) -> tuple[np.ndarray, np.ndarray]:
    """A fingertip body's long axis in its frame (joint anchor to centre of mass, the body's x
    axis when they coincide) and a unit axis normal to it (the spare for end-on contacts)."""
    ipos = model.body_ipos[body]
    anchor = model.jnt_pos[model.body_jntadr[body]] if model.body_jntnum[body] else np.zeros(3)
    distal = ipos - anchor
    if np.linalg.norm(distal) < 1e-9:
        distal = np.array([1.0, 0.0, 0.0])
    distal = distal / np.linalg.norm(distal)
    spare = np.eye(3)[int(np.argmin(np.abs(distal)))]
    lateral = np.cross(distal, spare)
    return distal, lateral / np.linalg.norm(lateral)


def sensor_layout(
    model: mujoco.MjModel,
    fingers: tuple[str, ...],
    slots: int,
    servo_weight: np.ndarray | None = None,
) -> SensorLayout:
    """Column offsets of the sensors :func:`add_replay_sensors` added to the compiled ``model``;
    ``servo_weight`` (per actuator sensor: 1 / force range of a closing joint, else 0; None: all
    0) turns the actuator forces into ``servo_load``."""

    def start(name: str, dim: int) -> int:
        sid = model.sensor(name).id
        if model.sensor_dim[sid] != dim:
            raise ValueError(f"sensor {name!r} has dimension {model.sensor_dim[sid]}, not {dim}")
        return int(model.sensor_adr[sid])

    bodies = [int(model.sensor_objid[model.sensor(f"replay_quat_{f}").id]) for f in fingers]
    axes = [finger_axes(model, b) for b in bodies]
    acts = [i for i in range(model.nsensor) if model.sensor(i).name.startswith("replay_act_")]
    weight = np.zeros(len(acts)) if servo_weight is None else np.asarray(servo_weight, float)
    if len(weight) != len(acts):
        raise ValueError(f"servo_weight has {len(weight)} entries for {len(acts)} actuator sensors")
    root = int(model.sensor_objid[model.sensor("replay_hand_dist").id])
    hand = [b for b in range(model.nbody) if _in_subtree(model, b, root)]
    return SensorLayout(
        fingertips=tuple(fingers),
        slots=int(slots),
        tip_start=tuple(start(f"replay_tip_{f}", _SLOT * slots) for f in fingers),
        quat_start=tuple(start(f"replay_quat_{f}", 4) for f in fingers),
        distal=np.array([a[0] for a in axes]).reshape(-1, 3),
        lateral=np.array([a[1] for a in axes]).reshape(-1, 3),
        dist_start=start("replay_hand_dist", 2),
        pos_start=start("replay_object_pos", 3),
        vel_start=start("replay_object_vel", 3),
        angvel_start=start("replay_object_angvel", 3),
        act_start=int(model.sensor_adr[acts[0]]) if acts else -1,
        servo_weight=weight,
        tip_bodies=tuple(bodies),
        hand_bodies=tuple(hand),
        object_body=int(model.sensor_objid[model.sensor("replay_object_pos").id]),
    )


def _in_subtree(model: mujoco.MjModel, body: int, root: int) -> bool:
    while body > 0:
        if body == root:
            return True
        body = int(model.body_parentid[body])
    return body == root


def rotate(quat: np.ndarray, v: np.ndarray) -> np.ndarray:
    """Body-frame vectors ``v (..., 3)`` in the world frame for unit quaternions ``quat (..., 4)``
    (w, x, y, z), broadcast against each other."""
    w, q = quat[..., :1], quat[..., 1:]
    c = np.cross(q, v)
    return v + 2.0 * w * c + 2.0 * np.cross(q, c)


def _unit(v: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    norm = np.linalg.norm(v, axis=-1, keepdims=True)
    return v / np.where(norm > 0, norm, 1.0), norm[..., 0]


def shear_components(
    block: np.ndarray, quat: np.ndarray, distal: np.ndarray, lateral: np.ndarray
) -> np.ndarray:
    """``(..., 2)`` (distal, lateral) components of fingertips' summed tangential forces.

    ``block (..., slots, 10)`` is a fingertip contact sensor's slots, ``quat (..., 4)`` the
    fingertip's orientation, ``distal`` and ``lateral (..., 3)`` its body-frame axes; leading
    axes broadcast (e.g. time x fingertip). The force is the fingertip's on the object; rows
    without contact give zeros."""
    f, n, t = block[..., 1:4], block[..., 4:7], block[..., 7:10]
    used = block[..., :1] > 0  # empty slots are zeros already; the count guards the axes
    tangential = ((f[..., 1:2] * t + f[..., 2:3] * np.cross(n, t)) * used).sum(axis=-2)
    normal, weight = _unit((np.abs(f[..., :1]) * n * used).sum(axis=-2))
    out = np.zeros((*tangential.shape[:-1], 2))
    for axis in (lateral, distal):  # distal where it lies in the plane, else the spare axis
        a = rotate(quat, axis)
        e1, size = _unit(a - (a * normal).sum(axis=-1, keepdims=True) * normal)
        ok = (size > 0.2) & (weight > 0)
        e2 = np.cross(normal, e1)
        both = np.stack([(tangential * e1).sum(-1), (tangential * e2).sum(-1)], axis=-1)
        out[ok] = both[ok]
    return out


def features(sensordata: np.ndarray, layout: SensorLayout) -> dict[str, np.ndarray]:
    """Trace channels of sensordata rows ``(T, nsensordata)``: :func:`motion_features` and
    :func:`force_features` together."""
    return {**motion_features(sensordata, layout), **force_features(sensordata, layout)}


def motion_features(sensordata: np.ndarray, layout: SensorLayout) -> dict[str, np.ndarray]:
    """``position (T, 3)``, ``velocity (T, 3)`` and ``min_distance (T,)`` (NaN without any
    hand-object contact): what the replay's stop rules and the load ramp read every chunk; and the
    failure anatomy's ``spin (T,)``, the object's angular speed [rad/s], and ``servo_load (T,)``,
    the largest closing-joint actuator force as a share of its range (1: saturated)."""
    rows = np.asarray(sensordata, dtype=np.float64)
    count = rows[:, layout.dist_start]
    k = len(layout.servo_weight)
    servo = (
        np.abs(rows[:, layout.act_start : layout.act_start + k]) * layout.servo_weight[None]
    ).max(axis=1, initial=0.0) if k else np.zeros(len(rows))  # fmt: skip
    return {
        "position": rows[:, layout.pos_start : layout.pos_start + 3],
        "velocity": rows[:, layout.vel_start : layout.vel_start + 3],
        "min_distance": np.where(count > 0, rows[:, layout.dist_start + 1], np.nan),
        "spin": np.linalg.norm(rows[:, layout.angvel_start : layout.angvel_start + 3], axis=1),
        "servo_load": servo,
    }


def force_features(sensordata: np.ndarray, layout: SensorLayout) -> dict[str, np.ndarray]:
    """``normal`` and ``shear (T, 5)`` (eq. 18, fingertip order of eq. 19), ``shear_distal`` and
    ``shear_lateral (T, 5)`` (:func:`shear_components`) and ``overflow (T,)``: the largest number
    of a fingertip's contacts that did not fit the slots."""
    rows = np.asarray(sensordata, dtype=np.float64)
    n, tips, slots = len(rows), len(layout.fingertips), layout.slots
    # every fingertip at once (a replay under the load ramp calls this on short chunks)
    cols = np.asarray(layout.tip_start)[:, None] + np.arange(_SLOT * slots)[None]
    block = rows[:, cols].reshape(n, tips, slots, _SLOT)
    quat = rows[:, np.asarray(layout.quat_start)[:, None] + np.arange(4)[None]]
    comp = shear_components(block, quat, layout.distal, layout.lateral)
    overflow = (block[:, :, 0, 0].astype(np.int64) - slots).max(axis=1, initial=0)
    return {
        "normal": np.abs(block[..., 1]).sum(axis=-1),
        "shear": np.hypot(block[..., 2], block[..., 3]).sum(axis=-1),
        "shear_distal": comp[..., 0],
        "shear_lateral": comp[..., 1],
        "overflow": np.maximum(overflow, 0),
    }
