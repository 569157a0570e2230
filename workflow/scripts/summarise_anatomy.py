"""Snakemake wrapper: one protocol's failure anatomy (graspstab.labels.summarise_anatomy)."""

from graspstab.common.jobs import job
from graspstab.labels.summarise_anatomy import summarise_anatomy

sm = snakemake  # noqa: F821  (injected by Snakemake)
with job(sm):
    p = dict(sm.params.dataset)
    summarise_anatomy(
        # the declared inputs, pairwise: replay_outputs() lists tables and traces in the same order
        list(zip(sm.input.tables, sm.input.traces, strict=True)),
        sm.output.table,
        sm.output.summary,
        dict(p["labels"]),
        dict(p["splits"]),
        float(p["dt"]),
        str(sm.params.protocol),
        figure_path=sm.output.figure,
        log_file=sm.log[0],
    )
