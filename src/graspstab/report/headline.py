"""The report's headline: this run's scale in one sentence and its key figures beside the
reference's published ones (thesis 4.3, 4.4, 4.5, 4.7), so a reader sees at once how far a run is
from a reproduction. An undefined value prints as "undefined" with its reason, never as 0.

Beside it, prediction, not detection: each family, the proxy and the persistence oracle on all
test windows (the reference's protocol) and on the still-now ones (the object still over the whole
observation period: early warning proper), read from the same summaries (:func:`still_section`).
"""

from __future__ import annotations

import re
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import polars as pl

from graspstab.common.io import read_json, read_parquet
from graspstab.figures.artefacts import StudyArtefacts
from graspstab.figures.presentation import (
    FAMILY_ORDER,
    ORACLE,
    ORACLE_LABEL,
    SPLIT_NAMES,
    UNDEFINED,
    family_label,
    finite,
    motion_reason,
)
from graspstab.report import html as H
from graspstab.report import still_now as S

SPLITS = ("train", "val", "test")


@dataclass(frozen=True)
class Figure:
    """One of this run's headline figures (fractions), or why it is undefined."""

    mean: float | None = None
    std: float | None = None
    reason: str = ""  # why mean (or, with a mean, why std) is undefined
    digits: int = 2

    def text(self) -> str:
        """'mean ± std %', 'mean %' or 'undefined (reason)'."""
        if not finite(self.mean):
            return f"{UNDEFINED} ({self.reason or 'no value'})"
        m = f"{100 * float(self.mean):.{self.digits}f}"
        if self.std is None and not self.reason:
            return f"{m} %"
        if finite(self.std):
            return f"{m} ± {100 * float(self.std):.{self.digits}f} %"
        return f"{m} % (std {UNDEFINED}: {self.reason or 'no value'})"


def _class_reason(row: Mapping[str, Any], split: str) -> str:
    """Why a ranking metric is undefined on a split (a seed summary's row): no unstable or no
    stable window in any run, or no seed gave a value."""
    name = SPLIT_NAMES.get(split, split)
    if row.get("no_unstable"):
        return f"the {name} split holds no unstable window"
    if row.get("no_stable"):
        return f"the {name} split holds no stable window"
    return "no seed gave a defined value"


def seed_figure(row: Mapping[str, Any], metric: str, digits: int = 2) -> Figure:
    """Mean ± std over seeds of ``metric`` from one row of a study's seed summary
    (``summary_defined.parquet``: 0/0 metrics undefined, as in the report's tables), with the
    reason when undefined."""
    mean, std, n = row[f"{metric}_mean"], row[f"{metric}_std"], row.get(f"{metric}_n", 0)
    if not finite(mean):
        return Figure(reason=_class_reason(row, str(row["split"])), digits=digits)
    reason = "" if finite(std) else f"{n} seed{'s' if n != 1 else ''} defined it"
    return Figure(mean, std if finite(std) else None, reason, digits)


def _absent(path: Path | None) -> str:
    """Why an artefact cannot be read: not given to the report, or not on disk."""
    return "not given to the report" if path is None else f"{path} not produced"


def _summary(path: Path | None, **where: Any) -> pl.DataFrame | str:
    """The rows of a seed summary (summary_defined.parquet) matching ``where`` (window_s matched
    to the microsecond), or why there are none."""
    if path is None or not Path(path).exists():
        return _absent(path)
    rows = read_parquet(path)
    for col, value in where.items():
        if col not in rows.columns:
            return f"{Path(path).name} has no column {col!r}"
        rows = rows.filter(
            (pl.col(col) - value).abs() < 1e-6 if isinstance(value, float) else pl.col(col) == value
        )
    return rows


def baseline_figure(a: StudyArtefacts, family: str, split: str, metric: str) -> Figure:
    """A metric of one family at the baseline window (4.3), mean ± std over seeds (``a``'s
    ``baseline_summary_defined``: a :class:`~graspstab.figures.artefacts.StudyArtefacts`)."""
    rows = _summary(a.baseline_summary_defined, family=family, split=split)
    if isinstance(rows, str):
        return Figure(reason=rows)
    if rows.is_empty():
        return Figure(reason=f"no {family_label(family)} run in this run's baseline study")
    return seed_figure(rows.row(0, named=True), metric)


