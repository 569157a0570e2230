"""The report's "Generalisation across objects" section: the object-level k-fold study of each
protocol (folds, pooled and per-object tables, the figure, the paired comparisons and the
one-sentence answers), read from graspstab.evaluation.studies.aggregate_crossval's files."""

from __future__ import annotations

import math
from collections.abc import Mapping
from pathlib import Path
from typing import Any

from graspstab.common.io import read_json, read_parquet
from graspstab.figures.presentation import ORACLE, ORACLE_LABEL, motion_reason
from graspstab.report import html as H
from graspstab.report import still_now as S
from graspstab.report.anatomy import missing_signal

PROTOCOLS = {"reference": "reference protocol", "creep_free": "creep-free load ramp"}
VARIANTS = {
    "ratio": "the proxy's ratio |f_t|/max(f_n, ratio_eps) per fingertip as a third input channel",
    "gain": "per-window normalisation by the window's mean total normal force (gain-invariant)",
    "best_f1": "the best-F1 threshold on validation instead of recall >= 0.9",
}


def _pct(v: Any, lo: Any = None, hi: Any = None) -> str:
    if v is None or not math.isfinite(float(v)):
        return "undefined"
    if lo is None or hi is None or not math.isfinite(float(lo)):
        return f"{100 * v:.1f}"
    return f"{100 * v:.1f} [{100 * lo:.1f}, {100 * hi:.1f}]"


def _pts(v: Any, lo: Any, hi: Any) -> str:
    if v is None or not math.isfinite(float(v)):
        return "undefined"
    return f"{100 * v:+.1f} [{100 * lo:+.1f}, {100 * hi:+.1f}]"


def _protocol_parts(
    protocol: str, files: Mapping[str, Any], config: Mapping[str, Any]
) -> list[str]:
    summary = read_json(Path(files["summary"]))
    per_object = read_parquet(Path(files["per_object"]))
    level = round(100 * summary["bootstrap"]["level"])
    name = PROTOCOLS.get(protocol, protocol)
    parts = [H.heading(3, f"crossval-{protocol}", f"Cross-validation: {name}")]
    parts.append(f'<p class="answer"><strong>{H.esc(summary["answer"])}</strong></p>')
    if "pooled_still" in summary:  # the same question on the still-now windows
        parts.append(f'<p class="answer"><strong>{H.esc(still_answer(summary, protocol))}'
                     "</strong></p>")  # fmt: skip
    pooled = summary["pooled"]
    folds = summary["fold_mean"]
    rows = []
    for scorer in summary["scorers"]:
        p, f = pooled[scorer], folds.get(scorer, {})
        rows.append(
            [
                scorer,
                p["windows"],
                p["unstable"],
                p["grasps"],
                _pct(p["auprc"], p["auprc_lo"], p["auprc_hi"]),
                _pct(p["auroc"], p["auroc_lo"], p["auroc_hi"]),
                f"{100 * f.get('auprc', math.nan):.1f} ± {100 * f.get('auprc_std', math.nan):.1f}",
            ]
        )
    oracle = summary.get("oracle")
    if oracle:  # pooled over all windows; scored once, so no fold mean
        rows.append(
            [
                f"{ORACLE_LABEL} (reads object motion: a reference line)",
                oracle["windows"],
                oracle["unstable"],
                oracle["grasps"],
                _pct(oracle["auprc"], oracle["auprc_lo"], oracle["auprc_hi"]),
                _pct(oracle["auroc"], oracle["auroc_lo"], oracle["auroc_hi"]),
                "—",
            ]
        )
    parts.append(
        H.table(
            [
                "scorer",
                "test windows",
                "unstable",
                "grasps",
                f"pooled AUPRC (%) [{level} % CI]",
                f"pooled AUROC (%) [{level} % CI]",
                "AUPRC over folds (%), mean ± std",
            ],
            rows,
            caption=f"Pooled test metrics, {summary['folds']} folds ({name})",
        )
    )
    parts.append(
        _paired_table(
            summary["paired"],
            level,
            f"Paired comparison with the friction-ratio proxy over test objects ({name})",
        )
    )
    scorers = summary["scorers"]
    wide = per_object.pivot(on="scorer", index="object", values="auprc")
    meta = per_object.unique("object").select(
        "object", "mass", "size", "shape", "windows", "unstable", "grasps"
    )
    table = meta.join(wide, on="object").sort("object")
    orows = [
        [
            r["object"],
            f"{r['mass']:.3g}",
            f"{100 * r['size']:.1f}" if r["size"] else "",
            r["shape"],
            r["windows"],
            r["unstable"],
            r["grasps"],
            *[_pct(r.get(s)) for s in scorers],
        ]
        for r in table.iter_rows(named=True)
    ]
    ci = {(r["scorer"], r["object"]): r for r in per_object.iter_rows(named=True)}
    for row, r in zip(orows, table.iter_rows(named=True), strict=True):
        for j, s in enumerate(scorers):
            c = ci.get((s, r["object"]))
            if c is not None:
                row[7 + j] = _pct(c["auprc"], c["auprc_lo"], c["auprc_hi"])
    parts.append(
        H.table(
            [
                "object",
                "mass (kg)",
                "size (cm)",
                "shape",
                "windows",
                "unstable",
                "grasps",
                *[f"{s} AUPRC (%)" for s in scorers],
            ],
            orows,
            caption=f"Per-object test AUPRC with {level} % grasp-bootstrap intervals ({name})",
        )
    )
    if summary["untested_objects"]:
        parts.append(
            "<p>Objects with no labelled window (the hand holds none of their grasps long enough "
            "for a window, so they have no test turn that can be scored): "
            + H.esc(", ".join(summary["untested_objects"]))
            + ".</p>"
        )
    parts.append(
        H.image(
            Path(files["figure"]),
            f"per-object AUPRC, {name}",
            f"Per-object test AUPRC against mass, size and shape class, and the "
            f"paired differences ({name}).",
            f"crossval-figure-{protocol}",
        )
    )
    if "pooled_still" in summary:
        parts += _still_parts(protocol, summary, files, level, name)
    if files.get("early_warning") is not None:
        parts += _warning_parts(read_json(Path(files["early_warning"])), name)
    if "answer_variants" in summary and any("+" in s for s in scorers):
        parts.append(f"<p>With the fairness variants: {H.esc(summary['answer_variants'])}</p>")
    if summary.get("variants"):
        parts.append(_variant_table(summary, level, name))
    if summary.get("thresholds"):
        parts.append(_threshold_table(summary, name))
    return parts


