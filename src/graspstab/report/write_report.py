"""Write ``results/report.html``: one self-contained page covering what the pipeline has built."""

from __future__ import annotations

import json
import logging
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import networkx as nx
import polars as pl

import graspstab
from graspstab.common.io import read_json, read_parquet, write_text
from graspstab.common.provenance import stable_hash
from graspstab.figures.artefacts import StudyArtefacts
from graspstab.figures.presentation import UNDEFINED, finite
from graspstab.report import dag
from graspstab.report import html as H
from graspstab.report.closed_loop import closed_loop_section
from graspstab.report.creep_free import Benchmark, creep_free_section
from graspstab.report.crossval import crossval_section
from graspstab.report.funnel import funnel, funnel_table
from graspstab.report.headline import headline_section, run_scale
from graspstab.report.learning import learning_section
from graspstab.report.monitor import monitor_section
from graspstab.report.provenance import (
    git_commit,
    package_versions,
    read_benchmark,
    stage_times,
)
from graspstab.report.sensing import audit_section, sensing_section

log = logging.getLogger(__name__)
REPO_DIR = Path(graspstab.__file__).resolve().parents[2]

# Every id a reader (or a link) may rely on, in the reference's order (tested to be present).
SECTION_IDS = (
    "contents", "headline", "pipeline", "objects", "hand", "hand-candidates", "hand-capsules",
    "synthesis", "pregrasp", "grasp-gallery", "replay", "replay-trace", "contact-model",
    "unstable-speeds", "datasets", "window",
    "dataset-counts", "learning", "tuning", "baseline-configurations", "metrics", "confusion",
    "per-object", "split-robustness", "sweep", "latency", "operating-points", "errors",
    "threshold-transfer", "reliability", "proxy", "monitor", "monitor-leads", "monitor-timeline",
    "protocols", "provenance", "stage-times",
    "funnel", "configuration",
)  # fmt: skip


def _fmt(value: Any, spec: str = ".1f", scale: float = 1.0) -> str:
    """A number formatted by ``spec`` (times ``scale``), or "undefined" for None/NaN (strict
    JSON stores an undefined value as null)."""
    return format(float(value) * scale, spec) if finite(value) else UNDEFINED


def _objects_section(config: dict[str, Any], metas: list[dict], bench: dict[str, dict]) -> str:
    rows = []
    for m in metas:
        oid = m["object_id"]
        entry = config["objects"]["items"][oid]
        rows.append(
            [
                oid,
                entry["split"],
                f"{m['mass']:.4f}",
                f"{m['volume'] * 1e6:.1f}",
                " x ".join(f"{e * 100:.1f}" for e in m["extents"]),
                m["watertight_before"],
                m["watertight_after"],
                m["convex_parts"],
                f"{bench[oid]['s']:.1f}" if oid in bench else "n/a",
            ]
        )
    return H.table(
        [
            "object",
            "split",
            "mass [kg]",
            "volume [cm3]",
            "extents [cm]",
            "watertight (raw)",
            "watertight (repaired)",
            "convex parts",
            "preprocess wall time [s]",
        ],
        rows,
        caption="Preprocessed objects (thesis 3.1.1, split of 4.1.1)",
    )


def _hand_section(hand: dict[str, Any]) -> str:
    rows = [
        [name, f"{lo:.4f}", f"{hi:.4f}"]
        for name, lo, hi in zip(
            hand["joint_names"], hand["joint_lower"], hand["joint_upper"], strict=True
        )
    ]
    tips = ", ".join(f"{f}: {b}" for f, b in hand["fingertips"].items())
    return (
        f"<p>{len(rows)} actuated finger joints plus a free wrist pose (joint "
        f"<code>{H.esc(hand['wrist_joint'])}</code>); fingertips: {H.esc(tips)}.</p>"
        + H.table(
            ["joint", "lower [rad]", "upper [rad]"],
            rows,
            caption="Finger joint limits, from the ORCA v2 description files",
        )
    )


