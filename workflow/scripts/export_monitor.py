"""Snakemake wrapper: one trained run to TorchScript, ONNX and a constants sidecar
(graspstab.monitor.export_models); rule export_pick first maps the sweep's pick to its run."""

from graspstab.common.cache import run_cached
from graspstab.common.jobs import job
from graspstab.monitor.export_models import export_run, pick_candidate

sm = snakemake  # noqa: F821  (injected by Snakemake)


def compute() -> None:
    if "sweep" in sm.input.keys():
        names = [k.removeprefix("checkpoint_") for k in sm.input.keys()
                 if k.startswith("checkpoint_")]  # fmt: skip
        runs = {n: (sm.input[f"checkpoint_{n}"], sm.input[f"metrics_{n}"]) for n in names}
        checkpoint, metrics = pick_candidate(sm.input.sweep, runs)
    else:
        checkpoint, metrics = sm.input.checkpoint, sm.input.metrics
    export_run(checkpoint, metrics, sm.output.onnx, sm.output.torchscript, sm.output.constants,
               log_file=sm.log[0], onnx_exporter=sm.params.onnx_exporter)  # fmt: skip


# Content-addressed: restored from the cache when the same job ran before (docs/design.md).
with job(sm):
    run_cached(sm, ("monitor/export_models",), compute)
