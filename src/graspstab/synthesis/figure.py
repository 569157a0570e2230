"""Figures of the grasp-synthesis stage (thesis figs. 3.4, 3.6, energy histograms) from plain data.

A pre-grasp (fig. 3.4), a gallery of synthesised grasps (fig. 3.6) and per-object histograms of the
total energy (eq. 4), drawn with matplotlib (Agg, no OpenGL) from arrays and grasp tables, so they
depend on no other synthesis module. This module composes the three figures; the other jobs live
beside it: input checks and the gallery's choice (:mod:`~graspstab.synthesis.figure_data`),
decimated meshes (:mod:`~graspstab.synthesis.figure_meshes`), drawing primitives and atomic
saving (:mod:`~graspstab.synthesis.figure_draw`). Everything is in the object frame (the world
frame: object at its centre of mass, +z up); hand poses follow hand.xml's wrist convention (palm
position and quaternion w, x, y, z, then 16 joints in hand.json ``joint_names`` order).
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from pathlib import Path
from typing import Any, Literal

import numpy as np
import polars as pl
import trimesh
from matplotlib.lines import Line2D
from matplotlib.patches import Patch

from graspstab.common.plotting import plt
from graspstab.hand.names import FINGERS, FINGERTIP_BODIES
from graspstab.synthesis.figure_data import (
    FigureInputError,
    energy_floor,
    grasp_arrays,
    pregrasp_entry,
    require_columns,
    select_gallery_grasps,
)
from graspstab.synthesis.figure_draw import (
    Arrow3D,
    add_meshes,
    add_scale_bar,
    save_png,
    setup_axes,
    unit,
)
from graspstab.synthesis.figure_meshes import (
    HAND_CELL_DETAIL,
    HAND_CELL_GALLERY,
    OBJECT_FACES_DETAIL,
    OBJECT_FACES_GALLERY,
    HandMeshes,
    Surface,
    flat_surface,
    mesh_surface,
)

__all__ = ["FigureInputError", "plot_energy_histograms", "plot_grasp_gallery", "plot_pregrasp"]

# Colours of fig. 3.4 (caption: blue hull, orange anchor, red surface point, magenta approach,
# teal open hand); the object is a neutral warm grey so the hand stands out against it.
HULL_RGBA = (0.25, 0.45, 0.85, 0.16)
OBJECT_RGB = (0.80, 0.74, 0.62)
HAND_RGB = (0.10, 0.62, 0.60)
ANCHOR_COLOUR = "tab:orange"
SURFACE_COLOUR = "red"
APPROACH_COLOUR = "magenta"
ENERGY_COLOURS = {"energy_start": "0.55", "energy": "tab:blue"}
#: Pre-grasp view: degrees turned from the pure side view towards the approach direction.
PREGRASP_TURN = 35.0


# --------------------------------------------------------------------------------------------
# Figure 3.4: one pre-grasp
# --------------------------------------------------------------------------------------------


def pregrasp_view(
    direction: np.ndarray, finger_axis: np.ndarray, turn: float = PREGRASP_TURN
) -> tuple[float, float]:
    """(elev, azim) looking along the hand's knuckle row (so the fingers and the approach arrow
    both lie across the screen), turned ``turn`` degrees towards +direction so that the palm,
    which faces along the approach, shows; the upper of the two such views is taken."""
    d = unit(np.asarray(direction, dtype=float))
    f = np.asarray(finger_axis, dtype=float)
    f = f - (f @ d) * d
    lateral = np.cross(d, unit(f)) if np.linalg.norm(f) > 1e-9 else np.cross(d, [0.0, 0.0, 1.0])
    if np.linalg.norm(lateral) < 1e-6:
        lateral = np.array([0.0, -1.0, 0.0])
    lateral = unit(lateral)
    if lateral[2] < 0:
        lateral = -lateral
    t = np.radians(turn)
    cam = unit(np.cos(t) * lateral + np.sin(t) * d)
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
        tip = anchor + unit(vec) * length
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
    return save_png(fig, out_path)


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
    return save_png(fig, out_path, tight=False)  # the grid already fills the figure


# --------------------------------------------------------------------------------------------
# Energy histograms


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
    return save_png(fig, out_path)
