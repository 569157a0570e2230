"""The report's "Sensor realism" section (our extension; the reference's 5.3): the baseline models
and the proxy scored on sensed test windows, a curve per corruption and a table per preset."""

from __future__ import annotations

from collections.abc import Mapping
from pathlib import Path
from typing import Any

import polars as pl

from graspstab.common.io import read_json, read_parquet
from graspstab.figures.presentation import UNDEFINED, family_label, finite
from graspstab.report import html as H
from graspstab.report import still_now as S
from graspstab.report.learning_tables import REFERENCE_PARAMETERS

ORDER = ("cnn", "gru", "lstm", "proxy")


def _pct(mean: Any, std: Any = None) -> str:
    if not finite(mean):
        return UNDEFINED
    return f"{100 * mean:.1f}" + (f" ± {100 * std:.1f}" if finite(std) else "")


def _label(family: str) -> str:
    return "proxy" if family == "proxy" else family_label(family)


#: Column suffix per training: clean-trained, the mixture's augmentation, and "own": the model
#: trained through the row's own corruption (sensing.augment.modes naming corruptions).
TRAININGS = {"clean": "", "none": "", "augmented": " (through sensors)",
             "own": " (through this corruption)"}  # fmt: skip
OWN = "augmented:"


def condition_table(
    summary: list[dict[str, Any]],
    kinds: tuple[str, ...],
    corruptions: tuple[str, ...] = (),
    metric: str = "auprc",
) -> tuple[list, list]:
    """Headers and rows: one row per condition of ``kinds`` (curves: of ``corruptions`` only,
    when given), test ``metric`` (%; ``still_auprc``: on the still-now windows) per scorer; a
    per-corruption model fills its own curve's rows."""
    frame = pl.DataFrame(summary, infer_schema_length=None).filter(pl.col("kind").is_in(kinds))
    if corruptions:
        frame = frame.filter((pl.col("kind") != "curve") | pl.col("corruption").is_in(corruptions))
    trained = set(zip(frame["family"].to_list(), frame["training"].to_list(), strict=True))
    scorers = [
        (f, t)
        for f in ORDER
        for t in TRAININGS
        if (f, t) in trained or (t == "own" and any(
            g == f and str(s).startswith(OWN) for g, s in trained))  # fmt: skip
    ]
    headers = ["condition", "strength", *[_label(f) + TRAININGS[t] for f, t in scorers]]
    rows = []
    for key, group in frame.group_by(["kind", "corruption", "strength"], maintain_order=True):
        cells = {(r["family"], r["training"]): r for r in group.iter_rows(named=True)}
        own = f"{OWN}{key[1]}"
        strength = "" if not finite(key[2]) or key[0] != "curve" else f"{key[2]:g}"
        row = [key[1] if key[0] != "clean" else "clean (simulator)", strength]
        for f, t in scorers:
            cell = cells.get((f, own if t == "own" else t))
            std = cell.get(f"{metric}_std") if cell is not None and cell["runs"] > 1 else None
            missing = "n/a" if t == "own" else UNDEFINED  # no model of that row's own corruption
            row.append(missing if cell is None else _pct(cell.get(f"{metric}_mean"), std))
        rows.append(row)
    return headers, rows


