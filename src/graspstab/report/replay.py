"""The report's "Grasp replay" section and its "Contact model" subsection: the replay outcome table
rule ``summarise_replays`` wrote, the contact model in use and the speeds behind the labels (3.2,
3.3.2), shown as written."""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import polars as pl

from graspstab.common.io import read_json, read_parquet
from graspstab.report import html as H
from graspstab.report.provenance import read_benchmark


def outcome_rows(outcomes: Path) -> list[dict[str, Any]]:
    """The per-object rows of a replay outcome table (its last row, over all objects, has a null
    ``object`` and is left out)."""
    table = read_parquet(outcomes)
    return table.filter(pl.col("object").is_not_null()).to_dicts()


def replay_parts(
    outcomes: Path | None,
    figures: Mapping[str, Path],
    replay_benchmarks: Sequence[Path] = (),
) -> list[str]:
    """Replay outcomes per object (3.2), when the run got that far (``outcomes``: the replay
    outcome table); the wall time is the replay jobs' (``replay_benchmarks``, Snakemake's
    benchmark files), not data: the tables hold none."""
    if outcomes is None:
        return []
    bench = {Path(p).stem: read_benchmark(p) for p in replay_benchmarks if Path(p).exists()}
    rows = []
    for r in outcome_rows(outcomes):
        oid = r["object"]
        wall = [b["s"] for k, b in bench.items() if k.startswith(f"{oid}_shard_")]
        rows.append(
            [
                oid,
                r["replays"],
                r["held"],
                r["contact_lost"],
                r["too_deep"],
                r["diverged"],
                H.fmt(r["median_max_penetration_m"], ".1f", 1000),
                f"{r['simulated_s']:.0f}",
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


def contact_parts(
    speeds: Path | None, figures: Mapping[str, Path], replay: Mapping[str, Any]
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
