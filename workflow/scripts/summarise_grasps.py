"""Snakemake wrapper: the per-object summary of the synthesised grasps (graspstab.synthesis)."""

from graspstab.common.jobs import job
from graspstab.common.logs import setup_logging
from graspstab.synthesis.summarise_grasps import summarise_grasps

sm = snakemake  # noqa: F821  (injected by Snakemake)
with job(sm):
    setup_logging(sm.log[0])
    summarise_grasps(sm.wildcards.object, list(sm.input), sm.output[0])
