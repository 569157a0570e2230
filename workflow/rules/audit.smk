# Input audit (our extension, issue 17): the baseline configurations and protocol at the baseline
# window trained on other inputs (graspstab.labels.input_sets), read from the replay traces at the
# baseline dataset's starts; the forces row is the baseline runs themselves.


wildcard_constraints:
    inputs="normal|shear|tangential|object_state",


rule label_input_set:
    input:
        index=rules.label_windows.output.index,
        motion=rules.label_windows.output.motion,
        traces=replay_outputs("traces"),
    output:
        **{Path(n).stem: f"results/datasets/inputs/{{inputs}}/{n}" for n in DATASET_FILES},
    params:
        trace_keys=replay_keys(),
    threads: 1
    resources:
        mem_mb=4000,
        runtime=30,
    log:
        "results/logs/label_input_set/{inputs}.log",
    benchmark:
        "results/benchmarks/label_input_set/{inputs}.tsv"
    script:
        "../scripts/label_input_set.py"


rule train_input_model:
    input:
        **dataset_inputs("results/datasets/inputs/{inputs}"),
    output:
        **run_outputs("results/train/inputs/{inputs}/{model}/seed{seed}", checkpoint=False),
    params:
        spec=lambda wc: config["model"][wc.model],
        train=config["train"],
        extra=lambda wc: {"input_set": wc.inputs},
    threads: 1
    resources:
        mem_mb=3000,
        runtime=120,
    log:
        "results/logs/train_input_model/{inputs}_{model}_seed{seed}.log",
    benchmark:
        "results/benchmarks/train_input_model/{inputs}_{model}_seed{seed}.tsv"
    script:
        "../scripts/train_model.py"


rule aggregate_inputs:
    input:
        metrics=[p for _, p in audit_runs()],
    output:
        runs="results/studies/inputs/runs.parquet",
        summary="results/studies/inputs/summary.json",
    params:
        input_sets=[s for s, _ in audit_runs()],
        out_dir=lambda wc, output: str(Path(output[0]).parent),
    threads: 1
    resources:
        mem_mb=1000,
        runtime=10,
    log:
        "results/logs/aggregate_inputs/inputs.log",
    benchmark:
        "results/benchmarks/aggregate_inputs/inputs.tsv"
    script:
        "../scripts/aggregate_inputs.py"


# What the report's "Input audit" reads, as named inputs audit_<artefact>.
AUDIT_ARTEFACTS = {"summary": rules.aggregate_inputs.output.summary}
