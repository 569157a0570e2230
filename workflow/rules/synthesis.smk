# Grasp synthesis (thesis 3.1.3-3.1.4): one annealing job per object x shard, a per-object summary,
# and the figures (pre-grasp, gallery, energy histograms).

OBJECT_INPUTS = ["mesh.obj", "sdf.npz", "hull_points.npy", "meta.json"]


rule anneal_grasps:
    input:
        **{Path(n).stem: f"results/objects/{{object}}/{n}" for n in OBJECT_INPUTS},
        hand=rules.build_hand.output,
    output:
        "results/grasps/{object}/shard_{shard}.parquet",
        # run-time measurements (wall time, rate): a sidecar beside the benchmark, not data
        timing="results/benchmarks/anneal_grasps/{object}_shard_{shard}.timing.json",
    params:
        synthesis=synthesis_params(),
        seed=config["seed"],
    threads: 1
    resources:
        mem_mb=3000,
        runtime=240,
    log:
        "results/logs/anneal_grasps/{object}_shard_{shard}.log",
    benchmark:
        "results/benchmarks/anneal_grasps/{object}_shard_{shard}.tsv"
    script:
        "../scripts/anneal_grasps.py"


rule summarise_grasps:
    input:
        shard_tables,
    output:
        "results/grasps/{object}/summary.json",
    threads: 1
    resources:
        mem_mb=1000,
        runtime=5,
    log:
        "results/logs/summarise_grasps/{object}.log",
    benchmark:
        "results/benchmarks/summarise_grasps/{object}.tsv"
    script:
        "../scripts/summarise_grasps.py"


rule plot_grasps:
    input:
        tables=shard_tables_of(object_ids()),
        objects=expand("results/objects/{object}/mesh.obj", object=object_ids()),
        hand=rules.build_hand.output,
    output:
        pregrasp="results/figures/pregrasp.png",
        gallery="results/figures/grasp_gallery.png",
        histograms="results/figures/energy_histograms.png",
    params:
        pregrasp=config["synthesis"]["pregrasp"],
        seed=config["seed"],
    threads: 1
    resources:
        mem_mb=2000,
        runtime=15,
    log:
        "results/logs/plot_grasps/grasps.log",
    benchmark:
        "results/benchmarks/plot_grasps/grasps.tsv"
    script:
        "../scripts/plot_grasps.py"
