"""The report's "Grasp synthesis" section: each object's grasp summary (rule
``summarise_grasps``) as one row, the deviations from eq. 16, and the synthesis figures."""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

from graspstab.common.io import read_json
from graspstab.report import html as H
from graspstab.report.provenance import read_benchmark

fmt = H.fmt


def synthesis_table(
    summaries: Sequence[Mapping[str, Any]], anneal_bench: Mapping[str, dict]
) -> str:
    """One row per object's grasp summary; the wall time sums the object's annealing jobs'
    benchmark files (``anneal_bench``: job -> record; timings, not data)."""
    rows = []
    for s in summaries:
        oid = s["object_id"]
        wall = sum(b["s"] for k, b in anneal_bench.items() if k.startswith(f"{oid}_shard_"))
        rows.append(
            [
                oid,
                s["grasps"],
                fmt(s["energy_start"]["q50"]),
                fmt(s["energy"]["q50"]),
                fmt(s["energy_fell_fraction"], ".2f"),
                fmt(s["terms"]["dis"]["q50"], ".1f", 1000 / 120),
                fmt(s["tip_abs_dist"]["q50"], ".1f", 1000),
                fmt(s["tips_within_5mm_mean"]),
                f"{fmt(s['min_candidate_dist']['q50'], '.1f', 1000)} / "
                f"{fmt(s['min_candidate_dist']['q05'], '.1f', 1000)}",
                f"{fmt(s['max_hand_depth']['q50'], '.1f', 1000)} / "
                f"{fmt(s['max_hand_depth']['q95'], '.1f', 1000)}",
                fmt(s["terms"]["pen"]["q50"], ".3f"),
                fmt(s["acceptance_rate"]["q50"], ".2f"),
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


def synthesis_parts(
    figures: Mapping[str, Path],
    grasp_summaries: Sequence[Path] | None,
    anneal_benchmarks: Sequence[Path] | None,
) -> list[str]:
    """The grasp-synthesis section, when the run got that far."""
    if not grasp_summaries:
        return []
    bench = {Path(p).stem: read_benchmark(p) for p in anneal_benchmarks or []}
    parts = [
        H.heading(2, "synthesis", "Grasp synthesis"),
        synthesis_table([read_json(p) for p in grasp_summaries], bench),
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
