"""Snakemake wrapper: the replay trace figure shaded by the labels (graspstab.labels.figure)."""

from graspstab.common.jobs import job
from graspstab.common.logs import setup_logging
from graspstab.labels.figure import plot_labelled_replay

sm = snakemake  # noqa: F821  (injected by Snakemake)
with job(sm):
    setup_logging(sm.log[0])
    plot_labelled_replay(
        sm.input.summary,
        sm.input.traces,
        float(sm.params.timestep),
        dict(sm.params.labels),
        sm.output[0],
    )