def _synthesis_section(summaries: list[dict], anneal_bench: dict[str, dict]) -> str:
    rows = []
    for s in summaries:
        oid = s["object_id"]
        wall = sum(b["s"] for k, b in anneal_bench.items() if k.startswith(f"{oid}_shard_"))
        rows.append(
            [
                oid,
                s["grasps"],
                _fmt(s["energy_start"]["q50"]),
                _fmt(s["energy"]["q50"]),
                _fmt(s["energy_fell_fraction"], ".2f"),
                _fmt(s["terms"]["dis"]["q50"], ".1f", 1000 / 120),
                _fmt(s["tip_abs_dist"]["q50"], ".1f", 1000),
                _fmt(s["tips_within_5mm_mean"]),
                f"{_fmt(s['min_candidate_dist']['q50'], '.1f', 1000)} / "
                f"{_fmt(s['min_candidate_dist']['q05'], '.1f', 1000)}",
                f"{_fmt(s['max_hand_depth']['q50'], '.1f', 1000)} / "
                f"{_fmt(s['max_hand_depth']['q95'], '.1f', 1000)}",
                _fmt(s["terms"]["pen"]["q50"], ".3f"),
                _fmt(s["acceptance_rate"]["q50"], ".2f"),
                f"{wall:.0f}" if wall else "n/a",
            ]
        )
    return H.table(
        [
            "object",
            "grasps",
            "median E start",
            "median E best",
            "fraction E fell",
            "median mean |d| [mm]",
            "median fingertip gap [mm]",
            "fingertips within 5 mm (mean of 5)",
            "deepest candidate, median / 5th pct [mm]",
            "deepest hand point, median / 95th pct [mm]",
            "median E_pen",
            "median acceptance",
            "anneal wall time [s]",
        ],
        rows,
        caption=(
            "Synthesised grasps (3.1.3-3.1.4): energy of eq. 4 (with our w_fc and E_hpen) at the "
            "pre-grasp and at the best annealing state; fingertip gap = |signed distance| of the "
            "distal-region candidate nearest the surface; deepest candidate = most negative "
            "candidate signed distance; deepest hand point = depth of the deepest point covering "
            "the hand's collision hulls inside the object (true mesh)"
        ),
    )


def _synthesis_parts(
    figures: dict[str, Path],
    grasp_summaries: list[Path] | None,
    anneal_benchmarks: list[Path] | None,
) -> list[str]:
    """The grasp-synthesis section, when the run got that far."""
    if not grasp_summaries:
        return []
    bench = {Path(p).stem: read_benchmark(p) for p in anneal_benchmarks or []}
    parts = [
        H.heading(2, "synthesis", "Grasp synthesis"),
        _synthesis_section([read_json(p) for p in grasp_summaries], bench),
        '<p class="note">Two deliberate deviations from eq. 16 (docs/protocols.md, '
        '"Annealing energies"): with '
        "the reference's energy the annealed grasps straddle the surface, fingertips within a "
        "millimetre of it while finger links sink in by centimetres, because E_fc over all 120 "
        "candidate normals rewards pushing candidates through the object and eq. 11 cannot see "
        "a link wholly inside it. We weight E_fc by 0.01 instead of 1 and add E_hpen (hand "
        "surface points inside the object, weight 10,000).</p>",
    ]
    captions = {
        "pregrasp": ("Pre-grasp (fig. 3.4)", "A structured pre-grasp: inflated hull, anchor, "
                     "nearest surface point, approach direction and the open hand (cf. thesis "
                     "fig. 3.4)."),
        "grasp_gallery": ("Grasp gallery (fig. 3.6)", "Lowest-energy synthesised grasps on "
                          "several objects (cf. fig. 3.6)."),
        "energy_histograms": ("", "Energy of eq. 4 per object, at the pre-grasp and after "
                              "annealing."),
    }  # fmt: skip
    for key, (toc, caption) in captions.items():
        anchor = key.replace("_", "-")
        parts.append(
            H.image(figures[key], key.replace("_", " "), caption, anchor, toc)
            if key in figures
            else H.missing_figure(anchor, toc, f"Figure '{key}' not produced in this run.")
        )
    return parts


