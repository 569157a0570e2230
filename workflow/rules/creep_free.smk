# The creep-free benchmark (our extension, docs/protocols.md "The creep-free load ramp"): the run's own grasps replayed a
# second time under the strict contact model with the load ramp, then the baseline task, the
# friction-ratio proxy and the window sweep on its datasets, set beside the main run in the report.
# Included only when creep_free.enabled. Every rule is the main run's rule with its paths under
# results/creep_free/ (`use rule ... with`), so the two benchmarks cannot drift apart: the same
# labels, models, training, thresholds and proxy. The sweep trains the main run's tuned
# configurations (tuning is not repeated) and shares its latency table (an architecture's latency
# does not depend on the data it was trained on).

CF = CREEP_FREE


use rule replay_grasps as replay_grasps_creep_free with:
    output:
        traces=f"{CF}/replay/{{object}}/traces_{{shard}}.npz",
        summary=f"{CF}/replay/{{object}}/replays_{{shard}}.parquet",
        timing="results/benchmarks/replay_grasps_creep_free/{object}_shard_{shard}.timing.json",
    params:
        replay=creep_free_replay(),
    log:
        "results/logs/replay_grasps_creep_free/{object}_shard_{shard}.log",
    benchmark:
        "results/benchmarks/replay_grasps_creep_free/{object}_shard_{shard}.tsv"


use rule summarise_replays as summarise_replays_creep_free with:
    input:
        tables=replay_outputs("replays", CF),
    output:
        f"{CF}/replay/outcomes.parquet",
    params:
        protocol=creep_free_replay()["protocol"],
    log:
        "results/logs/summarise_replays_creep_free/outcomes.log",
    benchmark:
        "results/benchmarks/summarise_replays_creep_free/outcomes.tsv"


use rule summarise_anatomy as summarise_anatomy_creep_free with:
    input:
        tables=replay_outputs("replays", CF),
        traces=replay_outputs("traces", CF),
    output:
        table=f"{CF}/replay/anatomy.parquet",
        summary=f"{CF}/replay/anatomy.json",
        figure="results/figures/creep_free/anatomy.png",
    params:
        dataset=creep_free_dataset_params(config["labels"]["window_s"]),
        protocol=creep_free_replay()["protocol"],
    log:
        "results/logs/summarise_anatomy_creep_free/anatomy.log",
    benchmark:
        "results/benchmarks/summarise_anatomy_creep_free/anatomy.tsv"


ANATOMY_ARTEFACTS["creep_free_summary"] = rules.summarise_anatomy_creep_free.output.summary
ANATOMY_ARTEFACTS["creep_free_figure"] = rules.summarise_anatomy_creep_free.output.figure


use rule label_windows as label_windows_creep_free with:
    input:
        tables=replay_outputs("replays", CF),
        traces=replay_outputs("traces", CF),
    output:
        **{Path(n).stem: f"{CF}/datasets/baseline/{n}" for n in DATASET_FILES},
    params:
        dataset=creep_free_dataset_params(config["labels"]["window_s"]),
    log:
        "results/logs/label_windows_creep_free/baseline.log",
    benchmark:
        "results/benchmarks/label_windows_creep_free/baseline.tsv"


use rule label_sweep_reference as label_sweep_reference_creep_free with:
    input:
        tables=replay_outputs("replays", CF),
        traces=replay_outputs("traces", CF),
    output:
        **{Path(n).stem: f"{CF}/datasets/sweep/reference/{n}" for n in DATASET_FILES},
    params:
        dataset=creep_free_dataset_params(max(config["creep_free"]["sweep_windows_s"])),
    log:
        "results/logs/label_sweep_reference_creep_free/reference.log",
    benchmark:
        "results/benchmarks/label_sweep_reference_creep_free/reference.tsv"


use rule trim_sweep_window as trim_sweep_window_creep_free with:
    input:
        rules.label_sweep_reference_creep_free.output,
    output:
        **{Path(n).stem: f"{CF}/datasets/sweep/w{{ms}}ms/{n}" for n in DATASET_FILES},
    log:
        "results/logs/trim_sweep_window_creep_free/w{ms}ms.log",
    benchmark:
        "results/benchmarks/trim_sweep_window_creep_free/w{ms}ms.tsv"


use rule plot_unstable_speeds as plot_unstable_speeds_creep_free with:
    input:
        index=rules.label_windows_creep_free.output.index,
        tables=replay_outputs("replays", CF),
        traces=replay_outputs("traces", CF),
    output:
        summary=f"{CF}/datasets/speeds.json",
        figure="results/figures/creep_free/unstable_speeds.png",
    params:
        contact=config["creep_free"]["contact"],
        labels=creep_free_labels(),
        dt=config["replay"]["timestep"],
    log:
        "results/logs/plot_unstable_speeds_creep_free/speeds.log",
    benchmark:
        "results/benchmarks/plot_unstable_speeds_creep_free/speeds.tsv"


use rule train_model as train_model_creep_free with:
    input:
        **dataset_inputs(f"{CF}/datasets/baseline"),
    output:
        **run_outputs(f"{CF}/train/baseline/{{model}}/seed{{seed}}"),
    log:
        "results/logs/train_model_creep_free/{model}_seed{seed}.log",
    benchmark:
        "results/benchmarks/train_model_creep_free/{model}_seed{seed}.tsv"


