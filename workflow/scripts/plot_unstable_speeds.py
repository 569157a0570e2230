"""Snakemake wrapper: creep and the speeds behind the labels (graspstab.labels.speed_figure)."""

from graspstab.common.jobs import job
from graspstab.common.logs import setup_logging
from graspstab.labels.speed_figure import plot_unstable_speeds

sm = snakemake  # noqa: F821  (injected by Snakemake)
with job(sm):
    setup_logging(sm.log[0])
    plot_unstable_speeds(
        sm.input.index,
        list(sm.input.tables),
        list(sm.input.traces),
        dict(sm.params.contact),
        dict(sm.params.labels),
        float(sm.params.dt),
        sm.output.summary,
        sm.output.figure,
    )
