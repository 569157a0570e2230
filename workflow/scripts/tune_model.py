"""Snakemake wrapper: run or resume one family's Optuna study (graspstab.learning)."""

from pathlib import Path

from graspstab.common.cache import run_cached
from graspstab.common.jobs import job
from graspstab.learning.tune_model import tune_model

sm = snakemake  # noqa: F821  (injected by Snakemake)


def compute() -> None:
    tune_model(
        Path(sm.input.index).parent,
        dict(sm.params.base),
        dict(sm.params.train),
        dict(sm.params.tune),
        sm.output.best,
        sm.output.trials,
        default_storage=sm.params.default_storage,
        threads=sm.threads,
        log_file=sm.log[0],
    )


# Content-addressed: restored from the cache when the same job ran before (docs/design.md).
with job(sm):
    run_cached(sm, ("learning/tune_model",), compute)
