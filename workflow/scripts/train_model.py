"""Snakemake wrapper: train one model x dataset x seed, then test it (evaluation.tested_run)."""

from pathlib import Path

from graspstab.common.cache import run_cached
from graspstab.common.jobs import job
from graspstab.evaluation.tested_run import train_and_test
from graspstab.learning.specs import study_spec

sm = snakemake  # noqa: F821  (injected by Snakemake)


def compute() -> None:
    p = dict(sm.params)
    spec = study_spec(p["spec"], sm.input.get("best"), p.get("pooling"))
    train_and_test(
        Path(sm.input.index).parent,
        spec,
        dict(p["train"]),
        int(sm.wildcards.seed),
        Path(sm.output.metrics).parent,
        assignment=p.get("assignment"),
        threads=sm.threads,
        checkpoint="checkpoint" in sm.output.keys(),
        extra=p.get("extra"),
        augment=(
            {**p["augment"], "trace_paths": list(sm.input.traces)} if "augment" in p else None
        ),
        features=p.get("features"),
        log_file=sm.log[0],
        timing_path=sm.output.timing,
    )


# Content-addressed: restored from the cache when the same job ran before (docs/design.md).
with job(sm):
    # the key covers the code this job runs: the tested run and what it imports (training)
    code = ("evaluation/tested_run", "learning/specs",
            *(("sensing",) if "augment" in sm.params.keys() else ()))  # fmt: skip
    run_cached(sm, code, compute)
