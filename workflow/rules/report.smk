# The self-contained HTML report: every stage, from the objects to the learning studies (chapter 4).


rule report:
    input:
        objects_figure="results/figures/objects.png",
        hand_candidates="results/figures/hand_candidates.png",
        hand_capsules="results/figures/hand_capsules.png",
        hand_json="results/hand/hand.json",
        meta=object_outputs("meta.json"),
        object_benchmarks=expand(
            "results/benchmarks/preprocess_object/{object}.tsv", object=object_ids()
        ),
        grasp_summaries=grasp_outputs("summary.json"),
        anneal_benchmarks=expand(
            "results/benchmarks/anneal_grasps/{object}_shard_{shard}.tsv",
            object=object_ids(),
            shard=range(config["synthesis"]["shards"]),
        ),
        replay_summaries=expand(
            "results/replay/{object}/replays_{shard}.parquet",
            object=object_ids(),
            shard=range(config["synthesis"]["shards"]),
        ),
        replay_trace=rules.plot_replay.output[0],
        dataset_summary=rules.label_windows.output.summary,
        window_figure=rules.plot_window.output[0],
        sweep_summaries=expand("results/datasets/sweep/w{ms}ms/summary.json", ms=sweep_ms()),
        pregrasp=rules.plot_grasps.output.pregrasp,
        gallery=rules.plot_grasps.output.gallery,
        histograms=rules.plot_grasps.output.histograms,
        studies=rules.studies.input,
        learning_figures=rules.plot_learning.output,
    output:
        "results/report.html",
    params:
        config=config,
    conda:
        CONDA_ENV
    threads: 1
    resources:
        mem_mb=1000,
        runtime=10,
    log:
        "results/logs/report/report.log",
    benchmark:
        "results/benchmarks/report/report.tsv"
    script:
        "../scripts/write_report.py"
