"""Early warning over the cross-validation folds: is a learned monitor ahead of the proxy on
unseen objects, at the same false-warning budget?

Each fold's monitors (its own models, and the friction-ratio proxy) get their threshold from the
fold's validation grasps (``monitor.early_warning.budget_threshold``), and are then scored on the
fold's test grasps (:func:`fold_rows`). Every object is a test object once, so pooling the folds'
test rows gives each monitor one figure over all objects (:func:`pooled_warning`): the share of
grasps failing after a still period that it warns at least ``ahead_s`` before the onset, and its
false warnings per stable grasp-second. Grasps of one object share its shape and mass, so the
intervals resample objects (a bootstrap over grasps clustered by object), and every monitor is
resampled with the same draw, which pairs the learned-minus-proxy differences.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np
import polars as pl

from graspstab.monitor.early_warning import ScoredGrasp, budget_threshold, grasp_outcomes

PROXY = "proxy"

ROW_SCHEMA = {
    "fold": pl.Int64, "monitor": pl.String, "object": pl.String, "grasp_id": pl.Int64,
    "failing": pl.Boolean, "after_still": pl.Boolean, "lead_s": pl.Float64,
    "warned_ahead": pl.Boolean, "false_warnings": pl.Int64, "stable_seconds": pl.Float64,
    "threshold": pl.Float64,
}  # fmt: skip


def fold_rows(scored: Mapping[str, Sequence[ScoredGrasp]], fold: int, *, budget_per_s: float,
              ahead_s: float, debounce: int,
              dt: float) -> tuple[pl.DataFrame, dict[str, Any]]:  # fmt: skip
    """One fold: each monitor's threshold from its validation grasps, and one row per (monitor,
    test grasp) at that threshold (:func:`~graspstab.monitor.early_warning.grasp_outcomes`)."""
    rows: list[dict[str, Any]] = []
    choices: dict[str, Any] = {}
    for name, grasps in scored.items():
        val = [g for g in grasps if g.split == "val"]
        test = [g for g in grasps if g.split == "test"]
        choice = budget_threshold(val, budget_per_s, debounce, dt)
        choices[name] = {**choice, "val_grasps": len(val), "test_grasps": len(test)}
        t = choice["threshold"]
        rows += [{"fold": fold, "monitor": name, **r, "threshold": t}
                 for r in grasp_outcomes(test, t, debounce, dt, ahead_s)]  # fmt: skip
    return pl.DataFrame(rows, schema=ROW_SCHEMA), choices


def _interval(draws: np.ndarray, level: float) -> tuple[float, float]:
    d = draws[np.isfinite(draws)]
    if not d.size:
        return math.nan, math.nan
    alpha = (1 - level) / 2
    lo, hi = np.quantile(d, [alpha, 1 - alpha])
    return float(lo), float(hi)


def _ratio(num: np.ndarray, den: np.ndarray) -> np.ndarray:
    with np.errstate(invalid="ignore", divide="ignore"):
        return np.where(den > 0, num / np.where(den > 0, den, 1), np.nan)


def pooled_warning(rows: pl.DataFrame, resamples: int, seed: int,
                   level: float = 0.95) -> dict[str, Any]:  # fmt: skip
    """Per monitor, every fold's test rows pooled: grasps, failing grasps, those failing after a
    still period, how many it warns ``ahead`` (share with its interval), the median lead of the
    warned ones, false warnings per stable grasp-second (with interval); and each other monitor
    minus the proxy in the warned-ahead share (paired: the same object draw for both)."""
    monitors = sorted(set(rows["monitor"].to_list()))
    objects = sorted(set(rows["object"].to_list()))
    index = {o: i for i, o in enumerate(objects)}
    # per (monitor, object) sums: the bootstrap resamples objects and adds these up
    cols = ("after", "ahead", "false", "seconds")
    sums = {c: np.zeros((len(monitors), len(objects))) for c in cols}
    out: dict[str, Any] = {"objects": len(objects), "monitors": {}}
    for m, name in enumerate(monitors):
        mine = rows.filter(pl.col("monitor") == name)
        for (obj,), g in mine.group_by(["object"]):
            j = index[obj]
            sums["after"][m, j] = int(g["after_still"].sum())
            sums["ahead"][m, j] = int(g["warned_ahead"].fill_null(False).sum())
            sums["false"][m, j] = int(g["false_warnings"].sum())
            sums["seconds"][m, j] = float(g["stable_seconds"].sum())
        leads = mine.filter(pl.col("after_still"))["lead_s"].drop_nulls().to_numpy()
        after, ahead = int(sums["after"][m].sum()), int(sums["ahead"][m].sum())
        out["monitors"][name] = {
            "folds": int(mine["fold"].n_unique()), "grasps": mine.height,
            "failing": int(mine["failing"].sum()), "failing_after_still": after,
            "warned_before_onset": int(leads.size), "warned_ahead": ahead,
            "warned_ahead_share": ahead / after if after else None,
            "median_lead_s": float(np.median(leads)) if leads.size else None,
            "false_warnings": int(sums["false"][m].sum()),
            "stable_seconds": float(sums["seconds"][m].sum()),
            "false_per_s": (float(sums["false"][m].sum() / sums["seconds"][m].sum())
                            if sums["seconds"][m].sum() > 0 else None),
        }  # fmt: skip
    rng = np.random.default_rng(seed)
    draw = rng.integers(0, len(objects), (resamples, len(objects))) if objects else None
    share = rate = None
    if draw is not None:
        pick = {c: sums[c][:, draw].sum(axis=-1) for c in cols}  # (monitors, resamples)
        share = _ratio(pick["ahead"], pick["after"])
        rate = _ratio(pick["false"], pick["seconds"])
    for m, name in enumerate(monitors):
        rec = out["monitors"][name]
        lo = hi = rlo = rhi = math.nan
        if share is not None and rate is not None:
            lo, hi = _interval(share[m], level)
            rlo, rhi = _interval(rate[m], level)
        rec.update({"warned_ahead_share_lo": lo, "warned_ahead_share_hi": hi,
                    "false_per_s_lo": rlo, "false_per_s_hi": rhi})  # fmt: skip
    out["paired"] = []
    if PROXY in monitors and share is not None:
        p = monitors.index(PROXY)
        base = out["monitors"][PROXY]["warned_ahead_share"]
        for m, name in enumerate(monitors):
            mine = out["monitors"][name]["warned_ahead_share"]
            if name == PROXY:
                continue
            lo, hi = _interval(share[m] - share[p], level)
            diff = mine - base if mine is not None and base is not None else None
            verdict = ("undefined" if diff is None or not math.isfinite(lo) else
                       "learned better" if lo > 0 else "proxy better" if hi < 0
                       else "not resolved")  # fmt: skip
            out["paired"].append({"monitor": name, "diff": diff, "lo": lo, "hi": hi,
                                  "verdict": verdict})  # fmt: skip
    out["bootstrap"] = {"resamples": resamples, "seed": seed, "level": level,
                        "unit": "object"}  # fmt: skip
    return out


def warning_answer(summary: Mapping[str, Any], protocol: str) -> str:
    """The one-sentence answer: at the budget, does a learned monitor warn ahead of more failing
    grasps than the proxy over every fold's unseen objects?"""
    mons = summary["monitors"]
    level = round(100 * summary["bootstrap"]["level"])
    budget, ahead = summary["budget_per_s"], summary["ahead_s"]
    after = max((m["failing_after_still"] for m in mons.values()), default=0)
    if not after:
        return (f"Under the {protocol} protocol no test grasp fails after a still period, so "
                "early warning is not measured.")
    def share(name: str) -> str:  # noqa: E306
        r = mons[name]
        s = r["warned_ahead_share"]
        return (f"{name} {r['warned_ahead']} of {r['failing_after_still']} "
                f"({100 * s:.0f} % [{100 * r['warned_ahead_share_lo']:.0f}, "
                f"{100 * r['warned_ahead_share_hi']:.0f}])")
    learned = [n for n in sorted(mons) if n != PROXY]
    verdicts = {r["verdict"] for r in summary["paired"]}
    if verdicts == {"learned better"}:
        head = "every learned monitor warns ahead of more failing grasps than the proxy"
    elif "learned better" in verdicts:
        better = [r["monitor"] for r in summary["paired"] if r["verdict"] == "learned better"]
        head = f"only {', '.join(better)} warn{'s' if len(better) == 1 else ''} ahead more often " \
               "than the proxy"
    elif "proxy better" in verdicts:
        head = "no learned monitor warns ahead more often than the proxy, and some less"
    else:
        head = "no learned monitor is distinguishable from the proxy"
    diffs = "; ".join(
        f"{r['monitor']} {100 * r['diff']:+.0f} points [{100 * r['lo']:+.0f}, {100 * r['hi']:+.0f}]"
        for r in summary["paired"] if r["diff"] is not None and math.isfinite(r["lo"])
    )  # fmt: skip
    return (
        f"Under the {protocol} protocol, over {summary['folds']} "
        f"fold{'s' if summary['folds'] != 1 else ''} of unseen objects at a "
        f"validation budget of one false warning per {1 / budget:.0f} stable grasp-seconds, "
        f"{head}: warned at least {1000 * ahead:.0f} ms before the onset, of the grasps failing "
        f"after a still period, " + ", ".join(share(n) for n in [*learned, PROXY] if n in mons)
        + (f"; learned minus proxy {diffs}" if diffs else "")
        + f" ({level} % intervals, bootstrap over objects)."
    )
