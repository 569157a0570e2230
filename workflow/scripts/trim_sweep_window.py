"""Snakemake wrapper: one sweep dataset trimmed from the reference (graspstab.labels)."""

from pathlib import Path

from graspstab.common.jobs import job
from graspstab.labels.build_datasets import trim_dataset

sm = snakemake  # noqa: F821  (injected by Snakemake)
with job(sm):
    trim_dataset(
        Path(sm.input[0]).parent,
        Path(sm.output.index).parent,
        int(sm.wildcards.ms) / 1000,
        float(sm.params.dt),
        log_file=sm.log[0],
    )
