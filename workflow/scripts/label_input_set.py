"""Snakemake wrapper: one input set's dataset at the baseline's starts (graspstab.labels)."""

from pathlib import Path

from graspstab.common.jobs import job
from graspstab.common.logs import setup_logging
from graspstab.labels.input_sets import build_input_dataset
from graspstab.labels.trace_windows import trace_map

sm = snakemake  # noqa: F821  (injected by Snakemake)
with job(sm):
    setup_logging(sm.log[0])
    build_input_dataset(Path(sm.input.index).parent,
                        trace_map(list(sm.input.traces), [tuple(k) for k in sm.params.trace_keys]),
                        sm.wildcards.inputs, Path(sm.output.index).parent)  # fmt: skip
