"""The report's tables of chapter 4's studies (split robustness 4.4, the window-length sweep,
latency and operating points 4.5, the friction-ratio proxy 4.7) beside the reference's numbers."""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import polars as pl

from graspstab.figures.presentation import (
    ORACLE,
    ORACLE_LABEL,
    UNDEFINED,
    family_label,
    motion_reason,
    ordered_families,
    rows_by,
)
from graspstab.report import html as H
from graspstab.report import still_now as S
from graspstab.report.learning_tables import motion_cells, motion_headers, note, num, pct

# The reference's numbers (thesis chapter 4).
REFERENCE_LATENCY = {  # section 4.5: median ± std [ms], throughput [windows/s] (approximate)
    "cnn": ("0.625 ± 0.032", "≈ 1600"),
    "lstm": ("2.407 ± 0.048", "≈ 415"),
    "gru": ("5.634 ± 0.118", "≈ 178"),
}
REFERENCE_SPLITS = {  # section 4.4, 0.01 s tuned LSTM, 30 assignments x 3 seeds
    "assignments": "30",
    "mean ± std": "97.14 ± 2.49 %",
    "median": "98.13 %",
    "minimum": "above 90 % (every assignment)",
    "fixed split": "97.90 %",
}
REFERENCE_PROXY = {"proxy": "96.27 %", "cnn": "98.03 %", "gru": "98.34 %", "lstm": "98.41 %"}
REFERENCE_SWEEP_F1 = {"cnn": "84.2-86.1 %", "gru": "85.4-85.9 %", "lstm": "85.0-85.4 %"}


def operating_points_table(points: pl.DataFrame, overview: Mapping[str, Any]) -> str:
    """Fig. 4.7's points: validation AUPRC and latency per family and window, best and pick."""
    choice = overview.get("choice", {})
    pick = choice.get("pick", {}) if choice.get("defined") else {}
    stars = {(b["family"], b["window_s"]) for b in overview.get("best_windows", [])}
    body = []
    for r in points.sort(["family", "window_s"]).iter_rows(named=True):
        key = (r["family"], r["window_s"])
        mark = " ".join(
            m
            for m, on in (
                ("★ best of family", key in stars),
                ("◎ latency-aware pick", key == (pick.get("family"), pick.get("window_s"))),
            )
            if on
        )
        body.append(
            [
                family_label(r["family"]),
                f"{r['window_s'] * 1000:g}",
                pct(r["val_auprc_mean"], r["val_auprc_std"], 3),
                num(r["latency_ms"], r["latency_std_ms"], 3),
                num(r["total_latency_ms"], None, 2),
                mark or "",
            ]
        )
    return H.table(
        [
            "model",
            "window [ms]",
            "validation AUPRC",
            "forward pass [ms]",
            "total decision latency [ms]",
            "",
        ],
        body,
        caption="Sweep operating points (section 4.5, fig. 4.7): mean ± std over seeds; "
        "total latency = window duration + median forward pass",
    )


def choice_text(overview: Mapping[str, Any]) -> str:
    """The latency-aware choice, its rule and the reference's."""
    c = overview.get("choice", {})
    rule = H.esc(c.get("rule", "?"))
    ref = (
        "The thesis: best mean validation AUPRC GRU at 0.10 s (98.762 ± 0.034 %, 106.10 ms); "
        "latency-aware pick LSTM at 0.01 s (98.747 ± 0.022 %, 10.17 ms)."
    )
    if not c.get("defined"):
        return note(
            f"Latency-aware choice undefined ({H.esc(c.get('reason', '?'))}). Rule: {rule}. {ref}"
        )

    def cfg(p: Mapping[str, Any]) -> str:
        auprc = pct(p.get("val_auprc_mean"), p.get("val_auprc_std"), 3)
        total = num(p.get("total_latency_ms"), None, 2)
        return f"{family_label(p['family'])} at {p['window_s']:g} s ({auprc}, {total} ms)"

    return (
        f"<p>Latency-aware rule: <i>{rule}</i>. Best configuration: {H.esc(cfg(c['best']))}; "
        f"cut-off {H.esc(pct(c.get('cutoff'), None, 3))}; <b>pick: "
        f"{H.esc(cfg(c['pick']))}</b>. {ref}</p>"
    )


