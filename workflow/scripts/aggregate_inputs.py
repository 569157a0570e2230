"""Snakemake wrapper: the input audit's table (graspstab.evaluation.studies)."""

from graspstab.common.jobs import job
from graspstab.evaluation import studies

sm = snakemake  # noqa: F821  (injected by Snakemake)
with job(sm):
    studies.aggregate_inputs(list(sm.input.metrics), list(sm.params.input_sets), sm.params.out_dir,
                             log_file=sm.log[0])  # fmt: skip
