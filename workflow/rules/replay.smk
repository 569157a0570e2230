# Grasp replay (thesis 3.2): every grasp of an object x shard held under gravity, traces recorded.


rule replay_grasps:
    input:
        grasps="results/grasps/{object}/shard_{shard}.parquet",
        object_xml="results/objects/{object}/object.xml",
        hand=rules.build_hand.output,
    output:
        traces="results/replay/{object}/traces_{shard}.npz",
        summary="results/replay/{object}/replays_{shard}.parquet",
        # run-time measurements (wall times, rate): a sidecar beside the benchmark, not data
        timing="results/benchmarks/replay_grasps/{object}_shard_{shard}.timing.json",
    params:
        replay=replay_params(config["replay"]),
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

