"""The replay scene: the hand fixed in place, the object free, built once per object (3.2).

The scene is built in the hand's frame: the hand's root sits at the world origin and each grasp
places the object's free joint at the object's pose relative to the hand, with gravity rotated
into that frame. One compiled model then serves every grasp of the object (compiling the meshes
costs ~0.7 s); the hand frame is inertial because the hand is fixed, so speeds and contact
forces are unchanged and positions map back to the object frame by one rigid transform.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Any

import mujoco
import numpy as np

from graspstab.common.io import read_json
from graspstab.replay.sensors import SensorLayout, add_replay_sensors, sensor_layout

OBJECT_PREFIX = "obj_"
CONES = {"elliptic": mujoco.mjtCone.mjCONE_ELLIPTIC, "pyramidal": mujoco.mjtCone.mjCONE_PYRAMIDAL}


@dataclass(frozen=True)
class ReplayScene:
    """A compiled replay model and the addresses a grasp placement writes."""

    model: mujoco.MjModel
    layout: SensorLayout
    object_qpos: int  # address of the object's free joint in qpos (position, then quaternion)
    object_body: int  # the object's body id (where the load-ramp protocol applies its force)
    finger_qpos: np.ndarray  # (16,) qpos addresses, hand.json joint order
    finger_ctrl: np.ndarray  # (16,) actuator ids, same order
    ctrl_range: np.ndarray  # (16, 2) servo target range [rad] (the joint limits), same order
    closing: np.ndarray  # (16,) 1 for the joints the squeeze closes, else 0, same order
    squeeze: float  # [rad] servo targets moved this far past the grasp's angles (0: 3.2 as is)


def build_replay_scene(
    hand_dir: str | Path, object_dir: str | Path, params: dict[str, Any]
) -> ReplayScene:
    """Hand (free wrist joint removed) plus the object's body; solver options and servo gains
    from the contact model ``params["contact"]``, the squeeze from ``params["squeeze"]``."""
    hand_dir, object_dir = Path(hand_dir), Path(object_dir)
    hand = read_json(hand_dir / "hand.json")
    spec = mujoco.MjSpec.from_file(str(hand_dir / "hand.xml"))
    spec.delete(spec.joint(hand["wrist_joint"]))
    obj = mujoco.MjSpec.from_file(str(object_dir / "object.xml"))
    spec.worldbody.add_frame().attach_body(obj.body("object"), OBJECT_PREFIX, "")
    object_body = f"{OBJECT_PREFIX}object"
    fingers = tuple(hand["fingers"])
    add_replay_sensors(
        spec,
        {f: hand["fingertips"][f] for f in fingers},
        hand["root_body"],
        object_body,
        int(params["contact_slots"]),
        hand["actuator_names"],
    )
    contact = params["contact"]
    opt = spec.option
    opt.timestep = float(params["timestep"])
    opt.cone = CONES[contact["cone"]]
    opt.impratio = float(contact["impratio"])
    opt.noslip_iterations = int(contact["noslip_iterations"])
    opt.gravity = [0.0, 0.0, 0.0]
    model = spec.compile()
    act = contact["actuator"]
    ctrl = np.array([model.actuator(a).id for a in hand["actuator_names"]])
    joints = list(hand["joint_names"])
    unknown = sorted(set(params["squeeze"]["joints"]) - set(joints))
    if unknown:
        raise ValueError(
            f"replay.squeeze.joints names {unknown}, which are not finger joints of "
            f"{hand_dir / 'hand.json'}; valid names: {', '.join(joints)}"
        )
    closing = np.array([float(j in params["squeeze"]["joints"]) for j in joints])
    kp, kv = float(act["kp"]), float(act["kv"])
    model.actuator_gainprm[ctrl, 0] = kp
    model.actuator_biasprm[ctrl, 1] = -kp
    model.actuator_biasprm[ctrl, 2] = -kv
    model.actuator_forcerange[ctrl] = (-float(act["forcerange"]), float(act["forcerange"]))
    joint = model.body(object_body).jntadr[0]
    servo_weight = closing / float(act["forcerange"])  # actuator sensors in actuator_names order
    return ReplayScene(
        model=model,
        layout=sensor_layout(model, fingers, int(params["contact_slots"]), servo_weight),
        object_qpos=int(model.jnt_qposadr[joint]),
        object_body=int(model.body(object_body).id),
        finger_qpos=np.array([model.joint(j).qposadr[0] for j in hand["joint_names"]]),
        finger_ctrl=ctrl,
        ctrl_range=model.actuator_ctrlrange[ctrl].copy(),
        closing=closing,
        squeeze=float(params["squeeze"]["angle"]),
    )


def squeeze_targets(
    joints: np.ndarray, closing: np.ndarray, angle: float, ctrl_range: np.ndarray
) -> np.ndarray:
    """Servo targets ``angle`` [rad] past the grasp's ``joints`` along each closing joint's
    closing (increasing) direction, never past its upper limit and never opened; other joints
    keep their angles. Angle 0 gives the grasp's own angles (3.2)."""
    joints = np.asarray(joints, dtype=np.float64)
    if angle < 0 or not np.isfinite(angle):
        raise ValueError(f"replay.squeeze.angle must be a finite angle >= 0 [rad], got {angle}")
    target = joints + angle * np.asarray(closing, dtype=np.float64)
    upper = np.maximum(np.asarray(ctrl_range)[:, 1], joints)  # a grasp beyond a limit stays put
    return np.minimum(target, upper)


