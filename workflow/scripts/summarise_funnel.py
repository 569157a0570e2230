"""Snakemake wrapper: the grasp funnel, annealed to windows (graspstab.labels.funnel)."""

from graspstab.common.jobs import job
from graspstab.labels.funnel import summarise_funnel

sm = snakemake  # noqa: F821  (injected by Snakemake)
with job(sm):
    summarise_funnel(
        list(sm.input.grasp_summaries),
        sm.input.replay_outcomes,
        sm.input.dataset_summary,
        sm.output[0],
        log_file=sm.log[0],
    )
