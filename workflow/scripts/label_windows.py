"""Snakemake wrapper: build one window dataset from the replays (graspstab.labels)."""

from pathlib import Path

from graspstab.common.jobs import job
from graspstab.labels.build_datasets import build_dataset

sm = snakemake  # noqa: F821  (injected by Snakemake)
with job(sm):
    p = dict(sm.params.dataset)
    build_dataset(
        # the declared inputs, pairwise: replay_outputs() lists tables and traces in the same order
        list(zip(sm.input.tables, sm.input.traces, strict=True)),
        Path(sm.output.index).parent,
        dict(p["labels"]),
        dict(p["splits"]),
        float(p["window_s"]),
        float(p["dt"]),
        int(p["seed"]),
        log_file=sm.log[0],
    )
