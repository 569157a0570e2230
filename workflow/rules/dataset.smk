# Window datasets (thesis 3.3, 3.5.4): the baseline task's dataset, the sweep's reference dataset at
# the longest window and one trimmed dataset per sweep window (same end, label, split, count).

DATASET_FILES = [
    "index.parquet", "windows.npy", "normalisation.json", "summary.json", "motion.npy"
]


rule label_windows:
    input:
        tables=replay_outputs("replays"),
        traces=replay_outputs("traces"),
    output:
        **{Path(n).stem: f"results/datasets/baseline/{n}" for n in DATASET_FILES},
    params:
        dataset=dataset_params(config["labels"]["window_s"]),
    threads: 1
    resources:
        mem_mb=4000,
        runtime=60,
    log:
        "results/logs/label_windows/baseline.log",
    benchmark:
        "results/benchmarks/label_windows/baseline.tsv"
    script:
        "../scripts/label_windows.py"


# Failure anatomy (docs/protocols.md "Failure anatomy"): when and how each usable grasp fails after
# settling, from the replay's contact slip, servo forces and spin: the table and summary the
# report's anatomy section reads.
rule summarise_anatomy:
    input:
        tables=replay_outputs("replays"),
        traces=replay_outputs("traces"),
    output:
        table="results/replay/anatomy.parquet",
        summary="results/replay/anatomy.json",
        figure="results/figures/anatomy.png",
    params:
        dataset=dataset_params(config["labels"]["window_s"]),
        protocol=config["replay"]["protocol"],
    threads: 1
    resources:
        mem_mb=3000,
        runtime=30,
    log:
        "results/logs/summarise_anatomy/anatomy.log",
    benchmark:
        "results/benchmarks/summarise_anatomy/anatomy.tsv"
    script:
        "../scripts/summarise_anatomy.py"


# The anatomy summaries and figures the report reads, named <protocol>_<artefact> (creep_free.smk
# adds the benchmark's).
ANATOMY_ARTEFACTS = {
    "reference_summary": rules.summarise_anatomy.output.summary,
    "reference_figure": rules.summarise_anatomy.output.figure,
}


rule label_sweep_reference:
    input:
        tables=replay_outputs("replays"),
        traces=replay_outputs("traces"),
    output:
        **{Path(n).stem: f"results/datasets/sweep/reference/{n}" for n in DATASET_FILES},
    params:
        dataset=dataset_params(max(config["sweep"]["windows_s"])),
    threads: 1
    resources:
        mem_mb=4000,
        runtime=60,
    log:
        "results/logs/label_sweep_reference/reference.log",
    benchmark:
        "results/benchmarks/label_sweep_reference/reference.tsv"
    script:
        "../scripts/label_windows.py"


rule trim_sweep_window:
    input:
        rules.label_sweep_reference.output,
    output:
        **{Path(n).stem: f"results/datasets/sweep/w{{ms}}ms/{n}" for n in DATASET_FILES},
    params:
        dt=config["replay"]["timestep"],
    wildcard_constraints:
        ms="[0-9]+",
    threads: 1
    resources:
        mem_mb=4000,
        runtime=30,
    log:
        "results/logs/trim_sweep_window/w{ms}ms.log",
    benchmark:
        "results/benchmarks/trim_sweep_window/w{ms}ms.tsv"
    script:
        "../scripts/trim_sweep_window.py"


# The replay trace figure (cf. fig. 3.7) of the first object's first shard, shaded by eq. 23's
# timestep labels: a labelling-stage figure drawn on the replay stage's plot.
rule plot_replay:
    input:
        summary=f"results/replay/{object_ids()[0]}/replays_0.parquet",
        traces=f"results/replay/{object_ids()[0]}/traces_0.npz",
    output:
        "results/figures/replay_trace.png",
    params:
        timestep=config["replay"]["timestep"],
        labels=config["labels"],
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


rule plot_window:
    input:
        index=rules.label_windows.output.index,
        tables=replay_outputs("replays"),
        traces=replay_outputs("traces"),
    output:
        "results/figures/window.png",
    params:
        labels=config["labels"],
        dt=config["replay"]["timestep"],
    threads: 1
    resources:
        mem_mb=2000,
        runtime=10,
    log:
        "results/logs/plot_window/window.log",
    benchmark:
        "results/benchmarks/plot_window/window.tsv"
    script:
        "../scripts/plot_window.py"


rule plot_unstable_speeds:
    input:
        index=rules.label_windows.output.index,
        tables=replay_outputs("replays"),
        traces=replay_outputs("traces"),
    output:
        summary="results/datasets/speeds.json",
        figure="results/figures/unstable_speeds.png",
    params:
        contact=config["replay"]["contact"],
        labels=config["labels"],
        dt=config["replay"]["timestep"],
    threads: 1
    resources:
        mem_mb=2000,
        runtime=10,
    log:
        "results/logs/plot_unstable_speeds/speeds.log",
    benchmark:
        "results/benchmarks/plot_unstable_speeds/speeds.tsv"
    script:
        "../scripts/plot_unstable_speeds.py"
