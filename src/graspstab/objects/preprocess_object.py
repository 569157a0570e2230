"""Stage entry point: preprocess one object mesh into the artefacts later stages read (3.1.1)."""

from __future__ import annotations

import argparse
import json
import logging
import os
import time
from collections.abc import Sequence
from contextlib import contextmanager
from pathlib import Path
from typing import Any

import numpy as np
import trimesh

from graspstab.assets.mesh_file import describe, load_object_mesh
from graspstab.common.io import atomic_path, save_npy, save_npz, write_json
from graspstab.common.logs import setup_logging
from graspstab.common.provenance import provenance

from .decompose import convex_decomposition
from .frame import to_upright_com_frame
from .inertia import compute_inertia
from .mjcf import write_object_mjcf
from .repair import repair_mesh
from .sdf import SDFGrid, check_grid_size
from .surface import sample_hull_points

log = logging.getLogger("graspstab.objects")

OUTPUT_FILES = (
    "mesh.obj",
    "convex_parts.npz",
    "object.xml",
    "sdf.npz",
    "hull_points.npy",
    "meta.json",
)

DEFAULT_PARAMS: dict[str, Any] = {
    "repair": {"sliver_max_faces": 16, "sliver_max_area_fraction": 0.01},
    "coacd": {
        "threshold": 0.05,
        "max_convex_hull": 16,
        "preprocess_resolution": 50,
        "resolution": 2000,
        "mcts_iterations": 100,
        "seed": 0,
    },
    "sdf": {"spacing": 0.0015, "margin": 0.05},
    "hull_points": {"count": 2000, "seed": 0},
    "contact": {"friction": [1.0, 0.005, 0.0001]},
}


def load_mesh(
    path: str | os.PathLike[str],
    object_id: str = "",
    user_file: str | os.PathLike[str] | None = None,
) -> trimesh.Trimesh:
    """Load an OBJ file as one triangle mesh, unprocessed, ignoring textures and materials;
    :class:`~graspstab.assets.mesh_file.MeshFileError` (naming the object and ``user_file``, the
    user's own file it was copied from) if it is not a readable OBJ of a hand-held size."""
    return load_object_mesh(path, object_id, user_file)


def _section(params: dict[str, Any], key: str) -> dict[str, Any]:
    return {**DEFAULT_PARAMS[key], **dict(params.get(key) or {})}