def proxy_figure(a: StudyArtefacts) -> Figure:
    """The friction-ratio proxy's test AUPRC (4.7)."""
    path = a.proxy
    if path is None or not Path(path).exists():
        return Figure(reason=_absent(path))
    test = read_json(path).get("test", {})
    if finite(test.get("auprc")):
        return Figure(float(test["auprc"]))
    n, pos = test.get("n", 0), test.get("n_unstable", 0)
    why = (
        "the test split holds no window" if not n
        else "the test split holds no unstable window" if not pos
        else "the test split holds no stable window" if pos == n
        else "not computed"
    )  # fmt: skip
    return Figure(reason=why)


def still_text(figure: Figure) -> str:
    """A still-now (moving-now) figure as text: 'undefined: <reason>' when undefined (e.g.
    "undefined: no still-now test window becomes unstable"), else as :meth:`Figure.text`."""
    return figure.text() if finite(figure.mean) else S.undefined(figure.reason or "no value")


def _motion_figure(row: Mapping[str, Any], metric: str, split: str, part: str,
                   digits: int = 2) -> Figure:  # fmt: skip
    """Mean ± std over seeds of ``<part>_<metric>`` from a seed summary's row, or why not."""
    mean, std = row.get(f"{part}_{metric}_mean"), row.get(f"{part}_{metric}_std")
    if not finite(mean):
        reason = motion_reason(row.get(f"{part}_n_mean"), row.get(f"{part}_n_unstable_mean"),
                               split, part)  # fmt: skip
        return Figure(reason=reason, digits=digits)
    n = row.get(f"{part}_{metric}_n", 0)
    reason = "" if finite(std) else f"{n} seed{'s' if n != 1 else ''} defined it"
    return Figure(mean, std if finite(std) else None, reason, digits)


def still_baseline_figure(
    a: StudyArtefacts, family: str, split: str, metric: str, part: str = "still"
) -> Figure:
    """A metric of one family at the baseline window on the split's still-now (``part``
    "moving": moving-now) windows, mean ± std over seeds, or why it is undefined."""
    rows = _summary(a.baseline_summary_defined, family=family, split=split)
    if isinstance(rows, str):
        return Figure(reason=rows)
    if rows.is_empty():
        return Figure(reason=f"no {family_label(family)} run in this run's baseline study")
    return _motion_figure(rows.row(0, named=True), metric, split, part)


def still_sweep_figure(
    a: StudyArtefacts, family: str, window_s: float, split: str = "val", part: str = "still"
) -> Figure:
    """A sweep configuration's AUPRC on the split's still-now windows (mean ± std over seeds)."""
    rows = _summary(a.sweep_summary_defined, family=family, split=split)
    if isinstance(rows, str):
        return Figure(reason=rows, digits=3)
    rows = rows.filter((pl.col("window_s") - window_s).abs() < 1e-6)
    if rows.is_empty():
        return Figure(reason=f"{family_label(family)} at {window_s:g} s is not in this run's "
                      "sweep", digits=3)  # fmt: skip
    return _motion_figure(rows.row(0, named=True), "auprc", split, part, digits=3)


def baseline_motion_row(a: StudyArtefacts, family: str, split: str = "test") -> dict[str, Any]:
    """One family's row of the baseline seed summary (``{}`` when absent)."""
    rows = _summary(a.baseline_summary_defined, family=family, split=split)
    return {} if isinstance(rows, str) or rows.is_empty() else rows.row(0, named=True)


def proxy_record(a: StudyArtefacts) -> dict[str, Any]:
    """The friction-ratio proxy's record (proxy.json; ``{}`` when absent)."""
    path = a.proxy
    return read_json(path) if path is not None and Path(path).exists() else {}


def record_figure(block: Mapping[str, Any] | None, metric: str, split: str = "test",
                  part: str = "all") -> Figure:  # fmt: skip
    """A ranking metric of one block of a record (``{n, n_unstable, auprc, auroc}``: all windows
    of a split, or its still-now / moving-now windows), or why it is undefined."""
    b = block or {}
    if finite(b.get(metric)):
        return Figure(float(b[metric]))
    n, pos = b.get("n"), b.get("n_unstable")
    if part != "all":
        return Figure(reason=motion_reason(n, pos, split, part))
    name = SPLIT_NAMES.get(split, split)
    why = (
        "not recorded" if not b
        else f"the {name} split holds no window" if not n
        else f"the {name} split holds no unstable window" if not pos
        else f"the {name} split holds no stable window" if pos == n
        else "not computed"
    )  # fmt: skip
    return Figure(reason=why)


