"""Contact candidate set: 12 farthest-point samples on the palm-facing patch of 10 regions (3.1.2).

A region is a finger's proximal link (PP) or distal link (fingertip body). Its palm-facing patch is
the part of the collision-mesh surface whose outward normal makes an angle of at most
arccos(``palm_facing_min_cos``) with the link's flexion direction: the direction the link's
surface moves when its own joint (MCP for PP, PIP for the tip) flexes, i.e. towards the palm side.
"""

from __future__ import annotations

from typing import Any

import mujoco
import numpy as np

from graspstab.hand import names
from graspstab.hand.meshes import BodyMesh, body_collision_mesh, body_id

REGION_KINDS = ("proximal", "distal")


def region_bodies(model: mujoco.MjModel, fingertips: dict[str, str]) -> list[tuple[str, str, str]]:
    """The 10 regions as (finger, kind, body), thumb first, proximal before distal.

    The proximal body is the fingertip body's parent (the PP link, which carries the MCP joint).
    """
    out = []
    for finger in names.FINGERS:
        tip = body_id(model, fingertips[finger])
        proximal = model.body(int(model.body_parentid[tip])).name
        out += [(finger, "proximal", proximal), (finger, "distal", fingertips[finger])]
    return out


def body_hinge(model: mujoco.MjModel, body: str) -> int:
    """Id of the one hinge joint that moves ``body`` relative to its parent."""
    bid = body_id(model, body)
    joints = [
        j
        for j in range(model.njnt)
        if model.jnt_bodyid[j] == bid and model.jnt_type[j] == mujoco.mjtJoint.mjJNT_HINGE
    ]
    if len(joints) != 1:
        raise ValueError(f"region body {body!r} must carry exactly one hinge joint, has {joints}")
    return joints[0]


def flexion_direction(model: mujoco.MjModel, body: str, mesh: BodyMesh) -> np.ndarray:
    """Unit direction (body frame) in which the link's surface moves when its joint flexes.

    Positive joint angles flex the ORCA fingers (ranges reach 1.75-1.87 rad), so a point p moves
    along axis x (p - anchor); we take it at the centroid of the link's collision vertices.
    """
    j = body_hinge(model, body)
    d = np.cross(model.jnt_axis[j], mesh.vertices.mean(axis=0) - model.jnt_pos[j])
    norm = np.linalg.norm(d)
    if norm < 1e-6:
        raise ValueError(f"link {body!r} has its centroid on its joint axis; no flexion direction")
    return d / norm


def sample_surface(
    mesh: BodyMesh, count: int, rng: np.random.Generator
) -> tuple[np.ndarray, np.ndarray]:
    """Area-uniform surface samples and their outward face normals (meshes are closed, CCW)."""
    tri = mesh.vertices[mesh.faces]
    cross = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    area = 0.5 * np.linalg.norm(cross, axis=1)
    keep = area > 0
    tri, cross, area = tri[keep], cross[keep], area[keep]
    face = rng.choice(len(tri), size=count, p=area / area.sum())
    u, v = rng.random(count), rng.random(count)
    flip = u + v > 1
    u[flip], v[flip] = 1 - u[flip], 1 - v[flip]
    t = tri[face]
    points = t[:, 0] + u[:, None] * (t[:, 1] - t[:, 0]) + v[:, None] * (t[:, 2] - t[:, 0])
    normals = cross[face] / (2 * area[face, None])
    return points, normals


def farthest_point_sampling(points: np.ndarray, k: int) -> np.ndarray:
    """Indices of ``k`` points by greedy farthest-point sampling, starting from the point nearest
    the centroid (deterministic for given points)."""
    if len(points) < k:
        raise ValueError(f"need at least {k} points for farthest-point sampling, got {len(points)}")
    first = int(np.argmin(np.linalg.norm(points - points.mean(axis=0), axis=1)))
    chosen = [first]
    dist = np.linalg.norm(points - points[first], axis=1)
    for _ in range(k - 1):
        nxt = int(np.argmax(dist))
        chosen.append(nxt)
        dist = np.minimum(dist, np.linalg.norm(points - points[nxt], axis=1))
    return np.asarray(chosen)


def contact_candidates(model: mujoco.MjModel, params: dict[str, Any]) -> dict[str, np.ndarray]:
    """The N = 10 x 12 candidates in their link frames, with normals, links, fingers and regions."""
    cfg = params["candidates"]
    k, min_cos = int(cfg["points_per_region"]), float(cfg["palm_facing_min_cos"])
    out: dict[str, list] = {k_: [] for k_ in ("points", "normals", "body", "finger", "region")}
    region_info: dict[str, list] = {"region_body": [], "region_finger": [], "region_kind": []}
    flex = []
    for region, (finger, kind, body) in enumerate(region_bodies(model, params["fingertips"])):
        mesh = body_collision_mesh(model, body)
        rng = np.random.default_rng(np.random.SeedSequence([int(cfg["seed"]), region]))
        pts, nrm = sample_surface(mesh, int(cfg["surface_samples"]), rng)
        d = flexion_direction(model, body, mesh)
        patch = nrm @ d >= min_cos
        idx = farthest_point_sampling(pts[patch], k)
        out["points"].append(pts[patch][idx])
        out["normals"].append(nrm[patch][idx])
        out["body"] += [body] * k
        out["finger"] += [finger] * k
        out["region"] += [region] * k
        region_info["region_body"].append(body)
        region_info["region_finger"].append(finger)
        region_info["region_kind"].append(kind)
        flex.append(d)
    return {
        "points": np.concatenate(out["points"]),
        "normals": np.concatenate(out["normals"]),
        "body": np.asarray(out["body"]),
        "body_id": np.asarray([body_id(model, b) for b in out["body"]], dtype=np.int32),
        "finger": np.asarray(out["finger"]),
        "region": np.asarray(out["region"], dtype=np.int32),
        "region_body": np.asarray(region_info["region_body"]),
        "region_finger": np.asarray(region_info["region_finger"]),
        "region_kind": np.asarray(region_info["region_kind"]),
        "region_flexion_dir": np.asarray(flex),
    }
