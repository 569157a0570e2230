"""Palm normal and grasp-focus point in the palm frame (used by the pre-grasp sampler, 3.1.3)."""

from __future__ import annotations

from typing import Any

import mujoco
import numpy as np

from graspstab.hand.candidates import body_hinge, flexion_direction
from graspstab.hand.meshes import body_collision_mesh, body_id

LONG_FINGERS = ("index", "middle", "ring", "little")


def palm_geometry(model: mujoco.MjModel, params: dict[str, Any]) -> dict[str, Any]:
    """Palm normal, knuckle centre, palm front centre and grasp focus (palm frame, open hand).

    * palm normal: mean flexion direction of the four long fingers' proximal links at qpos = 0,
      in the palm frame; the side the fingers close towards.
    * palm front centre: halfway between the palm box centre (mean of the palm collision vertices'
      extent) and the centroid of the four MCP anchors, moved along the normal onto the palm's
      front plane (the largest palm-vertex height along the normal).
    * grasp focus: the palm front centre plus ``grasp_focus_offset`` along the normal.
    """
    data = mujoco.MjData(model)
    mujoco.mj_kinematics(model, data)
    palm = body_id(model, params["palm_body"])
    w_r_palm, w_p_palm = data.xmat[palm].reshape(3, 3), data.xpos[palm]

    def to_palm(v: np.ndarray, point: bool) -> np.ndarray:
        return w_r_palm.T @ (v - w_p_palm) if point else w_r_palm.T @ v

    dirs, anchors = [], []
    for finger in LONG_FINGERS:
        tip = body_id(model, params["fingertips"][finger])
        proximal = model.body(int(model.body_parentid[tip])).name
        pid = body_id(model, proximal)
        d_body = flexion_direction(model, proximal, body_collision_mesh(model, proximal))
        dirs.append(to_palm(data.xmat[pid].reshape(3, 3) @ d_body, point=False))
        anchors.append(to_palm(data.xanchor[body_hinge(model, proximal)], point=True))
    normal = np.mean(dirs, axis=0)
    normal /= np.linalg.norm(normal)
    knuckles = np.mean(anchors, axis=0)
    verts = body_collision_mesh(model, params["palm_body"]).vertices
    palm_centre = 0.5 * (verts.min(axis=0) + verts.max(axis=0))
    lateral = 0.5 * (palm_centre + knuckles)
    front = float(np.max(verts @ normal))
    front_centre = lateral + (front - lateral @ normal) * normal
    focus = front_centre + float(params["grasp_focus_offset"]) * normal
    return {
        "palm_normal": normal,
        "knuckle_centre": knuckles,
        "palm_front_centre": front_centre,
        "grasp_focus": focus,
        "frame": params["palm_body"],
    }
