# Grasp replay (thesis 3.2): every grasp of an object x shard held under gravity, traces recorded.


rule replay_grasps:
    input:
        grasps="results/grasps/{object}/shard_{shard}.parquet",
        object_xml="results/objects/{object}/object.xml",
        hand=rules.build_hand.output,
    output:
        traces="results/replay/{object}/traces_{shard}.npz",
        summary="results/replay/{object}/replays_{shard}.parquet",
    params:
        replay=config["replay"],
    conda:
        CONDA_ENV
    threads: 1
    resources:
        mem_mb=3000,
        runtime=240,
    log:
        "results/logs/replay_grasps/{object}_shard_{shard}.log",
    benchmark:
        "results/benchmarks/replay_grasps/{object}_shard_{shard}.tsv"
    script:
        "../scripts/replay_grasps.py"


rule plot_replay:
    input:
        summary=f"results/replay/{object_ids()[0]}/replays_0.parquet",
        traces=f"results/replay/{object_ids()[0]}/traces_0.npz",
    output:
        "results/figures/replay_trace.png",
    params:
        timestep=config["replay"]["timestep"],
        labels=config["labels"],
    conda:
        CONDA_ENV
    threads: 1
    resources:
        mem_mb=2000,
        runtime=10,
    log:
        "results/logs/plot_replay/replay.log",
    benchmark:
        "results/benchmarks/plot_replay/replay.tsv"
    script:
        "../scripts/plot_replay.py"
