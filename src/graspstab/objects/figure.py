"""Thesis-style figure of the preprocessed objects, each drawn as its coloured convex parts."""

from __future__ import annotations

import json
import math
import os
from collections.abc import Sequence
from pathlib import Path

import numpy as np
from mpl_toolkits.mplot3d.art3d import Poly3DCollection

from graspstab.common.plotting import plt, save


def load_parts(object_dir: Path) -> list[tuple[np.ndarray, np.ndarray]]:
    """The (vertices, faces) of every convex part in ``object_dir/convex_parts.npz``."""
    with np.load(object_dir / "convex_parts.npz") as data:
        return [(data[f"vertices_{i}"], data[f"faces_{i}"]) for i in range(int(data["count"]))]


def plot_objects(
    object_dirs: Sequence[str | os.PathLike[str]], out_png: str | os.PathLike[str], dpi: int = 150
) -> None:
    """One 3-D panel per object (convex parts in distinct colours), written atomically as PNG."""
    dirs = [Path(d) for d in object_dirs]
    if not dirs:
        raise ValueError("plot_objects needs at least one object directory")
    ncols = min(len(dirs), 5)
    nrows = math.ceil(len(dirs) / ncols)
    fig = plt.figure(figsize=(3.0 * ncols, 3.0 * nrows))
    cmap = plt.get_cmap("tab20")
    for k, d in enumerate(dirs):
        meta_path = d / "meta.json"
        object_id = json.loads(meta_path.read_text())["object_id"] if meta_path.exists() else d.name
        parts = load_parts(d)
        ax = fig.add_subplot(nrows, ncols, k + 1, projection="3d")
        for i, (verts, faces) in enumerate(parts):
            poly = Poly3DCollection(
                verts[faces],
                facecolors=cmap(i % 20),
                edgecolors=cmap(i % 20),
                linewidths=0.05,
                shade=True,
            )
            ax.add_collection3d(poly)
        allv = np.vstack([v for v, _ in parts])
        lo, hi = allv.min(axis=0), allv.max(axis=0)
        centre, half = (lo + hi) / 2, max(float((hi - lo).max()) / 2, 1e-6)
        ax.set_xlim(centre[0] - half, centre[0] + half)
        ax.set_ylim(centre[1] - half, centre[1] + half)
        ax.set_zlim(centre[2] - half, centre[2] + half)
        ax.set_box_aspect((1, 1, 1))
        ax.view_init(elev=25, azim=-60)
        ax.set_axis_off()
        ax.set_title(f"{object_id}\n{len(parts)} convex parts", fontsize=9)
    fig.tight_layout()
    save(fig, out_png, dpi)
