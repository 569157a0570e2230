"""Snakemake wrapper: the split-robustness study tables (graspstab.evaluation.studies, 4.4)."""

from graspstab.common.jobs import job
from graspstab.evaluation import studies

sm = snakemake  # noqa: F821  (injected by Snakemake)
with job(sm):
    studies.aggregate_splits(
        list(sm.input.metrics), list(sm.params.assignments), sm.params.out_dir, log_file=sm.log[0]
    )
