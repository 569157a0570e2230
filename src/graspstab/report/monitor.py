"""The report's grasp-level section: one warning per grasp from a streaming monitor (our extension;
the reference's 5.3 names the gap), per family and for the friction-ratio proxy, the lead-time
histogram, one replay's timeline, and the exported models."""

from __future__ import annotations

from collections.abc import Mapping
from pathlib import Path
from typing import Any

from graspstab.common.io import read_json
from graspstab.figures.presentation import UNDEFINED, family_label, finite
from graspstab.report import html as H

SPLITS = ("test", "val")
EXPORTS = ("baseline_cnn", "baseline_gru", "baseline_lstm", "pick")


def _pct(x: Any) -> str:
    return f"{100 * x:.1f} %" if finite(x) else UNDEFINED


def _num(x: Any, spec: str) -> str:
    return format(float(x), spec) if finite(x) else UNDEFINED


def _label(name: str) -> str:
    return "friction-ratio proxy" if name == "proxy" else family_label(name)


def monitor_rows(summary: Mapping[str, Any]) -> list[list[str]]:
    """One row per monitor and split: grasps, failing grasps, warned in time, median lead time,
    false warnings per stable grasp-second and the share of stable time under a warning."""
    rows = []
    for split in SPLITS:
        for name, info in summary["monitors"].items():
            s = info["splits"][split]
            rows.append([
                split, _label(name), _num(info["threshold"], ".3f"), s["grasps"],
                s["failing_grasps"],
                f"{s['warned_in_time']} ({_pct(s['in_time_share'])})",
                f"{s['warnable_failing_grasps']} ({_pct(s['in_time_share_warnable'])})",
                s["warned_late"], s["not_warned"], _num(s["median_lead_s"], ".2f"),
                s["stable_grasps"], _num(s["false_warnings_per_stable_s"], ".3f"),
                _pct(s["stable_warning_share"]),
            ])  # fmt: skip
    return rows


def export_rows(exports: Mapping[str, Mapping[str, Path]]) -> list[list[str]]:
    """One row per exported model: family, window, threshold and the files' sizes."""
    rows = []
    for name in EXPORTS:
        files = exports.get(name)
        if not files:
            continue
        c = read_json(files["constants"])
        sizes = ", ".join(f"{Path(files[k]).name} {Path(files[k]).stat().st_size / 1024:.0f} KiB"
                          for k in ("onnx", "torchscript"))  # fmt: skip
        rows.append([name, family_label(c["family"]), c["window_steps"],
                     _num(c["threshold"], ".3f"), sizes])  # fmt: skip
    return rows


TITLE = "Grasp-level warnings from a streaming monitor"


def early_warning_part(summary: Mapping[str, Any], what: str = "") -> list[str]:
    """The early-warning table at a false-warning budget (``monitor.early_warning``), when the
    summary has it."""
    ew = summary.get("early_warning")
    if not ew:
        return []
    rows = []
    for name, e in ew["monitors"].items():
        th, t = e["threshold"], e["test"]
        cut = _num(th["threshold"], ".4g") + (" (grid floor)" if th["at_floor"] else "") + (
            " (never warns)" if th["never_warns"] else "")
        rows.append([_label(name), cut, _num(th["false_per_s"], ".3f"),
                     t["failing_after_still"], t["warned_before_onset"], t["warned_ahead"],
                     _pct(t["warned_ahead_share"]), _num(t["median_lead_s"], ".3f"),
                     _num(t["false_per_s"], ".3f")])  # fmt: skip
    budget, ahead = ew["budget_per_s"], ew["ahead_s"]
    return [
        f"<p>{H.esc(what)}Early warning at a false-warning budget: each monitor's threshold is "
        "the lowest from which on the validation grasps that hold raise at most "
        f"{budget:g} false warnings per stable grasp-second (one per {1 / budget:g} s); at it, "
        "the test grasps whose failing motion begins after a still observation window (the "
        "failure anatomy's onset) are warned ahead when the first warning after the settle "
        f"index comes at least {1e3 * ahead:g} ms before the onset. A threshold at the grid "
        "floor means the budget did not bind.</p>",
        H.table(["monitor", "threshold", "val false warnings / stable s",
                 "test grasps failing after a still period", "warned before onset",
                 f"warned >= {1e3 * ahead:g} ms ahead", "share", "median lead [s]",
                 "test false warnings / stable s"], rows,
                caption=f"{what}Early warning at the false-warning budget (test split)"),
    ]  # fmt: skip


def onset_at_start(summary: Mapping[str, Any], split: str = "test") -> tuple[int, int]:
    """(failing grasps, of them those whose onset left no room for a warning in time) of a split:
    under a creeping contact model most grasps are "unstable" from their first settled frame."""
    s = next(iter(summary["monitors"].values()))["splits"][split]
    return s["failing_grasps"], s["failing_grasps"] - s["warnable_failing_grasps"]


