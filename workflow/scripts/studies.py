"""Snakemake wrapper: the study-level steps (aggregation, latency, proxy) of graspstab.learning."""

from graspstab.learning import studies

sm = snakemake  # noqa: F821  (injected by Snakemake)
step = sm.params.step
if step == "baseline":
    studies.aggregate_baseline(list(sm.input.metrics), sm.params.out_dir, log_file=sm.log[0])
elif step == "latency":
    studies.measure_latencies(
        list(sm.input.checkpoints), list(sm.params.run_keys), sm.output[0],
        repeats=sm.params.latency["repeats"], warmup=sm.params.latency["warmup"],
        threads=sm.threads, log_file=sm.log[0],
    )  # fmt: skip
elif step == "sweep":
    studies.aggregate_sweep(
        list(sm.input.metrics), sm.input.latency, sm.params.out_dir, log_file=sm.log[0],
    )  # fmt: skip
elif step == "splits":
    studies.aggregate_splits(
        list(sm.input.metrics), list(sm.params.assignments), sm.params.out_dir, log_file=sm.log[0]
    )
elif step == "proxy":
    studies.evaluate_proxy(sm.params.dataset, sm.output[0], log_file=sm.log[0])
else:
    raise ValueError(f"unknown study step {step!r}")
