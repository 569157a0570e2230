"""Snakemake wrapper: figure of the preprocessed objects and their convex parts (fig. 3.1)."""

from pathlib import Path

from graspstab.common.jobs import job
from graspstab.common.logs import setup_logging
from graspstab.objects.figure import plot_objects

sm = snakemake  # noqa: F821  (injected by Snakemake)
with job(sm):
    setup_logging(sm.log[0])
    plot_objects([Path(p).parent for p in sm.input.meta], Path(sm.output[0]))
