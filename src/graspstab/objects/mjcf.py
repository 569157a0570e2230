"""Self-contained MJCF fragment of one object (inline meshes), attachable into any MjSpec."""

from __future__ import annotations

import os
from collections.abc import Mapping, Sequence
from typing import Any
from xml.sax.saxutils import quoteattr

import numpy as np
import trimesh

from graspstab.common.io import write_text

from .inertia import Inertia

DEFAULT_FRICTION = (1.0, 0.005, 0.0001)
BODY_NAME = "object"
JOINT_NAME = "object_free"


def _nums(values: np.ndarray, fmt: str = "{:.9g}") -> str:
    return " ".join(fmt.format(float(x)) for x in np.asarray(values).reshape(-1))


def _ints(values: np.ndarray) -> str:
    return " ".join(str(int(x)) for x in np.asarray(values).reshape(-1))


def _mesh_asset(name: str, mesh: trimesh.Trimesh) -> str:
    return f'    <mesh name="{name}" vertex="{_nums(mesh.vertices)}" face="{_ints(mesh.faces)}"/>'


def object_mjcf(
    object_id: str,
    visual_mesh: trimesh.Trimesh,
    parts: Sequence[trimesh.Trimesh],
    inertia: Inertia,
    contact: Mapping[str, Any] | None = None,
) -> str:
    """MJCF text: body ``object`` with a free joint, exact inertial, visual and collision geoms.

    The visual geom (group 2) does not collide; each convex part is a colliding mesh geom
    (group 3, contype/conaffinity 1, condim 3, friction from ``contact['friction']``). Meshes are
    written inline so the file needs no mesh directory.
    """
    if not parts:
        raise ValueError(f"object {object_id!r}: no convex parts for collision geometry")
    contact = dict(contact or {})
    friction = np.asarray(contact.get("friction", DEFAULT_FRICTION), dtype=np.float64)
    if friction.shape != (3,):
        raise ValueError(f"contact.friction must have 3 values, got {friction.tolist()}")
    fr = _nums(friction, "{:.6g}")
    assets = [_mesh_asset("object_visual", visual_mesh)]
    assets += [_mesh_asset(f"object_part_{i}", p) for i, p in enumerate(parts)]
    quat = _nums(inertia.quat, "{:.12g}")
    diag = _nums(inertia.principal_moments, "{:.12g}")
    geoms = [
        '      <geom name="object_visual" type="mesh" mesh="object_visual" contype="0" '
        'conaffinity="0" group="2" mass="0" rgba="0.8 0.7 0.55 1"/>'
    ]
    geoms += [
        f'      <geom name="object_collision_{i}" type="mesh" mesh="object_part_{i}" group="3" '
        f'contype="1" conaffinity="1" condim="3" friction="{fr}" mass="0" '
        f'rgba="0.3 0.5 0.9 0.5"/>'
        for i in range(len(parts))
    ]
    lines = [
        f"<mujoco model={quoteattr(object_id)}>",
        "  <asset>",
        *assets,
        "  </asset>",
        "  <worldbody>",
        f'    <body name="{BODY_NAME}">',
        f'      <freejoint name="{JOINT_NAME}"/>',
        f'      <inertial pos="0 0 0" quat="{quat}" mass="{inertia.mass:.12g}" '
        f'diaginertia="{diag}"/>',
        *geoms,
        "    </body>",
        "  </worldbody>",
        "</mujoco>",
        "",
    ]
    return "\n".join(lines)


def write_object_mjcf(path: str | os.PathLike[str], *args: Any, **kwargs: Any) -> None:
    """Write :func:`object_mjcf` output atomically to ``path``."""
    write_text(path, object_mjcf(*args, **kwargs))