def protocol_part(summary: Mapping[str, Any], leads: Path, timeline: Path, suffix: str = "",
                  what: str = "") -> list[str]:  # fmt: skip
    """One protocol's table, its room-for-a-warning sentence and both figures (anchors
    ``monitor-leads<suffix>``, ``monitor-timeline<suffix>``)."""
    tl = summary["timeline"]
    failing, no_room = onset_at_start(summary)
    return [
        H.table(
            ["split", "monitor", "threshold", "grasps", "failing", "warned in time",
             "warnable (in time)", "late", "not warned", "median lead [s]", "stable",
             "false warnings / stable s", "stable time under warning"],
            monitor_rows(summary),
            caption=f"{what}Per monitor and split. 'warnable': failing grasps whose onset came "
                    "at least the offset after the monitor's first possible warning.",
        ),  # fmt: skip
        f"<p>{H.esc(what)}{'of' if what else 'Of'} the {failing} failing test grasps, "
        f"{no_room} fail within the offset of the first frame a monitor can warn on (under a "
        "creeping contact model most at the settle index itself): no monitor can warn them in "
        "time, whatever it scores.</p>",
        *early_warning_part(summary, what),
        H.image(leads, "lead-time histogram",
                f"{what}Lead time (onset minus first warning) of the test split's failing grasps "
                "that were warned before their onset, per monitor.", f"monitor-leads{suffix}",
                f"Lead times{suffix and ' (ramp)'}"),  # fmt: skip
        H.image(timeline, "replay timeline",
                f"{what}One test replay as the {H.esc(tl['monitor'])} monitor sees it (chosen by "
                "rule: the failing grasp warned in time whose lead time is nearest the median): "
                "forces in, score and warning out, the onset in red.",
                f"monitor-timeline{suffix}", f"Replay timeline{suffix and ' (ramp)'}"),  # fmt: skip
    ]


def monitor_section(
    artefacts: Mapping[str, Any] | None, ramp: Mapping[str, Any] | None = None
) -> str:
    """The section "Grasp-level warnings" (anchor ``monitor``) from rule report's monitor_*
    inputs (prefix stripped): the summary, both figures and the exports; ``ramp``: the same of
    the creep-free benchmark (its ``monitor_summary`` etc.), set below. Without artefacts, a note
    (the anchors stay valid)."""
    if not artefacts:
        return "".join([
            H.heading(2, "monitor", TITLE),
            '<p class="note">No grasp-level evaluation was given to this report.</p>',
            H.missing_figure("monitor-leads", "Lead times", "No lead times."),
            H.missing_figure("monitor-timeline", "Replay timeline", "No timeline."),
        ])  # fmt: skip
    summary = read_json(artefacts["summary"])
    st = summary["settings"]
    exports: dict[str, dict[str, Path]] = {}
    for key, path in artefacts.items():
        if key.startswith("export_"):
            name, kind = key.removeprefix("export_").rsplit("_", 1)
            exports.setdefault(name, {})[kind] = Path(path)
    parts = [
        H.heading(2, "monitor", TITLE),
        "<p>The window metrics above score sampled windows; a controller needs one timely warning "
        "per grasp (the reference's 5.3 names this gap). Each family's first-seed sweep model at "
        f"the {st['window_s']:g} s window and the friction-ratio proxy read every validation and "
        f"test replay frame by frame, scoring every {st['stride']} frames "
        f"({1e3 * st['stride_s']:g} ms), with the model's validation-selected threshold (the "
        "proxy's chosen the same way on the same validation windows) and a debounce of "
        f"{st['debounce']} score(s). A grasp <em>fails</em> at the first step of its usable "
        f"interval that starts a run of eq. 23's u<sub>t</sub> = 1 lasting the horizon "
        f"({st['horizon_s']:g} s), or that ends in contact loss while moving; it is <em>warned in "
        f"time</em> when the first warning comes at least the offset ({st['offset_s']:g} s) "
        "ahead. False warnings count rising edges on grasps that never fail, per second of their "
        "checkable stretch. Validation replays chose the thresholds, so the test rows are the "
        "held-out figures.</p>",
        *protocol_part(summary, artefacts["leads_figure"], artefacts["timeline_figure"]),
    ]
    if ramp:
        parts += [
            H.heading(3, "monitor-ramp", "The same monitors under the creep-free load ramp"),
            "<p>The creep-free benchmark's models (its own sweep at the same window and seed) on "
            "its own replays of the same held-out grasps: strict contact model, rising load "
            '(section "Two protocols side by side").</p>',
            *protocol_part(read_json(ramp["monitor_summary"]), ramp["monitor_leads_figure"],
                           ramp["monitor_timeline_figure"], "-ramp", "Load ramp: "),  # fmt: skip
        ]
    rows = export_rows(exports)
    if rows:
        parts += [
            "<p>Exported for deployment (results/monitor/export/): raw forces "
            "(B, W, 5, 2) in newtons in, probability and logit out; normalisation inside the "
            "graph, constants embedded and beside in constants.json. Each file was loaded back "
            "and matched eager PyTorch before it was kept.</p>",
            H.table(["export", "family", "window [frames]", "threshold", "files"], rows),
        ]
    return "".join(parts)