def sweep_table(summary: pl.DataFrame) -> str:
    """Test F1 and AUPRC per window and family (fig. 4.5 D and F)."""
    test = summary.filter(pl.col("split") == "test")
    rows = rows_by(test, ["family", "window_s"])
    families = ordered_families(test["family"].to_list())
    body = []
    for w in sorted(test["window_s"].unique().to_list()):
        cells = [f"{w * 1000:g}"]
        for f in families:
            r = rows.get((f, w), {})
            cells += [
                pct(r.get("f1_mean"), r.get("f1_std"), 1),
                pct(r.get("auprc_mean"), r.get("auprc_std"), 1),
            ]
        body.append(cells)
    head = [
        "window [ms]",
        *[h for f in families for h in (f"{family_label(f)} F1", f"{family_label(f)} AUPRC")],
    ]
    ref = ", ".join(f"{family_label(f)} {v}" for f, v in REFERENCE_SWEEP_F1.items())
    return H.table(
        head,
        body,
        caption=(
            f"Test metrics across the sweep (fig. 4.5D, F), mean ± std over seeds. The thesis's "
            f"mean test F1 ranges over its windows: {ref}."
        ),
    )


def sweep_still_table(summary: pl.DataFrame) -> str:
    """Test ranking metrics per window and family on all windows and on the still-now windows
    (mean ± std over seeds); empty for a summary written before the still-now metrics."""
    if not S.has_motion(summary.columns):
        return ""
    test = summary.filter(pl.col("split") == "test")
    rows = rows_by(test, ["family", "window_s"])
    body = [
        [f"{w * 1000:g}", family_label(f), *motion_cells(rows[(f, w)], "test", 1)]
        for w in sorted(test["window_s"].unique().to_list())
        for f in ordered_families(test["family"].to_list())
        if (f, w) in rows
    ]
    return H.table(
        ["window [ms]", "model", *motion_headers("test")],
        body,
        caption=(
            "Prediction, not detection across the sweep: test ranking metrics on all windows and "
            "on the still-now windows (the object still over the whole observation period), "
            "mean ± std over seeds. A longer window leaves fewer still-now windows: its "
            "observation period has more time to see the object move."
        ),
    )


def latency_table(latency: pl.DataFrame) -> str:
    """Baseline forward-pass latency and throughput beside the reference's (fig. 4.6)."""
    base = latency.filter(pl.col("study") == "baseline")
    body = []
    for f in ordered_families(base["family"].to_list()):
        r = base.filter(pl.col("family") == f).row(0, named=True)
        ref = REFERENCE_LATENCY.get(f, ("—", "—"))
        body.append(
            [
                family_label(f),
                f"{r['window_s']:g}",
                num(r["median_ms"], r["std_ms"], 3),
                ref[0],
                num(r["throughput_per_s"], None, 0),
                ref[1],
            ]
        )
    return H.table(
        [
            "model",
            "window [s]",
            "median ± std [ms]",
            "thesis [ms]",
            "throughput [windows/s]",
            "thesis [windows/s]",
        ],
        body,
        caption="CPU batch-1 forward-pass latency of the baseline checkpoints (first seed; "
        "fig. 4.6). Different machines: compare the ordering, not the absolute times.",
    )


def splits_tables(summary: Mapping[str, Any], family: str | None) -> str:
    """Split-robustness statistics beside the reference's, and the hardest pairings."""
    s = summary
    ours = {
        "assignments": f"{s.get('assignments', '?')} ({s.get('defined', '?')} defined)",
        "mean ± std": pct(s.get("mean"), s.get("std")),
        "median": pct(s.get("median")),
        "minimum": pct(s.get("min")),
        "fixed split": pct(s.get("fixed_split")),
    }
    stats = H.table(
        ["test AUPRC across assignments", "ours", "thesis"],
        [[k, v, REFERENCE_SPLITS[k]] for k, v in ours.items()],
        caption=f"Split robustness (section 4.4, fig. 4.4), "
        f"{family_label(family) if family else 'model'} of the split study",
    )
    still = s.get("still")
    if isinstance(still, dict):
        stats = stats + splits_still_table(still)
    motion = any("still_auprc" in r for r in s.get("hardest", []))
    hard = [
        [
            r["assignment"],
            r["val_objects"],
            r["test_objects"],
            pct(r.get("auprc"), r.get("auprc_std")),
            r.get("seeds"),
            *(_assignment_still(r) if motion else []),
        ]
        for r in s.get("hardest", [])
    ]
    return stats + H.table(
        ["assignment", "validation objects", "test objects", "test AUPRC", "seeds",
         *(["test AUPRC: still now", "still-now test windows", "of which unstable",
            "chance AUPRC (still now)"] if motion else [])],
        hard,
        caption="Hardest sampled assignments (lowest mean test AUPRC). The thesis's hardest "
        "pairings repeatedly involve foam_brick, especially with lemon or sponge.",
    )  # fmt: skip


