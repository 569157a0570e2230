"""Entry points of rules export_monitor and export_pick: a trained run to deployable files.

One run (checkpoint + metrics.json) becomes a TorchScript file, an ONNX file and a JSON sidecar
of its constants (``monitor.export``), each loaded back and checked against eager PyTorch on
random raw windows before it is kept. The latency-aware pick (4.5) is read from the sweep's
summary (``choice.pick``: family and window) and mapped to the first-seed run of that
configuration among the candidates the rule declares.
"""

from __future__ import annotations

import logging
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import numpy as np
import torch

from graspstab.common.io import read_json
from graspstab.common.logs import setup_logging
from graspstab.common.units import ms_of
from graspstab.monitor.checkpoint import read_trained
from graspstab.monitor.constants import FRAME_SHAPE, MonitorError
from graspstab.monitor.export import export_onnx, export_torchscript, load_onnx, load_torchscript
from graspstab.monitor.scoring import TorchScorer

log = logging.getLogger("graspstab.monitor")

PARITY_ATOL = 1e-5  # probability; float32 graphs against eager float32
PARITY_WINDOWS = 64


def export_run(
    checkpoint: str | Path,
    metrics: str | Path,
    out_onnx: str | Path,
    out_torchscript: str | Path,
    out_constants: str | Path,
    log_file: str | Path | None = None,
    onnx_exporter: str = "torchscript",
) -> dict[str, Any]:
    """Export one trained run to both formats and the sidecar (ONNX with ``onnx_exporter``);
    refuse a file that does not reproduce eager PyTorch within PARITY_ATOL on random raw
    windows."""
    setup_logging(log_file)
    torch.set_num_threads(1)
    model, constants = read_trained(checkpoint, metrics)
    export_torchscript(model, constants, out_torchscript)
    export_onnx(model, constants, out_onnx, sidecar=out_constants, exporter=onnx_exporter)
    rng = np.random.default_rng(0)
    noise = rng.normal(size=(PARITY_WINDOWS, constants.window_steps, *FRAME_SHAPE))
    windows = (constants.mean + constants.std * noise).astype(np.float32)
    eager = TorchScorer(model, constants)(windows)
    gaps = {}
    for fmt, scorer in (("torchscript", load_torchscript(out_torchscript)),
                        ("onnx", load_onnx(out_onnx))):  # fmt: skip
        gaps[fmt] = float(np.max(np.abs(scorer(windows) - eager)))
        if gaps[fmt] > PARITY_ATOL:
            for path in (out_onnx, out_torchscript, out_constants):
                Path(path).unlink(missing_ok=True)
            raise MonitorError(
                f"the {fmt} export of {checkpoint} differs from eager PyTorch by {gaps[fmt]:.2e} "
                f"in probability (tolerance {PARITY_ATOL}); no file was kept"
            )
    log.info("exported %s (%s, %d frames, threshold %.3f): max |prob - eager| %s",
             checkpoint, constants.family, constants.window_steps, constants.threshold,
             {k: f"{v:.1e}" for k, v in gaps.items()})  # fmt: skip
    return {"family": constants.family, "window_steps": constants.window_steps, "parity": gaps}


def pick_candidate(
    sweep_summary: str | Path, candidates: Mapping[str, tuple[str | Path, str | Path]]
) -> tuple[str | Path, str | Path]:
    """The (checkpoint, metrics) of the sweep's latency-aware pick; ``candidates`` are keyed
    ``<family>_w<ms>ms``."""
    choice = read_json(sweep_summary).get("choice") or {}
    if not choice.get("defined"):
        raise MonitorError(
            f"{sweep_summary}: the sweep's latency-aware pick is undefined "
            f"({choice.get('reason', 'no choice recorded')}), so there is no pick to export"
        )
    pick = choice["pick"]
    key = f"{pick['family']}_w{ms_of(pick['window_s'])}ms"
    if key not in candidates:
        raise MonitorError(f"{sweep_summary}: the pick {key} is not among the declared runs "
                           f"{sorted(candidates)}")  # fmt: skip
    return candidates[key]