def _replay_parts(
    replay_summaries: list[Path] | None,
    figures: dict[str, Path],
    replay_benchmarks: Sequence[Path] = (),
) -> list[str]:
    """Replay outcomes per object (3.2), when the run got that far; the wall time is the replay
    jobs' (``replay_benchmarks``, Snakemake's benchmark files), not data: the tables hold none."""
    if not replay_summaries:
        return []
    table = pl.concat([read_parquet(p) for p in replay_summaries])
    bench = {Path(p).stem: read_benchmark(p) for p in replay_benchmarks if Path(p).exists()}
    rows = []
    for (oid,), g in sorted(table.group_by("object"), key=lambda kv: kv[0][0]):
        wall = [b["s"] for k, b in bench.items() if k.startswith(f"{oid}_shard_")]
        rows.append(
            [
                oid,
                g.height,
                int(g["held_at_end"].sum()),
                int((g["stop_reason"] == "contact_lost").sum()),
                int((g["stop_reason"] == "too_deep").sum()),
                int(g["diverged"].sum()),
                _fmt(g["max_penetration"].median(), ".1f", 1000),
                f"{g['duration_s'].sum():.0f}",
                f"{sum(wall):.0f}" if wall else "n/a",
            ]
        )
    return [
        H.heading(2, "replay", "Grasp replay"),
        H.table(
            [
                "object",
                "replays",
                "held to the end",
                "contact lost (stopped early)",
                "too deep (stopped early)",
                "diverged",
                "median deepest contact [mm]",
                "simulated [s]",
                "wall [s]",
            ],
            rows,
            caption="Replays under gravity (3.2), per object",
        ),  # fmt: skip
        H.image(
            figures["replay_trace"],
            "replay trace",
            "One replay: object motion, d_t and fingertip forces (cf. thesis fig. 3.7).",
            "replay-trace",
            "Replay trace (fig. 3.7)",
        )
        if "replay_trace" in figures
        else H.missing_figure("replay-trace", "Replay trace (fig. 3.7)", "Not produced."),
    ]


def _contact_parts(
    speeds: Path | None, figures: dict[str, Path], replay: dict[str, Any]
) -> list[str]:
    """The contact model in use, its creep, and the speeds behind the labels (3.2, 3.3.2)."""
    c, sq = replay["contact"], replay["squeeze"]
    rows = [
        ["contact model", c["name"]],
        ["friction cone", c["cone"]],
        ["impratio", f"{c['impratio']:g}"],
        ["noslip iterations", c["noslip_iterations"]],
        ["servo kp [N m/rad] / kv / force range [N m]",
         f"{c['actuator']['kp']:g} / {c['actuator']['kv']:g} / ±{c['actuator']['forcerange']:g}"],
        ["squeeze [rad]", f"{sq['angle']:g}" + (" (3.2 holds the grasp's own angles)"
                                                  if sq["angle"] == 0 else
                                                  " (our deviation: 3.2 holds the grasp's own "
                                                  "angles)")],
    ]  # fmt: skip
    parts = [H.heading(3, "contact-model", 'Contact model and what "unstable" means')]
    if speeds is not None:
        s = read_json(speeds)

        def mm(v: Any) -> str:
            return "undefined (none)" if v is None else f"{v * 1e3:.3g}"

        held, tgt = s["held_creep"], s["target_speed"]
        rows += [
            [f"creep of a 0.2 kg box held with {s['box_creep']['squeeze_n']:g} N per side [mm/s]",
             mm(s["box_creep"]["speed"])],
            [f"creep of this run's grasps held at the end, median of {held['grasps']} [mm/s]",
             mm(held["q50"])],
            ["instability threshold v_slip (eq. 23) [mm/s]", mm(s["v_slip"])],
            [f"unstable windows ({tgt['unstable']['n']}): target-interval speed q10 / q50 / q90 "
             "[mm/s]", " / ".join(mm(tgt["unstable"][q]) for q in ("q10", "q50", "q90"))],
            [f"stable windows ({tgt['stable']['n']}): target-interval speed q10 / q50 / q90 "
             "[mm/s]", " / ".join(mm(tgt["stable"][q]) for q in ("q10", "q50", "q90"))],
        ]  # fmt: skip
    parts.append(H.table(["", "value"], rows, cls="text", caption=(
        "The replay's contact model (config group contact: reference = MuJoCo's defaults with "
        "the hand description's servos; strict = elliptic cones, impratio 10, 10 noslip "
        "iterations, kp 20). Under reference a held object creeps at the order of v_slip, so "
        "part of what is labelled unstable is soft-contact creep; python "
        "benchmarks/replay_creep.py measures both models.")))  # fmt: skip
    parts.append(
        H.image(figures["unstable_speeds"], "speeds behind the labels", (
            "Median object speed over each labelled window's target interval, by label, with "
            "v_slip and the contact model's creep."), "unstable-speeds",
            "Speeds behind the labels")
        if "unstable_speeds" in figures
        else H.missing_figure("unstable-speeds", "Speeds behind the labels", "Not produced.")
    )  # fmt: skip
    return parts