def hand_frame(wrist_pos: np.ndarray, wrist_quat: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Rotation (3, 3) and position (3,) of the hand's root in the object frame."""
    rot = np.zeros(9)
    mujoco.mju_quat2Mat(rot, np.asarray(wrist_quat, dtype=np.float64))
    return rot.reshape(3, 3), np.asarray(wrist_pos, dtype=np.float64)


def place_grasp(
    scene: ReplayScene,
    data: mujoco.MjData,
    wrist_pos: np.ndarray,
    wrist_quat: np.ndarray,
    joints: np.ndarray,
    gravity: np.ndarray,
) -> None:
    """Reset ``data`` to a grasp: object at its pose relative to the hand, fingers at their
    angles, targets at their angles plus the squeeze; evaluated without gravity (3.2), then
    gravity switched on (hand frame)."""
    model = scene.model
    mujoco.mj_resetData(model, data)
    rot, pos = hand_frame(wrist_pos, wrist_quat)
    a = scene.object_qpos
    data.qpos[a : a + 3] = -rot.T @ pos  # the object frame's origin seen from the hand
    quat = np.zeros(4)
    mujoco.mju_negQuat(quat, np.asarray(wrist_quat, dtype=np.float64))
    data.qpos[a + 3 : a + 7] = quat / np.linalg.norm(quat)
    data.qpos[scene.finger_qpos] = joints
    data.ctrl[scene.finger_ctrl] = squeeze_targets(
        joints, scene.closing, scene.squeeze, scene.ctrl_range
    )
    model.opt.gravity[:] = 0.0
    mujoco.mj_forward(model, data)
    model.opt.gravity[:] = rot.T @ np.asarray(gravity, dtype=np.float64)


def to_object_frame(
    traces: dict[str, np.ndarray], wrist_pos: np.ndarray, wrist_quat: np.ndarray
) -> dict[str, np.ndarray]:
    """Positions, velocities and the load-ramp force recorded in the hand frame, expressed in
    the object frame."""
    rot, pos = hand_frame(wrist_pos, wrist_quat)
    out = dict(traces)
    out["position"] = (traces["position"].astype(np.float64) @ rot.T + pos).astype(np.float32)
    for vector in ("velocity", "load"):
        if vector in traces:
            out[vector] = (traces[vector].astype(np.float64) @ rot.T).astype(np.float32)
    return out
