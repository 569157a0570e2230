"""Times each grasp-synthesis energy term (3.1.4, eqs. 5-14) at annealing batch sizes.

Hand placements are synthetic but realistic for the penetration term: every grasp picks an anchor
on the object's hull samples, the palm box floats just off the surface there, and each capsule
(radii and palm box from the hand's capsules.json) has one end on/near a hull point close to the
anchor (within +-3 mm of touching, so some penetrate) or, for the non-touching share, 1-4 cm out.

With ``--anneal N`` it also times the terms and the whole :class:`GraspEnergy` call at realistic
states: structured pre-grasps (3.1.3) annealed for N iterations (3.1.4, config schedule).
E_pen and the SDF query are numba kernels (compiled once, cached on disk; the first-call time
printed includes loading or compiling them).

    python benchmarks/energy_terms.py [--object-dir DIR] [--hand-dir DIR] [--batch 256]
        [--threads 1] [--anneal 600]
"""

from __future__ import annotations

import argparse
import json
import time
from collections.abc import Callable
from pathlib import Path

import numpy as np
import torch
import trimesh
import yaml

from graspstab.synthesis.energy import (
    PenetrationPoints,
    e_dis,
    e_fc,
    e_joint,
    e_pen,
    e_pen_dense,
    e_spen,
    penetration_candidates,
)
from graspstab.synthesis.sdf_torch import TorchSDF

# the workflow's outputs, relative to the working directory (run from the repository root)
DEFAULT_OBJECT = Path("results/objects/061_foam_brick")
DEFAULT_HAND = Path("results/hand")


def _unit(v: np.ndarray) -> np.ndarray:
    return v / np.linalg.norm(v, axis=-1, keepdims=True)


def _random_rotations(rng: np.random.Generator, z_axes: np.ndarray) -> np.ndarray:
    """Rotations (B, 3, 3) whose third column is ``z_axes`` and whose roll is random."""
    z = _unit(z_axes)
    x = _unit(np.cross(z, rng.normal(size=z.shape)))
    y = np.cross(z, x)
    return np.stack([x, y, z], axis=-1)


def place_hands(
    hull: np.ndarray,
    normals: np.ndarray,
    radii: np.ndarray,
    half_extents: np.ndarray,
    batch: int,
    touch_fraction: float,
    seed: int,
) -> dict[str, np.ndarray]:
    """Capsule segments and palm boxes around the object, as described in the module docstring."""
    rng = np.random.default_rng(seed)
    k = len(radii)
    anchors = rng.integers(len(hull), size=batch)
    # hull points within 6 cm of each anchor: the region one hand can wrap
    dist = np.linalg.norm(hull[anchors][:, None] - hull[None], axis=-1)  # (B, M)
    ends = np.empty((batch, k), dtype=np.int64)
    for b in range(batch):
        near = np.flatnonzero(dist[b] < 0.06)
        ends[b] = rng.choice(near, size=k)
    n = normals[ends]  # (B, K, 3)
    touching = rng.random((batch, k)) < touch_fraction
    gap = np.where(
        touching, rng.uniform(-0.003, 0.003, (batch, k)), rng.uniform(0.01, 0.04, (batch, k))
    )
    p1 = hull[ends] + n * (radii + gap)[..., None]
    direction = _unit(n + 0.8 * rng.normal(size=n.shape))
    p0 = p1 + direction * rng.uniform(0.015, 0.045, (batch, k, 1))
    na = normals[anchors]
    center = hull[anchors] + na * (half_extents[2] + rng.uniform(0.005, 0.03, (batch, 1)))
    return {"p0": p0, "p1": p1, "box_center": center, "box_rotation": _random_rotations(rng, na)}


def time_call(fn: Callable[[], object], repeats: int, blocks: int = 5) -> float:
    """Mean wall time per call [s] over ``repeats`` calls, best of ``blocks`` blocks (after one
    warm-up call); the best block filters out interference from other processes."""
    fn()
    best = float("inf")
    for _ in range(blocks):
        start = time.perf_counter()
        for _ in range(repeats):
            fn()
        best = min(best, (time.perf_counter() - start) / repeats)
    return best