def _comparison_cells(r: Mapping[str, Any]) -> list[Any]:
    """A paired comparison's objects, difference with interval, wins/losses/ties, sign-test p
    and verdict, as table cells."""
    p = r["sign_p"]
    return [
        r["objects"],
        _pts(r["mean_diff"], r["lo"], r["hi"]),
        f"{r['wins']} / {r['losses']} / {r['ties']}",
        "undefined" if p is None or not math.isfinite(p) else f"{p:.3g}",
        r["verdict"],
    ]


def _paired_table(rows: Any, level: int, caption: str) -> str:
    """Learned minus proxy per scorer and metric, paired over test objects."""
    prows = [
        [
            r["scorer"],
            r["metric"].upper(),
            *_comparison_cells(r),
        ]
        for r in rows
    ]
    return H.table(
        [
            "learned scorer",
            "metric",
            "objects",
            f"learned - proxy (points) [{level} % CI]",
            "wins / losses / ties",
            "sign test p",
            "verdict",
        ],
        prows,
        caption=caption,
    )


def _still_metric(row: Mapping[str, Any], metric: str) -> str:
    """A pooled still-now metric with its interval, or 'undefined: <reason>'."""
    v = row.get(metric)
    if v is None or not math.isfinite(float(v)):
        return S.undefined(motion_reason(row.get("windows"), row.get("unstable")))
    return _pct(v, row.get(f"{metric}_lo"), row.get(f"{metric}_hi"))


