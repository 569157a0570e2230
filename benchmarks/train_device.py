"""Training throughput per family, device and precision, to budget the studies (3.5.2).

For every family's baseline configuration (config/model/<family>.yaml), thread count, device
(``train.device``: cpu, cuda, or auto) and precision (fp32, or amp: ``train.mixed_precision:
true``), a fresh subprocess trains on the dataset's training split exactly as ``fit`` does
(batches gathered from the memory map and normalised, AdamW, gradient clipping, autocast under
amp) for one warm-up epoch and ``--epochs`` timed ones, then times one validation pass. Reported:
epochs per second, the median epoch time, the same scaled to 10,000 training windows and to the
reference's 43,978 (thesis 4.1.1), the validation pass per 10,000 windows, the subprocess's peak
resident memory (``ru_maxrss``) and, on a GPU, its peak allocated memory; then the thesis
profile's baseline training (families x seeds x at most max_epochs epochs over the reference's
training and validation windows) projected per device. Without the dataset, random windows stand
in (the cost does not depend on the values). A CUDA device that torch cannot see is skipped,
with a line that says so.

    python benchmarks/train_device.py [--dataset results/datasets/baseline] [--windows 2000]
        [--threads 1 2] [--epochs 2] [--device cpu cuda] [--precision fp32 amp] [--json FILE]
"""

from __future__ import annotations

import argparse
import json
import resource
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

import numpy as np

from graspstab.common.provenance import cpu_model

REPO = Path(__file__).resolve().parents[1]
REFERENCE_TRAIN = 43_978  # training windows of the reference's fixed split (thesis 4.1.1)
REFERENCE_VAL = 12_052
PER = 10_000  # windows per scaled figure


def synthetic_dataset(root: Path, train: int, val: int, steps: int, seed: int = 0) -> Path:
    """A dataset directory of random windows in label_windows' layout (10 % unstable)."""
    import polars as pl

    from graspstab.labels.dataset import normalisation

    rng = np.random.default_rng(seed)
    n = train + val
    windows = np.lib.format.open_memmap(
        root / "windows.npy", mode="w+", dtype=np.float32, shape=(n, steps, 5, 2)
    )
    for i in range(0, n, 1024):  # fill in chunks: never more than 1024 windows in memory
        windows[i : i + 1024] = rng.random((min(1024, n - i), steps, 5, 2), dtype=np.float32)
    windows.flush()
    split = ["train"] * train + ["val"] * val
    index = pl.DataFrame({
        "object": [f"{s}_{k % 4}" for k, s in enumerate(split)],
        "grasp_id": np.arange(n) // 20, "shard": np.zeros(n, np.int32),
        "start": np.zeros(n, np.int64), "end": np.full(n, steps, np.int64),
        "r": np.zeros(n), "label": (rng.random(n) < 0.1).astype(np.int8), "split": split,
    }).with_row_index("sample_id")  # fmt: skip
    index.write_parquet(root / "index.parquet")
    (root / "normalisation.json").write_text(json.dumps(normalisation(windows, index)))
    return root


def _peak_rss_mib() -> float:
    """Peak resident set size of this process [MiB] (ru_maxrss is KiB on Linux, bytes on macOS)."""
    rss = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
    return rss / 2**20 if sys.platform == "darwin" else rss / 1024


