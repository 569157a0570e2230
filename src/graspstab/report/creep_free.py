"""The report's side-by-side section: the reference's gravity replay and the creep-free load ramp
on the same grasps (docs/protocols.md, "The creep-free load ramp"), and which of the reference's
conclusions hold under each, decided from the measured numbers by the rules written out in
:data:`CONCLUSIONS`.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import polars as pl

from graspstab.common.io import read_json, read_parquet
from graspstab.figures.artefacts import StudyArtefacts
from graspstab.figures.presentation import (
    ORACLE,
    ORACLE_LABEL,
    UNDEFINED,
    family_label,
    finite,
    motion_reason,
)
from graspstab.report import html as H
from graspstab.report import still_now as S
from graspstab.report.headline import (
    Figure,
    baseline_figure,
    baseline_motion_row,
    proxy_figure,
    proxy_record,
    record_figure,
    still_baseline_figure,
    still_sweep_figure,
    still_text,
    sweep_figure,
)

FAMILIES = ("cnn", "gru", "lstm")
SPLITS = ("train", "val", "test")
#: "Short windows suffice" (4.5) holds when the shortest sweep window's best validation AUPRC is
#: within this many points of the best over all windows.
SHORT_WINDOW_POINTS = 1.0


@dataclass(frozen=True)
class Benchmark:
    """One protocol's artefacts: its dataset and speed summaries, replay outcome table and
    studies."""

    name: str
    dataset: Path  # datasets/baseline/summary.json
    speeds: Path  # datasets/speeds.json
    replay_outcomes: Path  # replay/outcomes.parquet (rule summarise_replays)
    studies: StudyArtefacts
    speeds_figure: Path | None = None
    sweep_windows_s: Sequence[float] = field(default_factory=tuple)


def _pct(x: float | None, digits: int = 1) -> str:
    return f"{100 * x:.{digits}f} %" if finite(x) else UNDEFINED


def _mm(x: float | None) -> str:
    return f"{1e3 * x:.3g}" if finite(x) else UNDEFINED


def class_mix(b: Benchmark) -> dict[str, dict[str, Any]]:
    """Per split: windows, unstable share, and how many objects contribute windows."""
    d = read_json(b.dataset)
    out = {}
    for s in SPLITS:
        c = d["splits"][s]
        n = c["stable"] + c["unstable"]
        objects = sum(
            1 for o in d["objects"].values() if o[s]["stable"] + o[s]["unstable"] > 0
        )
        out[s] = {"n": n, "unstable": c["unstable"], "share": c["unstable"] / n if n else None,
                  "objects": objects}  # fmt: skip
    return out


def replay_outcomes(b: Benchmark) -> dict[str, Any]:
    """How the replays ended (the outcome table's row over all objects): held to the end,
    contact lost, too deep, and (under the ramp) slid under load with the median time from the
    slip to the end of contact."""
    t = read_parquet(b.replay_outcomes).filter(pl.col("object").is_null()).row(0, named=True)
    out = {"grasps": t["replays"], "held": t["held"], "lost": t["contact_lost"],
           "too_deep": t["too_deep"], "diverged": t["diverged"]}  # fmt: skip
    if t["slid"] is not None:
        out["slid"] = t["slid"]
        out["slip_to_loss_s"] = t["median_slip_to_loss_s"]
        out["peak_load_mg"] = t["median_peak_load_mg"]
    return out


def _best(figures: Mapping[str, Figure]) -> tuple[str | None, float | None]:
    defined = {k: float(f.mean) for k, f in figures.items() if finite(f.mean)}
    if not defined:
        return None, None
    k = max(defined, key=defined.get)
    return k, defined[k]


def conclusions(b: Benchmark) -> list[tuple[str, str, str]]:
    """(conclusion, verdict, evidence) for the reference's three claims under one protocol."""
    return judge(
        {f: baseline_figure(b.studies, f, "test", "auprc") for f in FAMILIES},
        proxy_figure(b.studies),
        {w: {f: sweep_figure(b.studies, f, w) for f in FAMILIES} for w in b.sweep_windows_s},
    )


def judge(
    test: Mapping[str, Figure], proxy: Figure, sweep: Mapping[float, Mapping[str, Figure]]
) -> list[tuple[str, str, str]]:
    """The verdicts from the figures: each family's test AUPRC at the baseline window, the
    proxy's, and each sweep window's validation AUPRC per family."""
    rows = []
    # 1. learned models beat the proxy (4.7): every family's mean test AUPRC above the proxy's
    if finite(proxy.mean) and all(finite(f.mean) for f in test.values()):
        above = [f for f, x in test.items() if x.mean > proxy.mean]
        verdict = "holds" if len(above) == len(FAMILIES) else (
            "partly" if above else "does not hold")  # fmt: skip
        evidence = (f"proxy {_pct(proxy.mean, 2)}; " + ", ".join(
            f"{family_label(f)} {_pct(x.mean, 2)}" for f, x in test.items()))  # fmt: skip
    else:
        verdict, evidence = UNDEFINED, "a test AUPRC is undefined"
    rows.append(("Learned models beat the friction-ratio proxy (4.7)", verdict, evidence))
    # 2. short windows suffice (4.5): the shortest window within SHORT_WINDOW_POINTS of the best
    windows = sorted(sweep)
    by_window = {w: _best(sweep[w])[1] for w in windows}
    defined = {w: v for w, v in by_window.items() if finite(v)}
    if windows and windows[0] in defined:
        best_w = max(defined, key=defined.get)
        gap = 100 * (defined[best_w] - defined[windows[0]])
        verdict = "holds" if gap <= SHORT_WINDOW_POINTS else "does not hold"
        evidence = (f"best validation AUPRC at {windows[0]:g} s {_pct(defined[windows[0]], 2)}, "
                    f"best over windows {_pct(defined[best_w], 2)} at {best_w:g} s "
                    f"({gap:.2f} points; threshold {SHORT_WINDOW_POINTS:g})")  # fmt: skip
    else:
        verdict, evidence = UNDEFINED, "the shortest sweep window has no defined AUPRC"
    rows.append(("Short windows suffice (4.5)", verdict, evidence))
    # 3. the GRU ranks best (4.3): the highest mean test AUPRC at the baseline window
    top, _ = _best(test)
    if top is None:
        rows.append(("The GRU ranks best (4.3)", UNDEFINED, "no family has a defined test AUPRC"))
    else:
        gru, best = test["gru"], test[top]
        verdict = "holds" if top == "gru" else "does not hold"
        within = (
            " (within one std of the best)"
            if top != "gru" and finite(gru.mean) and finite(best.std)
            and best.mean - gru.mean <= best.std else ""
        )  # fmt: skip
        evidence = (f"best: {family_label(top)} {best.text()}; GRU {gru.text()}{within}")
        rows.append(("The GRU ranks best (4.3)", verdict, evidence))
    return rows


def _has_still(b: Benchmark) -> bool:
    """Whether a protocol's studies hold the still-now metrics (an older run's do not)."""
    record = proxy_record(b.studies)
    return bool(record.get("test_still") or record.get(ORACLE)) or any(
        S.has_motion(baseline_motion_row(b.studies, f)) for f in FAMILIES
    )


def still_rows(main: Benchmark, ramp: Benchmark) -> list[list[Any]]:
    """The side-by-side table's still-now rows: each family's, the proxy's and the persistence
    oracle's test AUPRC on the still-now windows (the oracle's also on all windows), and the
    still-now test windows' count, positives and chance level (the proxy's record: every scorer
    reads the same test windows)."""
    pair = (main, ramp)
    records = [proxy_record(b.studies) for b in pair]
    rows: list[list[Any]] = [
        [f"{family_label(f)} test AUPRC, still now",
         *[still_text(still_baseline_figure(b.studies, f, "test", "auprc")) for b in pair]]
        for f in FAMILIES
    ]  # fmt: skip
    rows.append(["friction-ratio proxy test AUPRC, still now",
                 *[still_text(record_figure(r.get("test_still"), "auprc", "test", "still"))
                   for r in records]])  # fmt: skip
    rows.append([f"{ORACLE_LABEL} test AUPRC (reads object motion: a reference line)",
                 *[record_figure((r.get(ORACLE) or {}).get("test"), "auprc").text()
                   for r in records]])  # fmt: skip
    rows.append([f"{ORACLE_LABEL} test AUPRC, still now",
                 *[still_text(record_figure((r.get(ORACLE) or {}).get("test_still"), "auprc",
                                            "test", "still")) for r in records]])  # fmt: skip
    counts = [S.block_counts(r.get("test_still"), digits=1) if r.get("test_still")
              else None for r in records]  # fmt: skip
    rows.append(["still-now test windows (unstable; chance AUPRC)",
                 *[f"{c[0]} ({c[1]}; {c[2]})" if c else S.undefined(motion_reason(None, None))
                   for c in counts]])  # fmt: skip
    return rows


def load_sentence(replay: Mapping[str, Any]) -> str:
    """What the creep-free benchmark's load does, from its replay params (protocol ``ramp`` or
    ``perturb``, with the group of that name)."""
    if replay["protocol"] == "perturb":
        p = replay["perturb"]
        return (f"after a still period drawn per grasp from {p['delay_s'][0]:g}-"
                f"{p['delay_s'][1]:g} s the object also carries a force rising open-loop at a "
                f"rate drawn from {p['rate'][0]:g}-{p['rate'][1]:g} m g per second up to "
                f"{p['ceiling']:g} m g along {H.esc(p['directions'])} (the hidden-onset "
                "disturbance).")  # fmt: skip
    r = replay["ramp"]
    return (f"after {r['start_s']:g} s the object also carries a force rising "
            f"at {r['rate']:g} m g per second up to {r['ceiling']:g} m g along "
            f"{H.esc(r['directions'])} (path {H.esc(r['path'])}"
            + (f", held at {r['hold_fraction']:g} of the load at which the object first reaches "
               f"{r['slip_speed'] * 1e3:g} mm/s" if r["path"] == "hold" else "") + ").")


def creep_free_section(main: Benchmark, ramp: Benchmark, load: Mapping[str, Any]) -> str:
    """The section "Two protocols side by side" (anchor ``protocols``)."""
    names = [main.name, ramp.name]
    mix = [class_mix(b) for b in (main, ramp)]
    head = ["", *names]
    rows = []
    for s in SPLITS:
        rows.append([f"{s}: windows (unstable share)",
                     *[f"{m[s]['n']} ({_pct(m[s]['share'])})" for m in mix]])  # fmt: skip
        rows.append([f"{s}: objects with windows", *[m[s]["objects"] for m in mix]])
    outcomes = [replay_outcomes(b) for b in (main, ramp)]
    rows += [
        ["replays", *[o["grasps"] for o in outcomes]],
        ["held to the end", *[o["held"] for o in outcomes]],
        ["contact lost", *[o["lost"] for o in outcomes]],
        ["too deep (the depth rule rejects them)", *[o["too_deep"] for o in outcomes]],
        ["slid under the load while in contact", "—", outcomes[1].get("slid", UNDEFINED)],
        ["median slip to contact loss [s]", "—",
         f"{outcomes[1]['slip_to_loss_s']:.2f}" if finite(outcomes[1].get("slip_to_loss_s"))
         else UNDEFINED],
    ]  # fmt: skip
    speeds = [read_json(b.speeds) for b in (main, ramp)]
    rows += [
        ["creep of a held box [mm/s]", *[_mm(s["box_creep"]["speed"]) for s in speeds]],
        ["creep of grasps held at the end, median [mm/s]",
         *[_mm(s["held_creep"]["q50"]) for s in speeds]],
        ["unstable windows' target speed, median [mm/s]",
         *[_mm(s["target_speed"]["unstable"]["q50"]) for s in speeds]],
    ]  # fmt: skip
    for f in FAMILIES:
        rows.append([f"{family_label(f)} test AUPRC", *[
            baseline_figure(b.studies, f, "test", "auprc").text() for b in (main, ramp)]])
    rows.append(["friction-ratio proxy test AUPRC",
                 *[proxy_figure(b.studies).text() for b in (main, ramp)]])  # fmt: skip
    still = any(_has_still(b) for b in (main, ramp))
    if still:
        rows += still_rows(main, ramp)
    parts = [
        H.heading(2, "protocols", "Two protocols side by side: gravity and the load ramp"),
        f'<p>The same grasps replayed twice: under {H.esc(main.name)} (the main run) and under '
        f"{H.esc(ramp.name)}: {load_sentence(load)} Models, training, thresholds and the "
        "proxy are the same; under the strict contact model a held object does not creep, so an "
        "unstable label means real slip.</p>",
        H.table(head, rows, caption=(
            "Class mix, replay outcomes, creep and headline metrics (mean ± std over seeds; a "
            "figure without ± is one seed, e.g. creep_free.seeds) of the two protocols")),
    ]  # fmt: skip
    common = sorted(set(main.sweep_windows_s) & set(ramp.sweep_windows_s))
    sweep_rows = [
        [f"{w:g}", family_label(f),
         *[sweep_figure(b.studies, f, w).text() for b in (main, ramp)]]
        for w in common for f in FAMILIES
    ]  # fmt: skip
    if still:
        for row, (w, f) in zip(sweep_rows, [(w, f) for w in common for f in FAMILIES],
                               strict=True):
            row += [still_text(still_sweep_figure(b.studies, f, w)) for b in (main, ramp)]
        parts.append(
            f"<p>{S.ALL_WINDOWS_TEXT} {S.STILL_NOW_TEXT} {S.ORACLE_TEXT} The rows 'still now' "
            "above and the sweep's columns 'still now' (its still-now validation windows) give "
            "them under each protocol.</p>"
        )
    names_still = [f"{n}: still now (validation)" for n in names] if still else []
    parts.append(H.table(["window [s]", "family", *names, *names_still], sweep_rows,
                         caption="Window sweep: validation AUPRC (4.5) under each protocol"))
    verdicts = [conclusions(b) for b in (main, ramp)]
    parts.append(H.table(
        ["conclusion of the reference", *[f"{n}: verdict" for n in names],
         *[f"{n}: evidence" for n in names]],
        [[c[0][0], c[0][1], c[1][1], c[0][2], c[1][2]] for c in zip(*verdicts, strict=True)],
        cls="text", caption=(
            "Which of the reference's conclusions hold under each protocol, decided from the "
            "numbers above: the proxy rule needs every family above the proxy; 'short windows "
            f"suffice' allows {SHORT_WINDOW_POINTS:g} point of validation AUPRC"),
    ))  # fmt: skip
    for b, anchor in ((main, "protocols-speeds-main"), (ramp, "protocols-speeds-ramp")):
        if b.speeds_figure is not None:
            parts.append(H.image(b.speeds_figure, f"speeds behind the labels, {b.name}",
                                 f"Speeds behind the labels under {b.name}.", anchor))  # fmt: skip
    return "\n".join(parts)
