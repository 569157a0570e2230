# Object preprocessing (thesis 3.1.1), one job per object, plus the figure of all objects.

PREPROCESS_OUTPUTS = ["mesh.obj", "convex_parts.npz", "object.xml", "sdf.npz", "hull_points.npy",
                      "meta.json"]


rule preprocess_object:
    input:
        mesh="resources/ycb/{object}/textured.obj",
    output:
        **{Path(n).stem: f"results/objects/{{object}}/{n}" for n in PREPROCESS_OUTPUTS},
    params:
        preprocess=config["preprocess"],
        mass=lambda wc: object_entry(wc)["mass"],
        rotation_deg=lambda wc: object_entry(wc).get("rotation_deg"),
    threads: 1
    resources:
        mem_mb=3000,
        runtime=30,
    log:
        "results/logs/preprocess_object/{object}.log",
    benchmark:
        "results/benchmarks/preprocess_object/{object}.tsv"
    script:
        "../scripts/preprocess_object.py"


rule plot_objects:
    input:
        meta=object_outputs("meta.json"),
        parts=object_outputs("convex_parts.npz"),
    output:
        "results/figures/objects.png",
    threads: 1
    resources:
        mem_mb=2000,
        runtime=10,
    log:
        "results/logs/plot_objects/objects.log",
    benchmark:
        "results/benchmarks/plot_objects/objects.tsv"
    script:
        "../scripts/plot_objects.py"