def _dataset_parts(
    baseline: Path | None, sweep: list[Path] | None, figures: dict[str, Path]
) -> list[str]:
    """Window counts per split and class (cf. 4.1.1), per object, and per sweep window."""
    if baseline is None:
        return []
    base = read_json(baseline)
    head = ["", *[f"{s} {c}" for s in ("train", "val", "test") for c in ("stable", "unstable")]]

    def row(name: str, counts: dict) -> list:
        return [name, *[counts[s][c] for s in ("train", "val", "test")
                        for c in ("stable", "unstable")]]  # fmt: skip

    rows = [row("all objects", base["splits"])]
    rows += [row(o, c) for o, c in base["objects"].items()]
    window = (
        H.image(figures["window"], "window illustration", (
            "One sample's observation window, offset and horizon (dashed) on its replay's "
            "fingertip forces, with stable (green) and unstable (red) periods (cf. fig. 3.8)."),
            "window", "Window (fig. 3.8)")
        if "window" in figures
        else H.missing_figure("window", "Window (fig. 3.8)", "Not produced in this run.")
    )  # fmt: skip
    parts = [
        H.heading(2, "datasets", "Window datasets"),
        window,
        H.heading(3, "dataset-counts", "Dataset counts (section 4.1.1)"),
        H.table(head, rows, caption=(
            f"Baseline dataset ({base['window_s']:g} s windows, 3.3): labelled windows per split "
            "and class (cf. section 4.1.1)")),
    ]  # fmt: skip
    if sweep:
        sums = sorted((read_json(p) for p in sweep), key=lambda d: d["window_s"])
        parts.append(H.table(
            ["window [s]", "windows", "train unstable", "val unstable", "test unstable"],
            [[f"{d['window_s']:g}", d["windows"],
              *[d["splits"][s]["unstable"] for s in ("train", "val", "test")]] for d in sums],
            caption="Sweep datasets, trimmed from the longest window (same end, label, split)",
        ))  # fmt: skip
    return parts


def _pipeline_parts(
    graph: nx.DiGraph | None, counts: Mapping[str, int] | None, dpi: int
) -> list[str]:
    """The DAG overview: Snakemake's rule graph drawn with each rule's job count."""
    head = H.heading(2, "pipeline", "Pipeline and DAG overview")
    if graph is None or counts is None:
        return [head, '<p class="note">No rule graph given to the report.</p>']
    return [
        head,
        f"<p>{H.esc(dag.overview_text(graph, counts))}</p>",
        H.image(
            dag.draw_rule_graph(graph, counts, dpi),
            "rule graph",
            "Rule graph of this run (snakemake --rulegraph), top to bottom, with each rule's job "
            "count (snakemake --dag); orange: rules that fan out into several jobs. Edges implied "
            "by a longer path are omitted.",
            "rule-graph",
        ),
    ]