def sensing_section(sensing: Mapping[str, Any] | None, config: Mapping[str, Any]) -> str:
    """The section; a note how to run the study when this run has not."""
    parts = [H.heading(2, "sensing", "Sensor realism")]
    if not sensing or "summary" not in sensing:
        parts.append('<p class="note">This run has no sensor-robustness study '
                     "(sensing.robustness is false); <code>--config 'sensing={robustness: true}'"
                     "</code> runs it.</p>")  # fmt: skip
        return "\n".join(parts)
    info = read_json(Path(sensing["summary"]))
    runs = read_parquet(Path(sensing["runs"]))
    seeds = sorted({int(s) for s in runs.filter(pl.col("seed") >= 0)["seed"].to_list()})
    parts.append(
        "<p>The reference's features come from a clean simulator (its 5.3). Here the baseline "
        "models of table 4.3, trained on the simulator's forces, and the 4.7 friction-ratio proxy "
        "score test windows that came through a sensor model: a delay, a gain error per fingertip "
        "and channel, a bias drift, white noise, a converter's quantisation, sampling at the "
        "sensor's rate with a zero-order hold back onto the 2 kHz grid, and dropped samples "
        '(docs/extensions.md, "Sensor realism"). Each condition draws its sensed windows once; '
        "every scorer "
        f"reads the same ones. Test split: {info['n']} windows, {info['n_unstable']} unstable "
        f"(chance AUPRC {_pct(info['chance'])} %); models at seed(s) "
        f"{', '.join(map(str, seeds))} (mean ± std over seeds). Columns marked 'through "
        "sensors' are the same configuration trained with every training window, every "
        "epoch, through one condition drawn at random (clean with probability "
        f"{float(config['sensing']['augment']['clean_share']):g}); validation stays clean; "
        "'through this corruption' (when sensing.augment.modes names corruptions) is a model "
        "trained through that row's corruption only, at its curve's strengths. "
        "Noise and drift are in units of "
        "each channel's training std, the converter spans "
        f"±{float(config['sensing']['full_scale_n']):g} N.</p>"
    )
    headers, rows = condition_table(info["summary"], ("clean", "curve"))
    parts.append(H.table(headers, rows, caption="Test AUPRC (%) per corruption and strength"))
    still = info.get("still")
    if still and info["summary"] and "still_auprc_mean" in info["summary"][0]:
        parts.append(
            f"<p>On the {still['n']} still-now test windows (the object still over the whole "
            f"observation period: early warning proper), {still['n_unstable']} unstable (chance "
            f"AUPRC {_pct(still['chance'])} %); {UNDEFINED} where none is unstable.</p>"
        )
        headers, rows = condition_table(info["summary"], ("clean", "curve"), metric="still_auprc")
        parts.append(H.table(headers, rows, caption="Still-now test AUPRC (%) per corruption "
                             "and strength (mean over seeds)"))  # fmt: skip
    if "figure" in sensing:
        parts.append(H.image(Path(sensing["figure"]), "sensor robustness curves",
                             "Test AUPRC against each corruption's strength (solid: trained on "
                             "the simulator's forces; dashed: trained through the sensors; "
                             "dash-dot: through that corruption only); the "
                             "clean point sits at each curve's 'off' end (2 kHz for the rate, 4 "
                             "bits above the finest converter); dotted: chance.", "sensing-curves",
                             "Sensor robustness curves"))  # fmt: skip
    headers, rows = condition_table(info["summary"], ("clean", "preset"))
    presets = config["sensing"]["presets"]
    parts.append(H.table(headers, rows, caption="Test AUPRC (%) per sensor preset"))
    parts.append(H.table(
        ["preset", "settings"],
        [[name, ", ".join(f"{k} {v}" for k, v in values.items())]
         for name, values in presets.items()],
        caption="Sensor presets (illustrative settings, not any datasheet's)", cls="text",
    ))  # fmt: skip
    if "pick_summary" in sensing:
        parts.append(pick_table(read_json(Path(sensing["pick_summary"])), config))
    return "\n".join(parts)


def pick_table(info: Mapping[str, Any], config: Mapping[str, Any]) -> str:
    """The sweep models at the monitor's window under the rate curve and the presets."""
    window = float(config["monitor"]["window_s"])
    headers, rows = condition_table(info["summary"], ("clean", "curve", "preset"), ("rate",))
    note = (f"<p>The same conditions at the streaming monitor's window ({window:g} s, 4.5's "
            "latency-aware pick): each family's sweep models at that window (mean ± std over the "
            "scored seeds the sweep trained), on that dataset's test windows "
            f"({info['n']}, {info['n_unstable']} unstable, chance {_pct(info['chance'])} %). "
            f"The window spans {60 * window:.2g} sample periods of a 60 Hz sensor: under the "
            "hold it shows one or two distinct values.</p>")  # fmt: skip
    return note + H.table(headers, rows, caption=(
        f"Test AUPRC (%) at the {window:g} s window: the sampling-rate curve and the presets"))


