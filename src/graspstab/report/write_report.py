"""Write ``results/report.html``: one self-contained page covering what the pipeline has built.

Assembly only: this module reads the inputs the rule hands over, orders the sections and writes the
page. Each section is rendered by its own module (objects_hand, synthesis, replay, anatomy,
datasets, pipeline, learning, monitor, sensing, crossval, closed_loop, protocols,
provenance_section), and every number it shows is read from a summary a job wrote
(docs/report.md); the only arithmetic on measurements is over Snakemake's benchmark files, which
are timings, not data.
"""

from __future__ import annotations

import logging
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

from graspstab.common.io import read_json, write_text
from graspstab.figures.artefacts import StudyArtefacts
from graspstab.report import dag
from graspstab.report import html as H
from graspstab.report.anatomy import anatomy_parts
from graspstab.report.closed_loop import closed_loop_section
from graspstab.report.crossval import crossval_section
from graspstab.report.datasets import dataset_parts
from graspstab.report.funnel import funnel_total, read_funnel
from graspstab.report.headline import headline_section, run_scale
from graspstab.report.learning import learning_section
from graspstab.report.monitor import monitor_section
from graspstab.report.objects_hand import hand_parts, objects_parts
from graspstab.report.pipeline import pipeline_parts
from graspstab.report.protocols import protocols_parts
from graspstab.report.provenance import read_benchmark
from graspstab.report.provenance_section import provenance_parts
from graspstab.report.replay import contact_parts, replay_parts
from graspstab.report.sensing import audit_section, sensing_section
from graspstab.report.synthesis import synthesis_parts

log = logging.getLogger(__name__)

# Every id a reader (or a link) may rely on, in the reference's order (tested to be present).
SECTION_IDS = (
    "contents", "headline", "pipeline", "objects", "hand", "hand-candidates", "hand-capsules",
    "synthesis", "pregrasp", "grasp-gallery", "replay", "replay-trace", "contact-model",
    "unstable-speeds", "anatomy", "anatomy-figure", "datasets", "window",
    "dataset-counts", "learning", "tuning", "baseline-configurations", "metrics", "confusion",
    "per-object", "split-robustness", "sweep", "latency", "operating-points", "errors",
    "threshold-transfer", "reliability", "proxy", "monitor", "monitor-leads", "monitor-timeline",
    "protocols", "provenance", "stage-times",
    "funnel", "configuration",
)  # fmt: skip


def write_report(
    out_html: Path,
    config: dict[str, Any],
    figures: dict[str, Path],
    object_meta: list[Path],
    hand_json: Path,
    benchmark_files: list[Path],
    grasp_summaries: list[Path] | None = None,
    anneal_benchmarks: list[Path] | None = None,
    replay_outcomes: Path | None = None,
    funnel: Path | None = None,
    dataset_summary: Path | None = None,
    sweep_summaries: list[Path] | None = None,
    learning: StudyArtefacts | None = None,
    learning_figures: Mapping[str, Path] | None = None,
    rule_benchmarks: Mapping[str, Sequence[Path]] | None = None,
    rulegraph: Path | None = None,
    jobgraph: Path | None = None,
    speeds_summary: Path | None = None,
    creep_free: Mapping[str, Any] | None = None,
    monitor: Mapping[str, Any] | None = None,
    sensing: Mapping[str, Any] | None = None,
    audit: Mapping[str, Any] | None = None,
    crossval: Mapping[str, Any] | None = None,
    closed_loop: Mapping[str, Any] | None = None,
    anatomy: Mapping[str, Path] | None = None,
) -> None:
    """Assemble the report from the artefacts the workflow produced, reading only the paths it
    is given (the learning section and headline from ``learning``, the studies' artefacts, and
    ``learning_figures``, when given). ``benchmark_files`` are the
    preprocessing benchmarks, ``rule_benchmarks`` every rule's (rule -> files), ``rulegraph``
    and ``jobgraph`` Snakemake's ``--rulegraph`` and ``--dag`` dot files. ``replay_outcomes``:
    the main run's replay outcome table (rule ``summarise_replays``); ``funnel``: the grasp
    funnel (rule ``summarise_funnel``). ``creep_free``: the
    creep-free benchmark's artefacts (rule report's ``creep_free_*`` inputs, prefix stripped),
    set beside the main run's in the section "Two protocols side by side". ``monitor``: the
    streaming monitor's artefacts (``monitor_*`` inputs, prefix stripped), the section
    "Grasp-level warnings". ``sensing``: the sensor-robustness study's artefacts (``sensing_*``
    inputs), the section "Sensor realism"; ``audit``: the input audit's (``audit_*``);
    ``crossval``: the k-fold study's (``crossval_<protocol>_*``), the section "Generalisation
    across objects"; ``closed_loop``: the closed loop's summaries (``closed_loop_<protocol>_*``),
    the section "Closed loop"; ``anatomy``: the failure anatomy's summaries and figures
    (``anatomy_<protocol>_*``), the section "Failure anatomy"."""
    metas = [read_json(p) for p in object_meta]
    bench = {Path(p).stem: read_benchmark(p) for p in benchmark_files}
    hand = read_json(hand_json)
    dataset = read_json(dataset_summary) if dataset_summary is not None else None
    funnel_rows = read_funnel(funnel) if funnel is not None else None
    graph = counts = None
    if rulegraph is not None and jobgraph is not None:
        graph, counts = dag.read_graph(rulegraph, jobgraph)
    dpi = int(config.get("report", {}).get("figure_dpi", 110))
    scale = run_scale(config, len(metas), funnel_total(funnel_rows), dataset)
    ramp_monitor = creep_free if creep_free and "monitor_summary" in creep_free else None
    sections = [
        H.heading(2, "headline", "Headline: this run and the reference"),
        headline_section(scale, learning),
        *pipeline_parts(graph, counts, dpi),
        *objects_parts(config, metas, bench, figures["objects"]),
        *hand_parts(hand, figures["hand_candidates"], figures["hand_capsules"]),
        *synthesis_parts(figures, grasp_summaries, anneal_benchmarks),
        *replay_parts(replay_outcomes, figures, (rule_benchmarks or {}).get("replay_grasps", ())),
        *(contact_parts(speeds_summary, figures, config["replay"]) if replay_outcomes else []),
        *anatomy_parts(anatomy),
        *dataset_parts(dataset_summary, sweep_summaries, figures),
        *([learning_section(learning, learning_figures or {}, config)] if learning else []),
        monitor_section(monitor, ramp_monitor),
        sensing_section(sensing, config),
        audit_section(audit),
        crossval_section(crossval, config, anatomy),
        closed_loop_section(closed_loop, config),
        *protocols_parts(config, creep_free, dataset_summary, speeds_summary, replay_outcomes,
                         learning, figures),  # fmt: skip
        *provenance_parts(
            config,
            rule_benchmarks or {"preprocess_object": benchmark_files},
            graph,
            counts,
            funnel_rows,
        ),
    ]
    write_text(out_html, H.page(config["report"]["title"], sections, contents=True))
    log.info("wrote %s (%d objects)", out_html, len(metas))