def splits_figure(a: StudyArtefacts) -> Figure:
    """Test AUPRC across the sampled split assignments (4.4): mean ± std over assignments."""
    path = a.splits_overview
    if path is None or not Path(path).exists():
        return Figure(reason=_absent(path))
    s = read_json(path)
    defined, total = s.get("defined", 0), s.get("assignments", 0)
    if not finite(s.get("mean")):
        return Figure(reason=f"none of {total} assignments has a defined test AUPRC")
    std = s.get("std")
    reason = "" if finite(std) else f"{defined} of {total} assignments defined"
    return Figure(float(s["mean"]), float(std) if finite(std) else None, reason)


def sweep_figure(a: StudyArtefacts, family: str, window_s: float) -> Figure:
    """Validation AUPRC of one sweep configuration (4.5), mean ± std over seeds (read from
    ``a.sweep_summary_defined``)."""
    rows = _summary(a.sweep_summary_defined, family=family, split="val")
    if isinstance(rows, str):
        return Figure(reason=rows, digits=3)
    windows = sorted({float(w) for w in rows["window_s"]})
    rows = rows.filter((pl.col("window_s") - window_s).abs() < 1e-6)
    if rows.is_empty():
        have = ", ".join(f"{w:g}" for w in windows) or "none"
        return Figure(reason=f"{family_label(family)} at {window_s:g} s is not in this run's sweep "
                      f"(windows [s]: {have})", digits=3)  # fmt: skip
    return seed_figure(rows.row(0, named=True), "auprc", digits=3)


# (section, quantity, reference value as the thesis prints it, this run's figure)
HEADLINE: list[tuple[str, str, str, Callable[[StudyArtefacts], Figure]]] = [
    ("4.3", "GRU test AUPRC at the 0.20 s baseline window (mean ± std over seeds)",
     "98.43 ± 0.05 %", lambda s: baseline_figure(s, "gru", "test", "auprc")),
    ("4.3", "GRU test AUROC at the baseline window", "97.78 ± 0.07 %",
     lambda s: baseline_figure(s, "gru", "test", "auroc")),
    ("4.7", "Friction-ratio proxy, test AUPRC", "96.27 %", proxy_figure),
    ("4.7", "CNN test AUPRC at the baseline window (thesis: one saved checkpoint)", "98.03 %",
     lambda s: baseline_figure(s, "cnn", "test", "auprc")),
    ("4.7", "GRU test AUPRC at the baseline window (thesis: one saved checkpoint)", "98.34 %",
     lambda s: baseline_figure(s, "gru", "test", "auprc")),
    ("4.7", "LSTM test AUPRC at the baseline window (thesis: one saved checkpoint)", "98.41 %",
     lambda s: baseline_figure(s, "lstm", "test", "auprc")),
    ("4.4", "Split robustness: test AUPRC across sampled assignments (mean ± std)",
     "97.14 ± 2.49 %", splits_figure),
    ("4.5", "LSTM at a 0.01 s window, validation AUPRC (the latency-aware pick)",
     "98.747 ± 0.022 %", lambda s: sweep_figure(s, "lstm", 0.01)),
]  # fmt: skip


def gap_text(figure: Figure, reference: str) -> str:
    """This run's mean minus the reference's (as printed), in percentage points, or why not."""
    ref = re.match(r"\s*([0-9.]+)", reference)
    if not finite(figure.mean) or ref is None:
        return UNDEFINED
    return f"{100 * float(figure.mean) - float(ref.group(1)):+.{figure.digits}f}"


def headline_rows(artefacts: StudyArtefacts | None) -> list[list[str]]:
    """[section, quantity, this run, reference, run - reference in points] for every headline
    figure (``artefacts``: the studies' artefacts, None when the report was given no learning
    results)."""

    def figure(fig: Callable[[StudyArtefacts], Figure]) -> Figure:
        if artefacts is None:
            return Figure(reason="no learning results given to the report")
        return fig(artefacts)

    rows = []
    for sec, what, ref, fig in HEADLINE:
        got = figure(fig)
        rows.append([sec, what, got.text(), ref, gap_text(got, ref)])
    return rows


