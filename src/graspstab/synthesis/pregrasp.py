"""Structured pre-grasps (thesis 3.1.3): an open hand facing the object from a plausible direction.

The annealer (3.1.4) starts from g_0 sampled here instead of a random pose:

1. inflate the object's convex hull by moving each hull vertex a distance rho away from the object
   centroid c (``inflate_hull``);
2. sample an anchor a uniformly on the inflated hull surface, take the nearest object surface
   point s and the inward direction n = (s - a) / |s - a| (eq. 3);
3. jitter n uniformly within a cone of half-angle alpha (uniform on the spherical cap) to get the
   approach direction n_hat; with ``reject_upward`` a direction with a positive vertical component
   is rejected and the whole draw (anchor, s, n, n_hat) is repeated, because an anchor under the
   object can have a cone that lies entirely above the horizontal;
4. orient the wrist so the palm normal points along n_hat, with a uniform random roll about n_hat;
5. back the hand off: the grasp-focus point (a fixed point 4 cm in front of the palm, hand.json) is
   placed at s - d n_hat with d ~ U[d_min, d_max].

Interpretation of step 5. The reference says the hand is translated "backwards from the candidate
contact region by a random standoff distance d" and that "a fixed grasp-focus point in the palm
lies near the sampled anchor". We place the focus exactly at distance d from the contact region s
along the approach; since |s - a| is about rho = 0.08 m and d is in [0.06, 0.10] m, the focus
lands within a few centimetres of the anchor, so both statements hold, and d keeps its meaning of
a distance from the surface. Fingers are not jittered: every pre-grasp uses the same open joints.
"""

from __future__ import annotations

from typing import Any

import numpy as np
import torch
import trimesh

from graspstab.synthesis.kinematics import BatchedHandKinematics
from graspstab.synthesis.rotation import matrix_to_quat, matrix_to_rot6d

# The open finger configuration lives in config (synthesis.pregrasp.open_joints), with why.
PARAM_KEYS = ("inflation", "standoff", "cone_half_angle_deg", "reject_upward", "open_joints")
MAX_ROUNDS = 100  # rejection rounds before giving up (each redraws all missing pre-grasps)
OVERSAMPLE = 2  # candidate draws per missing pre-grasp in a round


def object_centroid(mesh: trimesh.Trimesh) -> np.ndarray:
    """The centroid c of 3.1.3: the solid's centre of mass if watertight, else the area centroid."""
    return np.asarray(mesh.center_mass if mesh.is_watertight else mesh.centroid, dtype=np.float64)


def inflate_hull(mesh: trimesh.Trimesh, rho: float) -> trimesh.Trimesh:
    """Convex hull of ``mesh`` with each vertex moved by ``rho`` away from the centroid (3.1.3)."""
    if not rho > 0:
        raise ValueError(f"inflation rho must be > 0 [m], got {rho}")
    hull = mesh.convex_hull
    c = object_centroid(mesh)
    v = np.asarray(hull.vertices, dtype=np.float64)
    offset = v - c
    norm = np.linalg.norm(offset, axis=1, keepdims=True)
    if np.any(norm < 1e-12):
        raise ValueError("a hull vertex coincides with the object centroid; the mesh is degenerate")
    return trimesh.Trimesh(
        vertices=v + rho * offset / norm, faces=np.asarray(hull.faces), process=False
    )


def sample_surface_uniform(
    mesh: trimesh.Trimesh, count: int, rng: np.random.Generator
) -> np.ndarray:
    """``count`` points uniformly distributed over the surface of ``mesh`` (area-weighted)."""
    tris = np.asarray(mesh.triangles, dtype=np.float64)
    area = np.asarray(mesh.area_faces, dtype=np.float64)
    face = rng.choice(len(tris), size=count, p=area / area.sum())
    r1, r2 = rng.random(count), rng.random(count)
    sq = np.sqrt(r1)
    w = np.stack((1.0 - sq, sq * (1.0 - r2), sq * r2), axis=1)
    return np.einsum("nk,nkj->nj", w, tris[face])


def closest_surface_points(mesh: trimesh.Trimesh, points: np.ndarray) -> np.ndarray:
    """Nearest points (N, 3) on the surface of ``mesh`` to ``points`` (N, 3) (libigl, AABB tree)."""
    import igl

    _, _, closest = igl.point_mesh_squared_distance(
        np.ascontiguousarray(points, dtype=np.float64),
        np.ascontiguousarray(mesh.vertices, dtype=np.float64),
        np.ascontiguousarray(mesh.faces, dtype=np.int64),
    )
    return np.asarray(closest, dtype=np.float64).reshape(-1, 3)


