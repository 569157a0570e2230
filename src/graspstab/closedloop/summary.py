"""A protocol's closed-loop tables summed up per policy, with intervals by bootstrap over grasps:
the figures a robot user asks for (how many drops a warning saves, at what false alarms and
force), the paired comparisons that decide whether the learned monitor saves more grasps than
the friction-ratio proxy, and every grasp where a policy does worse than no reflex.

Every figure is over the *usable* grasps (those whose no-reflex run has a verdict,
``closedloop.outcome.Baseline.usable``). Each bootstrap resample draws the grasps with
replacement once and scores every policy on that same draw, so policies are compared paired.
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np
import polars as pl

from graspstab.closedloop.policies import BUDGET, SHUFFLED
from graspstab.common.io import read_parquet, write_json, write_parquet

# rate name: (the row's flag, the grasps it is a share of); "all": every usable grasp
RATES: dict[str, tuple[str, str]] = {
    "drop_rate": ("dropped", "all"),
    "prevented_share": ("prevented", "baseline_dropped"),  # of the no-reflex run's drops
    "worse_share": ("worse", "baseline_held"),  # of the grasps the no-reflex run holds
    "false_alarm_rate": ("false_alarm", "holding"),  # of the grasps that hold without a reflex
    "fired_rate": ("fired", "all"),
}
# mean name: the row's column, averaged over the grasps where it is defined (finite)
MEANS: dict[str, str] = {
    "lead_s": "lead_s",
    "latency_s": "latency_s",
    "slip_mm": "slip_mm",
    "added_normal_mean_n": "added_normal_mean_n",
    "added_normal_peak_n": "added_normal_peak_n",
    "tightened_s": "tightened_s",
}
# ratio name: (the row's flag, the row's exposure column, the grasps it is over): false alarms
# per grasp-second of the holding grasps' runs after arming
RATIOS: dict[str, tuple[str, str, str]] = {
    "false_alarms_per_s": ("false_alarm", "armed_s", "holding"),
}
# the paired comparisons a summary states: (policy, against, the figure compared)
COMPARED = ("drop_rate", "prevented_share", "false_alarm_rate")


def _aligned(table: pl.DataFrame, policies: Sequence[str]) -> dict[str, pl.DataFrame]:
    """Each policy's rows over the same usable grasps, in one order."""
    usable = table.filter(pl.col("usable"))
    keys = (
        usable.filter(pl.col("policy") == policies[0])
        .select("object", "grasp_id")
        .sort("object", "grasp_id")
    )
    out = {}
    for p in policies:
        rows = keys.join(
            usable.filter(pl.col("policy") == p),
            on=["object", "grasp_id"],
            how="left",
            maintain_order="left",
        )
        if rows["policy"].null_count():
            missing = rows.filter(pl.col("policy").is_null()).head(1).row(0, named=True)
            raise ValueError(
                f"closed-loop tables: policy {p!r} has no row for object "
                f"{missing['object']!r} grasp {missing['grasp_id']} (every policy "
                "runs every grasp; rerun that object's closed_loop_object job)"
            )
        out[p] = rows
    return out


def _masks(rows: pl.DataFrame) -> dict[str, np.ndarray]:
    """The grasp subsets a rate is a share of (from the no-reflex verdicts every row carries)."""
    dropped = rows["baseline_dropped"].to_numpy().astype(bool)
    failing = rows["failing"].to_numpy().astype(bool)
    return {
        "all": np.ones(len(rows), bool),
        "baseline_dropped": dropped,
        "baseline_held": ~dropped,
        "holding": ~failing,
    }


def _figures(rows: pl.DataFrame, weights: np.ndarray) -> dict[str, np.ndarray]:
    """Every rate and mean under each row of ``weights`` (resamples x grasps; counts per grasp)."""
    masks = _masks(rows)
    out = {}
    for name, (flag, subset) in RATES.items():
        x = rows[flag].to_numpy().astype(np.float64)
        m = masks[subset].astype(np.float64)
        with np.errstate(invalid="ignore", divide="ignore"):
            out[name] = (weights @ (x * m)) / (weights @ m)
    for name, col in MEANS.items():
        x = rows[col].to_numpy().astype(np.float64)
        ok = np.isfinite(x)
        with np.errstate(invalid="ignore", divide="ignore"):
            out[name] = (weights @ np.where(ok, x, 0.0)) / (weights @ ok.astype(np.float64))
    for name, (flag, exposure, subset) in RATIOS.items():
        if exposure not in rows.columns:  # tables written before the column: undefined
            out[name] = np.full(len(weights), np.nan)
            continue
        x = rows[flag].to_numpy().astype(np.float64)
        e = rows[exposure].to_numpy().astype(np.float64)
        m = masks[subset].astype(np.float64)
        with np.errstate(invalid="ignore", divide="ignore"):
            out[name] = (weights @ (x * m)) / (weights @ (np.nan_to_num(e) * m))
    return out