def preprocess_object(
    object_id: str,
    mesh_path: str | os.PathLike[str],
    out_dir: str | os.PathLike[str],
    mass: float,
    params: dict[str, Any],
    rotation_deg: Sequence[float] | None = None,
    log_file: str | os.PathLike[str] | None = None,
) -> dict[str, Any]:
    """Repair, frame, inertia, CoACD, SDF, hull samples and MJCF for one object; return meta.

    Writes ``mesh.obj``, ``convex_parts.npz``, ``object.xml``, ``sdf.npz``, ``hull_points.npy``
    and ``meta.json`` (last) into ``out_dir``, each atomically. Missing ``params`` sections or keys
    fall back to :data:`DEFAULT_PARAMS`. A bad mesh (not OBJ, unreadable, not of hand-held size)
    or a signed-distance grid over the node cap fails before the slow steps, naming the object and
    the file, and creates nothing. (A user's own ``mesh:`` passed the same checks in the fetch
    step, whose message names it; this entry point reads only its declared input, the copy.)
    """
    if log_file is not None:
        setup_logging(log_file)
    out = Path(out_dir)
    timings: dict[str, float] = {}

    @contextmanager
    def step(name: str):  # type: ignore[no-untyped-def]
        log.info("%s: %s ...", object_id, name)
        t0 = time.perf_counter()
        yield
        timings[name] = round(time.perf_counter() - t0, 4)
        log.info("%s: %s done in %.2f s", object_id, name, timings[name])

    t_start = time.perf_counter()
    with step("load"):
        raw = load_mesh(mesh_path, object_id)
    with step("repair"):
        rp = _section(params, "repair")
        mesh, report = repair_mesh(
            raw,
            sliver_max_faces=int(rp["sliver_max_faces"]),
            sliver_max_area_fraction=float(rp["sliver_max_area_fraction"]),
            object_id=object_id,
            source=str(mesh_path),
        )
    with step("frame"):
        mesh, rot, translation = to_upright_com_frame(mesh, rotation_deg)
    sp = _section(params, "sdf")
    what = describe(object_id, mesh_path)
    # before the slow steps: a grid over the node cap fails now, with the spacing that would fit
    check_grid_size(mesh.bounds, float(sp["spacing"]), float(sp["margin"]), what)
    with step("inertia"):
        inertia = compute_inertia(mesh, float(mass))
    with step("decompose"):
        parts = convex_decomposition(mesh, _section(params, "coacd"))
    with step("sdf"):
        grid = SDFGrid.build(mesh, float(sp["spacing"]), float(sp["margin"]), what)
    with step("hull_points"):
        hp = _section(params, "hull_points")
        hull_points = sample_hull_points(mesh, count=int(hp["count"]), seed=int(hp["seed"]))
    with step("write"):
        out.mkdir(parents=True, exist_ok=True)  # only now: a failed step leaves no folder behind
        with atomic_path(out / "mesh.obj") as tmp:
            tmp.write_text(trimesh.exchange.obj.export_obj(mesh, include_normals=False))
        arrays: dict[str, np.ndarray] = {"count": np.int64(len(parts))}
        for i, part in enumerate(parts):
            arrays[f"vertices_{i}"] = np.asarray(part.vertices, dtype=np.float64)
            arrays[f"faces_{i}"] = np.asarray(part.faces, dtype=np.int64)
        save_npz(out / "convex_parts.npz", **arrays)
        write_object_mjcf(
            out / "object.xml", object_id, mesh, parts, inertia, _section(params, "contact")
        )
        grid.save(out / "sdf.npz")
        save_npy(out / "hull_points.npy", hull_points)
    timings["total"] = round(time.perf_counter() - t_start, 4)

    meta: dict[str, Any] = {
        "object_id": object_id,
        "source_mesh": str(mesh_path),
        "mass": float(mass),
        "inertia": inertia.to_dict(),
        "volume": float(mesh.volume),
        "density": float(mass) / float(mesh.volume),
        "extents": np.asarray(mesh.extents).tolist(),
        "bounds": np.asarray(mesh.bounds).tolist(),
        "rotation_deg": None if rotation_deg is None else [float(a) for a in rotation_deg],
        "rotation_matrix": rot.tolist(),
        # new = R @ old + t; the COM of the input mesh, in its own frame, was R^T @ -t
        "com_offset_applied": translation.tolist(),
        "com_in_source_frame": (rot.T @ -translation).tolist(),
        "watertight_before": report.watertight_before,
        "watertight_after": report.watertight_after,
        "repair": report.to_dict(),
        "num_vertices": len(mesh.vertices),
        "num_faces": len(mesh.faces),
        "convex_parts": len(parts),
        "convex_parts_volume": float(sum(p.volume for p in parts)),
        "sdf": {
            "spacing": grid.spacing,
            "margin": float(sp["margin"]),
            "shape": list(grid.shape),
            "origin": grid.origin.tolist(),
        },
        "hull_points": {"count": len(hull_points), "seed": int(hp["seed"])},
        # no timings: they differ on every run, so the log and the benchmark file hold them
        "files": list(OUTPUT_FILES),
        "provenance": provenance("objects", params),
    }
    write_json(out / "meta.json", meta)
    log.info(
        "%s: done in %.1f s (%d convex parts, volume %.1f cm^3)",
        object_id,
        timings["total"],
        len(parts),
        meta["volume"] * 1e6,
    )
    return meta


def main(argv: Sequence[str] | None = None) -> int:
    """Command-line entry: ``python -m graspstab.objects.preprocess_object --object-id ...``."""
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--object-id", required=True)
    ap.add_argument("--mesh", required=True, type=Path)
    ap.add_argument("--out-dir", required=True, type=Path)
    ap.add_argument("--mass", required=True, type=float, help="object mass [kg]")
    ap.add_argument("--params-json", default="{}", help="the preprocess config slice as JSON")
    ap.add_argument("--rotation-deg", type=float, nargs=3, default=None, help="x y z Euler degrees")
    ap.add_argument("--log-file", type=Path, default=None)
    args = ap.parse_args(argv)
    setup_logging(args.log_file)
    preprocess_object(
        args.object_id,
        args.mesh,
        args.out_dir,
        args.mass,
        json.loads(args.params_json),
        rotation_deg=args.rotation_deg,
    )
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
