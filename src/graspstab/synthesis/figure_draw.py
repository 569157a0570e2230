"""Drawing primitives of the synthesis figures: shading, depth-sorted meshes, axes, arrows, saving.

Apart from the three figures (:mod:`graspstab.synthesis.figure`), which compose these. Meshes are
drawn as one shaded ``Poly3DCollection`` per panel (object, hand and hull together, so
matplotlib's per-triangle depth sort orders them against each other). Files are written
atomically by :func:`graspstab.common.plotting.save`.
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np
from matplotlib.patches import FancyArrowPatch
from mpl_toolkits.mplot3d import proj3d
from mpl_toolkits.mplot3d.art3d import Poly3DCollection

from graspstab.common.plotting import save
from graspstab.synthesis.figure_meshes import Surface

DPI = 120
#: Back-face culling threshold on cos(shading normal, view); below zero so that silhouettes of
#: smoothed normals keep their faces.
BACKFACE_COS = -0.25


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


def save_png(fig: Any, out_path: str | Path, tight: bool = True) -> Path:
    """Write ``fig`` as a PNG atomically (dpi :data:`DPI`) and close it; ``tight`` crops the
    margins (at the cost of drawing the figure twice)."""
    save(fig, out_path, DPI, tight=tight, facecolor="white")
    return Path(out_path)


def unit(v: np.ndarray) -> np.ndarray:
    """``v`` normalised (the x axis for a near-zero vector)."""
    n = float(np.linalg.norm(v))
    return v / n if n > 1e-12 else np.array([1.0, 0.0, 0.0])
