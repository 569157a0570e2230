"""CoACD's cost against its fidelity, per object and setting (a preprocessing lever).

For each preprocessed object (its repaired, framed ``mesh.obj`` from a finished run) and each
setting, runs the decomposition as the workflow does (one thread, ``config/preprocess``'s
parameters with the setting's overrides) and prints its wall time, its convex parts and two
fidelity figures of the parts as MuJoCo collides with them, against the mesh itself:

- ``xor %``: the volume inside the parts or the mesh but not both, as a share of the mesh's
  volume (Monte Carlo over the bounding box, inside-mesh by libigl's winding number);
- ``dev mm``: the 99th percentile of |signed distance to the mesh| over points sampled on the
  outer surface of the parts' union, cut faces between parts excluded (how far a fingertip may
  touch the collision geometry off the real surface).

    python benchmarks/coacd_settings.py results/objects/* \
        --set mcts_iterations=100 --set mcts_iterations=50 --set mcts_iterations=25

Each ``--set`` is one setting (comma-separated key=value overrides; the first is the baseline).
"""

from __future__ import annotations

import argparse
import os
import time
from pathlib import Path

import numpy as np
import trimesh
import yaml

from graspstab.objects.decompose import convex_decomposition, inside_any_part

# one thread, as the workflow's single-threaded preprocessing job (Snakemake sets the same)
os.environ.setdefault("OMP_NUM_THREADS", "1")

DEFAULTS = Path(__file__).resolve().parents[1] / "config" / "preprocess" / "default.yaml"


def parse_setting(text: str) -> dict[str, float | int]:
    """``"a=1,b=0.5"`` -> ``{"a": 1, "b": 0.5}`` (ints stay ints)."""
    out: dict[str, float | int] = {}
    for item in filter(None, text.split(",")):
        key, _, value = item.partition("=")
        out[key.strip()] = int(value) if value.strip().lstrip("-").isdigit() else float(value)
    return out


def fidelity(mesh: trimesh.Trimesh, parts: list[trimesh.Trimesh], samples: int, seed: int):
    """(xor volume share of the mesh's volume, 99th percentile surface deviation [m])."""
    import igl

    rng = np.random.default_rng(seed)
    lo, hi = mesh.bounds
    lo, hi = lo - 0.005, hi + 0.005
    pts = rng.uniform(lo, hi, size=(samples, 3))
    v = np.ascontiguousarray(mesh.vertices, dtype=np.float64)
    f = np.ascontiguousarray(mesh.faces, dtype=np.int64)
    in_mesh = np.asarray(igl.fast_winding_number(v, f, pts)) > 0.5
    in_parts = inside_any_part(parts, pts)
    box = float(np.prod(hi - lo))
    xor = float(np.mean(in_mesh ^ in_parts)) * box / float(mesh.volume)
    surface = []
    for part in parts:
        pts, faces = trimesh.sample.sample_surface(
            part, max(200, samples // (20 * len(parts))), seed=seed
        )
        # keep the union's outer boundary: a point on a cut face shared with a neighbouring part
        # lies inside the object, not on its collision surface
        outward = pts + 5e-4 * part.face_normals[faces]
        surface.append(pts[~inside_any_part(parts, outward)])
    surface = np.concatenate(surface)
    d, _, _, _ = igl.signed_distance(surface, v, f, igl.SIGNED_DISTANCE_TYPE_PSEUDONORMAL)
    return xor, float(np.percentile(np.abs(d), 99))


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("objects", nargs="+", type=Path, help="results/objects/<id> folders")
    ap.add_argument(
        "--set",
        dest="settings",
        action="append",
        default=None,
        help="one setting, key=value[,key=value] (repeatable; first = baseline)",
    )
    ap.add_argument("--samples", type=int, default=200_000, help="Monte Carlo points per object")
    args = ap.parse_args()
    base = yaml.safe_load(DEFAULTS.read_text())["coacd"]
    settings = args.settings or ["mcts_iterations=100", "mcts_iterations=50"]
    print(f"baseline parameters (config/preprocess): {base}")
    header = f"{'object':<24}{'setting':<34}{'wall [s]':>9}{'parts':>7}{'xor %':>8}{'dev mm':>8}"
    print(header)
    totals = {s: 0.0 for s in settings}
    for folder in args.objects:
        mesh = trimesh.load(folder / "mesh.obj", force="mesh", process=False)
        for s in settings:
            params = {**base, **parse_setting(s)}
            t0 = time.perf_counter()
            parts = convex_decomposition(mesh, params)
            wall = time.perf_counter() - t0
            totals[s] += wall
            xor, dev = fidelity(mesh, parts, args.samples, seed=0)
            print(
                f"{folder.name:<24}{s:<34}{wall:>9.1f}{len(parts):>7}{100 * xor:>8.2f}"
                f"{1000 * dev:>8.2f}",
                flush=True,
            )
    for s in settings:
        print(f"total {s}: {totals[s]:.1f} s ({totals[s] / totals[settings[0]]:.2f}x baseline)")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
