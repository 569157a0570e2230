"""Capsule-per-finger-link and palm-box approximation of the hand, for the penetration energies.

Thesis 3.1.4 / fig. 3.5: the hand SDF uses capsules for the finger links and a box for the palm;
the self-penetration energy compares capsule pairs of different fingers.
"""

from __future__ import annotations

import itertools
import math
from typing import Any

import mujoco
import numpy as np
import trimesh
from scipy.optimize import minimize

from graspstab.hand import names
from graspstab.hand.meshes import body_collision_mesh, body_id, collision_geoms
from graspstab.hand.palm import palm_geometry

LINK_LABELS = {4: ("tp", "ap", "pp", "dp"), 3: ("ap", "pp", "dp")}

# Pair rule (documented in capsule_pairs).
PAIR_RULE = (
    "capsules of different fingers only (same-finger links are mechanically connected); "
    "the palm-mounted base (AP) links of the long fingers are in no pair"
)


def finger_links(model: mujoco.MjModel, fingertips: dict[str, str], palm: str) -> dict[str, list]:
    """Per finger, the bodies from the palm (exclusive) to the fingertip that carry collision
    meshes, palm side first (thumb: T-TP-R, R-T-AP, T-PP, T-DP; others AP, PP, tip)."""
    palm_id = body_id(model, palm)
    out: dict[str, list[str]] = {}
    for finger in names.FINGERS:
        chain, bid = [], body_id(model, fingertips[finger])
        while bid not in (palm_id, 0):
            chain.append(model.body(bid).name)
            bid = int(model.body_parentid[bid])
        if bid != palm_id:
            raise ValueError(f"fingertip {fingertips[finger]!r} is not below the palm {palm!r}")
        out[finger] = [b for b in reversed(chain) if collision_geoms(model, b)]
    return out


def point_segment_distance(points: np.ndarray, p0: np.ndarray, p1: np.ndarray) -> np.ndarray:
    """Euclidean distance of each point (n, 3) to the segment p0-p1."""
    d = p1 - p0
    denom = float(d @ d)
    t = np.zeros(len(points)) if denom == 0 else np.clip((points - p0) @ d / denom, 0.0, 1.0)
    return np.linalg.norm(points - (p0 + t[:, None] * d), axis=1)


def coverage_radius(dist: np.ndarray, coverage: float) -> float:
    """Smallest radius that encloses at least ``coverage`` of the points with these distances."""
    k = max(1, math.ceil(coverage * len(dist) - 1e-9))
    return float(np.partition(dist, k - 1)[k - 1])


def _capsule_volume(p0: np.ndarray, p1: np.ndarray, r: float) -> float:
    return math.pi * r * r * float(np.linalg.norm(p1 - p0)) + 4.0 / 3.0 * math.pi * r**3


def fit_capsule(points: np.ndarray, coverage: float = 0.95) -> tuple[np.ndarray, np.ndarray, float]:
    """Smallest-volume capsule (p0, p1, radius) enclosing ``coverage`` of ``points``.

    Initialised on the principal axis through the centroid (grid over the segment ends), then
    refined by Nelder-Mead over both endpoints; the radius is always the exact coverage radius of
    the current segment, so it has no slack.
    """
    pts = np.asarray(points, dtype=float)
    centre = pts.mean(axis=0)
    _, _, vt = np.linalg.svd(pts - centre, full_matrices=False)
    axis = vt[0]
    rel = pts - centre
    t = rel @ axis
    perp = rel - np.outer(t, axis)
    # centre the axis line on the middle of the cross-section's extent
    lo, hi = np.percentile(perp @ vt[1:].T, [1, 99], axis=0)
    offset = 0.5 * (lo + hi) @ vt[1:]
    perp_r2 = np.sum((perp - offset) ** 2, axis=1)
    t_lo, t_hi = np.percentile(t, [0, 100])
    mid = 0.5 * (t_lo + t_hi)
    k = max(1, math.ceil(coverage * len(pts) - 1e-9))
    best = (np.inf, mid, mid)
    for t1 in np.linspace(mid, t_hi, 21):
        t0s = np.linspace(t_lo, mid, 21)
        over = np.maximum(t0s[:, None] - t[None, :], 0.0) + np.maximum(t[None, :] - t1, 0.0)
        radii = np.sqrt(np.partition(perp_r2[None, :] + over**2, k - 1, axis=1)[:, k - 1])
        vols = math.pi * radii**2 * (t1 - t0s) + 4.0 / 3.0 * math.pi * radii**3
        i = int(np.argmin(vols))
        if vols[i] < best[0]:
            best = (float(vols[i]), float(t0s[i]), float(t1))
    x0 = np.concatenate([centre + offset + best[1] * axis, centre + offset + best[2] * axis])

    def volume(x: np.ndarray) -> float:
        p0, p1 = x[:3], x[3:]
        return _capsule_volume(
            p0, p1, coverage_radius(point_segment_distance(pts, p0, p1), coverage)
        )

    res = minimize(
        volume, x0, method="Nelder-Mead", options={"xatol": 1e-5, "fatol": 1e-12, "maxiter": 600}
    )
    x = res.x if res.fun < volume(x0) else x0
    p0, p1 = x[:3], x[3:]
    radius = coverage_radius(point_segment_distance(pts, p0, p1), coverage) + 1e-9
    return p0, p1, radius