use rule train_sweep_model as train_sweep_model_creep_free with:
    input:
        unpack(
            lambda wc: {
                **tuned_best(wc.model),
                **dataset_inputs(f"{CF}/datasets/sweep/w{wc.ms}ms"),
            }
        ),
    output:
        **run_outputs(f"{CF}/train/sweep/{{model}}/w{{ms}}ms/seed{{seed}}"),
    log:
        "results/logs/train_sweep_model_creep_free/{model}_w{ms}ms_seed{seed}.log",
    benchmark:
        "results/benchmarks/train_sweep_model_creep_free/{model}_w{ms}ms_seed{seed}.tsv"


use rule aggregate_baseline as aggregate_baseline_creep_free with:
    input:
        metrics=baseline_runs("metrics.json", creep_free_seeds(config, "train"), root=CF),
    output:
        **{k: f"{CF}/studies/baseline/{Path(v).name}"
           for k, v in rules.aggregate_baseline.output.items()},
    log:
        "results/logs/aggregate_baseline_creep_free/baseline.log",
    benchmark:
        "results/benchmarks/aggregate_baseline_creep_free/baseline.tsv"


use rule aggregate_sweep as aggregate_sweep_creep_free with:
    input:
        metrics=sweep_runs("metrics.json", creep_free_seeds(config, "sweep"), root=CF,
                           windows_ms=creep_free_sweep_ms()),
        latency=rules.measure_latency.output[0],
    output:
        **{k: f"{CF}/studies/sweep/{Path(v).name}"
           for k, v in rules.aggregate_sweep.output.items()},
    log:
        "results/logs/aggregate_sweep_creep_free/sweep.log",
    benchmark:
        "results/benchmarks/aggregate_sweep_creep_free/sweep.tsv"


use rule evaluate_proxy as evaluate_proxy_creep_free with:
    input:
        index=rules.label_windows_creep_free.output.index,
        windows=rules.label_windows_creep_free.output.windows,
        normalisation=rules.label_windows_creep_free.output.normalisation,
        motion=rules.label_windows_creep_free.output.motion,
    output:
        f"{CF}/studies/proxy.json",
    log:
        "results/logs/evaluate_proxy_creep_free/proxy.log",
    benchmark:
        "results/benchmarks/evaluate_proxy_creep_free/proxy.tsv"


use rule evaluate_monitor as evaluate_monitor_creep_free with:
    input:
        tables=held_out_replays("replays", CF),
        traces=held_out_replays("traces", CF),
        **dataset_inputs(f"{CF}/datasets/sweep/w{MONITOR_MS}ms"),
        **{f"checkpoint_{m}": sweep_first_seed(m, MONITOR_MS, "model.pt", CF) for m in MODELS},
        **{f"metrics_{m}": sweep_first_seed(m, MONITOR_MS, "metrics.json", CF) for m in MODELS},
    output:
        episodes=f"{CF}/monitor/episodes.parquet",
        summary=f"{CF}/monitor/summary.json",
        timeline=f"{CF}/monitor/timeline.npz",
    params:
        splits=object_splits(),
        labels=creep_free_labels(),
        dt=config["replay"]["timestep"],
        monitor=config["monitor"],
        threshold=config["train"]["threshold"],
    log:
        "results/logs/evaluate_monitor_creep_free/monitor.log",
    benchmark:
        "results/benchmarks/evaluate_monitor_creep_free/monitor.tsv"


use rule plot_monitor as plot_monitor_creep_free with:
    input:
        **dict(rules.evaluate_monitor_creep_free.output.items()),
    output:
        leads="results/figures/creep_free/monitor/lead_times.png",
        timeline="results/figures/creep_free/monitor/timeline.png",
    log:
        "results/logs/plot_monitor_creep_free/monitor.log",
    benchmark:
        "results/benchmarks/plot_monitor_creep_free/monitor.tsv"


# What the report's side-by-side section reads, as named inputs creep_free_<artefact>; the
# studies' ones are named study_<field of graspstab.figures.artefacts.StudyArtefacts>.
CREEP_FREE_ARTEFACTS = {
    "dataset": rules.label_windows_creep_free.output.summary,
    "speeds": rules.plot_unstable_speeds_creep_free.output.summary,
    "speeds_figure": rules.plot_unstable_speeds_creep_free.output.figure,
    "replay_outcomes": rules.summarise_replays_creep_free.output[0],
    **{f"study_baseline_{k}": v for k, v in rules.aggregate_baseline_creep_free.output.items()},
    **{f"study_sweep_{k}": v for k, v in rules.aggregate_sweep_creep_free.output.items()},
    "study_proxy": rules.evaluate_proxy_creep_free.output[0],
    # the grasp-level evaluation under the ramp (the report's "Grasp-level warnings")
    "monitor_summary": rules.evaluate_monitor_creep_free.output.summary,
    "monitor_leads_figure": rules.plot_monitor_creep_free.output.leads,
    "monitor_timeline_figure": rules.plot_monitor_creep_free.output.timeline,
}
