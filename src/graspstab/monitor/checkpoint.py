"""Read a trained run (model.pt, metrics.json, normalisation.json) into a model and its constants.

``learning.train_model`` writes ``model.pt`` with the state dict, the model spec, the window steps,
the training split's normalisation (``mean``, ``std``) and the validation-selected threshold, and
``metrics.json`` with the same threshold under ``threshold.threshold``. The checkpoint's own
values are used; ``metrics.json`` and a dataset's ``normalisation.json``, when given, fill what an
older checkpoint lacks and are otherwise cross-checked, so a file from another run is an error
rather than a silently wrong monitor. Paths are always given, never derived.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np
import torch
from torch import nn

from graspstab.common.io import read_json, reading
from graspstab.learning.models import build_model
from graspstab.monitor.constants import MonitorConstants, MonitorError, as_stat
from graspstab.monitor.scoring import TorchScorer
from graspstab.monitor.stream import StreamingMonitor


def read_checkpoint(path: str | Path) -> dict[str, Any]:
    """The checkpoint record (tensors and plain values only: ``weights_only`` loading)."""
    with reading(path):
        ckpt = torch.load(path, map_location="cpu", weights_only=True)
    missing = [k for k in ("state_dict", "model") if k not in ckpt]
    if missing:
        raise MonitorError(f"{path}: not a graspstab checkpoint (missing {missing})")
    return ckpt


def _agree(name: str, a: Any, b: Any, where: str) -> None:
    """Raise when two sources of one constant disagree."""
    if not np.allclose(np.asarray(a, dtype=np.float64), np.asarray(b, dtype=np.float64),
                       rtol=1e-9, atol=0.0):  # fmt: skip
        raise MonitorError(
            f"{name} differs between {where}: the files come from different runs or datasets "
            "(a split-assignment run has its own statistics); pass the run's own files"
        )


def read_trained(
    checkpoint: str | Path,
    metrics_json: str | Path | None = None,
    normalisation_json: str | Path | None = None,
    *,
    threshold: float | None = None,
) -> tuple[nn.Module, MonitorConstants]:
    """The trained model (eval mode) and its constants; ``threshold`` overrides the run's."""
    ckpt = read_checkpoint(checkpoint)
    model = build_model(ckpt["model"])
    model.load_state_dict(ckpt["state_dict"])
    stats = {k: ckpt.get(k) for k in ("mean", "std")}
    if normalisation_json is not None:
        stored = read_json(normalisation_json)
        for key in ("mean", "std"):
            if stats[key] is None:
                stats[key] = stored[key]
            else:
                _agree(key, as_stat(key, stats[key]), as_stat(key, stored[key]),
                       f"{checkpoint} and {normalisation_json}")  # fmt: skip
    if stats["mean"] is None or stats["std"] is None:
        raise MonitorError(
            f"{checkpoint} holds no normalisation: pass the dataset's normalisation.json"
        )
    steps, chosen = ckpt.get("window_steps"), ckpt.get("threshold")
    if metrics_json is not None:
        metrics = read_json(metrics_json)
        run_threshold = (metrics.get("threshold") or {}).get("threshold")
        if chosen is None:
            chosen = run_threshold
        elif run_threshold is not None:
            _agree("the threshold", chosen, run_threshold, f"{checkpoint} and {metrics_json}")
        if steps is None:
            steps = metrics.get("window_steps")
        elif metrics.get("window_steps") not in (None, steps):
            raise MonitorError(
                f"window_steps differs between {checkpoint} ({steps}) and {metrics_json} "
                f"({metrics['window_steps']}): the files come from different runs"
            )
    if steps is None:
        raise MonitorError(f"{checkpoint} holds no window_steps: pass the run's metrics.json")
    if threshold is None and chosen is None:
        raise MonitorError(f"{checkpoint} holds no threshold: pass metrics.json or threshold=")
    constants = MonitorConstants(
        mean=stats["mean"], std=stats["std"],
        threshold=chosen if threshold is None else threshold, window_steps=steps,
        family=ckpt["model"].get("family"), model=ckpt["model"],
    )  # fmt: skip
    return model.eval(), constants


def load_monitor(
    checkpoint: str | Path,
    metrics_json: str | Path | None = None,
    normalisation_json: str | Path | None = None,
    *,
    threshold: float | None = None,
    stride: int = 1,
    debounce: int = 1,
) -> StreamingMonitor:
    """A streaming monitor on a trained checkpoint (eager PyTorch), see :func:`read_trained`."""
    model, constants = read_trained(
        checkpoint, metrics_json, normalisation_json, threshold=threshold
    )
    scorer = TorchScorer(model, constants)
    return StreamingMonitor.from_scorer(scorer, stride=stride, debounce=debounce)
