"""Snakemake wrapper: one input set's dataset at the baseline's starts (graspstab.labels)."""

from pathlib import Path

from graspstab.common.logs import setup_logging
from graspstab.labels.input_sets import build_input_dataset

sm = snakemake  # noqa: F821  (injected by Snakemake)
setup_logging(sm.log[0])
traces = {(str(o), int(k)): p for p, (o, k) in zip(sm.input.traces, sm.params.trace_keys,
                                                    strict=True)}  # fmt: skip
build_input_dataset(Path(sm.input.index).parent, traces, sm.wildcards.inputs,
                    Path(sm.output.index).parent)  # fmt: skip
