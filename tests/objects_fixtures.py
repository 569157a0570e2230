"""Synthetic meshes shared by the tests of graspstab.objects."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import trimesh
from conftest import COARSE_COACD as COARSE_COACD  # re-exported for the objects tests


def sliver(at: np.ndarray, size: float = 0.001) -> tuple[np.ndarray, np.ndarray]:
    """A stray two-triangle quad (vertices, faces) of edge ``size`` at ``at``."""
    v = np.array([[0, 0, 0], [size, 0, 0], [size, size, 0], [0, size, 0]], float) + at
    f = np.array([[0, 1, 2], [0, 2, 3]])
    return v, f


def broken_sphere() -> trimesh.Trimesh:
    """A sphere with one face removed, some faces flipped and two tiny sliver components."""
    s = trimesh.creation.icosphere(subdivisions=3, radius=0.05)
    faces = s.faces.copy()
    faces[5:40] = faces[5:40, ::-1]  # flipped faces
    faces = np.delete(faces, 100, axis=0)  # a hole
    verts = [s.vertices]
    allf = [faces]
    offset = len(s.vertices)
    for at in ([0.2, 0, 0], [0, 0.2, 0.1]):
        v, f = sliver(np.array(at))
        verts.append(v)
        allf.append(f + offset)
        offset += len(v)
    return trimesh.Trimesh(np.vstack(verts), np.vstack(allf), process=False)


def mug_like(r_out: float = 0.04, r_in: float = 0.032, h: float = 0.08, floor: float = 0.01):
    """Open cup: cylinder minus a smaller cylinder from the top, closed bottom (z from 0 to h)."""
    outer = trimesh.creation.cylinder(radius=r_out, height=h, sections=48)
    outer.apply_translation([0, 0, h / 2])
    inner = trimesh.creation.cylinder(radius=r_in, height=h, sections=48)
    inner.apply_translation([0, 0, floor + h / 2])
    cup = trimesh.boolean.difference([outer, inner], engine="manifold")
    assert cup.is_watertight
    return cup


def own_object_set(tmp_path: Path, object_id: str, mesh: Path, mass: float) -> list[str]:
    """--config arguments selecting a one-object set whose entry gives ``mesh`` with sha256 null
    (an extra Hydra search path: --config cannot add a key to an entry, struct mode refuses it)."""
    conf = tmp_path / "conf" / "objects"
    conf.mkdir(parents=True)
    (conf / "own.yaml").write_text(
        f"name: own\nitems:\n  {object_id}:\n    split: train\n    mass: {mass}\n"
        f"    sha256: null\n    mesh: {mesh}\n"
    )
    searchpath = f'"hydra.searchpath=[file://{tmp_path / "conf"}]"'
    return ["--config", f"overrides=[{searchpath}]", "objects=own"]
