"""The k-fold study's figures of a finished run as Markdown, for the docs: per protocol the pooled
metrics per scorer, the paired comparisons with the proxy and the one-sentence answer, what each
fairness variant changes against its plain family, and the thresholded test metrics.

    python benchmarks/crossval_table.py <workdir>
"""

from __future__ import annotations

import argparse
import json
import math
from pathlib import Path

ROOTS = {"reference": "results", "creep_free": "results/creep_free"}


def pct(v: float | None, lo: float | None = None, hi: float | None = None) -> str:
    if v is None or not math.isfinite(v):
        return "undefined"
    if lo is None or hi is None or not math.isfinite(lo):
        return f"{100 * v:.1f}"
    return f"{100 * v:.1f} [{100 * lo:.1f}, {100 * hi:.1f}]"


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("workdir", type=Path)
    args = ap.parse_args()
    for protocol, root in ROOTS.items():
        path = args.workdir / root / "studies" / "crossval" / "summary.json"
        if not path.exists():
            print(f"({protocol}: no {path})\n")
            continue
        s = json.loads(path.read_text())
        level = round(100 * s["bootstrap"]["level"])
        print(
            f"**{protocol}** ({s['folds']} folds, {len(s['tested_objects'])} of "
            f"{s['objects']} objects with test windows)\n"
        )
        print(
            f"| scorer | test windows | unstable | pooled AUPRC [{level} % CI] | pooled AUROC "
            f"[{level} % CI] | AUPRC over folds, mean ± std |"
        )
        print("|---|---:|---:|---|---|---|")
        for scorer in s["scorers"]:
            p, f = s["pooled"][scorer], s["fold_mean"].get(scorer, {})
            print(
                f"| {scorer} | {p['windows']:,} | {p['unstable']:,} | "
                f"{pct(p['auprc'], p['auprc_lo'], p['auprc_hi'])} | "
                f"{pct(p['auroc'], p['auroc_lo'], p['auroc_hi'])} | "
                f"{100 * f.get('auprc', math.nan):.1f} ± {100 * f.get('auprc_std', math.nan):.1f} |"
            )
        print(
            f"\n| learned scorer | metric | objects | learned - proxy, points [{level} % CI] | "
            "wins / losses | sign test p | verdict |"
        )
        print("|---|---|---:|---|---|---:|---|")
        for r in s["paired"]:
            d = f"{100 * r['mean_diff']:+.1f} [{100 * r['lo']:+.1f}, {100 * r['hi']:+.1f}]"
            p = r["sign_p"]
            print(
                f"| {r['scorer']} | {r['metric'].upper()} | {r['objects']} | {d} | "
                f"{r['wins']} / {r['losses']} | {p:.3g} | {r['verdict']} |"
            )
        print(f"\n{s['answer']}\n")
        if s.get("answer_variants") and s.get("variants"):
            print(f"With the variants: {s['answer_variants']}\n")
        if s.get("variants"):
            print(
                f"| variant | against | metric | objects | variant - plain, points [{level} % CI] "
                "| wins / losses | sign test p | verdict |"
            )
            print("|---|---|---|---:|---|---|---:|---|")
            for r in s["variants"]:
                d = f"{100 * r['mean_diff']:+.1f} [{100 * r['lo']:+.1f}, {100 * r['hi']:+.1f}]"
                p = "-" if r["sign_p"] is None else f"{r['sign_p']:.3g}"  # all ties: no test
                print(
                    f"| {r['scorer']} | {r['against']} | {r['metric'].upper()} | {r['objects']} "
                    f"| {d} | {r['wins']} / {r['losses']} | {p} | {r['verdict']} |"
                )
            print()
        if s.get("thresholds"):
            print(
                "| learned scorer | threshold rule | fold runs | threshold, median [min, max] | "
                "at grid floor | precision | recall | F1 | false-positive rate |"
            )
            print("|---|---|---:|---|---:|---:|---:|---:|---:|")
            for r in s["thresholds"]:
                print(
                    f"| {r['scorer']} | {r['rule']} | {r['runs']} | {r['threshold_median']:.3f} "
                    f"[{r['threshold_min']:.3f}, {r['threshold_max']:.3f}] | {r['at_floor']} | "
                    f"{pct(r['precision'])} | {pct(r['recall'])} | {pct(r['f1'])} | "
                    f"{pct(r['fpr'])} |"
                )
            print()


if __name__ == "__main__":
    main()