def still_answer(summary: Mapping[str, Any], protocol: str) -> str:
    """The one-sentence answer on the still-now windows: the summary's ``answer_still`` when the
    job wrote one, else put together from its ``paired_still`` rows (test AUPRC, the plain
    families), as the all-windows ``answer`` is from ``paired``."""
    if summary.get("answer_still"):
        return str(summary["answer_still"])
    level = round(100 * summary["bootstrap"]["level"])
    name = protocol.replace("_", "-")
    rows = [r for r in summary.get("paired_still", [])
            if r["metric"] == "auprc" and "+" not in r["scorer"]]  # fmt: skip
    if not rows:
        return (f"Under the {name} protocol no learned model was compared with the proxy on "
                "still-now windows.")
    defined = [r for r in rows if r["verdict"] != "undefined"]
    if not defined:
        proxy = summary.get("pooled_still", {}).get("proxy", {})
        why = motion_reason(proxy.get("windows"), proxy.get("unstable"))
        return (f"Under the {name} protocol the comparison on still-now test windows is "
                f"undefined: {why} (no object has a defined still-now test AUPRC for both).")
    verdicts = {r["verdict"] for r in defined}
    if verdicts == {"learned better"} and len(defined) == len(rows):
        head = "every learned model beats the friction-ratio proxy"
    elif verdicts == {"proxy better"} and len(defined) == len(rows):
        head = "the friction-ratio proxy beats every learned model"
    elif "learned better" in verdicts:
        better = [r["scorer"] for r in defined if r["verdict"] == "learned better"]
        head = f"only {', '.join(better)} beat{'s' if len(better) == 1 else ''} the proxy"
    elif "proxy better" in verdicts:
        head = "no learned model beats the proxy, and some do worse"
    else:
        head = "no learned model is distinguishable from the proxy"
    parts = [
        f"{r['scorer']} {100 * r['mean_diff']:+.1f} points [{100 * r['lo']:+.1f}, "
        f"{100 * r['hi']:+.1f}] over {r['objects']} objects" if r["verdict"] != "undefined"
        else f"{r['scorer']} undefined (no object has a defined still-now AUPRC for both)"
        for r in rows
    ]  # fmt: skip
    return (
        f"Under the {name} protocol, on the still-now test windows of unseen objects (early "
        f"warning proper) {head} (test AUPRC, learned minus proxy, mean over objects, {level} % "
        "paired-bootstrap interval: " + "; ".join(parts) + ")."
    )


def _still_parts(
    protocol: str, summary: Mapping[str, Any], files: Mapping[str, Any], level: int, name: str
) -> list[str]:
    """The still-now part of a protocol: the answer on still-now windows, the pooled still-now
    table with the persistence oracle, the paired comparison and (when given) the per-object
    still-now AUPRC."""
    pooled = summary["pooled_still"]
    order = [s for s in summary["scorers"] if s in pooled]
    order += [s for s in pooled if s not in order and s != ORACLE]
    order += [ORACLE] if ORACLE in pooled else []
    rows = [
        [
            f"{ORACLE_LABEL} (reads object motion: a reference line)" if s == ORACLE else s,
            pooled[s].get("windows"),
            pooled[s].get("unstable"),
            pooled[s].get("grasps"),
            S.percent(pooled[s].get("chance"), sign=False, digits=1)
            or S.undefined(motion_reason(pooled[s].get("windows"), None)),
            _still_metric(pooled[s], "auprc"),
            _still_metric(pooled[s], "auroc"),
        ]
        for s in order
    ]
    parts = [
        f'<h4 id="crossval-still-{H.esc(protocol)}">Still now: early warning proper ({name})</h4>',
        f"<p>{S.ALL_WINDOWS_TEXT} {S.STILL_NOW_TEXT} {S.ORACLE_TEXT} The second answer above "
        "is this comparison's.</p>",
        H.table(
            [
                "scorer",
                "still-now test windows",
                "unstable",
                "grasps",
                "chance AUPRC (%)",
                f"pooled AUPRC (%) [{level} % CI]",
                f"pooled AUROC (%) [{level} % CI]",
            ],
            rows,
            caption=f"Pooled test metrics on the still-now windows, {summary['folds']} folds "
            f"({name})",
        ),
    ]
    if summary.get("paired_still"):
        parts.append(
            _paired_table(
                summary["paired_still"],
                level,
                "Paired comparison with the friction-ratio proxy over test objects, on the "
                f"still-now windows ({name})",
            )
        )
    if summary.get("paired_still_oracle"):
        parts.append(_oracle_table(summary["paired_still_oracle"], level, name))
    if files.get("per_object_still") is not None:
        parts.append(_per_object_still(read_parquet(Path(files["per_object_still"])), level,
                                       name))  # fmt: skip
    return parts


def _oracle_table(rows: Any, level: int, name: str) -> str:
    """Each scorer minus the persistence oracle on the still-now windows, paired over objects:
    how much of what motion itself tells a scorer does not reach."""
    named = {"learned better": "scorer better", "proxy better": "oracle better"}
    prows = [[r["scorer"], r["metric"].upper(), *_comparison_cells(r)[:-1],
              named.get(r["verdict"], r["verdict"])] for r in rows]  # fmt: skip
    return H.table(
        ["scorer", "metric", "objects", f"scorer - oracle (points) [{level} % CI]",
         "wins / losses / ties", "sign test p", "verdict"],
        prows,
        caption=f"Paired comparison with the {ORACLE_LABEL} over test objects, on the still-now "
        f"windows ({name}): the oracle reads the object's own motion, so a scorer below it "
        "misses what the motion would tell",
    )  # fmt: skip


