"""Write ``results/report.html``: one self-contained page covering what the pipeline has built."""

from __future__ import annotations

import json
import logging
from pathlib import Path
from typing import Any

import polars as pl

import graspstab
from graspstab.common.io import read_json, write_text
from graspstab.common.provenance import stable_hash
from graspstab.report import html as H
from graspstab.report.learning import learning_section
from graspstab.report.provenance import git_commit, package_versions, read_benchmark

log = logging.getLogger(__name__)
REPO_DIR = Path(graspstab.__file__).resolve().parents[2]


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
                f"{s['energy_start']['q50']:.1f}",
                f"{s['energy']['q50']:.1f}",
                f"{s['energy_fell_fraction']:.2f}",
                f"{s['terms']['dis']['q50'] * 1000 / 120:.1f}",
                f"{s['tip_abs_dist']['q50'] * 1000:.1f}",
                f"{s['tips_within_5mm_mean']:.1f}",
                f"{s['min_candidate_dist']['q50'] * 1000:.1f} / "
                f"{s['min_candidate_dist']['q05'] * 1000:.1f}",
                f"{s['max_hand_depth']['q50'] * 1000:.1f} / "
                f"{s['max_hand_depth']['q95'] * 1000:.1f}",
                f"{s['terms']['pen']['q50']:.3f}",
                f"{s['acceptance_rate']['q50']:.2f}",
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
        "<h2>Grasp synthesis</h2>",
        _synthesis_section([read_json(p) for p in grasp_summaries], bench),
        '<p class="note">Two deliberate deviations from eq. 16 (README, "Grasp synthesis"): with '
        "the reference's energy the annealed grasps straddle the surface, fingertips within a "
        "millimetre of it while finger links sink in by centimetres, because E_fc over all 120 "
        "candidate normals rewards pushing candidates through the object and eq. 11 cannot see "
        "a link wholly inside it. We weight E_fc by 0.01 instead of 1 and add E_hpen (hand "
        "surface points inside the object, weight 10,000).</p>",
    ]
    captions = {
        "pregrasp": "A structured pre-grasp: inflated hull, anchor, nearest surface point, "
        "approach direction and the open hand (cf. thesis fig. 3.4).",
        "grasp_gallery": "Lowest-energy synthesised grasps on several objects (cf. fig. 3.6).",
        "energy_histograms": "Energy of eq. 4 per object, at the pre-grasp and after annealing.",
    }
    for key, caption in captions.items():
        if key in figures:
            parts.append(H.image(figures[key], key.replace("_", " "), caption))
    return parts


def _replay_parts(replay_summaries: list[Path] | None, figures: dict[str, Path]) -> list[str]:
    """Replay outcomes per object (3.2), when the run got that far."""
    if not replay_summaries:
        return []
    table = pl.concat([pl.read_parquet(p) for p in replay_summaries])
    rows = []
    for (oid,), g in sorted(table.group_by("object"), key=lambda kv: kv[0][0]):
        rows.append(
            [
                oid,
                g.height,
                int(g["held_at_end"].sum()),
                int((g["stop_reason"] == "contact_lost").sum()),
                int(g["diverged"].sum()),
                f"{g['max_penetration'].median() * 1000:.1f}",
                f"{g['duration_s'].sum():.0f}",
                f"{g['wall_s'].sum():.0f}",
            ]
        )
    return [
        "<h2>Grasp replay</h2>",
        H.table(
            [
                "object", "replays", "held to the end", "contact lost (stopped early)",
                "diverged", "median deepest contact [mm]", "simulated [s]", "wall [s]",
            ],
            rows,
            caption=(
                "Replays under gravity (3.2). Solver settings and actuator gains are provisional "
                "(issue 4 in progress): these counts are not yet the dataset's."
            ),
        ),  # fmt: skip
        *(
            [
                H.image(
                    figures["replay_trace"],
                    "replay trace",
                    "One replay: object motion, d_t and fingertip forces (cf. thesis fig. 3.7; "
                    "the stable/unstable shading comes with the labelling stage).",
                )
            ]
            if "replay_trace" in figures
            else []
        ),
    ]


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
    parts = [
        "<h2>Window datasets</h2>",
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
    if "window" in figures:
        parts.append(H.image(figures["window"], "window illustration", (
            "One sample's observation window, offset and horizon (dashed) on its replay's "
            "fingertip forces, with stable (green) and unstable (red) periods (cf. fig. 3.8).")))
    return parts


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
    learning_results: Path | None = None,
    learning_figures: dict[str, Path] | None = None,
) -> None:
    """Assemble the report from the artefacts the workflow produced (the learning section from
    ``learning_results``, the results directory, when given)."""
    metas = [read_json(p) for p in object_meta]
    bench = {Path(p).stem: read_benchmark(p) for p in benchmark_files}
    hand = read_json(hand_json)
    cfg_hash = stable_hash(config)
    profile = config["profile_name"]
    sections = [
        f'<p class="note">Profile <b>{H.esc(profile)}</b>, {len(metas)} objects. This report '
        "covers every stage: objects, hand, grasp synthesis, replay, window datasets and the "
        "learning studies. A quick-profile run is a smoke test of the pipeline, not a "
        "reproduction of the reference's numbers.</p>",
        "<h2>Objects</h2>",
        _objects_section(config, metas, bench),
        H.image(
            figures["objects"],
            "preprocessed objects",
            "Preprocessed objects with their CoACD convex parts (cf. thesis fig. 3.1).",
        ),
        "<h2>Hand and contact candidates</h2>",
        _hand_section(hand),
        H.image(
            figures["hand_candidates"],
            "hand with contact candidates",
            "ORCA hand with its 120 contact candidates (cf. thesis fig. 3.3).",
        ),
        H.image(
            figures["hand_capsules"],
            "capsule approximation",
            "Capsule and box approximation used by the penetration energies (cf. fig. 3.5a).",
        ),
        *_synthesis_parts(figures, grasp_summaries, anneal_benchmarks),
        *_replay_parts(replay_summaries, figures),
        *_dataset_parts(dataset_summary, sweep_summaries, figures),
        *(
            [learning_section(learning_results, learning_figures or {}, config)]
            if learning_results is not None
            else []
        ),
        "<h2>Provenance</h2>",
        H.table(
            ["item", "value"],
            [
                ["config hash", cfg_hash],
                ["git commit", git_commit(REPO_DIR)],
                *[[f"package {k}", v] for k, v in package_versions().items()],
            ],
            caption="Run provenance",
        ),
        "<details><summary>Resolved configuration</summary><pre>"
        + H.esc(json.dumps(config, indent=2, sort_keys=True))
        + "</pre></details>",
    ]
    write_text(out_html, H.page(config["report"]["title"], sections))
    log.info("wrote %s (%d objects)", out_html, len(metas))
