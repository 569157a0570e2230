"""The streaming monitor's cost per frame at batch 1 on one thread, per family and format.

A controller pushes one force frame every 0.5 ms (the replay's 2 kHz); the monitor keeps the last
W frames and scores the window every ``--stride`` frames. For each model and format (PyTorch
eager, TorchScript, ONNX Runtime) this feeds a random raw trace through
``graspstab.monitor.stream.StreamingMonitor`` after the buffer has filled and a warm-up, times
every ``push``, and prints the mean, median and 99th percentile per frame against the frame
period, at stride 1 (a score every frame) and at each further ``--strides`` value (the workflow's
monitor scores every 10th frame, ``monitor.stride``). Issue 16's targets: every family below 0.5
ms (real time), the latency-aware pick at or below 0.1 ms in its best format.

Formats: PyTorch eager, TorchScript, ONNX Runtime (each scores the whole window), and for the CNN
``incremental`` (``graspstab.monitor.incremental``: each layer's shift-invariant part cached, so
a score recomputes only the positions the padding reaches). Each case also prints the
multiply-adds of one whole-window evaluation and the rate that scoring every frame would need:
a recurrent model must rerun its whole window per score (its state starts at the window's first
frame), so at stride 1 that rate bounds its cost from below in every format.

Models: trained checkpoints (``--checkpoint PATH``, repeatable; their own window, normalisation
and threshold), or, without any, random weights in the reference architectures: each family's
baseline (``config/model/<family>.yaml``) at the baseline window (``labels.window_s``, 0.2 s =
400 frames), and each family's sweep configuration at ``--pick-window-s`` (0.01 s = 20 frames,
the window the workflow's grasp-level monitor runs, ``monitor.window_s``), of which
``--pick-family``'s (LSTM by default) is the latency-aware pick. Weights do not change the cost.

    python benchmarks/monitor_latency.py [--frames 2000] [--warmup 200] [--strides 1 10]
        [--formats eager torchscript onnx incremental] [--checkpoint results/.../model.pt ...]

Torch runs one intra-op thread (``torch.set_num_threads(1)``), ONNX Runtime a session with
``intra_op_num_threads=1``, NumPy's BLAS one thread (threadpoolctl); the exports go to a
temporary directory.
"""

from __future__ import annotations

import argparse
import tempfile
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import torch
from threadpoolctl import threadpool_limits
from torch import nn

from graspstab.common.provenance import cpu_model, installed_versions
from graspstab.config import compose_config
from graspstab.labels.windows import step_counts
from graspstab.learning.models import build_model, count_parameters
from graspstab.monitor.checkpoint import read_trained
from graspstab.monitor.constants import MonitorConstants
from graspstab.monitor.export import export_onnx, export_torchscript, load_onnx, load_torchscript
from graspstab.monitor.incremental import IncrementalCNNScorer
from graspstab.monitor.scoring import TorchScorer, WindowScorer
from graspstab.monitor.stream import StreamingMonitor

CONFIG_DIR = Path(__file__).resolve().parents[1] / "config"
FORMATS = ("eager", "torchscript", "onnx", "incremental")
FRAME_PERIOD_MS = 0.5  # 2 kHz
PICK_TARGET_MS = 0.1


@dataclass
class Case:
    """One model to time: its label, the model and its constants."""

    label: str
    model: nn.Module
    constants: MonitorConstants
    pick: bool = False


def reference_cases(pick_family: str, pick_window_s: float, seed: int) -> list[Case]:
    """Random-weight baselines at the baseline window and the latency-aware pick."""
    cfg = compose_config(CONFIG_DIR)
    dt, labels = float(cfg["replay"]["timestep"]), cfg["labels"]
    steps = {w: step_counts(w, labels["offset_s"], labels["horizon_s"], dt)[0]
             for w in (labels["window_s"], pick_window_s)}  # fmt: skip
    rng = np.random.default_rng(seed)
    mean = np.stack([rng.uniform(1.0, 4.0, 5), rng.uniform(0.1, 1.0, 5)], axis=-1)
    std = np.stack([rng.uniform(0.2, 1.0, 5), rng.uniform(0.05, 0.3, 5)], axis=-1)
    specs = [(f"{f} baseline", cfg["model"][f], labels["window_s"], False) for f in cfg["model"]]
    # every family's sweep configuration at the pick's window: what the workflow's grasp-level
    # monitor runs (monitor.window_s); the pick family's is the latency-aware pick
    specs += [(f"{f} pick" if f == pick_family else f"{f} sweep", cfg["sweep"]["models"][f],
               pick_window_s, f == pick_family) for f in cfg["sweep"]["models"]]  # fmt: skip
    cases = []
    for label, spec, window_s, pick in specs:
        torch.manual_seed(seed)
        model = build_model(spec).eval()
        c = MonitorConstants(mean, std, 0.5, steps[window_s], family=spec["family"], model=spec)
        cases.append(Case(f"{label} {window_s:g} s", model, c, pick))
    return cases


def checkpoint_cases(paths: list[str]) -> list[Case]:
    """Trained checkpoints with their own constants."""
    cases = []
    for path in paths:
        model, c = read_trained(path)
        cases.append(Case(f"{c.family} W={c.window_steps} ({path})", model, c))
    return cases


def window_macs(model: nn.Module, steps: int) -> int:
    """Multiply-adds of one whole-window evaluation (convolutions, recurrences, linear layers)."""
    total = 0
    for mod in model.modules():
        if isinstance(mod, nn.Conv1d):
            total += mod.weight.numel() * steps
        elif isinstance(mod, nn.RNNBase):
            total += sum(p.numel() for name, p in mod.named_parameters()
                         if name.startswith("weight")) * steps  # fmt: skip
        elif isinstance(mod, nn.Linear):
            total += mod.weight.numel()
    return total


