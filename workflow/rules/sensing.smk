# Sensor realism (our extension; the reference's 5.3): the baseline models (table 4.3's) and the 4.7
# proxy scored on test windows that came through a sensor model (graspstab.sensing), one curve per
# corruption and one row per sensor preset. It reads the baseline dataset, the replay traces
# (the forces before each window, for the delay and the hold) and the baseline checkpoints.


wildcard_constraints:
    mode="mixture|noise|gain|drift|quantisation|rate|delay|drop",


rule train_augmented_model:
    input:
        **dataset_inputs("results/datasets/baseline"),
        traces=replay_outputs("traces"),
    output:
        **run_outputs("results/train/sensing/{mode}/{model}/seed{seed}"),
    params:
        spec=lambda wc: config["model"][wc.model],
        train=config["train"],
        augment=lambda wc: {
            "sensing": augment_sensing(wc.mode),
            "trace_keys": replay_keys(),
            "dt": config["replay"]["timestep"],
        },
        extra=lambda wc: {"training": training_label(wc.mode)},
    threads: 1
    resources:
        mem_mb=3000,
        runtime=120,
    log:
        "results/logs/train_augmented_model/{mode}_{model}_seed{seed}.log",
    benchmark:
        "results/benchmarks/train_augmented_model/{mode}_{model}_seed{seed}.tsv"
    script:
        "../scripts/train_model.py"


rule evaluate_sensor_robustness:
    input:
        index=rules.label_windows.output.index,
        windows=rules.label_windows.output.windows,
        normalisation=rules.label_windows.output.normalisation,
        traces=replay_outputs("traces"),
        checkpoints=baseline_runs("model.pt", sensing_seeds()) + augmented_runs("model.pt"),
    output:
        runs="results/studies/sensing/runs.parquet",
        summary="results/studies/sensing/summary.json",
    params:
        trace_keys=replay_keys(),
        run_keys=[{"family": m, "seed": s, "training": "clean"} for m in MODELS
                  for s in sensing_seeds()] + augmented_keys(),
        sensing=config["sensing"],
        dt=config["replay"]["timestep"],
        seed=config["seed"],
    threads: 1
    resources:
        mem_mb=2000,
        runtime=30,
    log:
        "results/logs/evaluate_sensor_robustness/sensing.log",
    benchmark:
        "results/benchmarks/evaluate_sensor_robustness/sensing.tsv"
    script:
        "../scripts/evaluate_sensor_robustness.py"


rule plot_sensor_robustness:
    input:
        runs=rules.evaluate_sensor_robustness.output.runs,
        summary=rules.evaluate_sensor_robustness.output.summary,
    output:
        "results/figures/sensing/robustness.png",
    params:
        dpi=config["report"]["figure_dpi"],
    threads: 1
    resources:
        mem_mb=1000,
        runtime=10,
    log:
        "results/logs/plot_sensor_robustness/sensing.log",
    benchmark:
        "results/benchmarks/plot_sensor_robustness/sensing.tsv"
    script:
        "../scripts/plot_sensor_robustness.py"


# What the report's "Sensor realism" section reads, as named inputs sensing_<artefact>.
SENSING_ARTEFACTS = {
    "runs": rules.evaluate_sensor_robustness.output.runs,
    "summary": rules.evaluate_sensor_robustness.output.summary,
    "figure": rules.plot_sensor_robustness.output[0],
}
