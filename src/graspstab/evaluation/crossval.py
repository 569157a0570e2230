"""Cross-validation statistics (our extension): per-object and pooled test metrics with grasp
bootstrap intervals, and paired learned-against-proxy comparisons over objects.

Every scorer (a learned family under one variant, or the friction-ratio proxy) gives each window a
score once, in the fold where its object is a test object. Intervals resample *grasps* (all of a
grasp's windows together, since windows of one replay are not independent, 3.5.1); the paired
comparison resamples *objects* (the unit the question is about: unseen objects), and a sign test
over objects is reported beside it.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np
import polars as pl
from scipy.stats import binomtest, rankdata

PROXY = "proxy"


def average_precision(scores: np.ndarray, labels: np.ndarray) -> float:
    """Average precision as scikit-learn's average_precision_score (step-wise, tied scores one
    threshold); NaN without both classes. Vectorised, for bootstrap loops."""
    y = np.asarray(labels, dtype=bool)
    pos = int(y.sum())
    if pos == 0 or pos == y.size:
        return math.nan
    order = np.argsort(-np.asarray(scores, dtype=np.float64), kind="mergesort")
    s, y = np.asarray(scores, dtype=np.float64)[order], y[order]
    last = np.r_[np.flatnonzero(np.diff(s)), s.size - 1]  # the last index of each tied block
    tp = np.cumsum(y)[last]
    fp = (last + 1) - tp
    precision = tp / (tp + fp)
    recall = tp / pos
    return float(np.sum(np.diff(np.r_[0.0, recall]) * precision))


def roc_auc(scores: np.ndarray, labels: np.ndarray) -> float:
    """Area under the ROC curve by the rank-sum (Mann-Whitney) identity, ties counted half; NaN
    without both classes."""
    y = np.asarray(labels, dtype=bool)
    pos, neg = int(y.sum()), int((~y).sum())
    if pos == 0 or neg == 0:
        return math.nan
    ranks = rankdata(np.asarray(scores, dtype=np.float64))
    return float((ranks[y].sum() - pos * (pos + 1) / 2) / (pos * neg))


METRICS = {"auprc": average_precision, "auroc": roc_auc}


def _group_rows(groups: np.ndarray) -> list[np.ndarray]:
    """Row numbers of each group (grasp), in first-appearance order."""
    _, inverse = np.unique(groups, return_inverse=True)
    order = np.argsort(inverse, kind="stable")
    bounds = np.flatnonzero(np.diff(inverse[order])) + 1
    return np.split(order, bounds)


def grasp_bootstrap(
    scores: np.ndarray,
    labels: np.ndarray,
    grasps: np.ndarray,
    resamples: int,
    rng: np.random.Generator,
    level: float = 0.95,
) -> dict[str, float]:
    """Each metric on the windows, and its percentile interval over ``resamples`` resamplings of
    the grasps with replacement (a resample with one class only is left out; ``*_valid`` counts
    the rest). ``scores`` may be (seeds, N): the metric is then the mean over seeds per resample."""
    s = np.atleast_2d(np.asarray(scores, dtype=np.float64))
    y = np.asarray(labels)
    out: dict[str, float] = {}
    for name, fn in METRICS.items():
        out[name] = float(np.mean([fn(row, y) for row in s]))
    parts = _group_rows(np.asarray(grasps))
    alpha = (1 - level) / 2
    draws: dict[str, list[float]] = {name: [] for name in METRICS}
    for _ in range(resamples):
        pick = np.concatenate([parts[i] for i in rng.integers(0, len(parts), len(parts))])
        yy = y[pick]
        if yy.min() == yy.max():
            continue
        for name, fn in METRICS.items():
            draws[name].append(float(np.mean([fn(row[pick], yy) for row in s])))
    for name in METRICS:
        d = np.asarray(draws[name])
        lo, hi = np.quantile(d, [alpha, 1 - alpha]) if d.size else (math.nan, math.nan)
        out[f"{name}_lo"], out[f"{name}_hi"] = float(lo), float(hi)
        out[f"{name}_valid"] = int(d.size)
    return out


def paired_comparison(
    learned: Mapping[str, float],
    proxy: Mapping[str, float],
    resamples: int,
    rng: np.random.Generator,
    level: float = 0.95,
) -> dict[str, Any]:
    """Learned minus proxy over the objects where both are defined: mean difference, its paired
    bootstrap interval (objects resampled with replacement), wins and losses, and a two-sided sign
    test (ties dropped). ``learned`` and ``proxy`` map object -> metric."""
    objs = sorted(
        o for o in learned if o in proxy and np.isfinite(learned[o]) and np.isfinite(proxy[o])
    )
    d = np.array([learned[o] - proxy[o] for o in objs], dtype=np.float64)
    if d.size == 0:
        return {
            "objects": 0,
            "mean_diff": math.nan,
            "lo": math.nan,
            "hi": math.nan,
            "wins": 0,
            "losses": 0,
            "ties": 0,
            "sign_p": math.nan,
            "verdict": "undefined",
        }
    means = d[rng.integers(0, d.size, (resamples, d.size))].mean(axis=1)
    alpha = (1 - level) / 2
    lo, hi = np.quantile(means, [alpha, 1 - alpha])
    wins, losses = int((d > 0).sum()), int((d < 0).sum())
    sign_p = float(binomtest(wins, wins + losses, 0.5).pvalue) if wins + losses else math.nan
    verdict = "learned better" if lo > 0 else "proxy better" if hi < 0 else "not resolved"
    return {
        "objects": int(d.size),
        "mean_diff": float(d.mean()),
        "lo": float(lo),
        "hi": float(hi),
        "wins": wins,
        "losses": losses,
        "ties": int(d.size - wins - losses),
        "sign_p": sign_p,
        "verdict": verdict,
    }


def per_object_table(
    scored: pl.DataFrame, resamples: int, seed: int, level: float = 0.95
) -> pl.DataFrame:
    """Per (scorer, object): windows, unstable share, grasps and the bootstrap metrics.

    ``scored`` holds one row per (scorer, seed, window): scorer, seed, sample_id, object, grasp
    (a grasp key unique within the object), label, score."""
    rows = []
    for (scorer, obj), g in scored.group_by(["scorer", "object"], maintain_order=True):
        rows.append({"scorer": scorer, "object": obj, **_scored_stats(g, resamples, seed, level)})
    return pl.DataFrame(rows).sort(["scorer", "object"])


def pooled_table(
    scored: pl.DataFrame, resamples: int, seed: int, level: float = 0.95
) -> pl.DataFrame:
    """Per scorer: the metrics of every object's test windows pooled (each object scored in its
    own fold), with a grasp bootstrap interval."""
    rows = []
    for (scorer,), g in scored.group_by(["scorer"], maintain_order=True):
        rows.append({"scorer": scorer, **_scored_stats(g, resamples, seed, level)})
    return pl.DataFrame(rows).sort("scorer")


def _scored_stats(g: pl.DataFrame, resamples: int, seed: int, level: float) -> dict[str, Any]:
    seeds = sorted(g["seed"].unique().to_list())
    first = g.filter(pl.col("seed") == seeds[0]).sort(["object", "sample_id"])
    mats = np.stack(
        [
            g.filter(pl.col("seed") == s).sort(["object", "sample_id"])["score"].to_numpy()
            for s in seeds
        ]
    )
    labels = first["label"].to_numpy()
    grasps = (first["object"] + "/" + first["grasp"].cast(pl.String)).to_numpy()
    rng = np.random.default_rng(seed)
    stats = grasp_bootstrap(mats, labels, grasps, resamples, rng, level)
    return {
        "windows": int(labels.size),
        "unstable": int(labels.sum()),
        "grasps": int(np.unique(grasps).size),
        "seeds": len(seeds),
        **stats,
    }


def paired_table(
    per_object: pl.DataFrame,
    resamples: int,
    seed: int,
    level: float = 0.95,
    proxy: str = PROXY,
) -> pl.DataFrame:
    """Every learned scorer against the proxy, per metric (:func:`paired_comparison`)."""
    rng = np.random.default_rng(seed)
    base = per_object.filter(pl.col("scorer") == proxy)
    rows = []
    for scorer in sorted(set(per_object["scorer"].to_list()) - {proxy}):
        mine = per_object.filter(pl.col("scorer") == scorer)
        for metric in METRICS:
            rows.append(
                {
                    "scorer": scorer,
                    "metric": metric,
                    **paired_comparison(
                        dict(zip(mine["object"], mine[metric], strict=True)),
                        dict(zip(base["object"], base[metric], strict=True)),
                        resamples,
                        rng,
                        level,
                    ),
                }
            )
    return pl.DataFrame(rows)


def variant_table(
    per_object: pl.DataFrame, resamples: int, seed: int, level: float = 0.95
) -> pl.DataFrame:
    """What each fairness variant changes: every ``family+variant`` scorer against its plain
    family, per metric, paired over objects as :func:`paired_comparison` (verdicts renamed
    "variant better" / "plain better")."""
    rng = np.random.default_rng(seed)
    rename = {"learned better": "variant better", "proxy better": "plain better"}
    rows = []
    for scorer in sorted(s for s in set(per_object["scorer"].to_list()) if "+" in s):
        family = scorer.split("+", 1)[0]
        mine = per_object.filter(pl.col("scorer") == scorer)
        base = per_object.filter(pl.col("scorer") == family)
        if base.is_empty():
            continue
        for metric in METRICS:
            row = paired_comparison(
                dict(zip(mine["object"], mine[metric], strict=True)),
                dict(zip(base["object"], base[metric], strict=True)),
                resamples,
                rng,
                level,
            )
            row["verdict"] = rename.get(row["verdict"], row["verdict"])
            rows.append({"scorer": scorer, "against": family, "metric": metric, **row})
    return pl.DataFrame(rows)


def threshold_counts(probs: np.ndarray, labels: np.ndarray, threshold: float) -> np.ndarray:
    """(tp, fp, fn, tn) of the alarm ``probs >= threshold`` against ``labels``."""
    pred, pos = np.asarray(probs) >= threshold, np.asarray(labels) == 1
    return np.array(
        [np.sum(pred & pos), np.sum(pred & ~pos), np.sum(~pred & pos), np.sum(~pred & ~pos)],
        dtype=np.int64,
    )


def threshold_table(runs: Sequence[Mapping[str, Any]]) -> pl.DataFrame:
    """Per learned scorer, the test windows at each fold's own validation threshold, pooled over
    folds and seeds: precision, recall, F1, false-positive rate, the thresholds chosen and how
    many sit on the grid's floor (where a recall rule that cannot be met ends up). AUPRC and AUROC
    do not see the threshold, so this is what a threshold rule changes.

    ``runs``: dicts with family, variant, ``predictions`` (split, label, prob) and ``metrics``
    (the run's metrics.json: ``threshold.threshold`` and ``params.train.threshold``)."""
    total: dict[str, np.ndarray] = {}
    chosen: dict[str, list[float]] = {}
    floor: dict[str, int] = {}
    rules: dict[str, set[str]] = {}
    for r in runs:
        name = scorer_name(r["family"], r["variant"])
        rule = r["metrics"]["params"]["train"]["threshold"]
        t = float(r["metrics"]["threshold"]["threshold"])
        test = r["predictions"].filter(pl.col("split") == "test")
        c = threshold_counts(test["prob"].to_numpy(), test["label"].to_numpy(), t)
        total[name] = total.get(name, np.zeros(4, dtype=np.int64)) + c
        chosen.setdefault(name, []).append(t)
        floor[name] = floor.get(name, 0) + int(np.isclose(t, float(rule["grid"][0])))
        rules.setdefault(name, set()).add(
            "best F1" if rule["rule"] == "best_f1" else f"recall >= {rule['min_recall']:g}"
        )
    rows = []
    for name in sorted(total):
        tp, fp, fn, tn = (int(x) for x in total[name])
        ts = np.asarray(chosen[name])
        rows.append(
            {
                "scorer": name,
                "rule": ", ".join(sorted(rules[name])),
                "runs": int(ts.size),
                "threshold_median": float(np.median(ts)),
                "threshold_min": float(ts.min()),
                "threshold_max": float(ts.max()),
                "at_floor": floor[name],
                "precision": tp / (tp + fp) if tp + fp else math.nan,
                "recall": tp / (tp + fn) if tp + fn else math.nan,
                "f1": 2 * tp / (2 * tp + fp + fn) if tp + fp + fn else math.nan,
                "fpr": fp / (fp + tn) if fp + tn else math.nan,
            }
        )
    return pl.DataFrame(rows)


def answer(
    paired: pl.DataFrame, protocol: str, scorers: Sequence[str], level: float, still: bool = False
) -> str:
    """The one-sentence answer for a protocol: do the learned models beat the proxy on unseen
    objects (test AUPRC, paired bootstrap over objects)? ``still``: on the still-now windows
    only (``paired`` from their per-object table): early warning, not recognition."""
    rows = paired.filter((pl.col("metric") == "auprc") & pl.col("scorer").is_in(list(scorers)))
    where = "on the still-now test windows of unseen objects" if still else "on unseen objects"
    metric = "still-now test AUPRC" if still else "test AUPRC"
    if not rows.is_empty():
        rows = rows.filter(pl.col("objects") > 0)
        if rows.is_empty():
            return (
                f"Under the {protocol} protocol no object has a defined {metric} for both a "
                "learned model and the proxy (a class is missing), so no comparison is made."
            )
    if rows.is_empty():
        return f"Under the {protocol} protocol no learned model was compared with the proxy."
    parts = [
        f"{r['scorer']} {100 * r['mean_diff']:+.1f} points [{100 * r['lo']:+.1f}, "
        f"{100 * r['hi']:+.1f}] over {r['objects']} objects"
        for r in rows.iter_rows(named=True)
    ]
    verdicts = set(rows["verdict"].to_list())
    if verdicts == {"learned better"}:
        head = "every learned model beats the friction-ratio proxy"
    elif verdicts == {"proxy better"}:
        head = "the friction-ratio proxy beats every learned model"
    elif "learned better" in verdicts:
        better = [
            r["scorer"] for r in rows.iter_rows(named=True) if r["verdict"] == "learned better"
        ]
        head = f"only {', '.join(better)} beat{'s' if len(better) == 1 else ''} the proxy"
    elif "proxy better" in verdicts:
        head = "no learned model beats the proxy, and some do worse"
    else:
        head = "no learned model is distinguishable from the proxy"
    return (
        f"Under the {protocol} protocol, {where} {head} ({metric}, learned minus "
        f"proxy, mean over objects, {round(100 * level)} % paired-bootstrap interval: "
        + "; ".join(parts)
        + ")."
    )


def scorer_name(family: str, variant: str) -> str:
    """A learned scorer's name: the family, with its fairness variant when not the plain forces."""
    return family if variant == "forces" else f"{family}+{variant}"


def scored_windows(
    runs: Sequence[Mapping[str, Any]], index: pl.DataFrame, proxy: pl.DataFrame
) -> pl.DataFrame:
    """One row per (scorer, seed, test window) from the fold runs' predictions and the proxy.

    ``runs``: dicts with family, variant, fold, seed and ``predictions`` (a frame of predictions
    .parquet). ``index``: the dataset's index (sample_id, object, shard, grasp_id, label).
    ``proxy``: sample_id and score of every window. Raises if a window is a test window of two
    folds for one scorer and seed (an object tested twice) or an object is never tested."""
    grasp = index.select(
        "sample_id",
        "object",
        "label",
        grasp=pl.col("shard").cast(pl.String) + ":" + pl.col("grasp_id").cast(pl.String),
    )
    frames = []
    for r in runs:
        test = r["predictions"].filter(pl.col("split") == "test").select("sample_id", "prob")
        frames.append(
            test.join(grasp, on="sample_id", how="inner").select(
                pl.lit(scorer_name(r["family"], r["variant"])).alias("scorer"),
                pl.lit(int(r["seed"])).alias("seed"),
                pl.lit(int(r["fold"])).alias("fold"),
                "sample_id",
                "object",
                "grasp",
                "label",
                pl.col("prob").alias("score"),
            )
        )
    learned = pl.concat(frames)
    dup = learned.group_by(["scorer", "seed", "sample_id"]).len().filter(pl.col("len") > 1)
    if not dup.is_empty():
        raise ValueError(f"{dup.height} windows are test windows of more than one fold")
    folds = learned.select("object", "fold").unique()
    proxy_rows = (
        proxy.join(grasp, on="sample_id", how="inner")
        .join(folds.unique("object"), on="object", how="inner")
        .select(
            pl.lit(PROXY).alias("scorer"),
            pl.lit(0).alias("seed"),
            "fold",
            "sample_id",
            "object",
            "grasp",
            "label",
            "score",
        )
    )
    return pl.concat([learned, proxy_rows.cast(learned.schema)])


def fold_table(scored: pl.DataFrame) -> pl.DataFrame:
    """Per (scorer, fold): the fold's test AUPRC and AUROC (mean over seeds)."""
    rows = []
    for (scorer, fold), g in scored.group_by(["scorer", "fold"], maintain_order=True):
        vals = {name: [] for name in METRICS}
        for (_seed,), s in g.group_by(["seed"]):
            for name, fn in METRICS.items():
                vals[name].append(fn(s["score"].to_numpy(), s["label"].to_numpy()))
        rows.append(
            {
                "scorer": scorer,
                "fold": int(fold),
                "windows": g.height // g["seed"].n_unique(),
                **{
                    n: float(np.nanmean(v)) if np.isfinite(v).any() else math.nan
                    for n, v in vals.items()
                },
            }
        )
    return pl.DataFrame(rows).sort(["scorer", "fold"])