def protocol_of(config: Mapping[str, Any]) -> dict[str, Any]:
    """The replay protocol's named choices (issue 13) and which of them deviate from the
    reference (reference contact model, eq. 16's energy, no squeeze)."""
    contact = config.get("replay", {}).get("contact", {}).get("name", "?")
    energy = config.get("synthesis", {}).get("energy", {}).get("name", "?")
    squeeze = float(config.get("replay", {}).get("squeeze", {}).get("angle", 0.0))
    settle = config.get("labels", {}).get("settle", {}).get("require", "?")
    deviations = [
        *([f"contact model {contact}"] if contact != "reference" else []),
        *([f"energy {energy} (w_fc 0.01 and E_hpen)"] if energy != "reference" else []),
        *([f"a {squeeze:g} rad squeeze"] if squeeze > 0 else []),
    ]
    return {"contact": contact, "energy": energy, "squeeze": squeeze, "settle": settle,
            "deviations": deviations}  # fmt: skip


def run_scale(
    config: Mapping[str, Any],
    n_objects: int,
    totals: Mapping[str, Any] | None,
    dataset: Mapping[str, Any] | None,
) -> dict[str, Any]:
    """The numbers that say how big this run is (and so how much its figures can mean):
    ``totals`` is the grasp funnel's row over all objects (rule ``summarise_funnel``: candidate
    grasps annealed, usable grasps), ``dataset`` the baseline dataset's summary."""
    splits = (dataset or {}).get("splits", {})
    windows = {s: sum(splits.get(s, {}).get(c, 0) for c in ("stable", "unstable")) for s in SPLITS}
    train, tune = config.get("train", {}), config.get("tune", {})
    totals = totals or {}
    return {
        "profile": config.get("profile_name", "?"),
        "objects": n_objects,
        "candidate_grasps": totals.get("annealed") or 0,
        "usable_grasps": totals.get("usable") if dataset else None,
        "windows": windows if dataset else None,
        "seeds": list(train.get("seeds", [])),
        "max_epochs": train.get("max_epochs"),
        "trials": tune.get("trials"),
        "protocol": protocol_of(config),
        "test_unstable_share": (
            splits["test"]["unstable"] / max(1, windows["test"])
            if dataset and "test" in splits and windows["test"] else None
        ),
    }  # fmt: skip


def scale_sentence(scale: Mapping[str, Any]) -> str:
    """The run's profile and scale as HTML, with the smoke-test warning in bold for quick runs."""
    w = scale["windows"]
    windows = " / ".join(f"{w[s]:,} {s}" for s in SPLITS) + " windows" if w else "no window dataset"
    usable = scale["usable_grasps"]
    seeds = scale["seeds"]
    text = (
        f"Profile <b>{H.esc(scale['profile'])}</b>: {scale['objects']} objects, "
        f"{scale['candidate_grasps']:,} candidate grasps annealed, "
        f"{f'{usable:,}' if usable is not None else UNDEFINED} usable grasps (with at least one "
        f"labelled window), {windows} at the baseline window; {len(seeds)} training seed"
        f"{'s' if len(seeds) != 1 else ''} ({', '.join(map(str, seeds))}), at most "
        f"{scale['max_epochs']} epochs, {scale['trials']} Optuna trials per family. "
    )
    proto = scale.get("protocol")
    if proto is not None:
        dev = proto["deviations"]
        text += (
            f"Replay protocol: contact model <b>{H.esc(proto['contact'])}</b>, energy "
            f"<b>{H.esc(proto['energy'])}</b>, squeeze {proto['squeeze']:g} rad, settle reading "
            f"'{H.esc(proto['settle'])}'; "
            + (f"deviations from the reference: {H.esc(', '.join(dev))} (docs/protocols.md "
               "gives what each changes). " if dev else
               "the reference's choices throughout. ")
        )  # fmt: skip
    chance = scale.get("test_unstable_share")
    if chance is not None:
        text += (
            f"The test split is {100 * chance:.1f} % unstable: the AUPRC of a scorer that knows "
            "nothing. "
        )
    if scale["profile"] == "thesis":
        return text + "This is the reference's scale: the figures below are comparable to it."
    return text + (
        f"<b>{H.esc(str(scale['profile']).capitalize())}-profile numbers come from a reduced "
        "scale (fewer grasps, windows, seeds, epochs and trials than the reference's 43,978 "
        "training windows, 5 seeds and 40 epochs): they are not a reproduction of the "
        "reference's results, and the last column says how far they are from it.</b>"
    )


