# Learning and evaluation (thesis 3.4-3.5, 4.3-4.7): the fixed-task benchmark, Optuna tuning, the
# window-length sweep, split robustness, latency and the friction-ratio proxy. One training job is
# one model x dataset x seed; aggregation jobs turn their metrics.json files into study tables.
# Every study step has its own script (one library call each); rule plot_learning and the report
# get the studies' artefacts as named inputs (STUDY_ARTEFACTS) and read only those.

# The one list of learning figures (name -> file), shared with the figures and the report.
from graspstab.figures.presentation import FIGURES as LEARNING_FIGURE_FILES


wildcard_constraints:
    model="|".join(MODELS),
    seed=r"[0-9]+",
    ms=r"[0-9]+",
    k=r"[0-9]+",


rule train_model:
    input:
        **dataset_inputs("results/datasets/baseline"),
    output:
        **run_outputs("results/train/baseline/{model}/seed{seed}"),
    params:
        spec=lambda wc: config["model"][wc.model],
        train=config["train"],
    threads: 1
    resources:
        mem_mb=3000,
        runtime=120,
    log:
        "results/logs/train_model/{model}_seed{seed}.log",
    benchmark:
        "results/benchmarks/train_model/{model}_seed{seed}.tsv"
    script:
        "../scripts/train_model.py"


rule tune_model:
    input:
        **sweep_dataset(ms_of(config["tune"]["window_s"])),
    output:
        best="results/tune/{model}/best.json",
        trials="results/tune/{model}/trials.parquet",
    params:
        base=lambda wc: config["model"][wc.model],
        train=config["train"],
        tune=config["tune"],
        default_storage=lambda wc: f"results/tune/{wc.model}/study.sqlite",
    threads: 1
    resources:
        mem_mb=3000,
        runtime=600,
    log:
        "results/logs/tune_model/{model}.log",
    benchmark:
        "results/benchmarks/tune_model/{model}.tsv"
    script:
        "../scripts/tune_model.py"


rule train_sweep_model:
    input:
        unpack(lambda wc: {**tuned_best(wc.model), **sweep_dataset(wc.ms)}),
    output:
        **run_outputs("results/train/sweep/{model}/w{ms}ms/seed{seed}"),
    params:
        spec=lambda wc: reference_spec(wc.model),
        pooling=config["sweep"]["recurrent_pooling"],
        train=config["train"],
        extra=lambda wc: {"window_s": int(wc.ms) / 1000},
    threads: 1
    resources:
        mem_mb=3000,
        runtime=120,
    log:
        "results/logs/train_sweep_model/{model}_w{ms}ms_seed{seed}.log",
    benchmark:
        "results/benchmarks/train_sweep_model/{model}_w{ms}ms_seed{seed}.tsv"
    script:
        "../scripts/train_model.py"


rule train_split_model:
    input:
        unpack(lambda wc: tuned_best(wc.model)),
        **sweep_dataset(ms_of(config["splits"]["window_s"])),
    output:
        **run_outputs("results/train/splits/{model}/a{k}/seed{seed}", checkpoint=False),
    params:
        spec=lambda wc: reference_spec(wc.model),
        pooling=config["sweep"]["recurrent_pooling"],
        train=config["train"],
        assignment=lambda wc: assignments()[int(wc.k)],
        extra=lambda wc: {"assignment_index": int(wc.k)},
    threads: 1
    resources:
        mem_mb=3000,
        runtime=120,
    log:
        "results/logs/train_split_model/{model}_a{k}_seed{seed}.log",
    benchmark:
        "results/benchmarks/train_split_model/{model}_a{k}_seed{seed}.tsv"
    script:
        "../scripts/train_model.py"


rule aggregate_baseline:
    input:
        metrics=baseline_runs("metrics.json"),
    output:
        runs="results/studies/baseline/runs.parquet",
        summary="results/studies/baseline/summary.parquet",
        objects="results/studies/baseline/objects.parquet",
        errors="results/studies/baseline/errors.parquet",
        overview="results/studies/baseline/summary.json",
        # mean +- std over seeds with 0/0 metrics undefined: what the report shows
        summary_defined="results/studies/baseline/summary_defined.parquet",
        # the threshold rule each run chose on validation, counted (the report's threshold table)
        threshold_rules="results/studies/baseline/threshold_rules.json",
    params:
        out_dir=lambda wc, output: str(Path(output[0]).parent),
    threads: 1
    resources:
        mem_mb=1000,
        runtime=10,
    log:
        "results/logs/aggregate_baseline/baseline.log",
    benchmark:
        "results/benchmarks/aggregate_baseline/baseline.tsv"
    script:
        "../scripts/aggregate_baseline.py"


# Latency of the first seed's checkpoint of every baseline model and sweep configuration.
LATENCY_KEYS = [
    {"study": "baseline", "family": m, "window_s": config["labels"]["window_s"]} for m in MODELS
] + [{"study": "sweep", "family": m, "window_s": ms / 1000} for m in MODELS for ms in sweep_ms()]


