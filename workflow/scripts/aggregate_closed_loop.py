"""Snakemake wrapper: one protocol's closed-loop summary (graspstab.closedloop.summary)."""

from pathlib import Path

from graspstab.closedloop.summary import aggregate_closed_loop
from graspstab.common.jobs import job
from graspstab.common.logs import setup_logging

sm = snakemake  # noqa: F821  (injected by Snakemake)
with job(sm):
    log = setup_logging(sm.log[0])
    summary = aggregate_closed_loop(
        list(sm.input), list(sm.params.policies), sm.wildcards.protocol,
        dict(sm.params.bootstrap), str(Path(sm.output.summary).parent),
    )  # fmt: skip
    log.info("%s", summary["answer"])
