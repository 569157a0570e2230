"""The report's "Closed loop" section: per protocol, the answer, the policy table with bootstrap
intervals, the paired comparisons and every grasp a policy drops that no reflex holds, read from
graspstab.closedloop.summary.aggregate_closed_loop's files."""

from __future__ import annotations

import math
from collections.abc import Mapping
from pathlib import Path
from typing import Any

from graspstab.common.io import read_json, read_parquet
from graspstab.report import html as H

PROTOCOLS = {"reference": "reference protocol", "creep_free": "creep-free benchmark"}
POLICIES = {
    "none": "no reflex",
    "always": "tighten at arming (the force-hungry bound)",
    "oracle": "tighten before the no-reflex run's failure onset, one run per lead of "
              "closed_loop.oracle_leads_s (the horizon without leads): the best a warning that "
              "early can do",
    "load_onset": "tighten when the load starts (a perfect detector of the load, not of slip; "
                  "never under gravity alone)",
    "proxy": "the friction-ratio proxy as the monitor",
    "pick": "the latency-aware pick (4.5)",
    "cnn": "the CNN monitor",
    "gru": "the GRU monitor",
    "lstm": "the LSTM monitor",
}
WORSE_ROWS = 30  # grasps listed in the worse table; the count says how many there are


def _finite(v: Any) -> bool:
    return v is not None and math.isfinite(float(v))


def _pct(r: Mapping[str, Any], key: str) -> str:
    v, lo, hi = r[key], r[f"{key}_lo"], r[f"{key}_hi"]
    if not _finite(v):
        return "-"
    span = f" [{100 * lo:.1f}, {100 * hi:.1f}]" if _finite(lo) and _finite(hi) else ""
    return f"{100 * v:.1f}{span}"


def _num(r: Mapping[str, Any], key: str, fmt: str = "{:.2f}") -> str:
    v, lo, hi = r[key], r[f"{key}_lo"], r[f"{key}_hi"]
    if not _finite(v):
        return "-"
    span = f" [{fmt.format(lo)}, {fmt.format(hi)}]" if _finite(lo) and _finite(hi) else ""
    return fmt.format(v) + span


def _figures(protocol: str, name: str, files: Mapping[str, Any]) -> list[str]:
    out = []
    for key, what, caption in (
        ("tradeoff_figure", "trade-off",
         f"The reflex's trade-off ({name}): drops prevented against false alarms and against "
         "added normal force, one setting changed at a time; always and the oracle for scale; "
         "bars: bootstrap intervals over grasps."),
        ("timeline_figure", "timeline",
         f"One grasp with and without the reflex ({name}): total normal force, object speed, "
         "the reflex's target offset; the no-reflex onset, the first warning and the first "
         "tightened step marked."),
    ):  # fmt: skip
        if key in files:
            out.append(H.image(Path(files[key]), f"closed-loop {what}", caption,
                               f"closed-loop-{protocol}-{what}"))  # fmt: skip
    return out


def _setting(r: Mapping[str, Any]) -> str:
    return "default" if r["parameter"] == "default" else f"{r['parameter']} = {r['value']:g}"


def _tradeoff_parts(trade: Any, name: str, level: int) -> list[str]:
    if trade.is_empty():
        return []
    rows = [
        [r["base"], _setting(r), _pct(r, "prevented_share"), _pct(r, "false_alarm_rate"),
         _pct(r, "drop_rate"), _num(r, "added_normal_mean_n")]
        for r in trade.iter_rows(named=True)
    ]  # fmt: skip
    return [
        H.table(
            ["policy", "setting", "drops prevented (%)", "false alarms (%)", "drops (%)",
             "added normal force, mean [N]"],
            rows,
            caption=f"The sweep ({name}), one setting changed at a time; [{level} % CI]",
        )
    ]  # fmt: skip


