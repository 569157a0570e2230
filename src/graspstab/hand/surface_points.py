"""Points covering every colliding hand link's surface, for the hand-in-object penetration term.

The reference's penetration energy (3.1.4, eq. 11) looks one way only: object hull points inside the
hand's capsules. A link that has passed wholly into the object holds no hull point and costs
nothing, and the annealer exploits that (docs/protocols.md, "Annealing energies"). Our added term
E_hpen looks the other way, at these points inside the object. They lie on the convex hull of each
collision geom, because that hull is what MuJoCo collides (so a grasp that keeps them outside the
object also keeps MuJoCo's contacts shallow), and are thinned from a dense area-uniform sample by
farthest-point sampling until every sample lies within ``cover_radius`` of a kept point (so every
hull point lies within about ``cover_radius`` plus the dense spacing, ~1.4 mm at 50 per cm^2): an
object edge can reach at most about that far into a link between two kept points.
"""

from __future__ import annotations

from typing import Any

import mujoco
import numpy as np
from scipy.spatial import ConvexHull

from graspstab.hand.candidates import sample_surface
from graspstab.hand.meshes import BodyMesh, collision_geoms, geom_mesh

SURFACE_POINTS_FILE = "surface_points.npz"


def farthest_point_cover(points: np.ndarray, radius: float) -> np.ndarray:
    """Indices chosen greedily farthest-first until every point lies within ``radius`` of one."""
    if len(points) == 0:
        return np.zeros(0, dtype=np.int64)
    chosen = [0]
    dist = np.linalg.norm(points - points[0], axis=1)
    while dist.max() > radius:
        nxt = int(np.argmax(dist))
        chosen.append(nxt)
        dist = np.minimum(dist, np.linalg.norm(points - points[nxt], axis=1))
    return np.asarray(chosen, dtype=np.int64)


def geom_hull(model: mujoco.MjModel, geom: int) -> BodyMesh:
    """Convex hull (body frame) of one mesh geom: the shape MuJoCo collides."""
    verts, _ = geom_mesh(model, geom)
    hull = ConvexHull(verts)
    faces = hull.simplices.astype(np.int64)
    # orient the faces outwards (qhull's simplices are unordered)
    centre = verts[hull.vertices].mean(axis=0)
    tri = verts[faces]
    normal = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    flip = np.einsum("ij,ij->i", normal, tri[:, 0] - centre) < 0
    faces[flip] = faces[flip][:, ::-1]
    return BodyMesh(model.body(int(model.geom_bodyid[geom])).name, verts, faces)


def hand_surface_points(model: mujoco.MjModel, params: dict[str, Any]) -> dict[str, np.ndarray]:
    """Covering points of every colliding body's geom hulls, in body frames, with body names.

    ``params`` is the ``hand.surface_points`` slice: ``cover_radius`` [m], ``samples_per_cm2``
    (dense area-uniform samples the cover is chosen from) and ``seed``.
    """
    radius = float(params["cover_radius"])
    if not radius > 0:
        raise ValueError(f"hand.surface_points.cover_radius must be > 0, got {radius}")
    density = float(params["samples_per_cm2"])
    points, bodies = [], []
    for body in range(1, model.nbody):
        name = model.body(body).name
        for g in collision_geoms(model, name):
            hull = geom_hull(model, g)
            tri = hull.vertices[hull.faces]
            area = 0.5 * np.linalg.norm(
                np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]), axis=1
            ).sum()
            count = max(64, int(np.ceil(area * 1e4 * density)))
            rng = np.random.default_rng(np.random.SeedSequence([int(params["seed"]), g]))
            dense, _ = sample_surface(hull, count, rng)
            # hull vertices first, so corners are always covered
            dense = np.concatenate([hull.vertices[np.unique(hull.faces)], dense])
            keep = dense[farthest_point_cover(dense, radius)]
            points.append(keep)
            bodies += [name] * len(keep)
    if not points:
        raise ValueError("the hand model has no colliding mesh geoms to cover with points")
    return {"points": np.concatenate(points), "body": np.asarray(bodies)}
