"""Snakemake wrapper: pre-grasps and annealing for one object x shard (graspstab.synthesis)."""

from pathlib import Path

from graspstab.common.cache import run_cached
from graspstab.common.jobs import job
from graspstab.synthesis.anneal_grasps import anneal_grasps

sm = snakemake  # noqa: F821  (injected by Snakemake)


def compute() -> None:
    anneal_grasps(
        sm.wildcards.object,
        Path(sm.input.meta).parent,
        Path(sm.input.hand[0]).parent,
        sm.output[0],
        params=dict(sm.params.synthesis),
        seed=int(sm.params.seed),
        shard=int(sm.wildcards.shard),
        threads=sm.threads,
        log_file=sm.log[0],
        timing_path=sm.output.timing,
    )


# Content-addressed: restored from the cache when the same job ran before (docs/design.md).
with job(sm):
    run_cached(sm, ("synthesis/anneal_grasps",), compute)
