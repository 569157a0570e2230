"""Snakemake wrapper: the k-fold study's per-object figure (graspstab.figures.crossval)."""

from pathlib import Path

from graspstab.common.io import read_json, read_parquet
from graspstab.common.jobs import job
from graspstab.common.logs import setup_logging
from graspstab.figures.crossval import plot_crossval

sm = snakemake  # noqa: F821  (injected by Snakemake)
with job(sm):
    setup_logging(sm.log[0])
    plot_crossval(
        read_parquet(sm.input.per_object),
        read_json(sm.input.summary),
        Path(sm.output[0]),
        int(sm.params.dpi),
    )