rule measure_latency:
    input:
        checkpoints=baseline_runs("model.pt", config["train"]["seeds"][:1])
        + sweep_runs("model.pt", config["sweep"]["seeds"][:1]),
    output:
        "results/studies/latency.parquet",
    params:
        run_keys=LATENCY_KEYS,
        latency=config["latency"],
    threads: config["latency"]["threads"]
    resources:
        mem_mb=1000,
        runtime=30,
    log:
        "results/logs/measure_latency/latency.log",
    benchmark:
        "results/benchmarks/measure_latency/latency.tsv"
    script:
        "../scripts/measure_latency.py"


rule aggregate_sweep:
    input:
        metrics=sweep_runs("metrics.json"),
        latency=rules.measure_latency.output[0],
    output:
        runs="results/studies/sweep/runs.parquet",
        summary="results/studies/sweep/summary.parquet",
        points="results/studies/sweep/operating_points.parquet",
        overview="results/studies/sweep/summary.json",
        summary_defined="results/studies/sweep/summary_defined.parquet",
        threshold_rules="results/studies/sweep/threshold_rules.json",
    params:
        out_dir=lambda wc, output: str(Path(output[0]).parent),
    threads: 1
    resources:
        mem_mb=1000,
        runtime=10,
    log:
        "results/logs/aggregate_sweep/sweep.log",
    benchmark:
        "results/benchmarks/aggregate_sweep/sweep.tsv"
    script:
        "../scripts/aggregate_sweep.py"


rule aggregate_splits:
    input:
        metrics=lambda wc: split_runs(),
    output:
        runs="results/studies/splits/runs.parquet",
        overview="results/studies/splits/summary.json",
        threshold_rules="results/studies/splits/threshold_rules.json",
    params:
        out_dir=lambda wc, output: str(Path(output[0]).parent),
        assignments=lambda wc: assignments(),
    threads: 1
    resources:
        mem_mb=1000,
        runtime=10,
    log:
        "results/logs/aggregate_splits/splits.log",
    benchmark:
        "results/benchmarks/aggregate_splits/splits.tsv"
    script:
        "../scripts/aggregate_splits.py"


rule evaluate_proxy:
    input:
        index=rules.label_windows.output.index,
        windows=rules.label_windows.output.windows,
        normalisation=rules.label_windows.output.normalisation,
        motion=rules.label_windows.output.motion,
    output:
        "results/studies/proxy.json",
    threads: 1
    resources:
        mem_mb=2000,
        runtime=10,
    log:
        "results/logs/evaluate_proxy/proxy.log",
    benchmark:
        "results/benchmarks/evaluate_proxy/proxy.tsv"
    script:
        "../scripts/evaluate_proxy.py"


rule studies:
    input:
        rules.aggregate_baseline.output,
        rules.aggregate_sweep.output,
        rules.aggregate_splits.output,
        rules.evaluate_proxy.output,
        expand("results/tune/{model}/best.json", model=MODELS),


# The studies' artefacts as named inputs (graspstab.figures.artefacts.StudyArtefacts): the
# aggregate tables and summaries, latency, proxy and the tuned best configurations (best_<model>).
STUDY_ARTEFACTS = {
    **{f"baseline_{k}": v for k, v in rules.aggregate_baseline.output.items()},
    **{f"sweep_{k}": v for k, v in rules.aggregate_sweep.output.items()},
    **{f"splits_{k}": v for k, v in rules.aggregate_splits.output.items()},
    "latency": rules.measure_latency.output[0],
    "proxy": rules.evaluate_proxy.output[0],
    **{f"best_{m}": expand(rules.tune_model.output.best, model=m)[0] for m in MODELS},
}
# Per model, the first seed's baseline predictions and metrics.json (figs. 4.8, 4.9) and the
# tuning trials (the optimisation histories), as named inputs <kind>_<model>.
FIRST_SEED_ARTEFACTS = {
    f"{kind}_{m}": expand(path, model=m, seed=config["train"]["seeds"][0])[0]
    for m in MODELS
    for kind, path in (
        ("predictions", rules.train_model.output.predictions),
        ("metrics", rules.train_model.output.metrics),
        ("trials", rules.tune_model.output.trials),
    )
}


rule plot_learning:
    input:
        **STUDY_ARTEFACTS,
        **FIRST_SEED_ARTEFACTS,
    output:
        **{n: f"results/figures/learning/{f}" for n, f in LEARNING_FIGURE_FILES.items()},
    params:
        dpi=config["report"]["figure_dpi"],
        first_seed=config["train"]["seeds"][0],
    threads: 1
    resources:
        mem_mb=2000,
        runtime=10,
    log:
        "results/logs/plot_learning/learning.log",
    benchmark:
        "results/benchmarks/plot_learning/learning.tsv"
    script:
        "../scripts/plot_learning.py"
