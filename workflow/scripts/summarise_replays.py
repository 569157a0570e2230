"""Snakemake wrapper: how one protocol's replays ended (graspstab.replay.outcomes)."""

from graspstab.common.jobs import job
from graspstab.replay.outcomes import summarise_replays

sm = snakemake  # noqa: F821  (injected by Snakemake)
with job(sm):
    summarise_replays(
        list(sm.input.tables), sm.output[0], str(sm.params.protocol), log_file=sm.log[0]
    )
