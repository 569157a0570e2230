"""What each label source and form changes in the trained figures: on a finished run's replays,
one window dataset per (protocol, labels.source, labels.form), each family trained on it once,
and its test AUPRC and AUROC on all windows and on the still-now windows, beside the
friction-ratio proxy and the persistence oracle (which reads object motion: a reference line).

    python benchmarks/label_source_models.py <workdir> [--run-config profile=quick ...] \\
        [--protocols reference creep_free] [--sources object_speed contact_slip displacement] \\
        [--forms share event] [--families gru] [--window-s 0.01] [--seed 42] [--epochs 8] \\
        [--out-dir DIR]

``--run-config`` takes the run's own ``--config`` entries, so that the labelling rules, splits,
training settings and each family's sweep configuration are the run's (the creep-free protocol's
labels are the benchmark's, ``creep_free_labels``, with the source and form replaced). Each
dataset is built at ``--window-s`` directly (eq. 26's starts for that window, seed 42), not
trimmed from the sweep's longest window as the workflow's same-end datasets are, so the figures
compare the labellings with one another, not with the run's report. Prints one markdown table
per protocol: per labelling, the test windows, their positives and chance, the still-now test
windows and their positives, and per scorer its test AUPRC/AUROC on all windows and still now.
"""

from __future__ import annotations

import argparse
import sys
import tempfile
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np
import torch

from graspstab.common.io import read_parquet
from graspstab.config import load_config
from graspstab.evaluation.detection import ORACLE, ranked, still_now, unstable_share
from graspstab.evaluation.proxy import friction_ratio
from graspstab.evaluation.tested_run import train_and_test
from graspstab.labels.build_datasets import build_dataset
from graspstab.labels.dataset import load_motion
from graspstab.learning.data import load_window_data
from graspstab.learning.specs import study_spec
from graspstab.replay.protocols import creep_free_labels

REPO = Path(__file__).resolve().parents[1]
ROOTS = {"reference": "results", "creep_free": "results/creep_free"}
SOURCES = ("object_speed", "contact_slip", "displacement")
FORMS = ("share", "event")


def run_config(entries: Sequence[str]) -> dict[str, Any]:
    """The run's composed config from its ``--config`` entries (``key=value``, YAML values)."""
    import yaml

    values = {}
    for entry in entries:
        key, _, value = entry.partition("=")
        values[key] = yaml.safe_load(value) if value else None
    return load_config(REPO / "config", REPO / "workflow" / "schemas" / "config.schema.yaml",
                       values, check_files=False)  # fmt: skip


def replay_pairs(workdir: Path, protocol: str) -> list[tuple[Path, Path]]:
    """(table, traces) of every replay shard of a protocol in the run, in name order."""
    root = workdir / ROOTS[protocol] / "replay"
    tables = sorted(root.glob("*/replays_*.parquet"))
    return [(t, t.with_name(t.name.replace("replays_", "traces_")).with_suffix(".npz"))
            for t in tables]  # fmt: skip


def labels_for(cfg: Mapping[str, Any], protocol: str, source: str, form: str) -> dict[str, Any]:
    """The protocol's labelling rules with ``source`` and ``form`` in place."""
    base = dict(cfg["labels"]) if protocol == "reference" else creep_free_labels(cfg)
    return {**base, "source": source, "form": form}


def scorer_rows(dataset: Path, predictions: Mapping[str, np.ndarray]) -> dict[str, Any]:
    """Test figures of each family's scores, the proxy and the oracle: all windows, still now."""
    data = load_window_data(dataset)
    index = read_parquet(dataset / "index.parquet")
    test = np.flatnonzero(index["split"].to_numpy() == "test")
    y = data.labels(test)
    motion = load_motion(dataset)[test]
    still = still_now(motion)
    scores = {**predictions, "proxy": friction_ratio(data.windows[test]),
              ORACLE: unstable_share(motion)}  # fmt: skip
    out: dict[str, Any] = {"all": ranked(np.zeros(len(y)), y),
                           "still": ranked(np.zeros(int(still.sum())), y[still])}  # fmt: skip
    for name, s in scores.items():
        out[name] = {"all": ranked(s, y), "still": ranked(s[still], y[still])}
    return out


