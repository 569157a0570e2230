"""Snakemake wrapper: lead-time histogram and replay timeline (graspstab.monitor.figures)."""

from graspstab.common.jobs import job
from graspstab.common.logs import setup_logging
from graspstab.monitor.figures import plot_monitor

sm = snakemake  # noqa: F821  (injected by Snakemake)
with job(sm):
    setup_logging(sm.log[0])
    plot_monitor(sm.input.episodes, sm.input.summary, sm.input.timeline, sm.output.leads,
                 sm.output.timeline, dpi=int(sm.params.dpi))  # fmt: skip