def worker(job: dict[str, Any]) -> dict[str, Any]:
    """One (family, threads) measurement in this (fresh) process."""
    import torch
    from torch import nn

    from graspstab.learning.data import load_window_data
    from graspstab.learning.models import build_model, count_parameters
    from graspstab.learning.train import TrainSettings, train_epoch

    torch.set_num_threads(int(job["threads"]))
    spec = job["model"]
    train = {**job["train"], "device": job["device"], "mixed_precision": job["amp"]}
    settings = TrainSettings.from_config(train, spec)
    placement = settings.placement()
    device = placement.device
    data = load_window_data(job["dataset"])
    rows, val_rows = data.rows("train"), data.rows("val")
    torch.manual_seed(0)
    model = build_model(spec).to(device)
    optimiser = torch.optim.AdamW(
        model.parameters(), lr=settings.learning_rate, weight_decay=settings.weight_decay
    )
    loss_fn = nn.BCEWithLogitsLoss()
    scaler = placement.scaler()
    rng = np.random.default_rng(0)
    setup_rss = _peak_rss_mib()

    def sync() -> None:
        if device.type == "cuda":
            torch.cuda.synchronize(device)

    def epoch() -> float:
        """One training epoch exactly as ``fit`` runs it (without the validation pass)."""
        sync()
        t0 = time.perf_counter()
        train_epoch(model, data, rows[rng.permutation(len(rows))], settings, optimiser, loss_fn,
                    placement, scaler)  # fmt: skip
        sync()
        return time.perf_counter() - t0

    def evaluation() -> float:
        """One inference pass over the validation split (eval batch size)."""
        model.eval()
        sync()
        t0 = time.perf_counter()
        with torch.inference_mode(), placement.autocast():
            for _, x in data.batches(val_rows, settings.eval_batch_size):
                model(x.to(device)).cpu()
        sync()
        return time.perf_counter() - t0

    epoch()  # warm-up: allocator, page cache, kernels
    times = [epoch() for _ in range(int(job["epochs"]))]
    val_s = evaluation() if len(val_rows) else float("nan")
    seconds = statistics.median(times)
    out = {
        "family": spec["family"],
        "threads": int(job["threads"]),
        "device": device.type,
        "precision": "amp" if placement.mixed_precision else "fp32",
        "amp_dtype": placement.describe()["amp_dtype"],
        "epochs_per_s": 1.0 / seconds,
        "parameters": count_parameters(model),
        "window_steps": data.window_steps,
        "train_windows": int(len(rows)),
        "val_windows": int(len(val_rows)),
        "batch_size": settings.batch_size,
        "epoch_s": seconds,
        "epoch_times_s": times,
        "epoch_s_per_10k": seconds * PER / len(rows),
        "val_pass_s_per_10k": val_s * PER / len(val_rows) if len(val_rows) else float("nan"),
        "setup_rss_mib": setup_rss,
        "peak_rss_mib": _peak_rss_mib(),
    }
    if device.type == "cuda":
        out["peak_gpu_mib"] = torch.cuda.max_memory_allocated(device) / 2**20
    return out


