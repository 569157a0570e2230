"""TorchScript and ONNX exports: parity with eager PyTorch per family, constants round trip."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import numpy as np
import pytest
import torch
from torch import nn

from graspstab.common.io import UnreadableArtefact
from graspstab.learning.models import build_model
from graspstab.monitor import export
from graspstab.monitor.constants import MonitorConstants, MonitorError, read_constants
from graspstab.monitor.export import (
    ExportError,
    export_onnx,
    export_torchscript,
    load_onnx,
    load_torchscript,
)
from graspstab.monitor.scoring import TorchScorer
from graspstab.monitor.stream import StreamingMonitor

STEPS = 16
# Each branch of the exported graph: CNN; recurrent mean pooling; bidirectional and
# unidirectional last-step pooling.
SPECS: dict[str, dict[str, Any]] = {
    "cnn": {"family": "cnn", "base_channels": 4, "kernel_sizes": [5, 5, 3]},
    "gru": {"family": "gru", "hidden_size": 8, "num_layers": 2, "bidirectional": True,
            "pooling": "last"},
    "lstm": {"family": "lstm", "hidden_size": 8, "num_layers": 1, "pooling": "mean"},
    "lstm_last": {"family": "lstm", "hidden_size": 8, "num_layers": 2, "pooling": "last"},
}  # fmt: skip


@pytest.fixture(autouse=True)
def _one_thread() -> None:
    torch.set_num_threads(1)


def _constants(spec: dict[str, Any]) -> MonitorConstants:
    rng = np.random.default_rng(3)
    mean = np.stack([rng.uniform(1.0, 4.0, 5), rng.uniform(0.1, 1.0, 5)], axis=-1)
    std = np.stack([rng.uniform(0.2, 1.0, 5), rng.uniform(0.05, 0.3, 5)], axis=-1)
    return MonitorConstants(mean, std, 0.37, STEPS, family=spec["family"], model=spec)


def _windows(batch: int, constants: MonitorConstants, seed: int) -> np.ndarray:
    """Raw windows around the statistics, in newtons."""
    z = np.random.default_rng(seed).normal(size=(batch, STEPS, 5, 2))
    return (constants.mean + 1.5 * constants.std * z).astype(np.float32)


# Every case through the default (trace-based) ONNX exporter; the torch.export-based one on the
# recurrent case with the most branches (two layers, bidirectional, last-step pooling).
CASES = [(name, "torchscript") for name in SPECS] + [("gru", "dynamo")]


@pytest.fixture(scope="module", params=CASES, ids=[f"{n}-{e}" for n, e in CASES])
def exported(request: pytest.FixtureRequest, tmp_path_factory: pytest.TempPathFactory) -> dict:
    """One small random model per case, exported to both formats with sidecars."""
    torch.set_num_threads(1)
    name, exporter = request.param
    spec = SPECS[name]
    torch.manual_seed(0)
    model = build_model(spec).eval()
    constants = _constants(spec)
    root = tmp_path_factory.mktemp(f"{name}_{exporter}")
    files = {k: root / name for k, name in [("ts", "model.ts"), ("ts_json", "model.ts.json"),
                                           ("onnx", "model.onnx"),
                                           ("onnx_json", "model.onnx.json")]}  # fmt: skip
    export_torchscript(model, constants, files["ts"], files["ts_json"])
    export_onnx(model, constants, files["onnx"], files["onnx_json"], exporter=exporter)
    return {"model": model, "constants": constants, "exporter": exporter, **files}


@pytest.mark.parametrize("batch", [1, 5])
def test_exports_match_eager_pytorch(exported: dict, batch: int) -> None:
    constants = exported["constants"]
    eager = TorchScorer(exported["model"], constants)
    x = _windows(batch, constants, seed=batch)
    reference = eager(x)
    assert reference.shape == (batch,)
    for scorer in (load_torchscript(exported["ts"]), load_onnx(exported["onnx"])):
        np.testing.assert_allclose(scorer(x), reference, rtol=0, atol=1e-6)
        assert scorer.score_one(x[0]) == pytest.approx(reference[0], abs=1e-6)
    if batch > 1:
        assert reference.std() > 1e-4  # distinct windows give distinct scores: the check bites


def test_onnx_graph_outputs_probability_and_logit_with_a_dynamic_batch(exported: dict) -> None:
    session = load_onnx(exported["onnx"]).session
    (inp,) = session.get_inputs()
    assert inp.name == "forces" and isinstance(inp.shape[0], str) and inp.shape[1:] == [STEPS, 5, 2]
    x = _windows(3, exported["constants"], seed=7)
    prob, logit = session.run(["prob", "logit"], {"forces": x})
    mean = torch.as_tensor(exported["constants"].mean, dtype=torch.float32)
    std = torch.as_tensor(exported["constants"].std, dtype=torch.float32)
    with torch.inference_mode():
        eager = exported["model"]((torch.from_numpy(x) - mean) / std)
    np.testing.assert_allclose(logit, eager.numpy(), rtol=0, atol=1e-5)
    np.testing.assert_allclose(prob, torch.sigmoid(eager).numpy(), rtol=0, atol=1e-6)
    if exported["exporter"] == "torchscript":  # the recurrent layer as ONNX's own operator
        import onnx

        ops = {node.op_type for node in onnx.load(str(exported["onnx"])).graph.node}
        family = exported["constants"].family
        assert (family.upper() in ops) == (family != "cnn"), ops


def test_constants_round_trip_beside_and_inside(exported: dict) -> None:
    constants = exported["constants"]
    copies = [read_constants(exported["ts_json"]), read_constants(exported["onnx_json"]),
              load_torchscript(exported["ts"]).constants,
              load_onnx(exported["onnx"]).constants]  # fmt: skip
    for got in copies:
        np.testing.assert_array_equal(got.mean, constants.mean)
        np.testing.assert_array_equal(got.std, constants.std)
        assert (got.threshold, got.window_steps) == (0.37, STEPS)
        assert (got.family, got.model) == (constants.family, constants.model)
    sidecar = json.loads(exported["onnx_json"].read_text())
    assert sidecar["file_format"] == "onnx" and sidecar["opset"] == export.ONNX_OPSET
    assert sidecar["exporter"] == exported["exporter"]
    assert sidecar["provenance"]["packages"]["onnxruntime"] != "not installed"


def test_monitor_on_an_export_streams_like_the_eager_monitor(exported: dict) -> None:
    c = exported["constants"]
    rng = np.random.default_rng(11)
    trace = (c.mean + c.std * rng.normal(size=(3 * STEPS, 5, 2))).astype(np.float32)
    eager = StreamingMonitor(exported["model"], c.mean, c.std, c.threshold, STEPS).run(trace)
    onnx_out = StreamingMonitor.from_scorer(load_onnx(exported["onnx"]), stride=2).run(trace)
    scored = ~np.isnan(onnx_out.prob)
    assert scored.sum() == (len(trace) - STEPS) // 2 + 1
    np.testing.assert_allclose(onnx_out.prob[scored], eager.prob[scored], rtol=0, atol=1e-6)
    ts_out = StreamingMonitor.from_scorer(load_torchscript(exported["ts"])).run(trace)
    np.testing.assert_allclose(ts_out.prob, eager.prob, rtol=0, atol=1e-6)  # NaNs align too


def test_exported_scorers_reject_windows_of_another_length(exported: dict) -> None:
    x = np.zeros((2, STEPS + 1, 5, 2), dtype=np.float32)
    for scorer in (load_torchscript(exported["ts"]), load_onnx(exported["onnx"])):
        with pytest.raises(MonitorError, match=rf"\(B, {STEPS}, 5, 2\)"):
            scorer(x)


def test_unknown_architecture_and_exporter_failure_are_clear_errors(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    constants = _constants(SPECS["cnn"])
    with pytest.raises(ExportError, match="only the learning stage's"):
        export_torchscript(nn.Linear(10, 1), constants, tmp_path / "x.ts")

    def broken(*args: Any, **kwargs: Any) -> None:
        raise RuntimeError("unsupported operator aten::foo")

    with pytest.raises(ExportError, match="unknown ONNX exporter 'jit'.*torchscript, dynamo"):
        export_onnx(build_model(SPECS["cnn"]), constants, tmp_path / "x.onnx", exporter="jit")
    monkeypatch.setattr(torch.onnx, "export", broken)
    for exporter in export.ONNX_EXPORTERS:
        with pytest.raises(ExportError, match=f"cnn model could not be exported to ONNX "
                                              f"\\({exporter} exporter.*aten::foo"):  # fmt: skip
            export_onnx(build_model(SPECS["cnn"]), constants, tmp_path / "x.onnx",
                        exporter=exporter)  # fmt: skip
    assert not (tmp_path / "x.onnx").exists()


@pytest.mark.filterwarnings("ignore:`torch.jit:DeprecationWarning")
def test_files_without_constants_or_truncated_are_named(tmp_path: Path) -> None:
    plain = torch.jit.trace(nn.Linear(2, 1), torch.zeros(1, 2))
    torch.jit.save(plain, str(tmp_path / "plain.ts"))
    with pytest.raises(MonitorError, match="carries no graspstab_monitor record"):
        load_torchscript(tmp_path / "plain.ts")
    (tmp_path / "cut.onnx").write_bytes(b"\x08\x07garbage")
    with pytest.raises(UnreadableArtefact, match="cut.onnx is unreadable"):
        load_onnx(tmp_path / "cut.onnx")