def _interval(draws: np.ndarray, level: float) -> tuple[float, float]:
    d = draws[np.isfinite(draws)]
    if not d.size:
        return float("nan"), float("nan")
    alpha = (1 - level) / 2
    lo, hi = np.quantile(d, [alpha, 1 - alpha])
    return float(lo), float(hi)


def bootstrap_weights(n: int, resamples: int, seed: int,
                      clusters: Sequence[str] | None = None) -> np.ndarray:  # fmt: skip
    """(resamples, n) counts of each grasp in each resample: grasps drawn with replacement, or
    with ``clusters`` (each grasp's object) whole objects drawn with replacement, every grasp of
    a drawn object counted once per draw (a bootstrap over grasps clustered by object: one
    object's grasps share its shape and mass, so they are not independent)."""
    rng = np.random.default_rng(seed)
    if clusters is None:
        draws = rng.integers(0, n, (resamples, n))
        return np.stack([np.bincount(d, minlength=n) for d in draws]).astype(np.float64)
    names, which = np.unique(np.asarray(clusters), return_inverse=True)
    picks = rng.integers(0, len(names), (resamples, len(names)))
    counts = np.stack([np.bincount(d, minlength=len(names)) for d in picks])
    return counts[:, which].astype(np.float64)


def summarise_policies(
    table: pl.DataFrame,
    policies: Sequence[str],
    *,
    resamples: int = 1000,
    level: float = 0.95,
    seed: int = 0,
    compare: Sequence[tuple[str, str]] = (),
    unit: str = "grasp",
) -> tuple[pl.DataFrame, pl.DataFrame]:
    """One row per policy (counts; every figure with its ``_lo``/``_hi`` bootstrap interval) and
    one row per comparison in ``compare`` ((policy, against): each figure of ``COMPARED`` as
    policy minus against, paired over the same grasps, with its interval and verdict). ``unit``:
    what the bootstrap resamples, ``grasp`` or ``object`` (grasps clustered by object)."""
    rows = _aligned(table, policies)
    n = rows[policies[0]].height
    if n == 0:
        raise ValueError("closed-loop tables: no usable grasp (no no-reflex run has a verdict)")
    if unit not in ("grasp", "object"):
        raise ValueError(f"closed_loop.bootstrap.unit must be grasp or object, got {unit!r}")
    point = np.ones((1, n))
    clusters = rows[policies[0]]["object"].to_list() if unit == "object" else None
    weights = bootstrap_weights(n, resamples, seed, clusters)
    figures = {p: (_figures(r, point), _figures(r, weights)) for p, r in rows.items()}
    out = []
    for p in policies:
        r, (est, draws) = rows[p], figures[p]
        masks = _masks(r)
        row: dict[str, Any] = {
            "policy": p,
            "grasps": n,
            "failing": int((~masks["holding"]).sum()),
            "baseline_drops": int(masks["baseline_dropped"].sum()),
            "drops": int(r["dropped"].sum()),
            "prevented": int(r["prevented"].sum()),
            "worse": int(r["worse"].sum()),
            "false_alarms": int(r["false_alarm"].sum()),
            "fired": int(r["fired"].sum()),
        }
        for name in (*RATES, *MEANS, *RATIOS):
            lo, hi = _interval(draws[name], level)
            row[name], row[f"{name}_lo"], row[f"{name}_hi"] = float(est[name][0]), lo, hi
        out.append(row)
    pairs = []
    for a, b in compare:
        if a not in figures or b not in figures:
            continue
        for name in COMPARED:
            diff = figures[a][0][name][0] - figures[b][0][name][0]
            lo, hi = _interval(figures[a][1][name] - figures[b][1][name], level)
            verdict = (
                ("higher" if lo > 0 else "lower" if hi < 0 else "not resolved")
                if np.isfinite(lo)
                else "undefined"
            )
            pairs.append(
                {
                    "policy": a,
                    "against": b,
                    "figure": name,
                    "diff": float(diff),
                    "lo": lo,
                    "hi": hi,
                    "verdict": verdict,
                }
            )
    schema = {
        "policy": pl.String,
        "against": pl.String,
        "figure": pl.String,
        "diff": pl.Float64,
        "lo": pl.Float64,
        "hi": pl.Float64,
        "verdict": pl.String,
    }
    return pl.DataFrame(out), pl.DataFrame(pairs, schema=schema)


def worse_grasps(table: pl.DataFrame) -> pl.DataFrame:
    """Every (grasp, policy) where the policy drops a grasp the no-reflex run holds."""
    cols = ["object", "grasp_id", "policy", "drop_s", "tighten_s", "warn_s", "peak_offset_rad"]
    return (
        table.filter(pl.col("usable") & pl.col("worse"))
        .select(cols)
        .sort("policy", "object", "grasp_id")
    )


