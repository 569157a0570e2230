"""Snakemake wrapper: the sensor-robustness study (graspstab.evaluation.robustness); the dataset
folder is the one holding the rule's declared index, windows and statistics."""

from pathlib import Path

from graspstab.common.jobs import job
from graspstab.evaluation.robustness import evaluate_robustness

sm = snakemake  # noqa: F821  (injected by Snakemake)
with job(sm):
    evaluate_robustness(
        Path(sm.input.index).parent,
        list(sm.input.traces),
        [tuple(k) for k in sm.params.trace_keys],
        list(sm.input.checkpoints),
        list(sm.params.run_keys),
        dict(sm.params.sensing),
        float(sm.params.dt),
        int(sm.params.seed),
        sm.output.runs,
        sm.output.summary,
        log_file=sm.log[0],
    )
