"""Snakemake wrapper: each family's monitor and the proxy over the validation and test replays,
scored grasp by grasp (graspstab.monitor.evaluate_monitor)."""

from pathlib import Path

from graspstab.common.cache import run_cached
from graspstab.common.jobs import job
from graspstab.monitor.evaluate_monitor import evaluate_monitor

sm = snakemake  # noqa: F821  (injected by Snakemake)


def compute() -> None:
    names = [k.removeprefix("checkpoint_") for k in sm.input.keys() if k.startswith("checkpoint_")]
    runs = {n: (sm.input[f"checkpoint_{n}"], sm.input[f"metrics_{n}"]) for n in names}
    evaluate_monitor(
        list(zip(sm.input.tables, sm.input.traces, strict=True)), runs,
        Path(sm.input.index).parent, dict(sm.params.splits), dict(sm.params.labels),
        float(sm.params.dt), dict(sm.params.monitor), dict(sm.params.threshold),
        sm.output.episodes, sm.output.summary, sm.output.timeline, log_file=sm.log[0],
    )  # fmt: skip


# Content-addressed: restored from the cache when the same job ran before (docs/design.md).
with job(sm):
    run_cached(sm, ("monitor/evaluate_monitor",), compute)
