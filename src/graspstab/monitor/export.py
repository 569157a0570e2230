"""Export a trained model to TorchScript and ONNX, constants inside and beside, and load it back.

The exported graph takes **raw** forces, ``forces (B, W, 5, 2)`` float32 in newtons (fingertips
in eq. 19's order, channels normal and shear), normalises them inside with the training mean and
std, and returns ``prob (B,)`` and ``logit (B,)``; the batch axis is dynamic, ``W`` is the
model's window. So a consumer needs nothing but the file: the constants (mean, std, threshold,
window steps, family, spec) are embedded (TorchScript extra file ``graspstab_monitor.json``, ONNX
``metadata_props["graspstab_monitor"]``) and, when asked, written beside it as a JSON sidecar.
The loaders return :mod:`~graspstab.monitor.scoring` scorers, which take their probability from
the logit with the learning stage's float64 sigmoid, like the eager monitor.

ONNX comes from one of torch's two exporters at opset :data:`ONNX_OPSET` (``monitor.
onnx_exporter``): ``torchscript``, the trace-based one (``dynamo=False``; nn.GRU and nn.LSTM
become ONNX's own GRU and LSTM operators), or ``dynamo``, the torch.export-based one (needs
onnxscript). Both export all three families (CNN, GRU, LSTM; uni- or bidirectional, mean or last
pooling) and match eager PyTorch (tests); the trace-based one is the default because torch.export
spends about two minutes on the baseline GRU (400 frames) where the trace takes two seconds
(docs/extensions.md). The learning models' own ``forward`` is exported: it keeps the batch
symbolic (no Python int of a dynamic size), so a trace or export works at any batch size.

TorchScript (``torch.jit.trace``, then ``torch.jit.freeze``) is deprecated upstream from torch
2.13 on, though it still works there; it is kept because it runs in-process without ONNX Runtime.
"""

from __future__ import annotations

import contextlib
import json
import logging
import tempfile
import warnings
from collections.abc import Iterator, Mapping
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path
from typing import Any

import numpy as np
import torch
from torch import nn

from graspstab.common.errors import GraspstabError
from graspstab.common.io import atomic_path, reading
from graspstab.common.provenance import code_version, installed_versions
from graspstab.learning.models import CNNClassifier, RecurrentClassifier
from graspstab.learning.train import sigmoid
from graspstab.monitor.constants import (
    FRAME_SHAPE,
    MonitorConstants,
    MonitorError,
    write_constants,
)
from graspstab.monitor.scoring import check_windows

ONNX_OPSET = 18  # the torch.export-based exporter's lowest; onnxruntime 1.32 runs up to 23
ONNX_EXPORTERS = ("torchscript", "dynamo")  # torch.onnx.export(dynamo=False | True)
INPUT = "forces"
OUTPUTS = ("prob", "logit")
META_KEY = "graspstab_monitor"  # ONNX metadata_props key and TorchScript extra file stem
TS_EXTRA = f"{META_KEY}.json"
_EXAMPLE_BATCH = 2  # not 1: torch.export specialises a size-1 dimension to a constant
# logs one warning per torchvision operator it cannot register (torchvision is not a dependency)
_REGISTRATION_LOG = "torch.onnx._internal.exporter._registration"


class ExportError(RuntimeError, GraspstabError):
    """A model that cannot be exported (unknown architecture, an exporter failure)."""


