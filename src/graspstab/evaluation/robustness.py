"""Sensor robustness (our extension; the reference's 5.3): test AUPRC of trained models and of the
friction-ratio proxy when the test windows come through a sensor model instead of the simulator.

Each condition (one corruption at one strength, or one sensor preset) draws its sensed test
windows once, from a stream seeded by the run's seed and the condition's position, and every model
and the proxy score those same windows. Models normalise with their own training statistics
(the checkpoint's), as a deployed model would.
"""

from __future__ import annotations

import logging
import time
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np
import polars as pl
import torch

from graspstab.common.io import write_json, write_parquet
from graspstab.common.logs import setup_logging
from graspstab.evaluation.detection import ranked, still_now
from graspstab.evaluation.proxy import friction_ratio, proxy_metrics
from graspstab.evaluation.studies import load_checkpoint
from graspstab.labels.dataset import load_motion
from graspstab.labels.trace_windows import trace_map
from graspstab.learning.data import load_window_data
from graspstab.learning.train import sigmoid
from graspstab.metrics.classification import binary_metrics
from graspstab.sensing.conditions import conditions
from graspstab.sensing.segments import window_segments
from graspstab.sensing.sensor_model import sense

log = logging.getLogger("graspstab.learning")


def _logits(model: torch.nn.Module, raw: np.ndarray, mean: np.ndarray, std: np.ndarray,
            batch: int = 1024) -> np.ndarray:  # fmt: skip
    x = (raw - mean.astype(np.float32)) / std.astype(np.float32)
    out = []
    with torch.inference_mode():
        for i in range(0, len(x), batch):
            out.append(model(torch.from_numpy(np.ascontiguousarray(x[i : i + batch]))).double())
    return torch.cat(out).numpy() if out else np.zeros(0)


def evaluate_robustness(
    dataset_dir: str | Path,
    trace_paths: Sequence[str],
    trace_keys: Sequence[tuple[str, int]],
    checkpoints: Sequence[str | Path],
    run_keys: Sequence[Mapping[str, Any]],
    sensing: Mapping[str, Any],
    dt: float,
    seed: int,
    out_table: str | Path,
    out_json: str | Path,
    split: str = "test",
    log_file: str | Path | None = None,
) -> pl.DataFrame:
    """Score every checkpoint (labelled by ``run_keys``: family, seed, training) and the proxy
    under every condition of ``sensing``; one row per condition x scorer."""
    setup_logging(log_file)
    torch.set_num_threads(1)
    data = load_window_data(dataset_dir)
    rows = data.rows(split)
    index = data.index[rows]
    labels = data.labels(rows)
    still = still_now(np.asarray(load_motion(dataset_dir)[rows]))  # prediction, not detection
    w = data.window_steps
    conds = conditions(sensing)
    context = max(c["sensor"].context_frames(dt) for c in conds)
    segments = window_segments(index, trace_map(list(trace_paths), list(trace_keys)), w, context)
    models = [(key, *load_checkpoint(p)) for key, p in zip(run_keys, checkpoints, strict=True)]
    streams = np.random.SeedSequence([int(seed), 0x5E5]).spawn(len(conds))
    out = []
    start = time.perf_counter()
    for i, (cond, stream) in enumerate(zip(conds, streams, strict=True)):
        sensed = sense(cond["sensor"], segments, w, data.std, dt, np.random.default_rng(stream))
        label = {k: cond[k] for k in ("kind", "corruption", "strength")}
        ratio = friction_ratio(sensed)
        proxy = proxy_metrics(ratio, labels)
        out.append({**label, "scorer": "proxy", "family": "proxy", "seed": -1,
                    "training": "none", **proxy, **_still(ratio, labels, still)})  # fmt: skip
        for key, model, ckpt in models:
            logits = _logits(model, sensed, np.asarray(ckpt["mean"]), np.asarray(ckpt["std"]))
            m = binary_metrics(sigmoid(logits), labels, 0.5, logits=logits)
            out.append({**label, "scorer": f"{key['family']}_seed{key['seed']}",
                        "family": str(key["family"]), "seed": int(key["seed"]),
                        "training": str(key.get("training", "clean")),
                        "auprc": float(m["auprc"]), "auroc": float(m["auroc"]),
                        **_still(sigmoid(logits), labels, still)})  # fmt: skip
        log.info("[%d/%d] %s %s %s: proxy AUPRC %.4f (%.0f s)", i + 1, len(conds), cond["kind"],
                 cond["corruption"], cond["strength"], proxy["auprc"],
                 time.perf_counter() - start)  # fmt: skip
    table = pl.DataFrame(out, infer_schema_length=None)
    write_parquet(out_table, table)
    summary = summarise(table, n=len(rows), n_unstable=int(labels.sum()))
    n_still, pos_still = int(still.sum()), int(labels[still].sum())
    summary["still"] = {"n": n_still, "n_unstable": pos_still,
                        "chance": pos_still / n_still if n_still else float("nan")}  # fmt: skip
    write_json(out_json, summary)
    return table


def _still(scores: np.ndarray, labels: np.ndarray, still: np.ndarray) -> dict[str, float]:
    """AUPRC and AUROC on the still-now windows (``still_auprc``, ``still_auroc``)."""
    block = ranked(scores[still], labels[still])
    return {"still_auprc": float(block["auprc"]), "still_auroc": float(block["auroc"])}


def summarise(table: pl.DataFrame, n: int, n_unstable: int) -> dict[str, Any]:
    """Mean and std of AUPRC over seeds per condition, family and training, and the chance level."""
    summary = (
        table.group_by(
            ["kind", "corruption", "strength", "family", "training"], maintain_order=True
        ).agg(
            pl.col("auprc").mean().alias("auprc_mean"),
            pl.col("auprc").std(ddof=0).alias("auprc_std"),
            pl.col("still_auprc").fill_nan(None).mean().alias("still_auprc_mean"),
            pl.len().alias("runs"),
        )  # fmt: skip
    )
    return {"split": "test", "n": n, "n_unstable": n_unstable,
            "chance": n_unstable / n if n else float("nan"),
            "summary": summary.to_dicts()}  # fmt: skip
