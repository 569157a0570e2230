"""The shared training loop (thesis 3.5.2): BCEWithLogits, AdamW, clipping, best-epoch selection.

Every family trains through ``fit``: at most ``max_epochs`` epochs, validation after each, the best
epoch's weights kept (by validation AUPRC unless configured otherwise), early stopping after
``patience`` epochs without an improvement larger than ``min_delta``. A seed fixes the weights,
the batch order and dropout, so the same seed gives the same metrics on the same machine. Training
runs where ``device`` and ``mixed_precision`` say (:mod:`graspstab.learning.device`); the weights
it returns are always on the CPU.
"""

from __future__ import annotations

import contextlib
import logging
import math
import time
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import torch
from torch import nn

from graspstab.learning.data import WindowData
from graspstab.learning.device import Placement, on_device, resolve
from graspstab.metrics.classification import binary_metrics

log = logging.getLogger("graspstab.learning")

SELECTION_METRICS = ("auprc", "auroc", "loss")


@dataclass(frozen=True)
class TrainSettings:
    """The training protocol of one run (3.5.2, table 4.2)."""

    max_epochs: int = 40  # 3.5.2
    batch_size: int = 256  # table 4.2
    learning_rate: float = 1e-3  # table 4.2 (LSTM 5e-4)
    weight_decay: float = 1e-4  # table 4.2
    grad_clip: float = 1.0  # max gradient norm; searched by Optuna (table 4.1)
    patience: int = 10  # table 4.2
    min_delta: float = 0.0  # minimum improvement that resets patience (table 4.1)
    selection_metric: str = "auprc"  # 3.5.2: best epoch by validation AUPRC
    class_weighting: bool = False  # weight unstable examples by class frequency (table 4.1)
    eval_batch_size: int = 1024
    device: str = "auto"  # auto | cpu | cuda (graspstab.learning.device)
    mixed_precision: str | bool = "auto"  # auto (CUDA only) | native | true | false

    @classmethod
    def from_config(cls, train: Mapping[str, Any], model: Mapping[str, Any]) -> TrainSettings:
        """Settings from the train group, with the model's own learning rate and any per-model
        training overrides (keys of this class present in the model spec win)."""
        names = {f for f in cls.__dataclass_fields__}
        values = {k: v for k, v in train.items() if k in names}
        values.update({k: v for k, v in model.items() if k in names})
        if values.get("selection_metric", "auprc") not in SELECTION_METRICS:
            raise ValueError(
                f"selection_metric {values['selection_metric']!r} unknown; "
                f"valid: {SELECTION_METRICS}"
            )
        return cls(**values)

    def placement(self) -> Placement:
        """The device and precision these settings name on this machine."""
        return resolve(self.device, self.mixed_precision)


@dataclass
class FitResult:
    """What ``fit`` returns: the best epoch's weights and the per-epoch history."""

    state_dict: dict[str, torch.Tensor]
    best_epoch: int
    selection_metric: str  # the metric actually used (loss when validation has one class)
    history: list[dict[str, float]] = field(default_factory=list)
    stopped_early: bool = False
    seconds: float = 0.0
    placement: dict[str, Any] = field(default_factory=dict)  # Placement.describe()


def seed_everything(seed: int) -> np.random.Generator:
    """Seed torch (weights, dropout) and return the numpy stream for batch order."""
    torch.manual_seed(seed)
    torch.use_deterministic_algorithms(True, warn_only=True)
    return np.random.default_rng(seed)


def cpu_state(model: nn.Module) -> dict[str, torch.Tensor]:
    """A copy of the model's weights on the CPU."""
    return {k: v.detach().to("cpu", copy=True) for k, v in model.state_dict().items()}


def predict_logits(
    model: nn.Module,
    data: WindowData,
    rows: np.ndarray,
    batch_size: int,
    placement: Placement | None = None,
) -> np.ndarray:
    """Logits of ``rows`` in evaluation mode, on the model's device (under the placement's
    autocast when one is given)."""
    model.eval()
    device = next(model.parameters()).device
    cast = placement.autocast() if placement is not None else contextlib.nullcontext()
    out = np.empty(len(rows), dtype=np.float64)
    with torch.inference_mode(), cast:
        i = 0
        for chunk, x in data.batches(rows, batch_size):
            out[i : i + len(chunk)] = model(x.to(device)).double().cpu().numpy()
            i += len(chunk)
    return out


def sigmoid(z: np.ndarray) -> np.ndarray:
    """Numerically stable logistic function (eq. 31)."""
    return np.exp(-np.logaddexp(0.0, -z))


def evaluate(
    model: nn.Module,
    data: WindowData,
    split: str,
    batch_size: int,
    placement: Placement | None = None,
) -> dict[str, float]:
    """Loss, AUROC and AUPRC of one split (threshold-free; the threshold comes later)."""
    rows = data.rows(split)
    if len(rows) == 0:  # an assignment whose objects have no usable window: nothing to score
        return {"loss": math.nan, "auroc": math.nan, "auprc": math.nan}
    logits = predict_logits(model, data, rows, batch_size, placement)
    m = binary_metrics(sigmoid(logits), data.labels(rows), 0.5, logits=logits)
    return {"loss": m["loss"], "auroc": m["auroc"], "auprc": m["auprc"]}


