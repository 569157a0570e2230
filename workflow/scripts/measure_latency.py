"""Snakemake wrapper: CPU batch-1 latency of the checkpoints (graspstab.evaluation.studies, 4.5)."""

from graspstab.common.jobs import job
from graspstab.evaluation import studies

sm = snakemake  # noqa: F821  (injected by Snakemake)
with job(sm):
    studies.measure_latencies(
        list(sm.input.checkpoints), list(sm.params.run_keys), sm.output[0],
        repeats=sm.params.latency["repeats"], warmup=sm.params.latency["warmup"],
        threads=sm.threads, log_file=sm.log[0],
    )  # fmt: skip
