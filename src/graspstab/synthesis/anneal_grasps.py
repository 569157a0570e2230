"""Synthesis stage entry point: pre-grasps and annealing for one object x shard (3.1.3-3.1.4).

A shard is annealed in seed blocks (``synthesis.seed_block`` grasps each, null: the whole shard):
a grasp depends on its id and the block size only, so shards can be resized without changing a
grasp, and fewer, larger shards share the annealer's per-iteration overhead.

Writes one Parquet row per candidate grasp: its best state along the annealing trajectory (wrist
position, 6-D rotation, MuJoCo quaternion, 16 joint angles, all in the object frame), every energy
term there, the total at the start, the acceptance rate and contact diagnostics.
"""

from __future__ import annotations

import argparse
import json
import logging
import time
import zlib
from pathlib import Path
from typing import Any

import numpy as np
import polars as pl
import torch
import trimesh

from graspstab.common.io import load_npz, read_json, write_parquet
from graspstab.common.logs import setup_logging
from graspstab.common.provenance import provenance, write_timing
from graspstab.synthesis.anneal import AnnealSchedule, anneal, log_progress
from graspstab.synthesis.grasp_energy import TERMS, GraspEnergy
from graspstab.synthesis.pregrasp import sample_pregrasps
from graspstab.synthesis.rotation import rot6d_to_quat

log = logging.getLogger("graspstab.synthesis")

#: Column order of the grasp table (one row per candidate grasp).
POSE_COLUMNS = (
    [f"wrist_{a}" for a in "xyz"]
    + [f"rot6d_{i}" for i in range(6)]
    + [f"quat_{a}" for a in "wxyz"]
    + [f"theta_{k:02d}" for k in range(16)]
)
ENERGY_COLUMNS = [f"e_{t}" for t in TERMS] + ["energy", "energy_start", "acceptance_rate"]
FINGERS = ("thumb", "index", "middle", "ring", "little")
DIAGNOSTIC_COLUMNS = [f"tip_dist_{f}" for f in FINGERS] + [
    "min_candidate_dist",
    "max_hand_depth",
    "best_iteration",
]


def object_key(object_id: str) -> int:
    """A stable 32-bit integer for an object id, one of the entropy words of its seeds."""
    return zlib.crc32(object_id.encode())


def shard_seeds(seed: int, object_id: str, shard: int, n: int) -> list[np.random.SeedSequence]:
    """Seeds of seed block ``shard`` (the shard itself when synthesis.seed_block is null) of ``n``
    grasps: [0] for its pre-grasps, [1 + i] for chain i (SeedSequence spawn keys)."""
    return np.random.SeedSequence([seed, object_key(object_id), shard]).spawn(n + 1)


def _signed_nearest(dist: np.ndarray) -> np.ndarray:
    """Per row, the signed distance of smallest magnitude (B, k) -> (B,)."""
    idx = np.argmin(np.abs(dist), axis=1)
    return dist[np.arange(len(dist)), idx]


def grasp_table(
    object_id: str,
    shard: int,
    seed: int,
    grasp_ids: np.ndarray,
    result: Any,
    terms: dict[str, np.ndarray],
    cand_dist: np.ndarray,
    cand_finger: np.ndarray,
    cand_distal: np.ndarray,
    hand_depth: np.ndarray,
) -> pl.DataFrame:
    """Assemble the per-grasp rows (see the module docstring)."""
    quat = rot6d_to_quat(torch.as_tensor(result.rot6d, dtype=torch.float64)).numpy()
    pose = np.concatenate([result.wrist_pos, result.rot6d, quat, result.joints], axis=1)
    cols: dict[str, Any] = {
        "grasp_id": grasp_ids.astype(np.int64),
        "object": [object_id] * len(grasp_ids),
        "shard": np.full(len(grasp_ids), shard, dtype=np.int32),
        "seed": np.full(len(grasp_ids), seed, dtype=np.int64),
    }
    cols.update({c: pose[:, k] for k, c in enumerate(POSE_COLUMNS)})
    cols.update({f"e_{t}": terms[t] for t in TERMS})
    cols["energy"] = result.energy
    cols["energy_start"] = result.energy_start
    cols["acceptance_rate"] = result.acceptance_rate
    for finger in FINGERS:
        mask = (cand_finger == finger) & cand_distal
        cols[f"tip_dist_{finger}"] = _signed_nearest(cand_dist[:, mask])
    cols["min_candidate_dist"] = cand_dist.min(axis=1)
    cols["max_hand_depth"] = hand_depth.max(axis=1)
    cols["best_iteration"] = result.best_iteration.astype(np.int64)
    return pl.DataFrame(cols)


def seed_blocks(params: dict[str, Any], shard: int) -> list[int]:
    """The seed blocks of a shard: ``grasps_per_shard / seed_block`` consecutive block numbers
    (the shard itself when ``seed_block`` is null). Block ``b`` holds grasp ids ``b * size`` to
    ``(b + 1) * size - 1`` and is seeded by ``(seed, object, b)``, so a grasp depends on its id and
    the block size only: two shards of 16 and one of 32 in blocks of 16 hold the same grasps."""
    n, size = int(params["grasps_per_shard"]), params.get("seed_block")
    size = n if size is None else int(size)
    if size < 1 or n % size:
        raise ValueError(f"synthesis.grasps_per_shard = {n} is not a multiple of "
                         f"synthesis.seed_block = {size}")  # fmt: skip
    per = n // size
    return list(range(shard * per, (shard + 1) * per))


