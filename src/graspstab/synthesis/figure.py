"""Figures of the grasp-synthesis stage (thesis figs. 3.4, 3.6, energy histograms) from plain data.

A pre-grasp (fig. 3.4), a gallery of synthesised grasps (fig. 3.6) and per-object histograms of the
total energy (eq. 4), drawn with matplotlib (Agg, no OpenGL) from arrays and grasp tables, so they
depend on no other synthesis module. Meshes are drawn as one shaded ``Poly3DCollection`` per panel
(object, hand and hull together, so matplotlib's per-triangle depth sort orders them against each
other), decimated by vertex clustering so that a panel renders in about a second. Everything is in
the object frame (the world frame: object at its centre of mass, +z up); hand poses follow
hand.xml's wrist convention (palm position and quaternion w, x, y, z, then 16 joints in hand.json
``joint_names`` order).
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Mapping, Sequence
from pathlib import Path
from typing import Any, Literal

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
import polars as pl  # noqa: E402
import trimesh  # noqa: E402
from matplotlib.lines import Line2D  # noqa: E402
from matplotlib.patches import FancyArrowPatch, Patch  # noqa: E402
from mpl_toolkits.mplot3d import proj3d  # noqa: E402
from mpl_toolkits.mplot3d.art3d import Poly3DCollection  # noqa: E402

from graspstab.common.io import atomic_path  # noqa: E402
from graspstab.hand.kinematics import HandKinematics  # noqa: E402
from graspstab.hand.meshes import body_collision_mesh, collision_geoms  # noqa: E402
from graspstab.hand.names import FINGERS, FINGERTIP_BODIES  # noqa: E402

DPI = 120
#: Grasp-table pose columns (object frame): palm position [m], quaternion w-x-y-z, 16 joints [rad].
WRIST_COLUMNS: tuple[str, ...] = ("wrist_x", "wrist_y", "wrist_z")
QUAT_COLUMNS: tuple[str, ...] = ("quat_w", "quat_x", "quat_y", "quat_z")
JOINT_COLUMNS: tuple[str, ...] = tuple(f"theta_{k:02d}" for k in range(16))
POSE_COLUMNS: tuple[str, ...] = WRIST_COLUMNS + QUAT_COLUMNS + JOINT_COLUMNS
#: Keys of a pre-grasp batch (3.1.3): arrays with a leading grasp dimension n.
PREGRASP_KEYS: tuple[str, ...] = (
    "wrist_pos",
    "quat",
    "joints",
    "anchor",
    "surface_point",
    "direction",
    "direction_raw",
    "standoff",
    "roll",
)

# Colours of fig. 3.4 (caption: blue hull, orange anchor, red surface point, magenta approach,
# teal open hand); the object is a neutral warm grey so the hand stands out against it.
HULL_RGBA = (0.25, 0.45, 0.85, 0.16)
OBJECT_RGB = (0.80, 0.74, 0.62)
HAND_RGB = (0.10, 0.62, 0.60)
ANCHOR_COLOUR = "tab:orange"
SURFACE_COLOUR = "red"
APPROACH_COLOUR = "magenta"
ENERGY_COLOURS = {"energy_start": "0.55", "energy": "tab:blue"}

# Decimation of the drawn meshes: clustering cells [m] for the hand's collision meshes (about 23k /
# 12k triangles for the whole ORCA hand) and target triangle counts for an object.
HAND_CELL_DETAIL = 0.002
HAND_CELL_GALLERY = 0.003
OBJECT_FACES_DETAIL = 4000
OBJECT_FACES_GALLERY = 3000
#: Back-face culling threshold on cos(shading normal, view); below zero so that silhouettes of
#: smoothed normals keep their faces.
BACKFACE_COS = -0.25
#: Pre-grasp view: degrees turned from the pure side view towards the approach direction.
PREGRASP_TURN = 35.0


class FigureInputError(ValueError):
    """A figure's input table or pre-grasp batch lacks a field or has the wrong shape."""


# --------------------------------------------------------------------------------------------
# Table helpers
# --------------------------------------------------------------------------------------------


