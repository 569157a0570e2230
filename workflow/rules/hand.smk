# The ORCA hand model (thesis 3.1.1-3.1.2): MjSpec build, capsules, 120 contact candidates.

HAND_OUTPUTS = [
    "hand.xml",
    "hand.json",
    "capsules.json",
    "contact_candidates.npz",
    "surface_points.npz",
]


rule build_hand:
    input:
        "resources/orcahand_description",
    output:
        # keys hand_xml, hand_json, ... (the stems alone would collide: hand.xml, hand.json)
        **{n.replace(".", "_"): f"results/hand/{n}" for n in HAND_OUTPUTS},
        meshes=directory("results/hand/meshes"),
    params:
        hand=config["hand"],
    threads: 1
    resources:
        mem_mb=2000,
        runtime=15,
    log:
        "results/logs/build_hand/hand.log",
    benchmark:
        "results/benchmarks/build_hand/hand.tsv"
    script:
        "../scripts/build_hand.py"


rule plot_hand:
    input:
        rules.build_hand.output,
    output:
        candidates="results/figures/hand_candidates.png",
        capsules="results/figures/hand_capsules.png",
    threads: 1
    resources:
        mem_mb=2000,
        runtime=10,
    log:
        "results/logs/plot_hand/hand.log",
    benchmark:
        "results/benchmarks/plot_hand/hand.tsv"
    script:
        "../scripts/plot_hand.py"