def applies(case: Case, fmt: str) -> bool:
    """Whether a format runs this case's model (incremental scoring is for the CNN)."""
    return fmt != "incremental" or case.constants.family == "cnn"


def scorer_for(case: Case, fmt: str, stem: Path) -> WindowScorer:
    """The case's model in one format (exported to ``stem`` + suffix where needed)."""
    if fmt == "incremental":
        return IncrementalCNNScorer(case.model, case.constants)
    if fmt == "eager":
        return TorchScorer(case.model, case.constants)
    if fmt == "torchscript":
        export_torchscript(case.model, case.constants, stem.with_suffix(".ts"))
        return load_torchscript(stem.with_suffix(".ts"))
    export_onnx(case.model, case.constants, stem.with_suffix(".onnx"))
    return load_onnx(stem.with_suffix(".onnx"), threads=1)


def time_monitor(
    monitor: StreamingMonitor, frames: int, warmup: int, seed: int
) -> dict[str, float]:
    """Per-frame push times [ms] over ``frames`` frames after the buffer filled and a warm-up."""
    c = monitor.constants
    rng = np.random.default_rng(seed)
    total = c.window_steps + warmup + frames
    trace = (c.mean + c.std * rng.normal(size=(total, 5, 2))).astype(np.float32)
    push: Callable[[Any], Any] = monitor.push
    monitor.reset()
    for frame in trace[: total - frames]:
        push(frame)
    times = np.empty(frames)
    clock = time.perf_counter
    for i, frame in enumerate(trace[total - frames :]):
        t0 = clock()
        push(frame)
        times[i] = clock() - t0
    ms = times * 1e3
    return {"mean": float(ms.mean()), "median": float(np.median(ms)),
            "p99": float(np.quantile(ms, 0.99))}  # fmt: skip


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--checkpoint", action="append", default=[], help="trained model.pt")
    parser.add_argument("--formats", nargs="+", choices=FORMATS, default=list(FORMATS))
    parser.add_argument("--frames", type=int, default=2000, help="timed frames per case")
    parser.add_argument("--warmup", type=int, default=200, help="untimed scored frames first")
    parser.add_argument("--strides", type=int, nargs="+", default=[1, 10])
    parser.add_argument("--pick-family", default="lstm")
    parser.add_argument("--pick-window-s", type=float, default=0.01)
    parser.add_argument("--seed", type=int, default=0)
    args = parser.parse_args()

    torch.set_num_threads(1)
    cases = (checkpoint_cases(args.checkpoint) if args.checkpoint
             else reference_cases(args.pick_family, args.pick_window_s, args.seed))  # fmt: skip
    versions = installed_versions(["torch", "onnxruntime", "numpy"])
    print(f"CPU {cpu_model()}; torch {versions['torch']} ({torch.get_num_threads()} thread), "
          f"onnxruntime {versions['onnxruntime']} (1 intra-op thread), numpy "
          f"{versions['numpy']} (1 BLAS thread); {args.frames} timed frames after "
          f"{args.warmup} warm-up; frame period {FRAME_PERIOD_MS} ms (2 kHz)")  # fmt: skip
    header = (f"{'model':<26} {'W':>4} {'params':>8} {'format':<12} {'stride':>6} "
              f"{'mean ms':>8} {'median':>8} {'p99':>8} {'of 0.5 ms':>9}  verdict")  # fmt: skip
    with tempfile.TemporaryDirectory() as tmpdir, threadpool_limits(1):
        for k, case in enumerate(cases):
            steps = case.constants.window_steps
            macs = window_macs(case.model, steps)
            need = macs / (FRAME_PERIOD_MS * 1e-3) / 1e9
            print(f"\n{case.label}: {macs / 1e6:.2f} M multiply-adds per whole-window score; "
                  f"whole-window scoring every frame needs {need:.1f} G multiply-adds/s")
            print(header)
            print("-" * len(header))
            best: dict[int, tuple[float, str]] = {}
            for fmt in [f for f in args.formats if applies(case, f)]:
                scorer = scorer_for(case, fmt, Path(tmpdir) / f"case{k}")
                for stride in args.strides:
                    monitor = StreamingMonitor.from_scorer(scorer, stride=stride)
                    t = time_monitor(monitor, args.frames, args.warmup, args.seed)
                    verdict = "real time" if t["mean"] < FRAME_PERIOD_MS else "TOO SLOW"
                    print(f"{case.label:<26} {steps:>4} {count_parameters(case.model):>8} "
                          f"{fmt:<12} {stride:>6} {t['mean']:>8.4f} {t['median']:>8.4f} "
                          f"{t['p99']:>8.4f} {t['mean'] / FRAME_PERIOD_MS:>8.0%}  "
                          f"{verdict}")  # fmt: skip
                    best[stride] = min(best.get(stride, (t["mean"], fmt)), (t["mean"], fmt))
            for stride, (ms, fmt) in sorted(best.items()):
                line = f"  -> stride {stride}: best {fmt} {ms:.4f} ms/frame"
                if case.pick:
                    ok = "meets" if ms <= PICK_TARGET_MS else "misses"
                    line += f"; the pick {ok} the {PICK_TARGET_MS} ms target"
                else:
                    ok = "meets" if ms < FRAME_PERIOD_MS else "misses"
                    line += f"; {ok} the {FRAME_PERIOD_MS} ms real-time budget"
                print(line)


if __name__ == "__main__":
    main()