def main() -> None:
    """Parse arguments, build the inputs and print the timing table."""
    parser = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawTextHelpFormatter
    )
    parser.add_argument("--object-dir", type=Path, default=DEFAULT_OBJECT)
    parser.add_argument("--hand-dir", type=Path, default=DEFAULT_HAND)
    parser.add_argument("--batch", type=int, default=256, help="grasps per call (B)")
    parser.add_argument("--points", type=int, default=2000, help="hull samples used (M)")
    parser.add_argument("--clusters", type=int, default=32, help="coarse clusters for E_pen")
    parser.add_argument("--leaf-size", type=int, default=8, help="points per leaf for E_pen")
    parser.add_argument("--touch-fraction", type=float, default=0.6)
    parser.add_argument("--repeats", type=int, default=10, help="calls per timing block")
    parser.add_argument("--threads", type=int, default=1, help="1: the production setting")
    parser.add_argument("--anneal", type=int, default=0, help="also time annealed states")
    parser.add_argument("--config", type=Path, default=Path("config/synthesis/default.yaml"))
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--float64", action="store_true", help="time in float64 instead of float32")
    args = parser.parse_args()
    torch.set_num_threads(args.threads)
    dtype = torch.float64 if args.float64 else torch.float32

    hull = np.load(args.object_dir / "hull_points.npy").astype(np.float64)[: args.points]
    sdf = TorchSDF.load(args.object_dir / "sdf.npz", dtype=dtype)
    _, hull_normals = sdf.query(torch.as_tensor(hull, dtype=dtype))
    capsules = json.loads((args.hand_dir / "capsules.json").read_text())
    radii = np.array([c["radius"] for c in capsules["capsules"]])
    half = np.array(capsules["palm_box"]["half_extents"])
    pairs = torch.as_tensor(capsules["pairs"], dtype=torch.long)
    hands = place_hands(
        hull, hull_normals.double().numpy(), radii, half, args.batch, args.touch_fraction, args.seed
    )
    t = {key: torch.as_tensor(v, dtype=dtype) for key, v in hands.items()}
    radii_t = torch.as_tensor(radii, dtype=dtype)
    half_t = torch.as_tensor(half, dtype=dtype)
    start = time.perf_counter()
    points = PenetrationPoints(hull, args.clusters, dtype, leaf_size=args.leaf_size)
    build_s = time.perf_counter() - start
    hand = (t["p0"], t["p1"], radii_t, t["box_center"], t["box_rotation"], half_t)

    rng = np.random.default_rng(args.seed + 1)
    n_cand = 120
    cand = torch.as_tensor(
        hull[rng.integers(len(hull), size=(args.batch, n_cand))]
        + rng.normal(scale=0.005, size=(args.batch, n_cand, 3)),
        dtype=dtype,
    )
    dist, normal = sdf.query(cand)
    inward = -normal
    theta = torch.as_tensor(rng.normal(size=(args.batch, 16)), dtype=dtype)
    lower, upper = -torch.ones(16, dtype=dtype), torch.ones(16, dtype=dtype)

    stats: dict[str, int] = {}
    start = time.perf_counter()
    culled = e_pen(points, *hand, stats=stats)
    first_pen_s = time.perf_counter() - start
    start = time.perf_counter()
    sdf.query(cand[:1])
    first_sdf_s = time.perf_counter() - start
    dense = e_pen_dense(points, *hand)
    n_pen = int((culled > 0).sum())
    with torch.no_grad():
        rows = [
            ("sdf query (B x 120)", lambda: sdf.query(cand)),
            ("e_dis (given distances)", lambda: e_dis(dist)),
            ("e_fc (given normals)", lambda: e_fc(cand, inward)),
            ("e_pen culled", lambda: e_pen(points, *hand)),
            ("e_pen dense", lambda: e_pen_dense(points, *hand)),
            ("  coarse culling only", lambda: penetration_candidates(points, *hand)),
            (f"e_spen ({len(pairs)} pairs)", lambda: e_spen(t["p0"], t["p1"], radii_t, pairs)),
            ("e_joint", lambda: e_joint(theta, lower, upper)),
        ]
        print(
            f"B={args.batch} M={len(hull)} K={len(radii)}+box C={points.n_clusters} "
            f"leaves/cluster={points.fan} S={points.leaf_members} dtype={dtype} "
            f"threads={torch.get_num_threads()} "
            f"(cluster build {build_s * 1e3:.1f} ms; first e_pen call {first_pen_s * 1e3:.0f} ms, "
            f"first sdf query {first_sdf_s * 1e3:.0f} ms after one warm-up query)"
        )
        for name, fn in rows:
            repeats = max(1, args.repeats // 10) if "dense" in name else args.repeats
            print(f"{name:28s} {time_call(fn, repeats) * 1e3:9.3f} ms/call (best-of-5 mean)")
    k1 = len(radii)
    print(
        f"active (grasp, primitive, cluster) triples: coarse capsule {stats['coarse_capsule']} of "
        f"{args.batch * k1 * points.n_clusters}, box {stats['coarse_box']} of "
        f"{args.batch * points.n_clusters}; leaf capsule {stats['leaf_capsule']} of "
        f"{args.batch * k1 * points.n_clusters * points.fan}, box {stats['leaf_box']}; "
        f"point evaluations {stats['point_evaluations']} "
        f"vs dense {args.batch * len(hull) * (k1 + 1)}"
    )
    print(
        f"grasps with penetration: {n_pen}/{args.batch}; mean E_pen {float(culled.mean()):.4g}; "
        f"max |culled - dense| {float((culled - dense).abs().max()):.3g} "
        f"(relative {float(((culled - dense).abs() / dense.abs().clamp_min(1e-30)).max()):.2g})"
    )
    if args.anneal > 0:
        time_annealed(args, dtype)


def time_annealed(args: argparse.Namespace, dtype: torch.dtype) -> None:
    """Times every term and the whole energy at ``--batch`` pre-grasps annealed ``--anneal``
    iterations (the state the annealer spends most of its 6000 iterations in)."""
    from graspstab.synthesis.anneal import AnnealSchedule, anneal
    from graspstab.synthesis.energy import e_spen as spen
    from graspstab.synthesis.grasp_energy import GraspEnergy
    from graspstab.synthesis.pregrasp import sample_pregrasps

    params = yaml.safe_load(args.config.read_text())
    schedule = dict(params["annealing"], iterations=args.anneal)
    energy = GraspEnergy.load(
        args.object_dir,
        args.hand_dir,
        params["energy"]["weights"],
        dtype,
        int(params["annealing"]["penetration_clusters"]),
    )
    kin = energy.kin
    mesh = trimesh.load(args.object_dir / "mesh.obj", force="mesh", process=False)
    pre = sample_pregrasps(
        mesh, kin, args.batch, np.random.default_rng(args.seed), params["pregrasp"]
    )
    start = time.perf_counter()
    res = anneal(
        energy,
        pre["wrist_pos"],
        pre["rot6d"],
        pre["joints"],
        kin.joint_lower.numpy(),
        kin.joint_upper.numpy(),
        AnnealSchedule.from_params(schedule),
        np.random.SeedSequence(args.seed).spawn(args.batch),
    )
    anneal_s = time.perf_counter() - start
    x = [torch.as_tensor(v, dtype=dtype) for v in (res.wrist_pos, res.rot6d, res.joints)]
    pose = kin.forward(*x)
    dist, normal = energy.sdf.query(pose.candidates)
    hand = (
        pose.capsule_p0,
        pose.capsule_p1,
        energy.radii,
        pose.box_center,
        pose.box_rot,
        kin.box_half_extents,
    )
    stats: dict[str, int] = {}
    e_pen(energy.pen_points, *hand, stats=stats)
    print(
        f"\nannealed states: {args.anneal} iterations in {anneal_s:.1f} s, median energy "
        f"{float(np.median(res.energy)):.4g}; point evaluations {stats['point_evaluations']}"
    )
    rows = [
        ("forward kinematics", lambda: kin.forward(*x)),
        ("sdf query (B x 120)", lambda: energy.sdf.query(pose.candidates)),
        ("e_dis", lambda: e_dis(dist)),
        ("e_fc", lambda: e_fc(pose.candidates, -normal)),
        ("e_pen culled", lambda: e_pen(energy.pen_points, *hand)),
        ("e_spen", lambda: spen(pose.capsule_p0, pose.capsule_p1, energy.radii, energy.pairs)),
        ("e_joint", lambda: e_joint(x[2], kin.joint_lower, kin.joint_upper)),
        (
            f"e_hpen ({kin.n_surface_points} points)",
            lambda: energy.sdf.depth_sum(pose.surface_points),
        ),
        ("GraspEnergy total", lambda: energy(*x)),
    ]
    with torch.no_grad():
        for name, fn in rows:
            print(f"{name:28s} {time_call(fn, args.repeats) * 1e3:9.3f} ms/call (best-of-5 mean)")


if __name__ == "__main__":
    main()
