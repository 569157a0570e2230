"""Snakemake wrapper: replay one object x shard of grasps (graspstab.replay)."""

from pathlib import Path

from graspstab.common.cache import run_cached
from graspstab.common.jobs import job, require_job_space
from graspstab.replay.replay_grasps import replay_grasps
from graspstab.replay.traces import shard_trace_bytes

sm = snakemake  # noqa: F821  (injected by Snakemake)


def compute() -> None:
    replay_grasps(
        sm.wildcards.object,
        Path(sm.input.object_xml).parent,
        Path(sm.input.hand[0]).parent,
        sm.input.grasps,
        sm.output.traces,
        sm.output.summary,
        params=dict(sm.params.replay),
        log_file=sm.log[0],
        timing_path=sm.output.timing,
    )


with job(sm):
    # The traces' largest size, free on their disk (and the cache's) before hours of simulation.
    need = shard_trace_bytes(sm.input.grasps, dict(sm.params.replay))
    require_job_space(sm, {sm.output.traces: need}, "this shard's replay traces")
    # Content-addressed: restored from the cache when the same job ran before (docs/design.md).
    run_cached(sm, ("replay/replay_grasps",), compute)
