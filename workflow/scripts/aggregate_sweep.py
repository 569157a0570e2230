"""Snakemake wrapper: the window-length sweep's study tables (graspstab.evaluation.studies, 4.5)."""

from graspstab.common.jobs import job
from graspstab.evaluation import studies

sm = snakemake  # noqa: F821  (injected by Snakemake)
with job(sm):
    studies.aggregate_sweep(
        list(sm.input.metrics), sm.input.latency, sm.params.out_dir, log_file=sm.log[0]
    )