def measure(workdir: Path, cfg: Mapping[str, Any], protocol: str, source: str, form: str,
            families: Sequence[str], window_s: float, seed: int, epochs: int,
            scratch: Path) -> dict[str, Any]:  # fmt: skip
    """One labelling's dataset, its families trained once, and :func:`scorer_rows`."""
    labels = labels_for(cfg, protocol, source, form)
    splits = {o: e["split"] for o, e in cfg["objects"]["items"].items()}
    name = f"{protocol}_{source}_{form}"
    dataset = scratch / name / "dataset"
    build_dataset(replay_pairs(workdir, protocol), dataset, labels, splits, window_s,
                  float(cfg["replay"]["timestep"]), 42)  # fmt: skip
    train = {**cfg["train"], "max_epochs": epochs}
    predictions = {}
    for family in families:
        spec = study_spec(cfg["sweep"]["models"][family], None, cfg["sweep"]["recurrent_pooling"])
        out = scratch / name / family
        train_and_test(dataset, spec, train, seed, out, checkpoint=False)
        index = read_parquet(dataset / "index.parquet").with_row_index("row")
        pred = read_parquet(out / "predictions.parquet").join(
            index.filter(index["split"] == "test").select("sample_id", "row"), on="sample_id")
        scores = pred.sort("row")["prob"].to_numpy()
        predictions[family] = scores
    return scorer_rows(dataset, predictions)


def _cell(block: Mapping[str, Any]) -> str:
    a, r = block["auprc"], block["auroc"]
    if not np.isfinite(a):
        return "undefined"
    return f"{100 * a:.1f} / {100 * r:.1f}"


def render(protocol: str, results: Mapping[tuple[str, str], Mapping[str, Any]],
           scorers: Sequence[str]) -> str:  # fmt: skip
    """One protocol's table."""
    head = ["source", "form", "test windows (unstable, chance %)",
            "still now (unstable, chance %)",
            *[f"{s} AUPRC / AUROC (%), all; still now" for s in scorers]]  # fmt: skip
    lines = [f"### {protocol}", "", "| " + " | ".join(head) + " |",
             "|" + "---|" * len(head)]  # fmt: skip
    for (source, form), r in results.items():
        a, s = r["all"], r["still"]
        cells = [source, form,
                 f"{a['n']:,} ({a['n_unstable']:,}, {100 * a['chance']:.1f})",
                 f"{s['n']:,} ({s['n_unstable']:,}, "
                 f"{100 * s['chance']:.1f})" if s["n"] else "0",
                 *[f"{_cell(r[x]['all'])}; {_cell(r[x]['still'])}" for x in scorers]]  # fmt: skip
        lines.append("| " + " | ".join(cells) + " |")
    return "\n".join(lines)


def main(argv: Sequence[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("workdir", type=Path)
    ap.add_argument("--run-config", nargs="*", default=[], help="the run's --config entries")
    ap.add_argument("--protocols", nargs="+", default=["reference", "creep_free"],
                    choices=sorted(ROOTS))  # fmt: skip
    ap.add_argument("--sources", nargs="+", default=list(SOURCES), choices=SOURCES)
    ap.add_argument("--forms", nargs="+", default=["share"], choices=FORMS)
    ap.add_argument("--families", nargs="+", default=["gru"], choices=["cnn", "gru", "lstm"])
    ap.add_argument("--window-s", type=float, default=0.01)
    ap.add_argument("--seed", type=int, default=42)
    ap.add_argument("--epochs", type=int, default=8)
    ap.add_argument("--out-dir", type=Path, help="keep the datasets and runs here (default: a "
                    "temporary folder, removed)")  # fmt: skip
    args = ap.parse_args(argv)
    torch.set_num_threads(1)
    cfg = run_config(args.run_config)
    scorers = [*args.families, "proxy", ORACLE]
    with tempfile.TemporaryDirectory() as tmp:
        scratch = args.out_dir or Path(tmp)
        for protocol in args.protocols:
            if not replay_pairs(args.workdir, protocol):
                print(f"{protocol}: no replays under {args.workdir / ROOTS[protocol]}",
                      file=sys.stderr)  # fmt: skip
                continue
            results = {
                (source, form): measure(args.workdir, cfg, protocol, source, form, args.families,
                                        args.window_s, args.seed, args.epochs, scratch)
                for source in args.sources for form in args.forms
            }  # fmt: skip
            print(render(protocol, results, scorers), flush=True)
            print()
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