def _protocol_parts(protocol: str, files: Mapping[str, Any], folds: bool = False) -> list[str]:
    summary = read_json(Path(files["summary"]))
    policies = read_parquet(Path(files["policies"]))
    pairs = read_parquet(Path(files["comparisons"]))
    worse = read_parquet(Path(files["worse"]))
    level = round(100 * summary["bootstrap"]["level"])
    name = PROTOCOLS.get(protocol, protocol)
    parts = [H.heading(3, f"closed-loop-folds-{protocol}", f"Closed loop over the folds: {name}")
             if folds else H.heading(3, f"closed-loop-{protocol}", f"Closed loop: {name}")]
    parts.append(f'<p class="answer"><strong>{H.esc(summary["answer"])}</strong></p>')
    if summary.get("thresholds"):  # a budget threshold at its grid's floor is said, never hidden
        cells = [f"{p} {t['threshold']:.3g}" + (" (at the grid floor: the budget did not bind)"
                                                 if t["at_floor"] else
                                                 " (above every validation score: never warns)"
                                                 if t.get("never_warns") else "")
                 for p, t in summary["thresholds"].items()]  # fmt: skip
        parts.append("<p>Thresholds (a monitor's own, from 3.5.3's recall rule; "
                     "<em>-budget</em>: the grasp-level evaluation's for its false-warning "
                     f"budget): {H.esc('; '.join(cells))}.</p>")
    rows = [
        [
            r["policy"],
            f"{r['drops']} ({_pct(r, 'drop_rate')})",
            f"{r['prevented']} of {r['baseline_drops']} ({_pct(r, 'prevented_share')})",
            r["worse"],
            f"{r['false_alarms']} ({_pct(r, 'false_alarm_rate')})",
            _num(r, "false_alarms_per_s", "{:.3f}") if "false_alarms_per_s" in r else "-",
            _num(r, "added_normal_mean_n"),
            _num(r, "added_normal_peak_n"),
            _num(r, "tightened_s"),
            _num(r, "lead_s", "{:.3f}"),
            _num(r, "latency_s", "{:.3f}"),
            _num(r, "slip_mm", "{:.1f}"),
        ]
        for r in policies.iter_rows(named=True)
    ]
    first = policies.row(0, named=True)
    parts.append(
        H.table(
            [
                "policy",
                "drops (% of grasps)",
                "drops prevented (% of no-reflex drops)",
                "worse than no reflex",
                "false alarms (% of holding grasps)",
                "false alarms per holding grasp-second after arming",
                "added normal force, mean [N]",
                "added normal force, peak [N]",
                "tightened [s]",
                "lead before onset [s]",
                "onset to tightened [s]",
                "slip onset to arrest [mm]",
            ],
            rows,
            caption=f"Policies on {first['grasps']} test grasps ({first['failing']} failing, "
            f"{first['baseline_drops']} dropped without a reflex), {name}; [{level} % CI], "
            "bootstrap over grasps; force, time and distance: means over the grasps where defined",
        )
    )
    prows = [
        [
            r["policy"],
            r["against"],
            r["figure"].replace("_", " "),
            f"{100 * r['diff']:+.1f} [{100 * r['lo']:+.1f}, {100 * r['hi']:+.1f}]"
            if _finite(r["lo"])
            else "-",
            r["verdict"],
        ]  # fmt: skip
        for r in pairs.iter_rows(named=True)
    ]
    parts.append(
        H.table(
            ["policy", "against", "figure", f"difference (points) [{level} % CI]", "verdict"],
            prows,
            caption=f"Paired comparisons over the same grasps ({name}; policy minus against)",
        )
    )
    parts += _figures(protocol, name, files)
    if "tradeoff" in files:
        parts += _tradeoff_parts(read_parquet(Path(files["tradeoff"])), name, level)
    total = worse.height
    listed = worse.head(WORSE_ROWS)
    parts.append(
        f"<p>{total} (grasp, policy) pairs where the policy drops a grasp that holds without a "
        f"reflex (tightening can push an object out)"
        + (f"; the first {WORSE_ROWS} are listed" if total > WORSE_ROWS else "")
        + ".</p>"
    )
    if total:
        parts.append(
            H.table(
                ["policy", "object", "grasp", "dropped at [s]", "tightened at [s]"],
                [
                    [
                        r["policy"],
                        r["object"],
                        r["grasp_id"],
                        f"{r['drop_s']:.2f}",
                        f"{r['tighten_s']:.2f}" if _finite(r["tighten_s"]) else "-",
                    ]
                    for r in listed.iter_rows(named=True)
                ],  # fmt: skip
                caption=f"Grasps a policy does worse on than no reflex ({name})",
            )
        )
    return parts


def closed_loop_section(closed_loop: Mapping[str, Any] | None, config: Mapping[str, Any]) -> str:
    """The section, one part per protocol; nothing when the closed loop is off (a run without
    it keeps the report it had)."""
    cl = config.get("closed_loop", {})
    folds = bool(cl.get("folds", {}).get("enabled"))
    if not closed_loop or not (cl.get("enabled") or folds):
        return ""
    parts = [H.heading(2, "closed-loop", "Closed loop: does a warning save the grasp?")]
    reflex = cl["reflex"]
    named = "; ".join(f"<em>{p}</em>: {POLICIES.get(p, p)}" for p in cl["policies"])
    parts.append(
        "<p>Every test grasp replayed once without a reflex and once per policy, on the same "
        "grasp, seed and load, with the grip reflex in the replay's loop: when the policy warns, "
        f"the closing joints' targets move {reflex['amount']} rad further in at "
        f"{reflex['rate']} rad/s, {reflex['delay_s']} s after the warning plus the monitor's "
        f"measured latency (release: {reflex['release']}). Monitors: each family's model at "
        f"{cl['window_s']} s with its validation-selected threshold, armed "
        + ("at the no-reflex run's settle index plus the window (the first window counted "
           "starts at settling, as every training window does)"
           if cl.get("arming", "fixed") == "settle" else f"{cl.get('arm_s', 0)} s after placement")
        + (", and a warning already up then counts only once it has dropped and risen again"
           if cl.get("fresh") else "")
        + f". Policies: {named}"
        + (". Each monitor also has a shuffled control (<em>&lt;monitor&gt;~shuffled</em>): its "
           "own tightening times after arming dealt to other grasps of the object, which is "
           "what its timing alone buys" if cl.get("shuffled") else "")
        + ". A drop is a contact-free run of at least labels.contact_loss_s; definitions in "
        "docs/extensions.md (Closed loop).</p>"
    )
    for protocol in cl["protocols"]:
        files = {
            k.removeprefix(f"{protocol}_"): v
            for k, v in closed_loop.items()
            if k.startswith(f"{protocol}_")
        }
        if "summary" in files and cl.get("enabled"):
            parts += _protocol_parts(protocol, files)
    for protocol in cl["protocols"] if folds else []:
        files = {k.removeprefix(f"folds_{protocol}_"): v for k, v in closed_loop.items()
                 if k.startswith(f"folds_{protocol}_")}  # fmt: skip
        if "summary" in files:
            parts.append(
                f"<p>Over the cross-validation folds: each object's first "
                f"{cl['folds']['grasps']} grasps under its own test fold's models, the proxy's "
                "threshold on that fold's validation windows and the budget thresholds chosen on "
                "its validation grasps; intervals resample whole objects.</p>")  # fmt: skip
            parts += _protocol_parts(protocol, files, folds=True)
    return "\n".join(parts)