AUDIT_LABELS = {
    "forces": "forces (5 × normal, shear; the text's inputs)",
    "normal": "normal only",
    "shear": "shear only",
    "tangential": "normal + shear's two fingertip-frame components",
    "object_state": "forces + object position, velocity (leakage control)",
}


def audit_section(audit: Mapping[str, Any] | None) -> str:
    """The input audit: test AUPRC and parameters per input set and family beside table 4.2."""
    parts = [H.heading(3, "input-audit", "Input audit")]
    if not audit or "summary" not in audit:
        parts.append('<p class="note">This run has no input audit (audit.enabled is false).</p>')
        return "\n".join(parts)
    info = read_json(Path(audit["summary"]))
    summary = pl.DataFrame(info["summary"], infer_schema_length=None)
    shapes = {(r["input_set"], r["family"]): r for r in info["shapes"]}
    families = [f for f in ORDER if f in set(summary["family"])]
    order = list(AUDIT_LABELS)  # the leakage control last, as the text says
    sets = sorted(dict.fromkeys(summary["input_set"].to_list()),
                  key=lambda s: order.index(s) if s in order else len(order))  # fmt: skip
    still = S.has_motion(summary.columns)
    rows = []
    for s in sets:
        width = next((shapes[(s, f)]["inputs"] for f in families if (s, f) in shapes), None)
        cells, extra, counts = [], [], None
        for f in families:
            test = summary.filter((pl.col("input_set") == s) & (pl.col("family") == f)
                                  & (pl.col("split") == "test"))  # fmt: skip
            if test.height:
                r = test.row(0, named=True)
                std = r["auprc_std"] if r.get("auprc_n", 2) > 1 else None
                cells += [
                    _pct(r["auprc_mean"], std),
                    f"{shapes[(s, f)]['parameters']:,}" if (s, f) in shapes else UNDEFINED,
                ]
                still_std = r.get("still_auprc_n", 2) > 1 if still else False
                extra.append(S.summary_metric(r, "auprc", std=still_std, sign=False, digits=1))
                # every family of an input set scores the same test windows: the first's counts
                counts = counts or S.summary_counts(r, digits=1, sign=False)
            else:
                cells += [UNDEFINED, UNDEFINED]
                extra.append(UNDEFINED)
        counts = counts or [UNDEFINED] * 3
        rows.append([AUDIT_LABELS.get(s, s), width, *cells,
                     *([*extra, *counts] if still else [])])  # fmt: skip
    headers = ["inputs", "per timestep"]
    for f in families:
        headers += [f"{_label(f)} test AUPRC (%)", f"{_label(f)} parameters"]
    if still:
        headers += [f"{_label(f)} test AUPRC, still now (%)" for f in families]
        headers += ["still-now test windows", "of which unstable", "chance AUPRC, still now (%)"]
    parts.append(
        "<p>Table 4.2's parameter counts ("
        + ", ".join(f"{_label(f)} {REFERENCE_PARAMETERS[f]:,}" for f in families)
        + ") are exactly what these architectures give with 16 inputs per timestep, not the "
        "text's 10. The baseline configurations and protocol of table 4.3, at the baseline "
        "window, trained on other inputs read from the replay traces at the same window starts, "
        "labels and splits; the forces row is the baseline runs themselves. The object's "
        "position and velocity (the last row) are what the labels are computed from: a leakage "
        "control, not a candidate input.</p>"
    )
    if still:
        parts.append(f"<p>{S.ALL_WINDOWS_TEXT} {S.STILL_NOW_TEXT} The columns 'still now' give "
                     "each input set's test AUPRC on those windows.</p>")  # fmt: skip
    parts.append(H.table(headers, rows, caption="Input audit: test AUPRC and parameters"))
    return "\n".join(parts)