def require_columns(columns: Iterable[str], required: Iterable[str], what: str) -> None:
    """Raise :class:`FigureInputError` naming every column of ``required`` not in ``columns``."""
    present = list(columns)
    missing = [c for c in required if c not in present]
    if missing:
        raise FigureInputError(
            f"{what} is missing column(s) {', '.join(repr(c) for c in missing)}; it has "
            f"{', '.join(present) if present else 'no columns'}. Pass a grasp table written by "
            "the synthesis stage (anneal_grasps)."
        )


def grasp_arrays(
    grasps: pl.DataFrame | Mapping[str, Any],
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Hand poses of grasp-table rows: wrist position (n, 3), quaternion w-x-y-z (n, 4) and
    joints (n, 16) as float64; ``grasps`` is a table or one row (``frame.row(i, named=True)``)."""
    columns = grasps.columns if isinstance(grasps, pl.DataFrame) else list(grasps)
    require_columns(columns, POSE_COLUMNS, "grasp table")

    def block(names: Sequence[str]) -> np.ndarray:
        if isinstance(grasps, pl.DataFrame):
            return grasps.select(names).to_numpy().astype(np.float64).reshape(-1, len(names))
        cols = [np.atleast_1d(np.asarray(grasps[c], dtype=np.float64)) for c in names]
        return np.stack(cols, axis=1)

    return block(WRIST_COLUMNS), block(QUAT_COLUMNS), block(JOINT_COLUMNS)


def select_gallery_grasps(
    grasps: pl.DataFrame,
    per_object: int = 2,
    max_objects: int = 6,
    seed: int = 0,
    choose: Literal["best", "random"] = "best",
) -> pl.DataFrame:
    """Rows for the gallery: the first ``max_objects`` objects in table order, and of each its
    ``per_object`` lowest-``energy`` grasps (``choose="best"``, ties by grasp_id) or a seeded
    random sample of them (``"random"``, as the caption of fig. 3.6 says). Non-finite energies are
    never shown. Returned in object order, then energy order."""
    if per_object < 1 or max_objects < 1:
        raise ValueError(
            f"per_object and max_objects must be >= 1, got {per_object}, {max_objects}"
        )
    if choose not in ("best", "random"):
        raise ValueError(f"choose must be 'best' or 'random', got {choose!r}")
    require_columns(grasps.columns, ("object", "energy", "grasp_id", *POSE_COLUMNS), "grasp table")
    finite = grasps.filter(pl.col("energy").is_finite())
    objects = finite["object"].unique(maintain_order=True).to_list()[:max_objects]
    rng = np.random.default_rng(seed)
    parts = []
    for obj in objects:
        rows = finite.filter(pl.col("object") == obj).sort(["energy", "grasp_id"])
        if choose == "random" and rows.height > per_object:
            pick = np.sort(rng.choice(rows.height, size=per_object, replace=False))
            rows = rows[pick.tolist()]
        parts.append(rows.head(per_object))
    if not parts:
        return grasps.clear()
    return pl.concat(parts)


# --------------------------------------------------------------------------------------------
# Geometry helpers
# --------------------------------------------------------------------------------------------


def decimate(
    vertices: np.ndarray, faces: np.ndarray, cell: float, normals: np.ndarray | None = None
) -> tuple[np.ndarray, np.ndarray]:
    """Vertex-clustering decimation on a ``cell``-sized grid that keeps the face winding;
    degenerate and duplicate faces are dropped. With vertex ``normals``, vertices whose normals
    point different ways (dominant axis and sign) never merge, so the two sides of a wall
    thinner than ``cell`` (a mug's rim) stay apart."""
    vertices, faces, _ = _cluster(vertices, faces, cell, normals)
    return vertices, faces


def _cluster(
    vertices: np.ndarray, faces: np.ndarray, cell: float, normals: np.ndarray | None = None
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Decimate as :func:`decimate`, also returning each original vertex's cluster index."""
    keys = np.floor(np.asarray(vertices) / cell).astype(np.int64)
    if normals is not None:
        axis = np.argmax(np.abs(normals), axis=1)
        side = np.take_along_axis(normals, axis[:, None], axis=1)[:, 0] > 0
        keys = np.column_stack([keys, 2 * axis + side])
    _, first, inverse = np.unique(keys, axis=0, return_index=True, return_inverse=True)
    inverse = inverse.reshape(-1)
    new_faces = inverse[np.asarray(faces)]
    ok = (
        (new_faces[:, 0] != new_faces[:, 1])
        & (new_faces[:, 1] != new_faces[:, 2])
        & (new_faces[:, 0] != new_faces[:, 2])
    )
    new_faces = new_faces[ok]
    _, keep = np.unique(np.sort(new_faces, axis=1), axis=0, return_index=True)
    return np.asarray(vertices)[first], new_faces[np.sort(keep)], inverse


def decimate_shaded(
    vertices: np.ndarray, faces: np.ndarray, cell: float, split_sides: bool = False
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Decimated (vertices, faces) plus per-face normals averaged from the ORIGINAL surface's
    vertex normals in each cluster: clustering folds a few small faces over, and shading them by
    their own normal would show dark specks, so the shading follows the undecimated surface.
    ``split_sides`` keeps the two sides of thin walls apart (see :func:`decimate`)."""
    normals = np.asarray(trimesh.Trimesh(vertices, faces, process=False).vertex_normals)
    new_vertices, new_faces, inverse = _cluster(
        vertices, faces, cell, normals if split_sides else None
    )
    cluster_normals = np.zeros((len(new_vertices), 3))
    np.add.at(cluster_normals, inverse, normals)
    face_normals = cluster_normals[new_faces].sum(axis=1)
    face_normals /= np.linalg.norm(face_normals, axis=1, keepdims=True) + 1e-15
    return new_vertices, new_faces, face_normals


Surface = tuple[np.ndarray, np.ndarray]
"""Triangles (m, 3, 3) [m] and their unit outward shading normals (m, 3)."""


def flat_surface(tris: np.ndarray) -> Surface:
    """Triangles with their own (flat) normals."""
    normals = np.cross(tris[:, 1] - tris[:, 0], tris[:, 2] - tris[:, 0])
    normals /= np.linalg.norm(normals, axis=1, keepdims=True) + 1e-15
    return tris, normals


def mesh_surface(mesh: trimesh.Trimesh, max_faces: int) -> Surface:
    """``mesh`` as a :data:`Surface`, decimated to roughly ``max_faces`` if it has more."""
    if len(mesh.faces) <= max_faces:
        tris = np.asarray(mesh.vertices)[np.asarray(mesh.faces)]
        return tris, np.asarray(mesh.face_normals)
    # A clustered surface has about 2 * area / cell^2 triangles.
    cell = math.sqrt(2.0 * float(mesh.area) / max_faces)
    vertices, faces, normals = decimate_shaded(mesh.vertices, mesh.faces, cell, split_sides=True)
    return vertices[faces], normals


class HandMeshes:
    """The hand's collision meshes (hand.xml geoms with contype/conaffinity), decimated once and
    posed by the MuJoCo reference kinematics."""

    def __init__(self, hand_dir: str | Path, cell: float = HAND_CELL_DETAIL) -> None:
        self.kin = HandKinematics(hand_dir)
        model = self.kin.model
        self.bodies: dict[str, tuple[np.ndarray, np.ndarray]] = {}
        for i in range(1, model.nbody):
            body = model.body(i).name
            if collision_geoms(model, body):
                mesh = body_collision_mesh(model, body)
                vertices, faces, normals = decimate_shaded(mesh.vertices, mesh.faces, cell)
                self.bodies[body] = (vertices[faces], normals)

    def surface(self, wrist_pos: np.ndarray, quat: np.ndarray, joints: np.ndarray) -> Surface:
        """World triangles and normals of the hand at one pose g = (P, R, theta)."""
        poses = self.kin.link_poses(
            np.asarray(wrist_pos, dtype=float),
            np.asarray(quat, dtype=float),
            np.asarray(joints, dtype=float),
        )
        tris = [t @ poses[b][1].T + poses[b][0] for b, (t, _) in self.bodies.items()]
        normals = [n @ poses[b][1].T for b, (_, n) in self.bodies.items()]
        return np.concatenate(tris), np.concatenate(normals)


def view_vector(elev: float, azim: float) -> np.ndarray:
    """Unit vector from the scene towards matplotlib's camera at (elev, azim) in degrees."""
    e, a = np.radians(elev), np.radians(azim)
    return np.array([np.cos(e) * np.cos(a), np.cos(e) * np.sin(a), np.sin(e)])


def shaded_colours(
    normals: np.ndarray, rgb: Sequence[float], alpha: float, elev: float, azim: float
) -> np.ndarray:
    """Per-triangle RGBA with Lambert shading from a light above-left of the camera."""
    cam = view_vector(elev, azim)
    right = np.cross([0.0, 0.0, 1.0], cam)
    right /= np.linalg.norm(right) + 1e-15
    light = cam + 0.6 * np.array([0.0, 0.0, 1.0]) - 0.4 * right
    light /= np.linalg.norm(light)
    shade = 0.40 + 0.60 * np.clip(normals @ light, 0.0, 1.0)
    colours = np.empty((len(normals), 4))
    colours[:, :3] = np.clip(np.asarray(rgb)[None, :] * shade[:, None], 0.0, 1.0)
    colours[:, 3] = alpha
    return colours


Layer = tuple[Surface, Sequence[float], float, bool]
"""A drawn surface: (surface, rgb, alpha, cull back faces)."""


def add_meshes(ax: Any, layers: Sequence[Layer], elev: float, azim: float) -> None:
    """Draw layers as ONE collection, so depth sorting spans them all. Culling the back faces of
    a closed opaque surface (the object) stops them poking through thin walls in the painter's
    algorithm; the hand is not culled (its decimated CAD parts have too many folded faces)."""
    cam = view_vector(elev, azim)
    tris, colours = [], []
    for (t, normals), rgb, alpha, cull in layers:
        if cull:
            front = normals @ cam > BACKFACE_COS
            t, normals = t[front], normals[front]
        tris.append(t)
        colours.append(shaded_colours(normals, rgb, alpha, elev, azim))
    face = np.concatenate(colours)
    edges = face.copy()
    edges[:, 3] = np.where(face[:, 3] >= 1.0, 1.0, 0.0)  # hide seams of opaque surfaces only
    coll = Poly3DCollection(
        np.concatenate(tris), facecolors=face, edgecolors=edges, linewidths=0.25, zorder=1
    )
    ax.add_collection3d(coll)


def setup_axes(ax: Any, points: np.ndarray, elev: float, azim: float, pad: float = 0.04) -> float:
    """Equal scaling on a cube around ``points``, orthographic view, no axes; returns the half
    side length of the cube [m]."""
    lo, hi = points.min(axis=0), points.max(axis=0)
    centre = 0.5 * (lo + hi)
    half = 0.5 * float(np.max(hi - lo)) * (1.0 + pad)
    for setter, c in zip((ax.set_xlim, ax.set_ylim, ax.set_zlim), centre, strict=True):
        setter(c - half, c + half)
    ax.set_box_aspect((1, 1, 1), zoom=1.25)
    ax.set_proj_type("ortho")
    ax.view_init(elev=elev, azim=azim)
    ax.set_axis_off()
    ax.computed_zorder = False
    return half


def add_scale_bar(ax: Any, points: np.ndarray, elev: float, azim: float, length: float) -> None:
    """A screen-horizontal bar of ``length`` [m] under the scene, labelled in centimetres."""
    cam = view_vector(elev, azim)
    right = np.cross([0.0, 0.0, 1.0], cam)
    right /= np.linalg.norm(right)
    up = np.cross(cam, right)
    depth = points @ up
    lateral = points @ right
    base = points.mean(axis=0) - (points.mean(axis=0) @ up - depth.min()) * up
    start = base + (lateral.min() - base @ right) * right - 0.02 * up
    end = start + length * right
    ax.plot(*np.stack([start, end]).T, color="k", linewidth=2.0, zorder=6)
    mid = 0.5 * (start + end) - 0.012 * up
    ax.text(*mid, f"{length * 100:g} cm", ha="center", va="top", fontsize=8, zorder=6)


class Arrow3D(FancyArrowPatch):
    """A 2-D arrow patch between two 3-D points, re-projected at every draw (matplotlib's 3-D
    quiver draws its head as two short lines that vanish when seen edge-on)."""

    def __init__(
        self,
        start: np.ndarray,
        end: np.ndarray,
        colour: str,
        linestyle: str = "-",
        alpha: float = 1.0,
        zorder: float = 7,
    ) -> None:
        super().__init__(
            (0.0, 0.0),
            (0.0, 0.0),
            arrowstyle="-|>",
            mutation_scale=16,
            shrinkA=0.0,
            shrinkB=4.0,
            color=colour,
            linewidth=2.0,
            linestyle=linestyle,
            alpha=alpha,
            zorder=zorder,
        )
        self._points = np.stack([np.asarray(start, float), np.asarray(end, float)])

    def do_3d_projection(self, renderer: Any = None) -> float:
        """Project the end points with the axes' current view (called by the 3-D axes)."""
        xs, ys, zs = proj3d.proj_transform(*self._points.T, self.axes.M)
        self.set_positions((xs[0], ys[0]), (xs[1], ys[1]))
        return float(np.min(zs))


def save_figure(fig: Any, out_path: str | Path, tight: bool = True) -> Path:
    """Write ``fig`` as a PNG atomically (dpi :data:`DPI`) and close it; ``tight`` crops the
    margins (at the cost of drawing the figure twice)."""
    out = Path(out_path)
    with atomic_path(out) as tmp:
        fig.savefig(
            tmp, format="png", dpi=DPI, bbox_inches="tight" if tight else None, facecolor="white"
        )
    plt.close(fig)
    return out


def _unit(v: np.ndarray) -> np.ndarray:
    n = float(np.linalg.norm(v))
    return v / n if n > 1e-12 else np.array([1.0, 0.0, 0.0])


# --------------------------------------------------------------------------------------------
# Figure 3.4: one pre-grasp
# --------------------------------------------------------------------------------------------


def pregrasp_entry(pregrasp: Mapping[str, Any], index: int) -> dict[str, np.ndarray]:
    """Entry ``index`` of a pre-grasp batch as float64 arrays, checking keys and shapes."""
    missing = [k for k in PREGRASP_KEYS if k not in pregrasp]
    if missing:
        raise FigureInputError(
            f"pre-grasp batch is missing key(s) {', '.join(repr(k) for k in missing)}; it has "
            f"{', '.join(pregrasp)}. Pass the dict returned by sample_pregrasps (3.1.3)."
        )
    shapes = {"quat": 4, "joints": 16, "standoff": 0, "roll": 0}
    n = len(np.asarray(pregrasp["wrist_pos"]))
    if not -n <= index < n:
        raise IndexError(f"pre-grasp index {index} out of range for a batch of {n}")
    out = {}
    for key in PREGRASP_KEYS:
        arr = np.asarray(pregrasp[key], dtype=np.float64)
        width = shapes.get(key, 3)
        expected = (n,) if width == 0 else (n, width)
        if arr.shape != expected:
            raise FigureInputError(f"pre-grasp {key!r} must have shape {expected}, got {arr.shape}")
        out[key] = arr[index]
    return out


def pregrasp_view(
    direction: np.ndarray, finger_axis: np.ndarray, turn: float = PREGRASP_TURN
) -> tuple[float, float]:
    """(elev, azim) looking along the hand's knuckle row (so the fingers and the approach arrow
    both lie across the screen), turned ``turn`` degrees towards +direction so that the palm,
    which faces along the approach, shows; the upper of the two such views is taken."""
    d = _unit(np.asarray(direction, dtype=float))
    f = np.asarray(finger_axis, dtype=float)
    f = f - (f @ d) * d
    lateral = np.cross(d, _unit(f)) if np.linalg.norm(f) > 1e-9 else np.cross(d, [0.0, 0.0, 1.0])
    if np.linalg.norm(lateral) < 1e-6:
        lateral = np.array([0.0, -1.0, 0.0])
    lateral = _unit(lateral)
    if lateral[2] < 0:
        lateral = -lateral
    t = np.radians(turn)
    cam = _unit(np.cos(t) * lateral + np.sin(t) * d)
    return float(np.degrees(np.arcsin(np.clip(cam[2], -1, 1)))), float(
        np.degrees(np.arctan2(cam[1], cam[0]))
    )


def plot_pregrasp(
    out_path: str | Path,
    mesh: trimesh.Trimesh,
    inflated_hull: trimesh.Trimesh,
    pregrasp: Mapping[str, Any],
    hand_dir: str | Path,
    index: int = 0,
    object_id: str = "",
    view: tuple[float, float] | None = None,
) -> Path:
    """Fig. 3.4: inflated hull (blue), anchor a (orange), nearest surface point s (red), approach
    n = (s - a)/|s - a| (eq. 3, solid magenta) and its jittered n-hat (dashed), the object and the
    open hand at the pre-grasp pose (teal). ``view`` = (elev, azim) overrides the automatic one."""
    entry = pregrasp_entry(pregrasp, index)
    anchor, surface = entry["anchor"], entry["surface_point"]
    meshes = HandMeshes(hand_dir, cell=HAND_CELL_DETAIL)
    hand = meshes.surface(entry["wrist_pos"], entry["quat"], entry["joints"])
    if view is None:
        poses = meshes.kin.link_poses(entry["wrist_pos"], entry["quat"], entry["joints"])
        tips = [poses[FINGERTIP_BODIES[f]][0] for f in FINGERS if f != "thumb"]
        view = pregrasp_view(entry["direction"], np.mean(tips, axis=0) - entry["wrist_pos"])
    elev, azim = view
    obj = mesh_surface(mesh, OBJECT_FACES_DETAIL)
    # Subdivide the big hull faces so that they depth-sort correctly against the small ones.
    edge = 0.08 * float(np.max(inflated_hull.extents))
    vertices, faces = trimesh.remesh.subdivide_to_size(
        inflated_hull.vertices, inflated_hull.faces, max_edge=edge
    )
    hull = flat_surface(np.asarray(vertices)[np.asarray(faces)])

    fig = plt.figure(figsize=(7.6, 5.4))
    ax = fig.add_axes((0.0, 0.0, 0.72, 0.92), projection="3d")
    add_meshes(
        ax,
        [
            (obj, OBJECT_RGB, 1.0, True),
            (hand, HAND_RGB, 1.0, False),
            (hull, HULL_RGBA[:3], HULL_RGBA[3], False),
        ],
        elev,
        azim,
    )
    gap = float(np.linalg.norm(surface - anchor))
    length = max(gap, 1e-3)
    for vec, style, alpha in ((entry["direction_raw"], "-", 1.0), (entry["direction"], "--", 0.8)):
        tip = anchor + _unit(vec) * length
        ax.add_artist(Arrow3D(anchor, tip, APPROACH_COLOUR, style, alpha, zorder=7))
    ax.scatter(*anchor, s=55, c=ANCHOR_COLOUR, edgecolors="k", linewidths=0.6, zorder=8)
    ax.scatter(*surface, s=55, c=SURFACE_COLOUR, edgecolors="k", linewidths=0.6, zorder=8)
    points = np.concatenate([hull[0].reshape(-1, 3), hand[0].reshape(-1, 3)])
    setup_axes(ax, points, elev, azim)
    add_scale_bar(ax, points, elev, azim, length=0.05)
    handles = [
        Patch(facecolor=HULL_RGBA[:3], alpha=0.35, label="inflated convex hull"),
        Patch(facecolor=OBJECT_RGB, label="object"),
        Line2D([], [], marker="o", ls="", mfc=ANCHOR_COLOUR, mec="k", label="anchor $a$"),
        Line2D([], [], marker="o", ls="", mfc=SURFACE_COLOUR, mec="k", label="surface point $s$"),
        Line2D([], [], color=APPROACH_COLOUR, lw=2, label=r"approach $\mathbf{n}$ (eq. 3)"),
        Line2D([], [], color=APPROACH_COLOUR, lw=2, ls="--", label=r"jittered $\hat{\mathbf{n}}$"),
        Patch(facecolor=HAND_RGB, label="open hand"),
    ]
    fig.legend(handles=handles, loc="center left", bbox_to_anchor=(0.72, 0.5), fontsize=9,
               frameon=False)  # fmt: skip
    title = "Pre-grasp initialisation" + (f": {object_id}" if object_id else "")
    detail = (
        f"standoff {entry['standoff'] * 100:.1f} cm, roll {np.degrees(entry['roll']):.0f}°, "
        f"$|s - a|$ = {gap * 100:.1f} cm"
    )
    fig.suptitle(f"{title}\n{detail}", fontsize=10, y=0.98)
    return save_figure(fig, out_path)


# --------------------------------------------------------------------------------------------
# Figure 3.6: gallery of synthesised grasps
# --------------------------------------------------------------------------------------------


def grasp_view(wrist_pos: np.ndarray, centre: np.ndarray) -> tuple[float, float]:
    """(elev, azim) from the hand's side, turned 55 degrees so the object is not hidden."""
    w = np.asarray(wrist_pos, dtype=float) - np.asarray(centre, dtype=float)
    azim = float(np.degrees(np.arctan2(w[1], w[0]))) + 55.0 if np.hypot(w[0], w[1]) > 1e-6 else 35.0
    elev = 25.0 if w[2] > -0.02 else -10.0  # look from below only if the hand is underneath
    return elev, azim


def plot_grasp_gallery(
    out_path: str | Path,
    grasps: pl.DataFrame,
    object_dirs: Mapping[str, str | Path],
    hand_dir: str | Path,
    per_object: int = 2,
    max_objects: int = 6,
    seed: int = 0,
    choose: Literal["best", "random"] = "best",
    ncols: int = 4,
) -> Path:
    """Fig. 3.6: a grid of 3-D panels, each an object (``object_dirs[id]/mesh.obj``) with one
    synthesised grasp, titled with the object id and the total energy E (eq. 4). By default it
    shows each object's ``per_object`` LOWEST-energy grasps (see :func:`select_gallery_grasps`),
    not random ones as the thesis caption says; ``choose="random"`` gives a seeded random pick."""
    rows = select_gallery_grasps(grasps, per_object, max_objects, seed, choose)
    if rows.height == 0:
        raise FigureInputError("grasp table has no grasp with a finite energy to show")
    unknown = sorted(set(rows["object"].to_list()) - set(object_dirs))
    if unknown:
        raise FigureInputError(
            f"no object directory for {', '.join(unknown)}; object_dirs has "
            f"{', '.join(sorted(object_dirs)) or 'nothing'}"
        )
    pos, quat, joints = grasp_arrays(rows)
    hand = HandMeshes(hand_dir, cell=HAND_CELL_GALLERY)
    meshes: dict[str, Surface] = {}
    ncols = max(1, min(ncols, rows.height))
    nrows = math.ceil(rows.height / ncols)
    height = 3.2 * nrows
    fig = plt.figure(figsize=(3.0 * ncols, height))
    for i, (obj, energy) in enumerate(zip(rows["object"], rows["energy"], strict=True)):
        if obj not in meshes:
            mesh = trimesh.load(Path(object_dirs[obj]) / "mesh.obj", force="mesh", process=False)
            meshes[obj] = mesh_surface(mesh, OBJECT_FACES_GALLERY)
        obj_surf = meshes[obj]
        hand_surf = hand.surface(pos[i], quat[i], joints[i])
        centre = obj_surf[0].reshape(-1, 3).mean(axis=0)
        elev, azim = grasp_view(pos[i], centre)
        ax = fig.add_subplot(nrows, ncols, i + 1, projection="3d")
        add_meshes(
            ax, [(obj_surf, OBJECT_RGB, 1.0, True), (hand_surf, HAND_RGB, 1.0, False)], elev, azim
        )
        setup_axes(ax, np.concatenate([obj_surf[0], hand_surf[0]]).reshape(-1, 3), elev, azim)
        ax.set_title(f"{obj}\n$E$ = {energy:.3g}", fontsize=9, pad=0)
    title_room = 0.42 / 3.2  # inches of title above each panel, as a fraction of a row
    fig.subplots_adjust(
        wspace=0.0, hspace=title_room, left=0.0, right=1.0, bottom=0.0, top=1.0 - 0.42 / height
    )
    return save_figure(fig, out_path, tight=False)  # the grid already fills the figure


# --------------------------------------------------------------------------------------------
# Energy histograms
# --------------------------------------------------------------------------------------------


def energy_floor(values: np.ndarray) -> float:
    """The smallest energy drawn on the log axis: half the smallest positive value (1e-6 if
    none); zeros (and any non-positive value) are drawn at this floor."""
    positive = values[np.isfinite(values) & (values > 0)]
    return 0.5 * float(positive.min()) if positive.size else 1e-6


def plot_energy_histograms(
    out_path: str | Path, grasps: pl.DataFrame, bins: int = 30, ncols: int = 4
) -> Path:
    """Per object (in table order), histograms of the total energy E (eq. 4) at the pre-grasp
    (``energy_start``) and at the best annealing state (``energy``) on shared log-spaced bins,
    medians dashed, one legend for the figure. Non-finite values are dropped, values <= 0 are
    drawn at :func:`energy_floor`."""
    require_columns(grasps.columns, ("object", "energy", "energy_start"), "grasp table")
    if grasps.height == 0:
        raise FigureInputError("grasp table is empty: nothing to histogram")
    both = np.concatenate([grasps[c].cast(pl.Float64).to_numpy() for c in ENERGY_COLOURS])
    floor = energy_floor(both)
    finite = both[np.isfinite(both)]
    if finite.size == 0:
        raise FigureInputError("grasp table has no finite energy_start or energy value")
    top = max(float(finite.max()), floor * 10.0)
    edges = np.geomspace(floor, top * 1.0001, bins + 1)
    objects = grasps["object"].unique(maintain_order=True).to_list()
    ncols = max(1, min(ncols, len(objects)))
    nrows = math.ceil(len(objects) / ncols)
    fig, axes = plt.subplots(
        nrows, ncols, figsize=(3.0 * ncols, 2.3 * nrows), sharex=True, squeeze=False
    )
    labels = {"energy_start": "pre-grasp $E(g_0)$", "energy": "best state $E(g^*)$"}
    for ax, obj in zip(axes.flat, objects, strict=False):
        rows = grasps.filter(pl.col("object") == obj)
        notes = []
        for col, colour in ENERGY_COLOURS.items():
            raw = rows[col].cast(pl.Float64).to_numpy()
            vals = raw[np.isfinite(raw)]
            if (low := int(np.sum(vals <= 0))) > 0:
                notes.append(f"{low} {col} ≤ 0 at left edge")
            if (bad := raw.size - vals.size) > 0:
                notes.append(f"{bad} {col} non-finite, omitted")
            if vals.size == 0:
                continue
            vals = np.maximum(vals, floor)
            ax.hist(vals, bins=edges, color=colour, alpha=0.6)
            ax.axvline(float(np.median(vals)), color=colour, ls="--", lw=1.3)
        if notes:
            box = {"fc": "white", "ec": "none", "alpha": 0.8}
            ax.text(0.5, 0.97, "\n".join(notes), transform=ax.transAxes, fontsize=6, ha="center",
                    va="top", color="0.25", bbox=box)  # fmt: skip
        ax.set_xscale("log")
        ax.set_title(f"{obj} (n = {rows.height})", fontsize=9)
        ax.tick_params(labelsize=7)
        ax.spines[["top", "right"]].set_visible(False)
    for ax in axes.flat[len(objects) :]:
        ax.set_visible(False)
    for ax in axes[:, 0]:
        ax.set_ylabel("grasps", fontsize=8)
    for j in range(ncols):  # the lowest visible panel of each column carries the x label
        col_axes = [a for a in axes[:, j] if a.get_visible()]
        if col_axes:
            col_axes[-1].set_xlabel("total energy $E$ (eq. 4 + $E_{hpen}$)", fontsize=8)
            col_axes[-1].xaxis.set_tick_params(labelbottom=True)
    handles = [
        Patch(facecolor=ENERGY_COLOURS["energy_start"], alpha=0.6, label=labels["energy_start"]),
        Patch(facecolor=ENERGY_COLOURS["energy"], alpha=0.6, label=labels["energy"]),
        Line2D([], [], color="k", ls="--", lw=1.3, label="median"),
    ]
    fig.legend(handles=handles, loc="upper center", ncol=3, fontsize=8, frameon=False)
    fig.tight_layout(rect=(0, 0, 1, 1.0 - 0.35 / (2.3 * nrows + 0.35)))
    return save_figure(fig, out_path)
