"""Snakemake wrapper: the fixed-task benchmark's study tables (evaluation.studies, 4.3)."""

from graspstab.common.jobs import job
from graspstab.evaluation import studies

sm = snakemake  # noqa: F821  (injected by Snakemake)
with job(sm):
    studies.aggregate_baseline(list(sm.input.metrics), sm.params.out_dir, log_file=sm.log[0])