def perpendicular_basis(n: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Two unit vectors (N, 3) that complete unit vectors ``n`` (N, 3) to a right-handed frame."""
    helper = np.where(np.abs(n[:, 2:3]) < 0.9, [[0.0, 0.0, 1.0]], [[1.0, 0.0, 0.0]])
    u = np.cross(helper, n)
    u /= np.linalg.norm(u, axis=1, keepdims=True)
    return u, np.cross(n, u)


def jitter_in_cone(n: np.ndarray, half_angle: float, rng: np.random.Generator) -> np.ndarray:
    """Unit vectors uniform on the spherical cap of half-angle ``half_angle`` [rad] around ``n``."""
    m = len(n)
    cos_t = 1.0 - rng.random(m) * (1.0 - np.cos(half_angle))
    sin_t = np.sqrt(np.clip(1.0 - cos_t**2, 0.0, None))
    phi = 2.0 * np.pi * rng.random(m)
    u, v = perpendicular_basis(n)
    return (
        cos_t[:, None] * n + (sin_t * np.cos(phi))[:, None] * u + (sin_t * np.sin(phi))[:, None] * v
    )


def palm_facing_rotation(
    direction: np.ndarray, roll: np.ndarray, palm_normal_root: np.ndarray
) -> np.ndarray:
    """Wrist rotations (N, 3, 3) that turn the root-frame palm normal onto ``direction`` (N, 3),
    rolled by ``roll`` (N,) [rad] about it (3.1.3)."""
    e1 = palm_normal_root / np.linalg.norm(palm_normal_root)
    e2, e3 = perpendicular_basis(e1[None])
    hand = np.stack((e1, e2[0], e3[0]), axis=1)  # columns: hand basis in the root frame
    p, q = perpendicular_basis(direction)
    f2 = np.cos(roll)[:, None] * p + np.sin(roll)[:, None] * q
    f3 = np.cross(direction, f2)
    world = np.stack((direction, f2, f3), axis=2)  # columns: the same basis in the world
    return world @ hand.T


def _check_params(params: dict[str, Any], kin: BatchedHandKinematics) -> dict[str, Any]:
    missing = [k for k in PARAM_KEYS if k not in params]
    if missing:
        raise KeyError(f"pre-grasp params lack {missing} (need {list(PARAM_KEYS)}; 3.1.3)")
    lo, hi = (float(x) for x in params["standoff"])
    if not 0 <= lo <= hi:
        raise ValueError(
            f"pre-grasp standoff must be [min, max] with 0 <= min <= max, got {lo, hi}"
        )
    alpha = float(params["cone_half_angle_deg"])
    if not 0 <= alpha <= 180:
        raise ValueError(f"pre-grasp cone_half_angle_deg must be in [0, 180], got {alpha}")
    joints = np.asarray(params["open_joints"], dtype=np.float64)
    if joints.shape != (len(kin.joint_names),):
        raise ValueError(
            f"pre-grasp open_joints must list {len(kin.joint_names)} angles in the order "
            f"{kin.joint_names}, got shape {joints.shape}"
        )
    lower = kin.joint_lower.double().numpy()
    upper = kin.joint_upper.double().numpy()
    outside = [
        f"{name}={q:.3f} not in [{a:.3f}, {b:.3f}]"
        for name, q, a, b in zip(kin.joint_names, joints, lower, upper, strict=True)
        if not a <= q <= b
    ]
    if outside:
        raise ValueError(f"pre-grasp open_joints outside the joint limits: {outside}")
    return {
        "rho": float(params["inflation"]),
        "standoff": (lo, hi),
        "alpha": np.deg2rad(alpha),
        "reject_upward": bool(params["reject_upward"]),
        "joints": joints,
    }


def sample_pregrasps(
    mesh: trimesh.Trimesh,
    kin: BatchedHandKinematics,
    n: int,
    rng: np.random.Generator,
    params: dict[str, Any],
) -> dict[str, np.ndarray]:
    """``n`` structured pre-grasps g_0 of ``mesh`` (object frame = world, +z up), see module doc.

    Returns float64 arrays: wrist_pos (n, 3) and rot6d (n, 6) / quat (n, 4, w-x-y-z, w >= 0) of
    hand_root, joints (n, 16), anchor a, surface_point s, direction n_hat, direction_raw n (n, 3),
    standoff d (n,) [m] and roll (n,) [rad]. Deterministic given the state of ``rng``.
    """
    p = _check_params(params, kin)
    if n < 0:
        raise ValueError(f"number of pre-grasps must be >= 0, got {n}")
    inflated = inflate_hull(mesh, p["rho"])
    anchors, surface, raw, jittered = (np.zeros((0, 3)) for _ in range(4))
    rounds = 0
    while len(anchors) < n:
        if rounds == MAX_ROUNDS:
            raise RuntimeError(
                f"pre-grasp sampling found only {len(anchors)} of {n} approach directions with "
                f"no upward component after {MAX_ROUNDS} rounds of rejection (3.1.3): almost every "
                "direction from the inflated hull points up; check the object's orientation "
                "(+z up, centred) or set reject_upward=false"
            )
        rounds += 1
        m = OVERSAMPLE * (n - len(anchors))
        a = sample_surface_uniform(inflated, m, rng)
        s = closest_surface_points(mesh, a)
        delta = s - a
        dist = np.linalg.norm(delta, axis=1, keepdims=True)
        d_raw = delta / np.maximum(dist, 1e-12)
        d_hat = jitter_in_cone(d_raw, p["alpha"], rng)
        ok = dist[:, 0] > 1e-9
        if p["reject_upward"]:
            ok &= d_hat[:, 2] <= 0.0
        take = np.flatnonzero(ok)[: n - len(anchors)]
        anchors = np.concatenate((anchors, a[take]))
        surface = np.concatenate((surface, s[take]))
        raw = np.concatenate((raw, d_raw[take]))
        jittered = np.concatenate((jittered, d_hat[take]))

    lo, hi = p["standoff"]
    standoff = rng.uniform(lo, hi, size=n)
    roll = rng.uniform(0.0, 2.0 * np.pi, size=n)
    palm_normal = kin.palm_normal_root.double().numpy()
    focus_root = kin.grasp_focus_root.double().numpy()
    rot = palm_facing_rotation(jittered, roll, palm_normal)
    focus = surface - standoff[:, None] * jittered
    wrist_pos = focus - np.einsum("nij,j->ni", rot, focus_root)
    rot_t = torch.from_numpy(rot)
    return {
        "wrist_pos": wrist_pos,
        "rot6d": matrix_to_rot6d(rot_t).numpy(),
        "quat": matrix_to_quat(rot_t).numpy(),
        "joints": np.tile(p["joints"], (n, 1)),
        "anchor": anchors,
        "surface_point": surface,
        "direction": jittered,
        "direction_raw": raw,
        "standoff": standoff,
        "roll": roll,
    }