def _score(metrics: Mapping[str, float], name: str) -> float:
    """Higher is better for every selection metric (loss is negated)."""
    return -metrics["loss"] if name == "loss" else metrics[name]


def train_epoch(
    model: nn.Module,
    data: WindowData,
    rows: np.ndarray,
    settings: TrainSettings,
    optimiser: torch.optim.Optimizer,
    loss_fn: nn.Module,
    placement: Placement | None = None,
    scaler: torch.amp.GradScaler | None = None,
) -> float:
    """One pass over ``rows`` (already in batch order): the mean training loss. A final batch of
    one window is dropped (batch norm cannot normalise it). The model must already be on the
    placement's device (fp32 on the CPU without one)."""
    placement = placement or resolve("cpu", False)
    scaler = scaler or placement.scaler()
    model.train()
    total, seen = 0.0, 0
    for i in range(0, len(rows), settings.batch_size):
        batch = rows[i : i + settings.batch_size]
        if len(batch) < 2 and seen:
            continue
        x = data.train_batch(batch).to(placement.device, non_blocking=True)
        y = torch.from_numpy(data.labels(batch)).to(placement.device, non_blocking=True)
        optimiser.zero_grad(set_to_none=True)
        with placement.autocast():
            logits = model(x)
        loss = loss_fn(logits.float(), y)  # the loss in fp32 under autocast too
        scaler.scale(loss).backward()
        if settings.grad_clip > 0:
            scaler.unscale_(optimiser)
            nn.utils.clip_grad_norm_(model.parameters(), settings.grad_clip)
        scaler.step(optimiser)
        scaler.update()
        total += float(loss.detach()) * len(batch)
        seen += len(batch)
    return total / max(seen, 1)


def fit(
    model: nn.Module,
    data: WindowData,
    settings: TrainSettings,
    seed: int,
    on_epoch: Callable[[int, dict[str, float]], None] | None = None,
) -> FitResult:
    """Train ``model`` on the train split, selecting the best epoch on the validation split.

    ``on_epoch(epoch, history_row)`` is called after every epoch (Optuna's pruning hook may
    raise to stop the run)."""
    rng = seed_everything(seed)
    train_rows = data.rows("train")
    if len(train_rows) == 0:
        raise ValueError(f"{data.source}: no training windows in this split assignment")
    y_train = data.labels(train_rows)
    stable, unstable = data.class_counts("val")
    metric = settings.selection_metric
    if metric != "loss" and (stable == 0 or unstable == 0):
        log.warning(
            "validation split has %d stable and %d unstable windows: %s is undefined, "
            "selecting epochs by validation loss instead",
            stable, unstable, metric.upper(),
        )  # fmt: skip
        metric = "loss"
    pos_weight = None
    if settings.class_weighting and y_train.sum() > 0:
        pos_weight = torch.tensor((len(y_train) - y_train.sum()) / y_train.sum())
    placement = settings.placement()
    if pos_weight is not None:
        pos_weight = pos_weight.to(placement.device)
    loss_fn = nn.BCEWithLogitsLoss(pos_weight=pos_weight)
    best_score, best_epoch = -math.inf, 0
    best_state = cpu_state(model)
    history: list[dict[str, float]] = []
    since_best, stopped_early = 0, False
    start = time.perf_counter()
    with on_device(model, placement):
        optimiser = torch.optim.AdamW(
            model.parameters(), lr=settings.learning_rate, weight_decay=settings.weight_decay
        )
        scaler = placement.scaler()
        for epoch in range(1, settings.max_epochs + 1):
            t0 = time.perf_counter()
            order = train_rows[rng.permutation(len(train_rows))]
            train_loss = train_epoch(model, data, order, settings, optimiser, loss_fn,
                                     placement, scaler)  # fmt: skip
            val = evaluate(model, data, "val", settings.eval_batch_size, placement)
            score = _score(val, metric)
            row = {"epoch": epoch, "train_loss": train_loss}
            row.update({f"val_{k}": v for k, v in val.items()})
            row["seconds"] = time.perf_counter() - t0
            history.append(row)
            improved = math.isfinite(score) and score > best_score + settings.min_delta
            if improved or best_epoch == 0:
                best_score = score if math.isfinite(score) else -math.inf
                best_epoch, since_best = epoch, 0
                best_state = cpu_state(model)
            else:
                since_best += 1
            log.info(
                "epoch %d/%d train_loss %.4f val_loss %.4f val_auprc %.4f val_auroc %.4f "
                "(%.1f s)%s", epoch, settings.max_epochs, row["train_loss"], val["loss"],
                val["auprc"], val["auroc"], row["seconds"], " *" if best_epoch == epoch else "",
            )  # fmt: skip
            if on_epoch is not None:
                on_epoch(epoch, row)
            if since_best >= settings.patience:
                stopped_early = True
                break
    model.load_state_dict(best_state)
    return FitResult(
        state_dict=best_state,
        best_epoch=best_epoch,
        selection_metric=metric,
        history=history,
        stopped_early=stopped_early,
        seconds=time.perf_counter() - start,
        placement=placement.describe(),
    )