def tradeoff_table(
    table: pl.DataFrame, *, resamples: int = 1000, level: float = 0.95, seed: int = 0
) -> pl.DataFrame:
    """Every swept variant (rows whose ``parameter`` is set) beside its policy's defaults: the
    policy rows of ``summarise_policies`` plus ``base`` (the policy), ``parameter`` ("default"
    for the defaults) and ``value``; empty without a sweep."""
    if "parameter" not in table.columns or table.filter(pl.col("parameter") != "").is_empty():
        return pl.DataFrame()
    swept = table.filter(pl.col("parameter") != "")
    meta = swept.select("policy", "parameter", "value").unique("policy", maintain_order=True)
    bases = list(dict.fromkeys(p.split("@")[0] for p in meta["policy"]))
    labels = [*bases, *meta["policy"]]
    pols, _ = summarise_policies(table, labels, resamples=resamples, level=level, seed=seed)
    info = pl.concat([
        pl.DataFrame({"policy": bases, "parameter": ["default"] * len(bases),
                      "value": [float("nan")] * len(bases)}),
        meta.with_columns(pl.col("value").cast(pl.Float64)),
    ])  # fmt: skip
    return pols.join(info, on="policy", how="left", maintain_order="left").with_columns(
        base=pl.col("policy").str.split("@").list.first()
    )


def is_control(policy: str) -> bool:
    """Whether a row label is a control rather than a monitor: no reflex, always, the load-onset
    controller, an oracle, or a monitor's shuffled-timing control."""
    return (policy in ("none", "always", "oracle", "load_onset") or policy.startswith("oracle-")
            or policy.endswith(SHUFFLED))  # fmt: skip


def default_comparisons(policies: Sequence[str]) -> list[tuple[str, str]]:
    """Each learned monitor against the proxy, each monitor against its own shuffled timing
    (what its timing alone buys), and every policy against no reflex."""
    monitors = [p for p in policies if not is_control(p)]
    # at the same threshold rule: a monitor at its budget against the proxy at the same budget
    pairs = [(p, f"proxy{BUDGET}" if p.endswith(BUDGET) else "proxy") for p in monitors
             if not p.startswith("proxy")
             and (f"proxy{BUDGET}" if p.endswith(BUDGET) else "proxy") in policies]  # fmt: skip
    pairs += [(p, f"{p}{SHUFFLED}") for p in monitors if f"{p}{SHUFFLED}" in policies]
    return pairs + [(p, "none") for p in policies if p != "none" and "none" in policies]


PROTOCOL_NAMES = {"reference": "the reference protocol (gravity switch)",
                  "creep_free": "the creep-free benchmark"}  # fmt: skip
LEARNED = ("pick", "cnn", "gru", "lstm")
DROP_VERDICTS = {"lower": "fewer drops than the proxy", "higher": "more drops than the proxy",
                 "not resolved": "no resolved difference from the proxy"}  # fmt: skip


def _pct(x: float) -> str:
    return "n/a" if not np.isfinite(x) else f"{100 * x:.1f} %"


def _span(lo: float, hi: float, points: bool = False) -> str:
    if not (np.isfinite(lo) and np.isfinite(hi)):
        return "[n/a]"
    f = "{:+.1f}" if points else "{:.1f}"
    return f"[{f.format(100 * lo)}, {f.format(100 * hi)}]"


