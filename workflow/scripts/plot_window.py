"""Snakemake wrapper: the window illustration of the baseline dataset (graspstab.labels.figure)."""

from graspstab.common.jobs import job
from graspstab.common.logs import setup_logging
from graspstab.labels.figure import plot_window

sm = snakemake  # noqa: F821  (injected by Snakemake)
with job(sm):
    setup_logging(sm.log[0])
    plot_window(
        sm.input.index,
        list(sm.input.tables),
        list(sm.input.traces),
        dict(sm.params.labels),
        float(sm.params.dt),
        sm.output[0],
    )