def fit_palm_box(points: np.ndarray, normal: np.ndarray) -> dict[str, Any]:
    """Box enclosing all palm collision vertices (palm frame), one axis along the palm normal.

    The palm is a plate: its thickness is measured along the palm normal and the in-plane
    rectangle is the minimum-area one (rotating calipers). Rotation columns are the box axes
    (third = palm normal).
    """
    pts = np.asarray(points, dtype=float)
    n = np.asarray(normal, dtype=float) / np.linalg.norm(normal)
    e1 = np.cross(n, [1.0, 0.0, 0.0] if abs(n[0]) < 0.9 else [0.0, 1.0, 0.0])
    e1 /= np.linalg.norm(e1)
    e2 = np.cross(n, e1)
    plane = np.stack([e1, e2], axis=1)  # (3, 2)
    to_origin, rect = trimesh.bounds.oriented_bounds_2D(pts @ plane)
    inv = np.linalg.inv(to_origin)
    a1 = plane @ inv[:2, 0]
    a2 = plane @ inv[:2, 1]
    if np.dot(np.cross(a1, a2), n) < 0:
        a2 = -a2
    h = pts @ n
    centre = plane @ inv[:2, 2] + 0.5 * (h.min() + h.max()) * n
    half = np.array([0.5 * rect[0], 0.5 * rect[1], 0.5 * (h.max() - h.min())])
    return {"center": centre, "rotation": np.stack([a1, a2, n], axis=1), "half_extents": half}


def fit_hand_capsules(
    model: mujoco.MjModel, params: dict[str, Any], palm_normal: np.ndarray | None = None
) -> dict[str, Any]:
    """Capsules for every finger link with a collision mesh and the palm box, as JSON-ready data.

    ``palm_normal`` (palm frame) orients the box; by default from :func:`palm_geometry`.
    """
    if palm_normal is None:
        palm_normal = palm_geometry(model, params)["palm_normal"]
    coverage = float(params["capsules"]["coverage"])
    max_slack = float(params["capsules"]["max_slack"])
    links = finger_links(model, params["fingertips"], params["palm_body"])
    capsules = []
    for finger in names.FINGERS:
        labels = LINK_LABELS.get(len(links[finger]), tuple(str(i) for i in range(99)))
        for idx, body in enumerate(links[finger]):
            verts = body_collision_mesh(model, body).vertices
            p0, p1, radius = fit_capsule(verts, coverage)
            dist = point_segment_distance(verts, p0, p1)
            r_min = coverage_radius(dist, coverage)
            if radius - r_min > max_slack:
                raise ValueError(f"capsule of {body} is {radius - r_min:.4f} m fatter than needed")
            capsules.append(
                {
                    "name": f"{finger}_{labels[idx]}",
                    "body": body,
                    "finger": finger,
                    "link_index": idx,
                    "p0": p0,
                    "p1": p1,
                    "radius": radius,
                    "coverage": float(np.mean(dist <= radius)),
                }
            )
    palm = params["palm_body"]
    box = {"body": palm, **fit_palm_box(body_collision_mesh(model, palm).vertices, palm_normal)}
    return {"capsules": capsules, "palm_box": box}


def capsule_pairs(capsules: list[dict[str, Any]]) -> list[tuple[int, int]]:
    """Index pairs (i < j) checked by the self-penetration energy (3.1.4).

    Only capsules of different fingers are paired: links of the same finger are mechanically
    connected. The base (AP, ``link_index`` 0) links of the long fingers (index to little) are in
    no pair: they sit side by side inside the palm, only abduct, and their capsules already touch
    their neighbours' AP and PP capsules in the open hand (gaps down to -3 mm), so they would add a
    constant offset rather than a useful penalty. The thumb's two base links are kept (they swing
    across the palm). They all still count for the object penetration energy.
    """

    def is_long_base(c: dict[str, Any]) -> bool:
        return c["finger"] != "thumb" and c["link_index"] == 0

    return [
        (i, j)
        for i, j in itertools.combinations(range(len(capsules)), 2)
        if capsules[i]["finger"] != capsules[j]["finger"]
        and not is_long_base(capsules[i])
        and not is_long_base(capsules[j])
    ]