def _stage_table(rows: Sequence[Mapping[str, Any]], own_rule: str = "report") -> str:
    """Per-rule wall times and peak memory from the benchmark files (``own_rule``, the rule
    writing this report, cannot have its benchmark yet)."""
    total = sum(r["job_s"] or 0.0 for r in rows)
    body = []
    for r in rows:
        unbenchmarked = (
            "runs now: benchmark after this report"
            if r["rule"] == own_rule
            else ("no benchmark file")
        )
        jobs = str(r["jobs"])
        if r["dag_jobs"] is not None and r["dag_jobs"] != r["jobs"]:
            jobs += f" (DAG: {r['dag_jobs']})"
        if r["missing"]:
            jobs += f" ({r['missing']} benchmark files missing)"
        bench = r["job_s"] is not None
        body.append([
            r["rule"], jobs,
            f"{r['job_s']:.1f}" if bench else unbenchmarked,
            _fmt(r["share"], ".1%") if bench else "—",
            f"{r['max_s']:.1f} ({r['max_job']})" if r["max_s"] is not None else "—",
            _fmt(r["peak_rss_mb"], ".0f") if bench else "—",
        ])  # fmt: skip
    jobs, dag_jobs = sum(r["jobs"] for r in rows), sum(r["dag_jobs"] or 0 for r in rows)
    all_jobs = f"{jobs} (DAG: {dag_jobs})" if dag_jobs and dag_jobs != jobs else str(jobs)
    body.append(["all rules", all_jobs, f"{total:.1f}", "100%", "", ""])
    return H.table(
        ["rule", "jobs", "total job-seconds", "share", "longest job [s]", "peak RSS [MB]"],
        body,
        caption="Per-stage wall time from every rule's Snakemake benchmark files: job-seconds sum "
        "the jobs' wall times (with several cores the run's elapsed time is shorter); peak RSS is "
        "the largest over the rule's jobs; 'DAG' is the job count in this run's DAG when it "
        "differs from the benchmarked jobs",
    )


def _provenance_parts(
    config: Mapping[str, Any],
    benchmarks: Mapping[str, Sequence[Path]],
    graph: nx.DiGraph | None,
    counts: Mapping[str, int] | None,
    funnel_rows: Sequence[Mapping[str, Any]],
) -> list[str]:
    """Config hash, commit, versions, stage times, the grasp funnel and the resolved config."""
    order = list(nx.topological_sort(graph)) if graph is not None else None
    return [
        H.heading(2, "provenance", "Provenance"),
        H.table(
            ["item", "value"],
            [
                ["config hash", stable_hash(dict(config))],
                ["git commit", git_commit(REPO_DIR)],
                *[[f"package {k}", v] for k, v in package_versions().items()],
            ],
            caption="Run provenance",
        ),
        H.heading(3, "stage-times", "Stage wall times and memory"),
        _stage_table(stage_times(benchmarks, counts, order))
        if benchmarks or counts
        else '<p class="note">No benchmark files given to the report.</p>',
        H.heading(3, "funnel", "Grasp funnel"),
        funnel_table(funnel_rows),
        H.heading(3, "configuration", "Resolved configuration"),
        "<details><summary>Resolved configuration (JSON)</summary><pre>"
        + H.esc(json.dumps(config, indent=2, sort_keys=True))
        + "</pre></details>",
    ]


def _protocols_parts(
    config: dict[str, Any], creep_free: Mapping[str, Any] | None, dataset: Path | None,
    speeds: Path | None, replays: list[Path] | None, learning: StudyArtefacts | None,
    figures: dict[str, Path],
) -> list[str]:  # fmt: skip
    """The two protocols side by side, when the run has the creep-free benchmark; else a note on
    how to turn it on."""
    if not creep_free or dataset is None or speeds is None or learning is None:
        return [
            H.heading(2, "protocols", "Two protocols side by side: gravity and the load ramp"),
            '<p class="note">This run has no creep-free benchmark (creep_free.enabled is false). '
            "<code>--config 'creep_free={enabled: true}'</code> replays the same grasps under the "
            "strict contact model with a rising load and sets the two side by side here "
            '(docs/protocols.md, "The creep-free load ramp").</p>',
        ]
    main = Benchmark(
        name=f"gravity ({config['replay']['contact']['name']} contact model)",
        dataset=dataset, speeds=speeds, replays=replays or [], studies=learning,
        speeds_figure=figures.get("unstable_speeds"),
        sweep_windows_s=[float(w) for w in config["sweep"]["windows_s"]],
    )  # fmt: skip
    cf = config["creep_free"]
    ramp = Benchmark(
        name=f"load ramp ({cf['contact']['name']} contact model)",
        dataset=Path(creep_free["dataset"]), speeds=Path(creep_free["speeds"]),
        replays=[Path(p) for p in creep_free["replays"]],
        studies=StudyArtefacts.from_inputs(creep_free, prefix="study_"),
        speeds_figure=Path(creep_free["speeds_figure"]),
        sweep_windows_s=[float(w) for w in cf["sweep_windows_s"]],
    )  # fmt: skip
    return [creep_free_section(main, ramp, config["replay"]["ramp"])]


