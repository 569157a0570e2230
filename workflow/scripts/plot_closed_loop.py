"""Snakemake wrapper: one protocol's closed-loop figures (graspstab.closedloop.figures)."""

from pathlib import Path

from graspstab.closedloop.figures import plot_closed_loop
from graspstab.common.jobs import job
from graspstab.common.logs import setup_logging

sm = snakemake  # noqa: F821  (injected by Snakemake)
with job(sm):
    setup_logging(sm.log[0])
    plot_closed_loop(
        Path(sm.input.summary).parent, list(sm.input.timelines), sm.wildcards.protocol,
        float(sm.params.v_slip), float(sm.params.dt), sm.output.tradeoff, sm.output.timeline,
        dpi=int(sm.params.dpi),
    )  # fmt: skip