def _assignment_still(r: Mapping[str, Any]) -> list[str]:
    """An assignment's still-now cells (splits summary.json, per_assignment / hardest rows)."""
    auprc = S.percent(r.get("still_auprc"), r.get("still_auprc_std"))
    reason = motion_reason(r.get("still_n"), r.get("still_n_unstable"), "test")
    return [auprc or S.undefined(reason),
            *S.block_counts({"n": r.get("still_n"), "n_unstable": r.get("still_n_unstable"),
                             "chance": r.get("still_chance")})]  # fmt: skip


def splits_still_table(still: Mapping[str, Any]) -> str:
    """The split study's test AUPRC on the still-now windows across assignments (its summary's
    ``still`` block: the same statistics as the all-windows ones)."""
    total, defined = still.get("assignments", "?"), still.get("defined", "?")
    why = S.undefined(f"none of {total} assignments has a defined still-now test AUPRC (its "
                      "still-now test windows hold no unstable window, or no stable one)")

    def cell(text: str, reason: str = why) -> str:
        return reason if text == UNDEFINED else text

    rows = [
        ["assignments", f"{total} ({defined} defined)"],
        ["mean ± std", cell(pct(still.get("mean"), still.get("std")))],
        ["median", cell(pct(still.get("median")))],
        ["minimum", cell(pct(still.get("min")))],
        ["fixed split", cell(pct(still.get("fixed_split")), S.undefined(
            "the fixed split's still-now test windows hold no unstable window, or no stable "
            "one"))],
    ]
    return H.table(
        ["test AUPRC across assignments: still now", "ours"],
        rows,
        caption="Split robustness on the still-now test windows (the object still over the "
        "whole observation period); the thesis reports all windows only",
    )


def proxy_still_table(proxy: Mapping[str, Any], summary: pl.DataFrame | None) -> str:
    """The proxy, the models (mean ± std over seeds) and the persistence oracle on all test
    windows and on the still-now ones, with their count, positives and chance level; empty for
    a proxy record written before the still-now metrics."""
    if "test_still" not in proxy and ORACLE not in proxy:
        return ""

    def record_row(name: str, rec: Mapping[str, Any]) -> list[str]:
        test, still = rec.get("test") or {}, rec.get("test_still")
        return [
            name,
            pct(test.get("auprc")),
            S.block_metric(still, "auprc"),
            pct(test.get("auroc")),
            S.block_metric(still, "auroc"),
            *S.block_counts(still),
        ]

    body = [record_row("friction-ratio proxy", proxy)]
    if summary is not None and S.has_motion(summary.columns):
        rows = rows_by(summary.filter(pl.col("split") == "test"), ["family"])
        for f in ordered_families(f for (f,) in rows):
            body.append([f"{family_label(f)} (mean ± std over seeds)",
                         *motion_cells(rows[(f,)], "test")])  # fmt: skip
    if ORACLE in proxy:
        body.append(record_row(f"{ORACLE_LABEL} (reads object motion)", proxy[ORACLE]))
    return f"<p>{S.ALL_WINDOWS_TEXT} {S.STILL_NOW_TEXT} {S.ORACLE_TEXT}</p>" + H.table(
        ["score", *motion_headers("test")],
        body,
        caption="Prediction, not detection: the proxy, the models and the persistence oracle "
        "on all test windows and on the still-now ones; the thesis reports all windows only",
    )


def proxy_table(proxy: Mapping[str, Any], summary: pl.DataFrame | None) -> str:
    """Friction-ratio proxy vs the models' mean test AUPRC (fig. 4.10)."""
    test = proxy.get("test", {})
    body = [
        [
            "friction-ratio proxy",
            pct(test.get("auprc")),
            pct(test.get("auroc")),
            REFERENCE_PROXY["proxy"],
        ]
    ]
    if summary is not None:
        rows = rows_by(summary.filter(pl.col("split") == "test"), ["family"])
        for f in ordered_families(f for (f,) in rows):
            r = rows[(f,)]
            body.append(
                [
                    f"{family_label(f)} (mean ± std over seeds)",
                    pct(r["auprc_mean"], r["auprc_std"]),
                    pct(r["auroc_mean"], r["auroc_std"]),
                    REFERENCE_PROXY.get(f, "—"),
                ]
            )
    n, pos = test.get("n", 0), test.get("n_unstable", 0)
    body.append(
        [
            "chance level (test unstable fraction)",
            pct(pos / n if n else None),
            "50.00 %",
            "59.2 % (8632 / 14587)",
        ]
    )
    return H.table(
        ["score", "test AUPRC", "test AUROC", "thesis test AUPRC"],
        body,
        caption=f"Friction-ratio proxy (section 4.7) on the unseen-object test split "
        f"({pos} unstable of {n} windows)",
    )
