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



# How the replays ended, per object and over all objects (held, contact lost, too deep, diverged,
# deepest contact, simulated time): the table the report's replay section, grasp funnel and
# side-by-side section read, so the report counts nothing itself.
rule summarise_replays:
    input:
        tables=replay_outputs("replays"),
    output:
        "results/replay/outcomes.parquet",
    params:
        protocol=config["replay"]["protocol"],
    threads: 1
    resources:
        mem_mb=1000,
        runtime=10,
    log:
        "results/logs/summarise_replays/outcomes.log",
    benchmark:
        "results/benchmarks/summarise_replays/outcomes.tsv"
    script:
        "../scripts/summarise_replays.py"