def answer(protocol: str, policies: pl.DataFrame, pairs: pl.DataFrame, level: float,
           unit: str = "grasps") -> str:  # fmt: skip
    """The section's one-paragraph answer: does a learned monitor save more grasps than the proxy
    (drop rate, paired over grasps), at what false alarms and force, and what no warning saves."""
    rows = {r["policy"]: r for r in policies.iter_rows(named=True)}
    n = next(iter(rows.values()))["grasps"]
    drops = next(iter(rows.values()))["baseline_drops"]
    head = (f"Under {PROTOCOL_NAMES[protocol]}, over {n} test grasps ({drops} dropped without a "
            "reflex)")  # fmt: skip
    if "proxy" not in rows and f"proxy{BUDGET}" not in rows:
        return head + ": the proxy was not run, so no learned-against-proxy answer is given."
    parts = []
    for suffix, rule in (("", "at the recall rule's thresholds"),
                         (BUDGET, "at the false-warning budget's thresholds")):  # fmt: skip
        base = f"proxy{suffix}"
        cmp = {(r["policy"], r["figure"]): r for r in pairs.iter_rows(named=True)
               if r["against"] == base}  # fmt: skip
        mine = []
        for m in (f"{m}{suffix}" for m in LEARNED):
            if m not in rows or (m, "drop_rate") not in cmp:
                continue
            d, fa = cmp[(m, "drop_rate")], cmp[(m, "false_alarm_rate")]
            says = DROP_VERDICTS.get(d["verdict"], "undefined")
            alarms = (f"false alarms {100 * fa['diff']:+.1f} points "
                      f"{_span(fa['lo'], fa['hi'], True)} against it" if np.isfinite(fa["diff"])
                      else "false alarms undefined: no grasp holds without a reflex")  # fmt: skip
            mine.append(f"{m} drops {_pct(rows[m]['drop_rate'])} against the proxy's "
                        f"{_pct(rows[base]['drop_rate'])} ({says}: "
                        f"{100 * d['diff']:+.1f} points {_span(d['lo'], d['hi'], True)}; "
                        f"{alarms})")  # fmt: skip
        if mine:
            parts.append(f"{rule}, " + "; ".join(mine))
    text = head + ": " + ("; ".join(parts) if parts else "no learned monitor was run") + "."
    # what each monitor's knowledge of the grasp buys over its own timing dealt to other grasps
    own = {r["policy"]: r for r in pairs.iter_rows(named=True) if r["figure"] == "drop_rate"
           and r["against"] == f"{r['policy']}{SHUFFLED}"}  # fmt: skip
    if own:
        text += (" Against its own tightening times dealt to other grasps (the shuffled "
                 "control), drop rate: " + "; ".join(
                     f"{p} {100 * r['diff']:+.1f} points {_span(r['lo'], r['hi'], True)}"
                     for p, r in own.items()) + ".")  # fmt: skip
    bounds = {"oracle": "the best any warning can do", "always": "the force-hungry bound",
              "load_onset": "a perfect detector of the load"}  # fmt: skip
    bounds |= {p: f"tightening {p.removeprefix('oracle-')} before the onset"
               for p in rows if p.startswith("oracle-")}  # fmt: skip
    bound = [f"{p} ({why}) prevents {rows[p]['prevented']} of {drops}"
             for p, why in bounds.items() if p in rows]  # fmt: skip
    if bound:
        text += " " + "; ".join(bound).capitalize() + "."
    text += f" Intervals: {round(100 * level)} % paired bootstrap over {unit}."
    return text


def aggregate_closed_loop(
    tables: Sequence[str],
    policies: Sequence[str],
    protocol: str,
    bootstrap: dict[str, Any],
    out_dir: str,
) -> dict[str, Any]:
    """A protocol's per-object closed-loop tables -> policies.parquet, comparisons.parquet,
    worse.parquet (the policies at their defaults), tradeoff.parquet (the swept variants beside
    their defaults) and summary.json (counts, the answer, the worse grasps per policy) in
    ``out_dir``."""
    every = pl.concat([read_parquet(t) for t in tables], how="diagonal_relaxed")
    if "parameter" not in every.columns:
        every = every.with_columns(parameter=pl.lit(""), value=pl.lit(float("nan")))
    table = every.filter(pl.col("parameter") == "")
    level = float(bootstrap["level"])
    boot = {
        "resamples": int(bootstrap["resamples"]),
        "level": level,
        "seed": int(bootstrap["seed"]),
    }
    tradeoff = tradeoff_table(every, **boot)
    pols, pairs = summarise_policies(
        table, list(policies), compare=default_comparisons(policies), **boot,
        unit=str(bootstrap.get("unit", "grasp")),
    )
    worse = worse_grasps(table)
    out = Path(out_dir)
    write_parquet(out / "policies.parquet", pols)
    write_parquet(out / "comparisons.parquet", pairs)
    write_parquet(out / "worse.parquet", worse)
    write_parquet(out / "tradeoff.parquet", tradeoff)
    summary = {
        "protocol": protocol,
        "objects": sorted(table["object"].unique().to_list()),
        "grasps": int(pols["grasps"][0]),
        "unusable": int(table.filter(~pl.col("usable") & (pl.col("policy") == policies[0])).height),
        "bootstrap": dict(bootstrap),
        "worse_by_policy": {p: int((worse["policy"] == p).sum()) for p in policies},
        "swept": 0 if tradeoff.is_empty() else int((tradeoff["parameter"] != "default").sum()),
        # each monitor's threshold, and whether a budget threshold sat at its grid's floor
        "thresholds": {
            r["policy"]: {"threshold": r["threshold"], "at_floor": r["threshold_at_floor"],
                          "never_warns": bool(r.get("threshold_never_warns") or False)}
            for r in table.filter(pl.col("threshold").is_not_nan())
            .unique("policy", keep="first", maintain_order=True).iter_rows(named=True)
        } if "threshold" in table.columns else {},
        "answer": answer(protocol, pols, pairs, level,
                         "grasps clustered by object" if bootstrap.get("unit") == "object"
                         else "grasps"),
    }
    write_json(out / "summary.json", summary)
    return summary