def write_report(
    out_html: Path,
    config: dict[str, Any],
    figures: dict[str, Path],
    object_meta: list[Path],
    hand_json: Path,
    benchmark_files: list[Path],
    grasp_summaries: list[Path] | None = None,
    anneal_benchmarks: list[Path] | None = None,
    replay_summaries: list[Path] | None = None,
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
) -> None:
    """Assemble the report from the artefacts the workflow produced, reading only the paths it
    is given (the learning section and headline from ``learning``, the studies' artefacts, and
    ``learning_figures``, when given). ``benchmark_files`` are the
    preprocessing benchmarks, ``rule_benchmarks`` every rule's (rule -> files), ``rulegraph``
    and ``jobgraph`` Snakemake's ``--rulegraph`` and ``--dag`` dot files. ``creep_free``: the
    creep-free benchmark's artefacts (rule report's ``creep_free_*`` inputs, prefix stripped),
    set beside the main run's in the section "Two protocols side by side". ``monitor``: the
    streaming monitor's artefacts (``monitor_*`` inputs, prefix stripped), the section
    "Grasp-level warnings". ``sensing``: the sensor-robustness study's artefacts (``sensing_*``
    inputs), the section "Sensor realism"; ``audit``: the input audit's (``audit_*``);
    ``crossval``: the k-fold study's (``crossval_<protocol>_*``), the section "Generalisation
    across objects"; ``closed_loop``: the closed loop's summaries (``closed_loop_<protocol>_*``),
    the section "Closed loop"."""
    metas = [read_json(p) for p in object_meta]
    bench = {Path(p).stem: read_benchmark(p) for p in benchmark_files}
    hand = read_json(hand_json)
    summaries = [read_json(p) for p in grasp_summaries or []]
    dataset = read_json(dataset_summary) if dataset_summary is not None else None
    graph = counts = None
    if rulegraph is not None and jobgraph is not None:
        graph, counts = dag.read_graph(rulegraph, jobgraph)
    dpi = int(config.get("report", {}).get("figure_dpi", 110))
    sections = [
        H.heading(2, "headline", "Headline: this run and the reference"),
        headline_section(run_scale(config, len(metas), summaries, dataset), learning),
        *_pipeline_parts(graph, counts, dpi),
        H.heading(2, "objects", "Objects"),
        _objects_section(config, metas, bench),
        H.image(
            figures["objects"],
            "preprocessed objects",
            "Preprocessed objects with their CoACD convex parts (cf. thesis fig. 3.1).",
            "objects-figure",
        ),
        H.heading(2, "hand", "Hand and contact candidates"),
        _hand_section(hand),
        H.image(
            figures["hand_candidates"],
            "hand with contact candidates",
            "ORCA hand with its 120 contact candidates (cf. thesis fig. 3.3).",
            "hand-candidates",
            "Contact candidates (fig. 3.3)",
        ),
        H.image(
            figures["hand_capsules"],
            "capsule approximation",
            "Capsule and box approximation used by the penetration energies (cf. fig. 3.5a).",
            "hand-capsules",
            "Capsule approximation (fig. 3.5a)",
        ),
        *_synthesis_parts(figures, grasp_summaries, anneal_benchmarks),
        *_replay_parts(replay_summaries, figures, (rule_benchmarks or {}).get("replay_grasps", ())),
        *(_contact_parts(speeds_summary, figures, config["replay"]) if replay_summaries else []),
        *_dataset_parts(dataset_summary, sweep_summaries, figures),
        *([learning_section(learning, learning_figures or {}, config)] if learning else []),
        monitor_section(monitor, creep_free if creep_free and "monitor_summary" in creep_free
                        else None),  # fmt: skip
        sensing_section(sensing, config),
        audit_section(audit),
        crossval_section(crossval, config),
        closed_loop_section(closed_loop, config),
        *_protocols_parts(config, creep_free, dataset_summary, speeds_summary, replay_summaries,
                          learning, figures),  # fmt: skip
        *_provenance_parts(
            config,
            rule_benchmarks or {"preprocess_object": benchmark_files},
            graph,
            counts,
            funnel(summaries, replay_summaries or [], dataset),
        ),
    ]
    write_text(out_html, H.page(config["report"]["title"], sections, contents=True))
    log.info("wrote %s (%d objects)", out_html, len(metas))
