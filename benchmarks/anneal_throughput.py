"""Annealing throughput at thesis settings against a one-grasp-at-a-time reference (docs/design.md).

Prints candidate grasps per second of the batched annealer (6000 iterations, 120 contact
candidates, 2000 penetration points by default) run as the workflow runs it on 2 cores (two
single-threaded jobs side by side, ``--workers 2``), and of a straightforward one-chain-at-a-time
evaluation of the same energy (graspstab.synthesis.energy_reference, 1 thread), measured in the
same run, and their ratio. Targets: >= 2 candidates/s on 2 cores and >= 50x the reference.

    python benchmarks/anneal_throughput.py --object-dir results/objects/061_foam_brick \
        --hand-dir results/hand
"""

from __future__ import annotations

import argparse
import multiprocessing as mp
import time
from pathlib import Path

import numpy as np
import torch
import trimesh
import yaml

from graspstab.synthesis.anneal import AnnealSchedule, anneal
from graspstab.synthesis.anneal_grasps import shard_seeds
from graspstab.synthesis.energy_reference import ReferenceEnergy
from graspstab.synthesis.grasp_energy import GraspEnergy
from graspstab.synthesis.pregrasp import sample_pregrasps

DEFAULTS = Path(__file__).resolve().parents[1] / "config" / "synthesis" / "default.yaml"


def _setup(object_dir: Path, hand_dir: Path, batch: int, shard: int, params: dict, dtype):
    energy = GraspEnergy.load(
        object_dir, hand_dir, params["energy"]["weights"], dtype,
        params["annealing"]["penetration_clusters"],
    )  # fmt: skip
    mesh = trimesh.load(object_dir / "mesh.obj", force="mesh", process=False)
    seeds = shard_seeds(0, object_dir.name, shard, batch)
    rng = np.random.Generator(np.random.PCG64(seeds[0]))
    pre = sample_pregrasps(mesh, energy.kin, batch, rng, params["pregrasp"])
    return energy, pre, seeds


def anneal_shard(job: tuple) -> tuple[float, np.ndarray, np.ndarray, np.ndarray]:
    """Anneal one batch in this process (1 torch thread); return wall time and the results."""
    object_dir, hand_dir, batch, shard, params, dtype_name = job
    torch.set_num_threads(1)
    dtype = getattr(torch, dtype_name)
    energy, pre, seeds = _setup(object_dir, hand_dir, batch, shard, params, dtype)
    lower, upper = energy.kin.joint_lower.numpy(), energy.kin.joint_upper.numpy()
    energy(*(torch.as_tensor(pre[k][:2], dtype=dtype) for k in ("wrist_pos", "rot6d", "joints")))
    t0 = time.perf_counter()  # after loading and the kernels' first call (numba cache)
    res = anneal(
        energy, pre["wrist_pos"], pre["rot6d"], pre["joints"], lower, upper,
        AnnealSchedule.from_params(params["annealing"]), seeds[1:], dtype=dtype,
    )  # fmt: skip
    return time.perf_counter() - t0, res.energy_start, res.energy, res.acceptance_rate


def main() -> None:
    """Run both measurements and print the figures."""
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--object-dir", type=Path, required=True)
    ap.add_argument("--hand-dir", type=Path, required=True)
    ap.add_argument("--batch", type=int, default=256, help="chains per vectorised call")
    ap.add_argument("--workers", type=int, default=2, help="single-threaded processes side by side")
    ap.add_argument("--iterations", type=int, default=None, help="default: the config's (6000)")
    ap.add_argument("--reference-evals", type=int, default=200)
    ap.add_argument("--dtype", choices=["float32", "float64"], default=None)
    args = ap.parse_args()

    params = yaml.safe_load(DEFAULTS.read_text())
    if args.iterations:
        params["annealing"]["iterations"] = args.iterations
    iterations = params["annealing"]["iterations"]
    dtype_name = args.dtype or params["annealing"]["dtype"]
    jobs = [
        (args.object_dir, args.hand_dir, args.batch, k, params, dtype_name)
        for k in range(args.workers)
    ]
    t0 = time.perf_counter()
    with mp.get_context("spawn").Pool(args.workers) as pool:
        results = pool.map(anneal_shard, jobs)
    wall = time.perf_counter() - t0
    busy = max(r[0] for r in results)
    rate = args.workers * args.batch / busy

    # reference: one chain at a time, same energy, same iteration count (timed on a sample)
    torch.set_num_threads(1)
    dtype = getattr(torch, dtype_name)
    energy, pre, _ = _setup(args.object_dir, args.hand_dir, args.batch, 0, params, dtype)
    ref = ReferenceEnergy(args.object_dir, args.hand_dir, params["energy"]["weights"])
    lower, upper = energy.kin.joint_lower.numpy(), energy.kin.joint_upper.numpy()
    rng = np.random.default_rng(0)
    states = [
        (
            pre["wrist_pos"][i % args.batch] + rng.normal(0, 0.005, 3),
            pre["rot6d"][i % args.batch] + rng.normal(0, 0.02, 6),
            np.clip(pre["joints"][i % args.batch] + rng.normal(0, 0.05, 16), lower, upper),
        )
        for i in range(args.reference_evals)
    ]
    t0 = time.perf_counter()
    ref_values = np.array([ref(*s) for s in states])
    per_eval = (time.perf_counter() - t0) / args.reference_evals
    ref_rate = 1.0 / (per_eval * iterations)
    with torch.no_grad():
        batched = energy(
            *(torch.as_tensor(np.stack([s[k] for s in states]), dtype=dtype) for k in range(3))
        )
    rel = np.abs(batched.double().numpy() - ref_values) / np.maximum(np.abs(ref_values), 1.0)

    start = np.concatenate([r[1] for r in results])
    best = np.concatenate([r[2] for r in results])
    acc = np.concatenate([r[3] for r in results])
    print(
        f"object {args.object_dir.name}: {args.workers} workers x {args.batch} chains x "
        f"{iterations} iterations, 1 torch thread each, {dtype_name}"
    )
    print(
        f"batched annealer: {busy:7.1f} s per worker ({wall:.1f} s wall incl. start-up) -> "
        f"{rate:.2f} candidate grasps/s on {args.workers} cores "
        f"({busy / iterations * 1e3:.1f} ms per iteration of a {args.batch}-chain batch)"
    )
    print(
        f"reference (1 chain, 1 core): {per_eval * 1e3:.2f} ms per energy evaluation -> "
        f"{ref_rate:.4f} candidate grasps/s"
    )
    print(
        f"speed-up per core: {rate / args.workers / ref_rate:.0f}x; "
        f"on {args.workers} cores vs the reference on one: {rate / ref_rate:.0f}x"
    )
    print(
        f"energy agreement on {args.reference_evals} states: max relative difference "
        f"{rel.max():.1e}"
    )
    print(
        f"median energy start {np.median(start):.1f} -> best {np.median(best):.1f}; "
        f"median acceptance {np.median(acc):.3f}"
    )


if __name__ == "__main__":
    main()