def anneal_grasps(
    object_id: str,
    object_dir: str | Path,
    hand_dir: str | Path,
    out_path: str | Path,
    params: dict[str, Any],
    seed: int,
    shard: int,
    threads: int | None = None,
    log_file: str | Path | None = None,
    timing_path: str | Path | None = None,
) -> pl.DataFrame:
    """Sample the shard's pre-grasps block by block (:func:`seed_blocks`), anneal all of its
    chains in batches of ``batch_size`` and write the Parquet table; with ``timing_path``, the
    job's wall time and rate go to that timing sidecar (they differ on every run, so they stay
    out of the table). A chain depends only on its seed and start (graspstab.synthesis.anneal),
    so a block's grasps come out the same in any shard that holds it; one call over more chains
    costs less per grasp."""
    setup_logging(log_file)
    if threads:
        torch.set_num_threads(int(threads))
    t0 = time.perf_counter()
    object_dir, hand_dir = Path(object_dir), Path(hand_dir)
    ann = params["annealing"]
    dtype = {"float32": torch.float32, "float64": torch.float64}[ann["dtype"]]
    n = int(params["grasps_per_shard"])
    blocks = seed_blocks(params, shard)
    size = n // len(blocks)
    energy = GraspEnergy.load(
        object_dir, hand_dir, params["energy"]["weights"], dtype, ann["penetration_clusters"]
    )
    mesh = trimesh.load(object_dir / "mesh.obj", force="mesh", process=False)
    starts, chain_seeds = [], []
    for block in blocks:
        seeds = shard_seeds(seed, object_id, block, size)
        starts.append(sample_pregrasps(mesh, energy.kin, size,
                                       np.random.Generator(np.random.PCG64(seeds[0])),
                                       params["pregrasp"]))  # fmt: skip
        chain_seeds += seeds[1:]
    pre = {k: np.concatenate([p[k] for p in starts]) for k in ("wrist_pos", "rot6d", "joints")}
    schedule = AnnealSchedule.from_params(ann)
    log.info(
        "%s shard %d: %d grasps (%d seed block(s) of %d) x %d iterations, batches of %d, "
        "%d torch threads", object_id, shard, n, len(blocks), size, schedule.iterations,
        ann["batch_size"], torch.get_num_threads(),
    )  # fmt: skip
    cands = load_npz(hand_dir / "contact_candidates.npz")
    cand_finger = cands["finger"].astype(str)
    cand_distal = cands["region_kind"][cands["region"]].astype(str) == "distal"
    frames = []
    batch = int(ann["batch_size"])
    for lo in range(0, n, batch):
        hi = min(lo + batch, n)
        result = anneal(
            energy,
            pre["wrist_pos"][lo:hi],
            pre["rot6d"][lo:hi],
            pre["joints"][lo:hi],
            energy.kin.joint_lower.numpy(),
            energy.kin.joint_upper.numpy(),
            schedule,
            chain_seeds[lo:hi],
            dtype=dtype,
            progress=log_progress(f"{object_id} shard {shard} grasps {lo}-{hi - 1}"),
        )
        with torch.no_grad():
            state = [torch.as_tensor(a, dtype=dtype) for a in (result.wrist_pos, result.rot6d)]
            joints = torch.as_tensor(result.joints, dtype=dtype)
            terms = energy.terms(*state, joints)
            cand_dist = energy.candidate_distances(*state, joints)
            hand_depth = energy.hand_depths(*state, joints)
        frames.append(
            grasp_table(
                object_id,
                shard,
                seed,
                shard * n + np.arange(lo, hi),
                result,
                {t: terms[t].to(torch.float64).numpy() for t in TERMS},
                cand_dist.to(torch.float64).numpy(),
                cand_finger,
                cand_distal,
                hand_depth.to(torch.float64).numpy(),
            )
        )
    table = pl.concat(frames)
    elapsed = time.perf_counter() - t0
    meta = {
        "object_id": object_id,
        "shard": shard,
        "seed": seed,
        "grasps": n,
        "seed_blocks": blocks,
        "torch_threads": torch.get_num_threads(),
        "frame": "object frame (centre of mass, +z up); quaternions w, x, y, z",
        "provenance": provenance("synthesis", params),
    }
    write_parquet(out_path, table, metadata=meta)
    write_timing(timing_path, {"object_id": object_id, "shard": shard, "grasps": n,
                               "wall_time_s": elapsed, "grasps_per_s": n / elapsed})  # fmt: skip
    log.info(
        "%s shard %d: %d grasps in %.1f s (%.2f grasps/s); median energy %.1f -> %.1f",
        object_id, shard, n, elapsed, n / elapsed,
        float(np.median(table["energy_start"])), float(np.median(table["energy"])),
    )  # fmt: skip
    return table


def main(argv: list[str] | None = None) -> int:
    """Command-line entry point (the Snakemake rule calls :func:`anneal_grasps` directly)."""
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--object-id", required=True)
    ap.add_argument("--object-dir", required=True, type=Path)
    ap.add_argument("--hand-dir", required=True, type=Path)
    ap.add_argument("--out", required=True, type=Path)
    ap.add_argument("--params-json", required=True, help="the synthesis config slice as JSON")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--shard", type=int, default=0)
    ap.add_argument("--threads", type=int, default=None)
    ap.add_argument("--log-file", default=None)
    ap.add_argument("--timing", type=Path, default=None, help="the timing sidecar (JSON) to write")
    args = ap.parse_args(argv)
    params = json.loads(args.params_json)
    read_json(args.object_dir / "meta.json")  # fail early, naming the file, if not preprocessed
    anneal_grasps(
        args.object_id, args.object_dir, args.hand_dir, args.out, params, args.seed, args.shard,
        threads=args.threads, log_file=args.log_file, timing_path=args.timing,
    )  # fmt: skip
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