def _warning_parts(summary: Mapping[str, Any], name: str) -> list[str]:
    """Grasp-level early warning over the folds (graspstab.monitor.fold_warning): each fold's
    monitors at its validation budget threshold, every object's test grasps pooled."""
    level = round(100 * summary["bootstrap"]["level"])
    mons = summary["monitors"]
    paired = {r["monitor"]: r for r in summary.get("paired", [])}
    k = summary["folds"]
    rows = []
    for m in [*sorted(n for n in mons if n != "proxy"), *(["proxy"] if "proxy" in mons else [])]:
        r, t = mons[m], summary["thresholds"].get(m, {})
        p = paired.get(m)
        share = r["warned_ahead_share"]
        rows.append([
            m, f"{t.get('at_floor', 0)} / {t.get('never_warns', 0)} of {k}", r["grasps"],
            r["failing"], r["failing_after_still"], r["warned_ahead"],
            "undefined" if share is None else _pct(share, r["warned_ahead_share_lo"],
                                                    r["warned_ahead_share_hi"]),
            "—" if r["median_lead_s"] is None else f"{1000 * r['median_lead_s']:.0f}",
            "undefined" if r["false_per_s"] is None else
            f"{r['false_per_s']:.3f} [{r['false_per_s_lo']:.3f}, {r['false_per_s_hi']:.3f}]",
            "—" if p is None or p["diff"] is None else
            f"{_pts(p['diff'], p['lo'], p['hi'])} ({p['verdict']})",
        ])  # fmt: skip
    budget, ahead = summary["budget_per_s"], summary["ahead_s"]
    return [
        f'<h4 id="crossval-warning-{H.esc(summary["protocol"])}">Early warning over the folds '
        f"({name})</h4>",
        f'<p class="answer"><strong>{H.esc(summary["answer"])}</strong></p>',
        "<p>Each fold's monitors (its own plain-forces models, streamed as deployed, and the "
        "friction-ratio proxy) take the lowest threshold whose false warnings on the fold's "
        f"validation grasps that hold stay within {budget:g} per stable grasp-second (one per "
        f"{1 / budget:.0f} s), and run at it on the fold's test grasps, armed at the settle "
        "index. A grasp fails after a still period when the failure anatomy's onset follows at "
        "least one observation window without an eq. 23 step: only those can be foreseen. "
        f"Warned ahead: the first warning at least {1000 * ahead:.0f} ms before the onset. "
        f"Intervals: {level} % bootstrap over objects (every monitor on the same draw, so the "
        "differences are paired).</p>",
        H.table(
            ["monitor", "threshold at grid floor / never warns (folds)", "test grasps", "failing",
             "failing after a still period", "warned ahead", f"share warned ahead (%) [{level} % "
             "CI]", "median lead of the warned (ms)",
             f"false warnings per stable s, test [{level} % CI]",
             f"minus proxy, share (points) [{level} % CI]"],
            rows,
            caption=f"Grasp-level early warning, {k} fold{'s' if k != 1 else ''}, every "
            f"object's test grasps ({name})",
        ),  # fmt: skip
    ]


def _per_object_still(per_object: Any, level: int, name: str) -> str:
    """Per-object test AUPRC on the still-now windows (per_object_still.parquet)."""
    scorers = sorted(set(per_object["scorer"].to_list()))
    by = {(r["scorer"], r["object"]): r for r in per_object.iter_rows(named=True)}
    objects = sorted(set(per_object["object"].to_list()))
    rows = []
    for o in objects:
        first = next(by[(s, o)] for s in scorers if (s, o) in by)
        rows.append([o, first["windows"], first["unstable"],
                     *[_still_metric(by[(s, o)], "auprc") if (s, o) in by else "—"
                       for s in scorers]])  # fmt: skip
    return H.table(
        ["object", "still-now windows", "unstable", *[f"{s} AUPRC (%)" for s in scorers]],
        rows,
        caption=f"Per-object test AUPRC on the still-now windows with {level} % grasp-bootstrap "
        f"intervals ({name})",
    )


