"""Hand figures: contact candidates (thesis fig. 3.3) and the capsule/box approximation (3.5a)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
from mpl_toolkits.mplot3d.art3d import Poly3DCollection

from graspstab.common.io import read_json
from graspstab.common.plotting import plt, save
from graspstab.hand import names
from graspstab.hand.kinematics import HandKinematics
from graspstab.hand.meshes import body_collision_mesh, collision_geoms

DPI = 150
FINGER_COLOURS = {
    "thumb": "tab:orange",
    "index": "tab:blue",
    "middle": "tab:green",
    "ring": "tab:purple",
    "little": "tab:brown",
}
VIEWS = ((10.0, 90.0, "palm side"), (25.0, 50.0, "oblique"))  # (elevation, azimuth, title)


def display_pose() -> np.ndarray:
    """A mildly flexed open pose (canonical joint order) that shows the palm-side surfaces."""
    pose = {"abd": 0.0, "mcp": 0.35, "pip": 0.35, "t-cmc": 0.0, "t-abd": 0.4}
    joints = []
    for j in names.FINGER_JOINTS:
        short = j.removeprefix("right_")
        joints.append(pose[short] if short in pose else pose[short.split("-")[1]])
    return np.asarray(joints)


def decimate(vertices: np.ndarray, faces: np.ndarray, cell: float) -> tuple[np.ndarray, np.ndarray]:
    """Vertex-clustering decimation on a ``cell``-sized grid (enough for a drawing)."""
    keys = np.floor(vertices / cell).astype(np.int64)
    _, first, inverse = np.unique(keys, axis=0, return_index=True, return_inverse=True)
    inverse = inverse.reshape(-1)
    new_faces = inverse[faces]
    ok = (
        (new_faces[:, 0] != new_faces[:, 1])
        & (new_faces[:, 1] != new_faces[:, 2])
        & (new_faces[:, 0] != new_faces[:, 2])
    )
    new_faces = np.unique(np.sort(new_faces[ok], axis=1), axis=0)
    return vertices[first], new_faces


def _world_triangles(kin: HandKinematics, joints: np.ndarray, cell: float) -> np.ndarray:
    poses = kin.link_poses(np.zeros(3), np.array([1.0, 0, 0, 0]), joints)
    tris = []
    for body, (pos, rot) in poses.items():
        if not collision_geoms(kin.model, body):
            continue
        mesh = body_collision_mesh(kin.model, body)
        v, f = decimate(mesh.vertices, mesh.faces, cell)
        tris.append((v @ rot.T + pos)[f])
    return np.concatenate(tris)


def _setup_axes(ax: plt.Axes, tris: np.ndarray, elev: float, azim: float, title: str) -> None:
    pts = tris.reshape(-1, 3)
    centre = 0.5 * (pts.min(axis=0) + pts.max(axis=0))
    half = 0.5 * float(np.max(pts.max(axis=0) - pts.min(axis=0)))
    ax.set_xlim(centre[0] - half, centre[0] + half)
    ax.set_ylim(centre[1] - half, centre[1] + half)
    ax.set_zlim(centre[2] - half, centre[2] + half)
    ax.set_box_aspect((1, 1, 1))
    ax.view_init(elev=elev, azim=azim)
    ax.set_xlabel("x [m]")
    ax.set_ylabel("y [m]" if azim != 90.0 else "")
    if azim == 90.0:  # looking along -y: the y axis is edge-on
        ax.set_yticklabels([])
    ax.set_zlabel("z [m]")
    ax.tick_params(labelsize=6)
    ax.set_title(title, fontsize=9)
    ax.computed_zorder = False


def _mesh_collection(tris: np.ndarray, alpha: float) -> Poly3DCollection:
    normals = np.cross(tris[:, 1] - tris[:, 0], tris[:, 2] - tris[:, 0])
    normals /= np.linalg.norm(normals, axis=1, keepdims=True) + 1e-12
    light = np.array([0.3, 0.8, 0.5]) / np.linalg.norm([0.3, 0.8, 0.5])
    shade = 0.55 + 0.4 * np.abs(normals @ light)
    colours = np.column_stack([shade, shade, shade, np.full(len(shade), alpha)])
    return Poly3DCollection(tris, facecolors=colours, edgecolors="none", zorder=1)


def plot_candidates(hand_dir: str | Path, out_png: str | Path) -> None:
    """The hand's collision meshes with the 120 contact candidates as red dots (fig. 3.3)."""
    kin = HandKinematics(hand_dir)
    joints = display_pose()
    tris = _world_triangles(kin, joints, cell=0.0012)
    pts = kin.candidates_world(np.zeros(3), np.array([1.0, 0, 0, 0]), joints)
    fig = plt.figure(figsize=(10, 5))
    for i, (elev, azim, title) in enumerate(VIEWS):
        ax = fig.add_subplot(1, 2, i + 1, projection="3d")
        ax.add_collection3d(_mesh_collection(tris, alpha=1.0))
        ax.scatter(*pts.T, c="red", s=9, depthshade=False, zorder=5, edgecolors="darkred")
        _setup_axes(ax, tris, elev, azim, f"{title}: {len(pts)} contact candidates")
    save(fig, out_png, DPI, tight=True)


