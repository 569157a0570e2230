"""Snakemake wrapper: one fold's monitors over its validation and test replays, thresholds for the
false-warning budget from validation (graspstab.monitor.evaluate_fold_monitor)."""

from graspstab.common.cache import run_cached
from graspstab.common.jobs import job
from graspstab.monitor.evaluate_fold_monitor import evaluate_fold_monitor

sm = snakemake  # noqa: F821  (injected by Snakemake)


def compute() -> None:
    names = [k.removeprefix("checkpoint_") for k in sm.input.keys() if k.startswith("checkpoint_")]
    runs = {n: (sm.input[f"checkpoint_{n}"], sm.input[f"metrics_{n}"]) for n in names}
    evaluate_fold_monitor(
        list(zip(sm.input.tables, sm.input.traces, strict=True)), runs,
        dict(sm.params.assignment), int(sm.wildcards.fold), dict(sm.params.labels),
        float(sm.params.dt), dict(sm.params.monitor), sm.output.grasps, sm.output.thresholds,
        log_file=sm.log[0],
    )  # fmt: skip


# Content-addressed: restored from the cache when the same job ran before (docs/design.md).
with job(sm):
    run_cached(sm, ("monitor/evaluate_fold_monitor",), compute)