def _variant_table(summary: Mapping[str, Any], level: int, name: str) -> str:
    rows = [
        [
            r["scorer"],
            r["against"],
            r["metric"].upper(),
            *_comparison_cells(r),
        ]
        for r in summary["variants"]
    ]
    return H.table(
        [
            "variant",
            "against",
            "metric",
            "objects",
            f"variant - plain (points) [{level} % CI]",
            "wins / losses / ties",
            "sign test p",
            "verdict",
        ],
        rows,
        caption=f"What each fairness variant changes, paired over test objects ({name})",
    )


def _threshold_table(summary: Mapping[str, Any], name: str) -> str:
    rows = [
        [
            r["scorer"],
            r["rule"],
            r["runs"],
            f"{r['threshold_median']:.3f} [{r['threshold_min']:.3f}, {r['threshold_max']:.3f}]",
            r["at_floor"],
            _pct(r["precision"]),
            _pct(r["recall"]),
            _pct(r["f1"]),
            _pct(r["fpr"]),
        ]
        for r in summary["thresholds"]
    ]
    return H.table(
        [
            "learned scorer",
            "threshold rule",
            "fold runs",
            "threshold, median [min, max]",
            "at the grid's floor",
            "precision (%)",
            "recall (%)",
            "F1 (%)",
            "false-positive rate (%)",
        ],
        rows,
        caption=(
            f"Test windows at each fold's own validation threshold, pooled over folds ({name}); "
            "AUPRC and AUROC do not see the threshold, so this is what a threshold rule changes"
        ),
    )


def crossval_section(crossval: Mapping[str, Any] | None, config: Mapping[str, Any],
                     anatomy: Mapping[str, Path] | None = None) -> str:  # fmt: skip
    """The section, one part per protocol; a note when the study is off. ``anatomy``: the
    failure anatomy's summaries (``<protocol>_summary``), which say what the signal misses where
    the learned models do not beat the proxy on still-now windows or in early warning."""
    parts = [H.heading(2, "crossval", "Generalisation across objects")]
    cv = config.get("crossval", {})
    if not crossval or not cv.get("enabled"):
        parts.append(
            '<p class="note">This run has no cross-validation (crossval.enabled is '
            "false; the wide profile runs it: --config profile=wide).</p>"
        )
        return "\n".join(parts)
    variants = "; ".join(f"<em>{v}</em>: {VARIANTS[v]}" for v in cv["variants"])
    parts.append(
        f"<p>Object-level {cv['k']}-fold cross-validation over {len(config['objects']['items'])} "
        f"objects: every object is a test object in exactly one fold, the next fold validates "
        "(thresholds, early stopping) and the rest train (normalisation). Models: the reference's "
        f"sweep configurations (3.4.3, no tuning, which would choose on other folds' test objects) "
        f"at {cv['window_s']} s, seeds {cv['seeds']}. Per-object intervals resample grasps; the "
        "paired comparison resamples objects (paired bootstrap of the mean per-object difference "
        "in test AUPRC, learned minus proxy), with a two-sided sign test over objects beside it. "
        "The friction-ratio proxy needs no training and scores every window once. "
        + (
            f"Fairness variants ({', '.join(cv['variant_families'])}): {variants}."
            if variants
            else ""
        )
        + "</p>"
    )
    for protocol in cv["protocols"]:
        files = {
            k.removeprefix(f"{protocol}_"): v
            for k, v in crossval.items()
            if k.startswith(f"{protocol}_")
        }
        if "summary" in files:
            parts += _protocol_parts(protocol, files, config)
            summary = (anatomy or {}).get(f"{protocol}_summary")
            if summary is not None and not _learned_wins(files):
                text = missing_signal(read_json(Path(summary)))
                if text:
                    parts.append(f"<p>{H.esc(text)}</p>")
    return "\n".join(parts)


def _learned_wins(files: Mapping[str, Any]) -> bool:
    """Whether every plain family beats the proxy on still-now windows (paired, test AUPRC) and,
    where it ran, in early warning over the folds."""
    summary = read_json(Path(files["summary"]))
    still = [r for r in summary.get("paired_still", [])
             if r["metric"] == "auprc" and "+" not in r["scorer"]]  # fmt: skip
    wins = bool(still) and all(r["verdict"] == "learned better" for r in still)
    if files.get("early_warning") is not None:
        paired = read_json(Path(files["early_warning"])).get("paired", [])
        wins = wins and bool(paired) and all(r["verdict"] == "learned better" for r in paired)
    return wins