def _capsule_surface(p0: np.ndarray, p1: np.ndarray, r: float, n: int = 14) -> np.ndarray:
    """Grid points (3, m, n) of a capsule surface: cylinder plus two hemispheres."""
    axis = p1 - p0
    length = float(np.linalg.norm(axis))
    a = axis / length if length > 1e-9 else np.array([0.0, 0.0, 1.0])
    u = np.cross(a, [1.0, 0, 0] if abs(a[0]) < 0.9 else [0, 1.0, 0])
    u /= np.linalg.norm(u)
    w = np.cross(a, u)
    phi = np.linspace(0, 2 * np.pi, n)
    theta = np.linspace(-np.pi / 2, np.pi / 2, n)
    # s: position along the axis, rho: radius of the ring
    rings_s = np.concatenate(
        [r * np.sin(theta[: n // 2]), [0.0, length], length + r * np.sin(theta[n // 2 :])]
    )
    rings_rho = np.concatenate([r * np.cos(theta[: n // 2]), [r, r], r * np.cos(theta[n // 2 :])])
    pts = (
        p0[:, None, None]
        + a[:, None, None] * rings_s[None, :, None]
        + rings_rho[None, :, None]
        * (
            u[:, None, None] * np.cos(phi)[None, None, :]
            + w[:, None, None] * np.sin(phi)[None, None, :]
        )
    )
    return pts


def _box_faces(centre: np.ndarray, rot: np.ndarray, half: np.ndarray) -> np.ndarray:
    signs = np.array([[x, y, z] for x in (-1, 1) for y in (-1, 1) for z in (-1, 1)], dtype=float)
    corners = centre + (signs * half) @ rot.T
    quads = [[0, 1, 3, 2], [4, 5, 7, 6], [0, 1, 5, 4], [2, 3, 7, 6], [0, 2, 6, 4], [1, 3, 7, 5]]
    return corners[np.array(quads)]


def plot_capsules(hand_dir: str | Path, out_png: str | Path) -> None:
    """Capsules (per finger colour) and the palm box over the faint hand mesh (fig. 3.5a)."""
    kin = HandKinematics(hand_dir)
    data = read_json(Path(hand_dir) / "capsules.json")
    joints = display_pose()
    poses = kin.link_poses(np.zeros(3), np.array([1.0, 0, 0, 0]), joints)
    tris = _world_triangles(kin, joints, cell=0.0015)
    box = data["palm_box"]
    pos, rot = poses[box["body"]]
    quads = _box_faces(
        pos + rot @ np.asarray(box["center"]),
        rot @ np.asarray(box["rotation"]),
        np.asarray(box["half_extents"]),
    )
    fig = plt.figure(figsize=(10, 5))
    for i, (elev, azim, title) in enumerate(VIEWS):
        ax = fig.add_subplot(1, 2, i + 1, projection="3d")
        ax.add_collection3d(_mesh_collection(tris, alpha=0.25))
        for c in data["capsules"]:
            bpos, brot = poses[c["body"]]
            p0 = bpos + brot @ np.asarray(c["p0"])
            p1 = bpos + brot @ np.asarray(c["p1"])
            x, y, z = _capsule_surface(p0, p1, float(c["radius"]))
            ax.plot_surface(
                x,
                y,
                z,
                color=FINGER_COLOURS[c["finger"]],
                alpha=0.45,
                linewidth=0.2,
                edgecolor="k",
                shade=True,
                zorder=3,
            )
            ax.plot(*np.stack([p0, p1]).T, "k--", linewidth=0.8, zorder=4)
        ax.add_collection3d(
            Poly3DCollection(
                quads,
                facecolors=(0.8, 0.2, 0.2, 0.15),
                edgecolors="darkred",
                linewidths=0.8,
                zorder=2,
            )
        )
        _setup_axes(ax, tris, elev, azim, f"{title}: {len(data['capsules'])} capsules + palm box")
    save(fig, out_png, DPI, tight=True)