def main() -> None:
    """Measure every (family, threads) pair in its own subprocess and print the table."""
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument(
        "--dataset",
        type=Path,
        default=REPO / "results/datasets/baseline",
        help="a window dataset directory; random windows when it does not exist",
    )
    ap.add_argument(
        "--windows",
        type=int,
        default=2000,
        help="training windows of the synthetic stand-in (validation in the "
        "reference's proportion)",
    )
    ap.add_argument(
        "--window-steps",
        type=int,
        default=None,
        help="W of the synthetic stand-in (default: the configured baseline window)",
    )
    ap.add_argument("--threads", type=int, nargs="+", default=[1, 2])
    ap.add_argument("--epochs", type=int, default=2, help="timed epochs after one warm-up")
    ap.add_argument("--families", nargs="+", default=["cnn", "gru", "lstm"])
    ap.add_argument("--device", nargs="+", choices=["auto", "cpu", "cuda"], default=["cpu"],
                    help="train.device values to measure (auto: CUDA when torch sees a GPU)")
    ap.add_argument("--precision", nargs="+", choices=["fp32", "amp"], default=["fp32"],
                    help="amp: train.mixed_precision: true (bfloat16 autocast on the CPU)")
    ap.add_argument("--config-dir", type=Path, default=REPO / "config")
    ap.add_argument("--json", type=Path, help="also write the measurements here")
    ap.add_argument("--worker", help=argparse.SUPPRESS)
    args = ap.parse_args()  # fmt: skip
    if args.worker:
        print(json.dumps(worker(json.loads(args.worker))))
        return

    import torch

    from graspstab.config import load_config
    from graspstab.labels.windows import step_counts

    cfg = load_config(config_dir=args.config_dir,
                      schema_path=REPO / "workflow/schemas/config.schema.yaml",
                      snakemake_config={})  # fmt: skip
    thesis = load_config(config_dir=args.config_dir,
                         schema_path=REPO / "workflow/schemas/config.schema.yaml",
                         snakemake_config={"profile": "thesis"}, check_files=False)  # fmt: skip
    labels, dt = cfg["labels"], float(cfg["replay"]["timestep"])
    steps = (
        args.window_steps
        or step_counts(labels["window_s"], labels["offset_s"], labels["horizon_s"], dt)[0]
    )
    devices = []
    for device in dict.fromkeys(args.device):
        if device == "cuda" and not torch.cuda.is_available():
            print("device cuda: torch sees no GPU here, skipped (run this on a GPU machine)")
            continue
        devices.append(device)
    if not devices:
        raise SystemExit("no device to measure")
    train = {k: v for k, v in cfg["train"].items() if k != "seeds"}

    with tempfile.TemporaryDirectory(prefix="train_device_") as tmp:
        if (args.dataset / "index.parquet").is_file():
            dataset, source = args.dataset, str(args.dataset)
        else:
            val = max(2, round(args.windows * REFERENCE_VAL / REFERENCE_TRAIN))
            dataset = synthetic_dataset(Path(tmp), args.windows, val, steps)
            source = f"synthetic random windows ({args.windows} train, {val} val, W={steps})"
        results = []
        for device in devices:
            for precision in args.precision:
                for family in args.families:
                    for threads in args.threads:
                        job = {"model": cfg["model"][family], "train": train,
                               "dataset": str(dataset), "threads": threads,
                               "epochs": args.epochs, "device": device,
                               "amp": precision == "amp"}  # fmt: skip
                        proc = subprocess.run(
                            [sys.executable, __file__, "--worker", json.dumps(job)],
                            capture_output=True, text=True, cwd=REPO,
                        )  # fmt: skip
                        if proc.returncode:
                            sys.stderr.write(proc.stderr)
                            raise SystemExit(f"{family} x {threads} threads on {device} "
                                             f"({precision}) failed")  # fmt: skip
                        results.append(json.loads(proc.stdout.strip().splitlines()[-1]))

    names = {"cpu": cpu_model()}
    if torch.cuda.is_available():
        names["cuda"] = torch.cuda.get_device_name(0)
    print(f"torch {torch.__version__}; " + "; ".join(f"{k}: {v}" for k, v in names.items()))
    print(f"dataset: {source}")
    print(f"median of {args.epochs} epoch(s) after one warm-up; batch {train['batch_size']}")
    head = (
        f"{'family':6} {'device':6} {'prec':>4} {'thr':>3} {'params':>8} {'W':>4} {'train':>6} "
        f"{'epoch/s':>8} {'s/epoch':>9} {'s/10k':>8} {'s@43,978':>9} {'val s/10k':>9} "
        f"{'RSS MiB':>8} {'GPU MiB':>8}"
    )
    print(head)
    print("-" * len(head))
    for r in results:
        gpu = f"{r['peak_gpu_mib']:>8.0f}" if "peak_gpu_mib" in r else f"{'-':>8}"
        print(
            f"{r['family']:6} {r['device']:6} {r['precision']:>4} {r['threads']:>3} "
            f"{r['parameters']:>8,} {r['window_steps']:>4} {r['train_windows']:>6} "
            f"{r['epochs_per_s']:>8.3f} {r['epoch_s']:>9.3f} {r['epoch_s_per_10k']:>8.2f} "
            f"{r['epoch_s_per_10k'] * REFERENCE_TRAIN / PER:>9.1f} "
            f"{r['val_pass_s_per_10k']:>9.2f} {r['peak_rss_mib']:>8.0f} {gpu}"
        )
    print("s/10k: epoch time scaled to 10,000 training windows; s@43,978: extrapolated to the "
          "reference's training split; val s/10k: one validation pass per 10,000 windows "
          f"(the reference's validation split has {REFERENCE_VAL:,}); RSS MiB: peak resident "
          "memory of the measuring process; GPU MiB: peak allocated on the GPU")  # fmt: skip
    print()
    print(thesis_projection(results, thesis["train"]))
    if args.json:
        args.json.write_text(json.dumps(results, indent=1))


def thesis_projection(results: list[dict[str, Any]], train: dict[str, Any]) -> str:
    """The thesis profile's baseline training per (device, precision, threads): every family's
    seeds for at most max_epochs epochs, each epoch a training pass over the reference's 43,978
    windows plus a validation pass over its 12,052, at the measured rates (an upper bound: early
    stopping ends runs sooner)."""
    seeds, epochs = len(train["seeds"]), int(train["max_epochs"])
    lines = [
        f"thesis baseline training ({seeds} seeds x <= {epochs} epochs per family, "
        f"{REFERENCE_TRAIN:,} train + {REFERENCE_VAL:,} val windows), one process:"
    ]
    groups: dict[tuple[str, str, int], dict[str, float]] = {}
    for r in results:
        per_epoch = (r["epoch_s_per_10k"] * REFERENCE_TRAIN + r["val_pass_s_per_10k"]
                     * REFERENCE_VAL) / PER  # fmt: skip
        key = (r["device"], r["precision"], r["threads"])
        groups.setdefault(key, {})[r["family"]] = per_epoch * seeds * epochs
    for (device, precision, threads), fams in groups.items():
        parts = ", ".join(f"{f} {s / 3600:.1f} h" for f, s in fams.items())
        lines.append(f"  {device} {precision} {threads} thread(s): {parts}; "
                     f"all {sum(fams.values()) / 3600:.1f} h")  # fmt: skip
    return "\n".join(lines)


if __name__ == "__main__":
    main()
