"""A local YCB directory (``<dir>/<id>/textured.obj``, config key assets.ycb_dir): its layout and
the load-time check that it holds the run's objects, shared by the config validator and the fetch
job, which runs in the YCB entry module."""

from __future__ import annotations

import os
from collections.abc import Iterable, Mapping
from pathlib import Path
from typing import Any

from graspstab.assets.errors import AssetError

MESH_NAME = "textured.obj"


def missing_local_meshes_message(
    missing: list[str], local_dir: str | os.PathLike[str], present: Iterable[str] = ()
) -> str:
    """Why and how to fix: the local YCB directory lacks the meshes of the objects ``missing``
    (``present``: the run's objects it does hold, for the only_objects example)."""
    folder = Path(local_dir)
    key = "config key assets.ycb_dir or env var GRASPSTAB_YCB_DIR"
    if not folder.is_dir():
        return (
            f"the local YCB directory {folder} ({key}) does not exist; set it to a directory laid "
            "out <dir>/<id>/textured.obj, or unset it to download the official archive"
        )
    kept = list(present)
    only = f" (e.g. --config 'only_objects=[{','.join(kept)}]', the run's objects it holds)"
    only = only if kept else ""
    unset = "or unset assets.ycb_dir / GRASPSTAB_YCB_DIR to download the official archive"
    if len(missing) == 1:
        object_id = missing[0]
        return (
            f"the local YCB directory {folder} ({key}) lacks the mesh of object '{object_id}': "
            f"no {folder / object_id / MESH_NAME}. Fix it by one of: put the object's google_16k "
            f"textured.obj there as <dir>/<id>/textured.obj; leave it out of the run with "
            f"only_objects{only}; give your own mesh in config field "
            f"objects.items.{object_id}.mesh; {unset}"
        )
    return (
        f"the local YCB directory {folder} ({key}) lacks the mesh of {len(missing)} objects of "
        f"this run: no <dir>/<id>/textured.obj for {', '.join(missing)}. Fix it by one of: put "
        "each object's google_16k textured.obj there as <dir>/<id>/textured.obj; leave them out "
        f"of the run with only_objects{only}; give your own mesh in config field "
        f"objects.items.<id>.mesh; {unset}"
    )


def check_local_ycb_dir(
    items: Mapping[str, Any],
    local_dir: str | os.PathLike[str] | None,
    selected: Iterable[str] | None = None,
) -> None:
    """At load time: the local YCB directory holds ``<id>/textured.obj`` for every object the run
    covers (``selected``, the only_objects list; None: all of ``items``) that has no own mesh
    (field ``mesh``); objects left out are not looked at. :class:`AssetError` naming the objects,
    the directory, the config key and the fixes."""
    if local_dir in (None, ""):
        return
    chosen = list(items) if selected is None else [o for o in items if o in set(selected)]
    ycb = [o for o in chosen if not (items[o] or {}).get("mesh")]
    missing = [o for o in ycb if not (Path(local_dir) / o / MESH_NAME).is_file()]
    if missing:
        present = [o for o in chosen if o not in missing]
        raise AssetError(missing_local_meshes_message(missing, local_dir, present))
