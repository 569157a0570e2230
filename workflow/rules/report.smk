# The self-contained HTML report: every stage, from the objects to the learning studies (chapter 4),
# with the pipeline's own rule graph and every rule's benchmark. The report renders what jobs wrote:
# its counts, medians and means over seeds are read from summaries (summarise_replays,
# summarise_funnel, the studies' summary_defined.parquet and threshold_rules.json), never computed
# from per-grasp or per-seed tables in the report.

import shlex
import sys
from glob import glob

from snakemake.io import strip_wildcard_constraints

from graspstab.report.inputs import benchmark_inputs, benchmark_wildcards, nested_config_args

# DAG overview, option (a) of issue 7: the graph is Snakemake's own output for this very run
# (--rulegraph for the edges, --dag for the jobs per rule), written by rule rulegraph and parsed by
# graspstab.report.dag. A hand-made edge list (option b) would need a test to catch its drift and
# would still be wrong in any run between a rule change and that test; this one cannot drift. The
# nested Snakemake only prints graphs (it runs nothing), so --nolock is safe while this run holds
# the lock, and --forceall makes it list every job, done or not. It gets this run's --config
# overrides (common.smk keeps them as _raw_overrides), so it builds this run's DAG, and runs on the
# interpreter running this workflow (sys.executable), the one sure to have this Snakemake. Moving
# the checkout changes these paths and so reruns rulegraph and report (seconds), no more. The rule
# files are inputs: the graph is remade whenever one changes.
NESTED_SNAKEMAKE = (
    f"{shlex.quote(sys.executable)} -m snakemake -s {shlex.quote(workflow.main_snakefile)} "
    "--nolock --forceall"
)
WORKFLOW_SOURCES = [
    workflow.main_snakefile,
    *sorted(glob(str(Path(workflow.basedir) / "workflow" / "rules" / "*.smk"))),
]


# Seconds of graph printing: on a cluster it runs beside Snakemake, not as a submitted job.
localrules:
    rulegraph,


rule rulegraph:
    input:
        sources=WORKFLOW_SOURCES,
    output:
        rules="results/report/rulegraph.dot",
        jobs="results/report/jobgraph.dot",
    params:
        snakemake=NESTED_SNAKEMAKE,
        # a function: Snakemake would expand braces in a plain string param (e.g. "{model}" in a
        # tune.storage URL) as wildcards
        config=lambda wc: nested_config_args(_raw_overrides),
    threads: 1
    resources:
        mem_mb=1000,
        runtime=10,
    log:
        "results/logs/rulegraph/rulegraph.log",
    benchmark:
        "results/benchmarks/rulegraph/rulegraph.tsv"
    shell:
        "({params.snakemake} results/report.html --rulegraph {params.config} > {output.rules}.tmp"
        " && {params.snakemake} results/report.html --dag {params.config} > {output.jobs}.tmp"
        " && mv {output.rules}.tmp {output.rules} && mv {output.jobs}.tmp {output.jobs}) 2> {log}"


# The grasp funnel (annealed -> replayed -> usable -> windows, per object and in total): the table
# the report's provenance section and headline read, so the report sums nothing itself.
rule summarise_funnel:
    input:
        grasp_summaries=grasp_outputs("summary.json"),
        replay_outcomes=rules.summarise_replays.output[0],
        dataset_summary=rules.label_windows.output.summary,
    output:
        "results/report/funnel.parquet",
    threads: 1
    resources:
        mem_mb=1000,
        runtime=10,
    log:
        "results/logs/summarise_funnel/funnel.log",
    benchmark:
        "results/benchmarks/summarise_funnel/funnel.tsv"
    script:
        "../scripts/summarise_funnel.py"


rule report:
    input:
        # every other rule's benchmark files (graspstab.report.inputs), evaluated only when the
        # report is needed, so that targeting one stage does not need the studies' assignments
        unpack(
            lambda wc: benchmark_inputs(
                [
                    (r.name, strip_wildcard_constraints(str(r.benchmark)))
                    for r in workflow.rules
                    if r.benchmark is not None
                ],
                benchmark_wildcards(config, object_ids(), len(assignments()), MODELS),
            )
        ),
        objects_figure="results/figures/objects.png",
        hand_candidates="results/figures/hand_candidates.png",
        hand_capsules="results/figures/hand_capsules.png",
        hand_json="results/hand/hand.json",
        meta=object_outputs("meta.json"),
        grasp_summaries=grasp_outputs("summary.json"),
        replay_outcomes=rules.summarise_replays.output[0],
        funnel=rules.summarise_funnel.output[0],
        replay_trace=rules.plot_replay.output[0],
        dataset_summary=rules.label_windows.output.summary,
        window_figure=rules.plot_window.output[0],
        speeds_summary=rules.plot_unstable_speeds.output.summary,
        speeds_figure=rules.plot_unstable_speeds.output.figure,
        sweep_summaries=expand("results/datasets/sweep/w{ms}ms/summary.json", ms=sweep_ms()),
        pregrasp=rules.plot_grasps.output.pregrasp,
        gallery=rules.plot_grasps.output.gallery,
        histograms=rules.plot_grasps.output.histograms,
        # the studies' artefacts (graspstab.figures.artefacts), named study_<artefact>
        **{f"study_{k}": v for k, v in STUDY_ARTEFACTS.items()},
        learning_figures=rules.plot_learning.output,
        # the streaming monitor's grasp-level summary, figures and exports, named monitor_<artefact>
        **{f"monitor_{k}": v for k, v in MONITOR_ARTEFACTS.items()},
        # the creep-free benchmark's artefacts when it is enabled, named creep_free_<artefact>
        **{f"creep_free_{k}": v for k, v in CREEP_FREE_ARTEFACTS.items()},
        # the sensor-robustness study's artefacts when it runs, named sensing_<artefact>
        **{f"sensing_{k}": v for k, v in SENSING_ARTEFACTS.items()},
        # the input audit's table when it runs, named audit_<artefact>
        **{f"audit_{k}": v for k, v in AUDIT_ARTEFACTS.items()},
        # the k-fold study's artefacts when it runs, named crossval_<protocol>_<artefact>
        **{f"crossval_{k}": v for k, v in CROSSVAL_ARTEFACTS.items()},
        # each protocol's failure anatomy, named anatomy_<protocol>_<artefact>
        **{f"anatomy_{k}": v for k, v in ANATOMY_ARTEFACTS.items()},
        # the closed loop's summaries when it runs, named closed_loop_<protocol>_<artefact>
        **{f"closed_loop_{k}": v for k, v in CLOSED_LOOP_ARTEFACTS.items()},
        rulegraph=rules.rulegraph.output.rules,
        jobgraph=rules.rulegraph.output.jobs,
    output:
        "results/report.html",
    params:
        config=config,
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