class RawWindowModel(nn.Module):
    """The exported graph: raw windows -> (probability, logit), normalisation inside."""

    def __init__(self, model: nn.Module, constants: MonitorConstants) -> None:
        super().__init__()
        if not isinstance(model, CNNClassifier | RecurrentClassifier):
            raise ExportError(
                f"cannot export a {type(model).__name__}: only the learning stage's "
                "CNNClassifier and RecurrentClassifier (families cnn, gru, lstm) are supported"
            )
        self.model = model.eval()
        self.register_buffer("mean", torch.as_tensor(constants.mean, dtype=torch.float32))
        self.register_buffer("std", torch.as_tensor(constants.std, dtype=torch.float32))

    def forward(self, forces: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        """``forces (B, W, 5, 2)`` raw [N] -> ``prob (B,)``, ``logit (B,)``."""
        logit = self.model((forces - self.mean) / self.std)
        return torch.sigmoid(logit), logit


@contextlib.contextmanager
def _quiet(name: str) -> Iterator[None]:
    """Raise one logger to ERROR for the duration of a block."""
    logger = logging.getLogger(name)
    level = logger.level
    logger.setLevel(logging.ERROR)
    try:
        yield
    finally:
        logger.setLevel(level)


@contextlib.contextmanager
def _jit_quiet() -> Iterator[None]:
    """Silence the tracer's warnings and torch 2.13's deprecation notices of ``torch.jit``."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", torch.jit.TracerWarning)
        warnings.filterwarnings("ignore", r".*torch\.jit\.", DeprecationWarning)
        yield


def _example(constants: MonitorConstants) -> torch.Tensor:
    """A raw example batch around the training mean (tracing follows no data-dependent path)."""
    g = torch.Generator().manual_seed(0)
    noise = torch.randn(_EXAMPLE_BATCH, constants.window_steps, *FRAME_SHAPE, generator=g)
    mean = torch.as_tensor(constants.mean, dtype=torch.float32)
    return mean + noise * torch.as_tensor(constants.std, dtype=torch.float32)


def _extra(fmt: str, **more: Any) -> dict[str, Any]:
    """What the embedded record and the sidecar hold beside the constants: the file format and
    the exporting code's provenance."""
    packages = installed_versions(["torch", "onnx", "onnxruntime", "onnxscript"])
    return {
        "file_format": fmt,
        **more,
        "provenance": {"stage": "monitor", "code_version": code_version("monitor", "learning"),
                       "packages": packages},
    }  # fmt: skip


def _trace_apart(model: nn.Module, example: torch.Tensor) -> torch.jit.ScriptModule:
    """``model`` traced and frozen in a thread of its own: the tracer writes the Python call stack
    into the file's debug records, and the caller's (a Snakemake job's temporary script, its working
    directory) differs on every run; a fresh thread's stack holds only this module's frames, so a
    rerun exports the same bytes."""

    def trace() -> torch.jit.ScriptModule:
        with torch.no_grad():  # grad mode is per thread
            return torch.jit.freeze(torch.jit.trace(model, (example,)))

    with ThreadPoolExecutor(max_workers=1) as pool:
        return pool.submit(trace).result()


def export_torchscript(
    model: nn.Module,
    constants: MonitorConstants,
    path: str | Path,
    sidecar: str | Path | None = None,
) -> None:
    """Trace ``model`` (with its normalisation) to a frozen TorchScript file at ``path``; write
    the constants sidecar too when ``sidecar`` is given."""
    wrapped = RawWindowModel(model, constants).eval()
    extra = _extra("torchscript")
    record = json.dumps({**extra, **constants.to_dict()}, sort_keys=True)
    with torch.no_grad(), _jit_quiet(), atomic_path(path) as tmp:
        traced = _trace_apart(wrapped, _example(constants))
        # a file object: given a path, the archive's folder is named after the (random) temporary
        # file, and no two exports would be the same bytes
        with open(tmp, "wb") as fh:
            torch.jit.save(traced, fh, _extra_files={TS_EXTRA: record})
    if sidecar is not None:
        write_constants(sidecar, constants, extra)


def export_onnx(
    model: nn.Module,
    constants: MonitorConstants,
    path: str | Path,
    sidecar: str | Path | None = None,
    *,
    opset: int = ONNX_OPSET,
    exporter: str = "torchscript",
) -> None:
    """Export ``model`` (with its normalisation) to one self-contained ONNX file at ``path`` with
    ``exporter`` (one of :data:`ONNX_EXPORTERS`), dynamic batch axis, constants in its
    ``metadata_props``; the sidecar too when given."""
    import onnx

    if exporter not in ONNX_EXPORTERS:
        raise ExportError(f"unknown ONNX exporter {exporter!r}: monitor.onnx_exporter is one of "
                          f"{', '.join(ONNX_EXPORTERS)}")  # fmt: skip
    wrapped = RawWindowModel(model, constants).eval()
    family = constants.family or type(model).__name__
    if exporter == "dynamo":
        axes = {"dynamic_shapes": {INPUT: {0: torch.export.Dim("batch", min=1)}},
                "external_data": False}  # fmt: skip
    else:
        axes = {"dynamic_axes": {INPUT: {0: "batch"}}}
    with tempfile.TemporaryDirectory() as tmpdir:
        raw = Path(tmpdir) / "model.onnx"
        try:
            with warnings.catch_warnings(), _quiet(_REGISTRATION_LOG), torch.no_grad():
                warnings.simplefilter("ignore")
                torch.onnx.export(
                    wrapped, (_example(constants),), raw, dynamo=exporter == "dynamo",
                    opset_version=opset, input_names=[INPUT], output_names=list(OUTPUTS),
                    verbose=False, **axes,
                )  # fmt: skip
        except Exception as exc:  # noqa: BLE001 - any exporter failure, one clear message
            raise ExportError(
                f"the {family} model could not be exported to ONNX ({exporter} exporter, opset "
                f"{opset}, torch {torch.__version__}): {type(exc).__name__}: {exc}"
            ) from exc
        proto = onnx.load(str(raw))
    extra = _extra("onnx", opset=opset, exporter=exporter)
    record = json.dumps({**extra, **constants.to_dict()}, sort_keys=True)
    onnx.helper.set_model_props(proto, {META_KEY: record})
    onnx.checker.check_model(proto)
    with atomic_path(path) as tmp:
        onnx.save(proto, str(tmp))
    if sidecar is not None:
        write_constants(sidecar, constants, extra)


def _constants_from(text: str | bytes, source: str) -> MonitorConstants:
    """Constants from an embedded JSON record."""
    if not text:
        raise MonitorError(f"{source} carries no {META_KEY} record: export it with monitor.export")
    data: Mapping[str, Any] = json.loads(text)
    return MonitorConstants.from_dict(data, source=source)


class TorchScriptScorer:
    """A loaded TorchScript export as a scorer (raw windows in)."""

    def __init__(self, module: torch.jit.ScriptModule, constants: MonitorConstants) -> None:
        self.module = module
        self.constants = constants

    def score_one(self, window: np.ndarray) -> float:
        """Probability of one raw window ``(W, 5, 2)``."""
        with torch.inference_mode():
            _, logit = self.module(torch.from_numpy(window).unsqueeze(0))
        return float(sigmoid(np.float64(logit.item())))

    def __call__(self, windows: np.ndarray) -> np.ndarray:
        """Probabilities of raw windows ``(B, W, 5, 2)``."""
        x = torch.from_numpy(check_windows(windows, self.constants.window_steps))
        with torch.inference_mode():
            _, logits = self.module(x)
        return sigmoid(logits.double().numpy())


class OnnxScorer:
    """A loaded ONNX export on ONNX Runtime (CPU) as a scorer (raw windows in)."""

    def __init__(self, session: Any, constants: MonitorConstants) -> None:
        self.session = session
        self.constants = constants
        self._feed: dict[str, np.ndarray] = {}

    def score_one(self, window: np.ndarray) -> float:
        """Probability of one raw window ``(W, 5, 2)``."""
        self._feed[INPUT] = window[None]
        (logit,) = self.session.run(["logit"], self._feed)
        return float(sigmoid(np.float64(logit[0])))

    def __call__(self, windows: np.ndarray) -> np.ndarray:
        """Probabilities of raw windows ``(B, W, 5, 2)``."""
        x = check_windows(windows, self.constants.window_steps)
        (logits,) = self.session.run(["logit"], {INPUT: x})
        return sigmoid(logits.astype(np.float64))


def load_torchscript(path: str | Path) -> TorchScriptScorer:
    """Load a file written by :func:`export_torchscript` (CPU)."""
    extra = {TS_EXTRA: ""}
    with reading(path), _jit_quiet():
        module = torch.jit.load(str(path), map_location="cpu", _extra_files=extra)
    return TorchScriptScorer(module.eval(), _constants_from(extra[TS_EXTRA], str(path)))


def load_onnx(path: str | Path, *, threads: int = 1) -> OnnxScorer:
    """Load a file written by :func:`export_onnx` into an ONNX Runtime CPU session of
    ``threads`` intra-op threads (one inter-op thread, sequential execution)."""
    import onnxruntime as ort

    options = ort.SessionOptions()
    options.intra_op_num_threads = int(threads)
    options.inter_op_num_threads = 1
    options.execution_mode = ort.ExecutionMode.ORT_SEQUENTIAL
    options.graph_optimization_level = ort.GraphOptimizationLevel.ORT_ENABLE_ALL
    with reading(path):
        session = ort.InferenceSession(str(path), options, providers=["CPUExecutionProvider"])
    meta = session.get_modelmeta().custom_metadata_map.get(META_KEY, "")
    return OnnxScorer(session, _constants_from(meta, str(path)))
