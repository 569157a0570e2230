"""The input audit's datasets on synthetic replays: the same windows as the baseline's, other
channels; and the parameter counts the baseline configurations give with 16 inputs (table 4.2)."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import polars as pl
import pytest
import yaml
from conftest import CONFIG_DIR
from synthetic_replays import labelled_replays

from graspstab.evaluation.studies import load_checkpoint
from graspstab.labels.dataset import load_windows
from graspstab.labels.input_sets import InputSetError, build_input_dataset, features
from graspstab.learning.models import build_model, count_parameters
from graspstab.replay.traces import trace_key

LABELS = yaml.safe_load((CONFIG_DIR / "labels" / "default.yaml").read_text())
DT = 0.0005
T = 6000


def _trace(slip_at: int, rng: np.random.Generator) -> dict:
    vel = np.zeros((T, 3), np.float32)
    vel[slip_at:, 2] = -0.005
    pos = np.cumsum(vel, axis=0) * DT + rng.random(3).astype(np.float32)
    normal = (2 + rng.random((T, 5))).astype(np.float32)
    angle = rng.random((T, 5)).astype(np.float32)
    shear = (0.3 * normal + 0.1 * rng.random((T, 5))).astype(np.float32)
    return {"position": pos.astype(np.float32), "velocity": vel,
            "min_distance": np.full(T, -0.001, np.float32), "normal": normal, "shear": shear,
            "shear_distal": shear * np.cos(angle),
            "shear_lateral": shear * np.sin(angle)}  # fmt: skip


@pytest.fixture(scope="module")
def baseline(tmp_path_factory) -> tuple[Path, dict]:
    rng = np.random.default_rng(1)
    return labelled_replays(
        tmp_path_factory.mktemp("inputs"), (("a", 0, (0, 1)), ("b", 0, (2,)), ("c", 1, (4,))),
        lambda g: _trace(2500 + 400 * g, rng), LABELS, {"a": "train", "b": "val", "c": "test"},
        DT,
    )  # fmt: skip


def test_feature_names_and_widths() -> None:
    """forces 10, normal 5, shear 5, tangential 15, object_state 16, fingertip-major; unknown
    sets refused."""
    sets = ("forces", "normal", "shear", "tangential", "object_state")
    assert [len(features(s)) for s in sets] == [10, 5, 5, 15, 16]
    assert features("forces")[:3] == ["normal_0", "shear_0", "normal_1"]
    assert features("tangential")[:4] == ["normal_0", "shear_distal_0", "shear_lateral_0",
                                          "normal_1"]  # fmt: skip
    assert features("object_state")[-6:] == ["position_x", "position_y", "position_z",
                                             "velocity_x", "velocity_y", "velocity_z"]  # fmt: skip
    with pytest.raises(InputSetError, match="unknown input set"):
        features("tactile_image")


def test_input_datasets_hold_the_baseline_windows_with_other_channels(baseline, tmp_path):
    """Same index; forces = the baseline windows flattened; normal/shear their channel; the
    object's state its trace slice; statistics from training windows only."""
    ds, traces = baseline
    base = np.asarray(load_windows(ds))
    index = pl.read_parquet(ds / "index.parquet")
    flat = base.reshape(len(base), base.shape[1], 10)
    for name, expect in (("forces", flat), ("normal", base[..., 0]), ("shear", base[..., 1])):
        build_input_dataset(ds, traces, name, tmp_path / name)
        got = np.load(tmp_path / name / "windows.npy")
        assert got.shape == (*base.shape[:2], 1, expect.shape[-1])
        np.testing.assert_array_equal(got[:, :, 0], expect)
        assert pl.read_parquet(tmp_path / name / "index.parquet").equals(index)
    build_input_dataset(ds, traces, "tangential", tmp_path / "tan")
    got = np.load(tmp_path / "tan" / "windows.npy").reshape(*base.shape[:2], 5, 3)
    np.testing.assert_array_equal(got[..., 0], base[..., 0])  # the normal channel
    # the two components' length is the magnitude channel (the synthetic traces' construction)
    np.testing.assert_allclose(np.hypot(got[..., 1], got[..., 2]), base[..., 1], rtol=1e-5)
    summary = build_input_dataset(ds, traces, "object_state", tmp_path / "obj")
    got = np.load(tmp_path / "obj" / "windows.npy")
    np.testing.assert_array_equal(got[:, :, 0, :10], flat)
    row = index.row(0, named=True)
    with np.load(traces[(row["object"], row["shard"])]) as npz:
        vel = npz[trace_key(row["grasp_id"], "velocity")][row["start"] : row["end"]]
    np.testing.assert_array_equal(got[0, :, 0, 13:], vel)
    norm = json.loads((tmp_path / "obj" / "normalisation.json").read_text())
    train = got[(index["split"] == "train").to_numpy()].reshape(-1, 16).astype(np.float64)
    np.testing.assert_allclose(norm["mean"][0], train.mean(0), rtol=1e-6, atol=1e-9)
    assert summary["features"] == features("object_state")


def test_sixteen_inputs_reproduce_table_4_2() -> None:
    """The baseline configurations give table 4.2's counts with 16 inputs, ours with 10."""
    specs = {m: yaml.safe_load((CONFIG_DIR / "model" / f"{m}.yaml").read_text())
             for m in ("cnn", "gru", "lstm")}  # fmt: skip
    sixteen = {m: count_parameters(build_model(s, channels=16, fingertips=1))
               for m, s in specs.items()}  # fmt: skip
    assert sixteen == {"cnn": 178_753, "gru": 171_777, "lstm": 25_217}
    ten = {m: count_parameters(build_model(s)) for m, s in specs.items()}
    assert ten == {"cnn": 176_833, "gru": 169_473, "lstm": 23_681}


def test_training_on_an_input_set_records_its_layout(baseline, tmp_path) -> None:
    """train_model reads the layout from the dataset; the checkpoint rebuilds the same model."""
    from graspstab.evaluation.tested_run import train_and_test

    ds, traces = baseline
    build_input_dataset(ds, traces, "object_state", tmp_path / "obj")
    spec = {"family": "lstm", "hidden_size": 8, "num_layers": 1, "bidirectional": False,
            "pooling": "mean", "dropout": 0.0, "learning_rate": 1e-3}  # fmt: skip
    train = yaml.safe_load((CONFIG_DIR / "train" / "default.yaml").read_text())
    train.update(max_epochs=1, patience=1)
    record = train_and_test(tmp_path / "obj", spec, train, 0, tmp_path / "run")
    assert record["inputs"] == {"fingertips": 1, "channels": 16}
    model, ckpt = load_checkpoint(tmp_path / "run" / "model.pt")
    assert model.in_features == 16 and ckpt["inputs"] == record["inputs"]
