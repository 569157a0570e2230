"""The window dataset builder on synthetic replays written in the replay stage's layout."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import polars as pl
import yaml
from conftest import CONFIG_DIR

from graspstab.common.io import save_npz
from graspstab.labels.dataset import load_windows
from graspstab.labels.label_windows import label_windows
from graspstab.replay.traces import trace_key

LABELS = yaml.safe_load((CONFIG_DIR / "labels" / "default.yaml").read_text())
DT = 0.0005
T = 12000  # 6 s


def _trace(slip_at: int, loss_at: int, scale: float, rng: np.random.Generator) -> dict:
    """Held still, then slipping at 5 mm/s from ``slip_at``; contact lost at ``loss_at``."""
    vel = np.zeros((T, 3), np.float32)
    vel[slip_at:, 2] = -0.005
    dist = np.full(T, -0.001, np.float32)
    dist[loss_at:] = np.nan
    normal = (scale * (1 + rng.random((T, 5)))).astype(np.float32)
    shear = (0.3 * normal).astype(np.float32)
    return {"position": np.zeros((T, 3), np.float32), "velocity": vel, "min_distance": dist,
            "normal": normal, "shear": shear}  # fmt: skip


def _write_replays(
    root: Path, object_id: str, shard: int, traces: dict[int, dict]
) -> tuple[Path, Path]:
    rows = [{"grasp_id": g, "object": object_id, "shard": shard, "diverged": False}
            for g in traces]  # fmt: skip
    table = root / object_id / f"replays_{shard}.parquet"
    table.parent.mkdir(parents=True, exist_ok=True)
    pl.DataFrame(rows).write_parquet(table)
    # the traces live apart from the table, under another name: label_windows must read the
    # declared file, not one derived from the table's path
    trace_file = root / "elsewhere" / f"{object_id}_{shard}_forces.npz"
    save_npz(trace_file,
             **{trace_key(g, c): v for g, tr in traces.items() for c, v in tr.items()})  # fmt: skip
    return table, trace_file


def _replays(tmp_path: Path, test_scale: float) -> list[tuple[Path, Path]]:
    rng = np.random.default_rng(0)
    return [
        _write_replays(tmp_path, "obj_train", 0, {0: _trace(6000, 10000, 1.0, rng),
                                                   1: _trace(12000, 12000, 2.0, rng)}),
        _write_replays(tmp_path, "obj_test", 0, {7: _trace(8000, 11000, test_scale, rng)}),
    ]  # fmt: skip


def test_dataset_windows_labels_splits_and_normalisation(tmp_path: Path) -> None:
    splits = {"obj_train": "train", "obj_test": "test"}
    index = label_windows(_replays(tmp_path, 1.0), tmp_path / "ds", LABELS, splits, 0.2, DT, 0)
    windows = load_windows(tmp_path / "ds")
    assert windows.shape == (index.height, 400, 5, 2) and windows.dtype == np.float32
    assert isinstance(windows, np.memmap)
    # every window of a grasp carries its object's split; 20 windows per long grasp at most
    per_grasp = index.group_by("object", "grasp_id").agg(pl.col("split").n_unique(), pl.len())
    assert (per_grasp["split"] == 1).all() and (per_grasp["len"] <= 20).all()
    assert dict(zip(index["object"], index["split"], strict=True)) == splits
    # windows are the trace slices [start, start + W) of (normal, shear)
    with np.load(tmp_path / "elsewhere" / "obj_train_0_forces.npz") as npz:
        row = index.filter(pl.col("grasp_id") == 0).row(3, named=True)
        expect = np.stack([npz[trace_key(0, c)] for c in ("normal", "shear")], -1)
        np.testing.assert_array_equal(windows[row["sample_id"]], expect[row["start"]:row["end"]])
    # grasp 0 slips from row 6000: targets after it are unstable, targets before it stable
    g0 = index.filter(pl.col("grasp_id") == 0)
    first = g0["start"].to_numpy() + 400 + 200
    assert (g0["label"].to_numpy()[first >= 6000] == 1).all()
    assert (g0["label"].to_numpy()[first + 300 <= 6000] == 0).all()
    assert set(index["label"].unique()) <= {0, 1}
    # normalisation: training windows only; changing the test object's forces changes nothing
    norm = json.loads((tmp_path / "ds" / "normalisation.json").read_text())
    train = windows[(index["split"] == "train").to_numpy()].reshape(-1, 5, 2).astype(np.float64)
    np.testing.assert_allclose(norm["mean"], train.mean(0), rtol=1e-6)
    np.testing.assert_allclose(norm["std"], train.std(0), rtol=1e-6)
    (tmp_path / "ds2").mkdir()
    label_windows(_replays(tmp_path / "other", 50.0), tmp_path / "ds2", LABELS, splits, 0.2, DT, 0)
    assert json.loads((tmp_path / "ds2" / "normalisation.json").read_text()) == norm
    # deterministic for a seed
    again = label_windows(_replays(tmp_path / "b", 1.0), tmp_path / "ds3", LABELS, splits, 0.2, DT,
                          0)  # fmt: skip
    assert again["start"].to_list() == index["start"].to_list()


def test_the_event_form_reads_what_the_failure_needs(tmp_path: Path) -> None:
    """labels.form event through label_windows (the rule's entry), under eq. 23's source: the
    anatomy's failure reads positions, which that source alone does not ask for. The test
    object slides away from 4 s (the position follows its velocity): its positive windows are
    those whose target interval holds the onset."""
    rng = np.random.default_rng(0)
    tr = _trace(8000, 11000, 1.0, rng)
    tr["position"] = np.cumsum(tr["velocity"].astype(np.float64) * DT, axis=0).astype(np.float32)
    held = _trace(12000, 12000, 1.0, rng)
    replays = [_write_replays(tmp_path, "obj_train", 0, {0: held}),
               _write_replays(tmp_path, "obj_test", 0, {7: tr})]  # fmt: skip
    labels = {**LABELS, "form": "event", "windows_per_grasp": 10_000}
    index = label_windows(replays, tmp_path / "ds", labels, {"obj_train": "train",
                          "obj_test": "test"}, 0.2, DT, 0)  # fmt: skip
    test = index.filter(pl.col("object") == "obj_test")
    assert test.height and test["label"].sum() > 0
    assert index.filter(pl.col("object") == "obj_train")["label"].sum() == 0
