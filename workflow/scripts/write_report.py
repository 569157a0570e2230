"""Snakemake wrapper: write the self-contained HTML report (graspstab.report)."""

from pathlib import Path

from graspstab.common.jobs import job
from graspstab.common.logs import setup_logging
from graspstab.figures.artefacts import StudyArtefacts
from graspstab.report.write_report import write_report

sm = snakemake  # noqa: F821  (injected by Snakemake)
setup_logging(sm.log[0])
PREFIX = "benchmark_"
CREEP_FREE = "creep_free_"
MONITOR = "monitor_"
SENSING = "sensing_"
AUDIT = "audit_"
CROSSVAL = "crossval_"
CLOSED_LOOP = "closed_loop_"
ANATOMY = "anatomy_"
benchmarks = {
    name.removeprefix(PREFIX): [Path(p) for p in ([files] if isinstance(files, str) else files)]
    for name, files in sm.input.items()
    if name.startswith(PREFIX)
}


def prefixed(prefix: str) -> dict:
    """The rule's named inputs that start with ``prefix``, the prefix stripped."""
    return {n.removeprefix(prefix): f for n, f in sm.input.items() if n.startswith(prefix)}


with job(sm):
    write_report(
        out_html=Path(sm.output[0]),
        config=dict(sm.params.config),
        figures={
            "objects": Path(sm.input.objects_figure),
            "hand_candidates": Path(sm.input.hand_candidates),
            "hand_capsules": Path(sm.input.hand_capsules),
            "pregrasp": Path(sm.input.pregrasp),
            "grasp_gallery": Path(sm.input.gallery),
            "energy_histograms": Path(sm.input.histograms),
            "replay_trace": Path(sm.input.replay_trace),
            "window": Path(sm.input.window_figure),
            "unstable_speeds": Path(sm.input.speeds_figure),
        },
        object_meta=[Path(p) for p in sm.input.meta],
        hand_json=Path(sm.input.hand_json),
        benchmark_files=benchmarks.get("preprocess_object", []),
        grasp_summaries=[Path(p) for p in sm.input.grasp_summaries],
        anneal_benchmarks=benchmarks.get("anneal_grasps", []),
        replay_outcomes=Path(sm.input.replay_outcomes),
        funnel=Path(sm.input.funnel),
        dataset_summary=Path(sm.input.dataset_summary),
        sweep_summaries=[Path(p) for p in sm.input.sweep_summaries],
        learning=StudyArtefacts.from_inputs(dict(sm.input.items()), prefix="study_"),
        learning_figures={Path(p).stem: Path(p) for p in sm.input.learning_figures},
        rule_benchmarks=benchmarks,
        rulegraph=Path(sm.input.rulegraph),
        jobgraph=Path(sm.input.jobgraph),
        speeds_summary=Path(sm.input.speeds_summary),
        creep_free=prefixed(CREEP_FREE),
        monitor=prefixed(MONITOR),
        sensing=prefixed(SENSING),
        audit=prefixed(AUDIT),
        crossval=prefixed(CROSSVAL),
        closed_loop=prefixed(CLOSED_LOOP),
        anatomy={k: Path(v) for k, v in prefixed(ANATOMY).items()},
    )
