"""Snakemake wrapper: replay one object x shard of grasps (graspstab.replay)."""

from pathlib import Path

from graspstab.common.cache import run_cached
from graspstab.replay.replay_grasps import replay_grasps

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
    )


# Content-addressed: restored from the cache when the same job ran before (docs/design.md).
run_cached(sm, ("replay",), compute)