#: The reference's test figures per scorer (all windows: the thesis has no other), 4.3 and 4.7.
REFERENCE_SCORERS = {
    "cnn": "AUPRC 98.03 % (one saved checkpoint)",
    "gru": "AUPRC 98.43 ± 0.05 %, AUROC 97.78 ± 0.07 %",
    "lstm": "AUPRC 98.41 % (one saved checkpoint)",
    "proxy": "AUPRC 96.27 %",
    ORACLE: "—",
}
STILL_HEADERS = [
    "scorer", "reference (thesis; all windows)", "test AUPRC: all windows",
    "test AUPRC: still now", "test AUROC: all windows", "test AUROC: still now",
    "still-now test windows", "of which unstable", "chance AUPRC (still now)",
]  # fmt: skip


def still_rows(artefacts: StudyArtefacts | None) -> list[list[str]]:
    """One row per family (baseline window, mean ± std over seeds), the friction-ratio proxy and
    the persistence oracle: test AUPRC and AUROC on all windows and on the still-now windows, the
    still-now windows' count, positives and chance level (:data:`STILL_HEADERS`); ``[]`` when no
    artefact holds still-now metrics (written before them) or none was given."""
    if artefacts is None:
        return []
    a = artefacts
    record = proxy_record(a)
    summary_rows = {f: baseline_motion_row(a, f) for f in FAMILY_ORDER}
    if not (record.get("test_still") or record.get(ORACLE)
            or any(S.has_motion(r) for r in summary_rows.values())):  # fmt: skip
        return []
    rows = []
    for f, row in summary_rows.items():
        rows.append([
            f"{family_label(f)} (baseline window, mean ± std over seeds)", REFERENCE_SCORERS[f],
            baseline_figure(a, f, "test", "auprc").text(),
            still_text(still_baseline_figure(a, f, "test", "auprc")),
            baseline_figure(a, f, "test", "auroc").text(),
            still_text(still_baseline_figure(a, f, "test", "auroc")),
            *S.summary_counts(row),
        ])  # fmt: skip
    for name, rec, all_auprc in (
        ("friction-ratio proxy", record, proxy_figure(a)),
        (f"{ORACLE_LABEL} (reads object motion: a reference line, not a monitor)",
         record.get(ORACLE) or {}, None),
    ):  # fmt: skip
        test, still = rec.get("test"), rec.get("test_still")
        key = "proxy" if rec is record else ORACLE
        rows.append([
            name, REFERENCE_SCORERS[key],
            (all_auprc or record_figure(test, "auprc")).text(),
            still_text(record_figure(still, "auprc", "test", "still")),
            record_figure(test, "auroc").text(),
            still_text(record_figure(still, "auroc", "test", "still")),
            *S.block_counts(still),
        ])  # fmt: skip
    return rows


def still_section(artefacts: StudyArtefacts | None) -> str:
    """The headline's prediction-not-detection table (:func:`still_rows`) with what each window
    set means; empty when no artefact holds still-now metrics."""
    rows = still_rows(artefacts)
    if not rows:
        return ""
    return (
        f"<p>{S.ALL_WINDOWS_TEXT} {S.STILL_NOW_TEXT} {S.ORACLE_TEXT} The reference reports all "
        "windows only.</p>"
        + H.table(STILL_HEADERS, rows, cls="text", caption=(
            "Prediction, not detection: this run's test AUPRC and AUROC on all windows and on "
            "the still-now windows (percent; AUROC's chance level is 50 %)"))
    )  # fmt: skip


def headline_section(scale: Mapping[str, Any], artefacts: StudyArtefacts | None) -> str:
    """The scale sentence, the table of this run's figures beside the reference's and the
    same scorers on all windows and on the still-now windows (:func:`still_section`)."""
    return f'<p class="note">{scale_sentence(scale)}</p>' + H.table(
        ["section", "figure", "this run", "reference (thesis)", "run - reference [points]"],
        headline_rows(artefacts),
        caption="Headline figures: this run beside the reference's published numbers "
        "(percent; 'undefined' gives the reason a value could not be computed)",
        cls="text",
    ) + still_section(artefacts)
