"""Training and tuning (thesis 3.5, 4.1) on small synthetic datasets; the per-seed record that the
studies' aggregation reads."""

from __future__ import annotations

import copy
import json
import math
import shutil
from pathlib import Path
from typing import Any

import numpy as np
import optuna
import polars as pl
import pytest
import torch
import yaml
from conftest import CONFIG_DIR

from graspstab.evaluation import aggregate
from graspstab.evaluation.tested_run import train_and_test
from graspstab.labels.dataset import normalisation
from graspstab.learning.data import DatasetError, load_window_data
from graspstab.learning.models import build_model
from graspstab.learning.train import TrainSettings, evaluate, fit, sigmoid
from graspstab.learning.tune_model import tune_model
from graspstab.metrics.classification import select_threshold, threshold_grid

W = 20  # timesteps per synthetic window
OBJECTS = [f"o{i:02d}" for i in range(12)]
SPLITS = {o: "train" if i < 8 else "val" if i < 10 else "test" for i, o in enumerate(OBJECTS)}

TRAIN: dict[str, Any] = {
    **yaml.safe_load((CONFIG_DIR / "train" / "default.yaml").read_text()),
    "max_epochs": 6,
    "batch_size": 32,
    "patience": 6,
}
LSTM: dict[str, Any] = {"family": "lstm", "hidden_size": 16, "num_layers": 1,
                        "bidirectional": False, "pooling": "mean", "dropout": 0.0,
                        "learning_rate": 1e-2}  # fmt: skip
CNN: dict[str, Any] = {"family": "cnn", "base_channels": 8, "kernel_sizes": [5, 5, 3],
                       "dropout": 0.0, "learning_rate": 1e-2}  # fmt: skip
TUNE: dict[str, Any] = {
    "trials": 2,
    "window_s": 0.01,
    "seed": 0,
    "objective": "auprc",
    "storage": None,
    "pruner": {"startup_trials": 5, "warmup_epochs": 5},
    "space": {
        "common": {
            "learning_rate": {"low": 1e-3, "high": 1e-2, "log": True},
            "batch_size": [32, 64],
            "threshold_rule": ["min_recall", "best_f1"],  # dropped: the objective is AUPRC
        },
        "recurrent": {"hidden_size": [8, 16]},
        "cnn": {"base_channels": [4, 8]},
    },
}


def write_dataset(
    root: Path,
    per_split: dict[str, int],
    *,
    planted: bool = True,
    one_class_val: bool = False,
    seed: int = 0,
) -> Path:
    """Write a dataset directory in label_windows' layout: 40 % unstable windows per object whose
    shear rises (and normal load dips) over the last 8 steps; ``planted=False`` then permutes
    the labels within each object so they are independent of the windows. Every third window's
    object moves over its observation period (its motion), the others are still."""
    rng = np.random.default_rng(seed)
    ramp = np.clip((np.arange(W) - (W - 8)) / 7, 0.0, 1.0)[None, :, None]
    rows, chunks = [], []
    for obj in OBJECTS:
        split = SPLITS[obj]
        n = per_split[split]
        y = (rng.permutation(n) < round(0.4 * n)).astype(np.int8)
        if one_class_val and split == "val":
            y[:] = 0
        normal = rng.uniform(1.0, 3.0, (n, 1, 5)) * np.ones((1, W, 1))
        x = np.stack([normal, 0.3 * normal], axis=-1) + rng.normal(0.0, 0.2, (n, W, 5, 2))
        x[y == 1, :, :, 1] += 0.8 * ramp
        x[y == 1, :, :, 0] -= 0.4 * ramp
        if not planted:
            y = rng.permutation(y)
        chunks.append(x.astype(np.float32))
        rows += [{"object": obj, "grasp_id": k // 5, "shard": 0, "start": k, "end": k + W,
                  "r": float(y[k]), "label": int(y[k]), "split": split}
                 for k in range(n)]  # fmt: skip
    index = pl.DataFrame(
        rows,
        schema={"object": pl.String, "grasp_id": pl.Int64, "shard": pl.Int32, "start": pl.Int64,
                "end": pl.Int64, "r": pl.Float64, "label": pl.Int8, "split": pl.String},
    ).with_row_index("sample_id")  # fmt: skip
    windows = np.concatenate(chunks)
    root.mkdir(parents=True, exist_ok=True)
    np.save(root / "windows.npy", windows)
    # the object moves over the whole observation period of every third window: those are
    # moving-now, the rest still-now (labels.dataset.MOTION: u_t, speed)
    moving = (np.arange(len(windows)) % 3 == 0)[:, None] * np.ones((1, W))
    np.save(root / "motion.npy", np.stack([moving, 0.002 * moving], -1).astype(np.float32))
    index.write_parquet(root / "index.parquet")
    (root / "normalisation.json").write_text(json.dumps(normalisation(windows, index)))
    return root


def _same(a: Any, b: Any) -> bool:
    """Equality that treats NaN as equal to NaN (JSON round trip)."""
    return json.dumps(a, sort_keys=True) == json.dumps(b, sort_keys=True)


@pytest.fixture(autouse=True)
def _one_thread() -> None:
    torch.set_num_threads(1)


@pytest.fixture(scope="module")
def planted(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """360 windows: 8 train / 2 val / 2 test objects of 30 windows each."""
    return write_dataset(tmp_path_factory.mktemp("planted"), {"train": 30, "val": 30, "test": 30})


@pytest.fixture(scope="module")
def one_class_val(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """Like ``planted`` but every validation window is stable."""
    root = tmp_path_factory.mktemp("one_class_val")
    return write_dataset(root, {"train": 30, "val": 30, "test": 30}, one_class_val=True)


@pytest.fixture(scope="module")
def lstm_run(planted: Path, tmp_path_factory: pytest.TempPathFactory) -> Path:
    """One LSTM run (seed 0) on the planted dataset, shared by the tests that read its files."""
    out = tmp_path_factory.mktemp("lstm_seed0")
    train_and_test(planted, LSTM, TRAIN, 0, out)
    return out


def _metrics(run: Path) -> dict[str, Any]:
    return json.loads((run / "metrics.json").read_text())


# -- training -------------------------------------------------------------------------------------


def test_planted_signal_is_learned(planted: Path, lstm_run: Path, tmp_path: Path) -> None:
    torch.manual_seed(0)
    untrained = evaluate(build_model(LSTM), load_window_data(planted), "test", 1024)
    assert untrained["auprc"] < 0.8  # the pattern has to be learned, not found by chance
    lstm = _metrics(lstm_run)
    cnn = train_and_test(planted, CNN, TRAIN, 0, tmp_path / "cnn")
    for record in (lstm, cnn):
        assert record["test"]["auprc"] > 0.95, record["family"]
        assert record["counts"]["test"] == {"stable": 36, "unstable": 24}
    assert {p.name for p in (tmp_path / "cnn").iterdir()} >= {
        "metrics.json", "predictions.parquet", "model.pt"}  # fmt: skip


def test_shuffled_labels_give_chance_auroc(tmp_path: Path) -> None:
    data = write_dataset(tmp_path / "ds", {"train": 30, "val": 30, "test": 150}, planted=False)
    record = train_and_test(data, LSTM, TRAIN, 0, tmp_path / "run", checkpoint=False)
    n1 = record["test"]["n_unstable"]
    n0 = record["test"]["n"] - n1
    # Under independence the test AUROC is the Mann-Whitney U / (n0 n1) null distribution:
    # mean 0.5, sd sqrt((n0 + n1 + 1) / (12 n0 n1)) = 0.034 for 180 stable + 120 unstable.
    # Tolerance 4 sd = 0.137 (< 0.15), a false alarm rate below 1e-4.
    tolerance = 4.0 * math.sqrt((n0 + n1 + 1) / (12.0 * n0 * n1))
    assert (n0, n1) == (180, 120) and tolerance < 0.15
    assert abs(record["test"]["auroc"] - 0.5) < tolerance


def test_same_seed_same_metrics_other_seed_other_weights(
    planted: Path, lstm_run: Path, tmp_path: Path
) -> None:
    timing = tmp_path / "again" / "timing.json"
    again = train_and_test(planted, LSTM, TRAIN, 0, tmp_path / "again", timing_path=timing)
    # the same bytes: the run's timings are in its timing sidecar, not in its data
    for name in ("metrics.json", "predictions.parquet", "model.pt"):
        assert (lstm_run / name).read_bytes() == (tmp_path / "again" / name).read_bytes(), name
    assert not any("seconds" in k for row in again["history"] for k in row)
    seconds = json.loads(timing.read_text())
    assert len(seconds["epoch_seconds"]) == again["epochs_run"] > 0
    assert seconds["train_seconds"] >= sum(seconds["epoch_seconds"]) > 0
    train_and_test(planted, LSTM, TRAIN, 1, tmp_path / "seed1")
    w0 = torch.load(lstm_run / "model.pt", weights_only=False)["state_dict"]
    w1 = torch.load(tmp_path / "seed1" / "model.pt", weights_only=False)["state_dict"]
    assert w0.keys() == w1.keys()
    assert any(not torch.equal(w0[k], w1[k]) for k in w0)


def test_threshold_from_validation_only(planted: Path, lstm_run: Path, tmp_path: Path) -> None:
    record = _metrics(lstm_run)
    pred = pl.read_parquet(lstm_run / "predictions.parquet")
    assert set(pred["split"].unique()) == {"val", "test"}
    data = load_window_data(planted)
    for split in ("val", "test"):
        ids = pred.filter(pl.col("split") == split)["sample_id"].to_numpy()
        np.testing.assert_array_equal(ids, data.index["sample_id"].to_numpy()[data.rows(split)])
    np.testing.assert_allclose(pred["prob"].to_numpy(), sigmoid(pred["logit"].to_numpy()))
    val = pred.filter(pl.col("split") == "val")
    t = TRAIN["threshold"]
    choice = select_threshold(val["prob"].to_numpy(), val["label"].to_numpy(),
                              threshold_grid(*t["grid"]), t["min_recall"], t["rule"])  # fmt: skip
    assert record["threshold"]["threshold"] == choice.threshold
    assert record["threshold"]["rule"] == choice.rule
    assert record["test"]["threshold"] == choice.threshold

    # Flip every test label in a copy: the threshold and validation results cannot move.
    flipped = tmp_path / "flipped"
    shutil.copytree(planted, flipped)
    index = pl.read_parquet(flipped / "index.parquet")
    index = index.with_columns(
        pl.when(pl.col("split") == "test").then(1 - pl.col("label")).otherwise(pl.col("label"))
        .cast(pl.Int8).alias("label")
    )  # fmt: skip
    index.write_parquet(flipped / "index.parquet")
    other = train_and_test(flipped, LSTM, TRAIN, 0, tmp_path / "run", checkpoint=False)
    assert other["threshold"] == record["threshold"]
    assert _same(other["val"], record["val"])
    assert other["test"]["n_unstable"] == record["test"]["n"] - record["test"]["n_unstable"]


def test_one_class_validation_falls_back_to_loss(one_class_val: Path, tmp_path: Path) -> None:
    data = load_window_data(one_class_val)
    assert data.class_counts("val") == (60, 0)
    torch.manual_seed(0)
    settings = TrainSettings.from_config({**TRAIN, "max_epochs": 2}, LSTM)
    result = fit(build_model(LSTM), data, settings, seed=0)
    assert result.selection_metric == "loss"
    assert all(math.isnan(h["val_auprc"]) for h in result.history)
    record = train_and_test(one_class_val, LSTM, TRAIN, 0, tmp_path, checkpoint=False)
    assert record["selection_metric"] == "loss"
    assert record["threshold"]["rule"] == "undefined"
    assert record["threshold"]["threshold"] == 0.5
    assert math.isnan(record["val"]["auprc"])
    assert math.isfinite(record["test"]["auprc"]) and math.isfinite(record["test"]["loss"])
    assert record["test"]["tp"] + record["test"]["fn"] == 24


def test_early_stopping_keeps_first_epoch(planted: Path) -> None:
    data = load_window_data(planted)
    settings = TrainSettings.from_config(
        {**TRAIN, "max_epochs": 5, "patience": 1, "min_delta": 10.0}, LSTM
    )
    torch.manual_seed(0)
    model = build_model(LSTM)
    seen: dict[int, dict[str, torch.Tensor]] = {}
    result = fit(
        model,
        data,
        settings,
        seed=0,
        on_epoch=lambda e, _: seen.__setitem__(e, copy.deepcopy(model.state_dict())),
    )
    assert len(result.history) == 2 and result.stopped_early
    assert result.best_epoch == 1
    assert any(not torch.equal(seen[1][k], seen[2][k]) for k in seen[1])
    for k, v in model.state_dict().items():
        assert torch.equal(v, seen[1][k]) and torch.equal(result.state_dict[k], seen[1][k])


# -- data -----------------------------------------------------------------------------------------


def test_assignment_recomputes_train_statistics(planted: Path) -> None:
    objects = OBJECTS[:10]  # o10 and o11 are left out and must be dropped
    assignment = {o: "train" for o in objects[2:9]} | {"o00": "val", "o01": "val", "o09": "test"}
    data = load_window_data(planted, assignment)
    assert sorted(data.index["object"].unique()) == objects
    assert len(data.windows) == len(data.index) == 300
    assert sorted(set(data.objects(data.rows("test")))) == ["o09"]

    raw = np.load(planted / "windows.npy")
    index = pl.read_parquet(planted / "index.parquet")
    train_objects = {o for o, s in assignment.items() if s == "train"}
    for f in range(5):
        for c in range(2):
            values = np.concatenate([raw[i, :, f, c] for i, o in enumerate(index["object"])
                                     if o in train_objects]).astype(np.float64)  # fmt: skip
            mean = values.sum() / values.size
            std = math.sqrt(((values - mean) ** 2).sum() / values.size)
            assert data.mean[f, c] == pytest.approx(mean, rel=1e-9, abs=1e-12)
            assert data.std[f, c] == pytest.approx(std, rel=1e-9)
    assert not np.allclose(data.mean, load_window_data(planted).mean)

    rows = np.array([5, 299, 0, 150, 17])
    ids = data.index["sample_id"].to_numpy()[rows]
    expected = (raw[ids].astype(np.float64) - data.mean) / data.std
    np.testing.assert_allclose(data.batch(rows).numpy(), expected, rtol=1e-5, atol=1e-5)
    assert isinstance(data.windows.base, np.memmap)  # the row view still reads lazily

    with pytest.raises(DatasetError, match="unknown split"):
        load_window_data(planted, {**assignment, "o10": "training"})
    unknown = load_window_data(planted, {**assignment, "no_such_object": "train"})
    assert len(unknown.index) == 300


def test_windows_memory_mapped_and_batches_normalised(planted: Path) -> None:
    data = load_window_data(planted)
    assert isinstance(data.windows, np.memmap)
    assert data.window_steps == W
    stored = json.loads((planted / "normalisation.json").read_text())
    np.testing.assert_array_equal(data.mean, np.asarray(stored["mean"]))
    raw = np.load(planted / "windows.npy")
    rows = np.array([300, 3, 200, 3, 42])  # unsorted, with a repeat
    expected = (raw[rows].astype(np.float64) - data.mean) / data.std
    batch = data.batch(rows)
    assert batch.dtype == torch.float32 and tuple(batch.shape) == (5, W, 5, 2)
    np.testing.assert_allclose(batch.numpy(), expected, rtol=1e-5, atol=1e-5)


# -- tuning ---------------------------------------------------------------------------------------


def _tune(dataset: Path, root: Path, **overrides: Any) -> dict[str, Any]:
    return tune_model(
        dataset, LSTM, {**TRAIN, "max_epochs": 2}, {**TUNE, **overrides}, root / "best.json",
        root / "trials.parquet", default_storage=root / "study.sqlite",
    )  # fmt: skip


def _study(root: Path, name: str) -> optuna.Study:
    return optuna.load_study(study_name=name, storage=f"sqlite:///{root / 'study.sqlite'}")


@pytest.fixture(scope="module")
def tuned(planted: Path, tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A finished two-trial study of the LSTM on the planted dataset."""
    root = tmp_path_factory.mktemp("tune")
    _tune(planted, root)
    return root


def _copy_study(src: Path, dst: Path) -> Path:
    dst.mkdir(parents=True, exist_ok=True)
    shutil.copy(src / "study.sqlite", dst / "study.sqlite")
    return dst


def test_tune_writes_best_spec_and_trials(tuned: Path) -> None:
    best = json.loads((tuned / "best.json").read_text())
    assert best["searched"] == ["batch_size", "hidden_size", "learning_rate"]
    assert best["trials"]["complete"] == 2
    study = _study(tuned, best["study_name"])
    assert best["best_trial"] == study.best_trial.number
    assert best["spec"] == {**LSTM, **study.best_trial.params}
    trials = pl.read_parquet(tuned / "trials.parquet")
    assert trials["state"].to_list() == ["complete", "complete"]
    assert trials["epochs_run"].to_list() == [2, 2]


def test_tune_marks_interrupted_trial_failed(planted: Path, tuned: Path, tmp_path: Path) -> None:
    root = _copy_study(tuned, tmp_path)
    name = json.loads((tuned / "best.json").read_text())["study_name"]
    assert optuna.get_all_study_names(f"sqlite:///{root / 'study.sqlite'}") == [name]
    _study(root, name).ask()  # a trial a killed job left RUNNING
    record = _tune(planted, root)
    assert record["study_name"] == name
    assert record["trials"]["fail"] == 1 and record["trials"]["running"] == 0
    assert record["trials"]["complete"] == 2  # the failed trial is not counted: none re-run
    assert len(_study(root, name).trials) == 3


def test_tune_resumes_with_more_trials(planted: Path, tuned: Path, tmp_path: Path) -> None:
    root = _copy_study(tuned, tmp_path)
    name = json.loads((tuned / "best.json").read_text())["study_name"]
    record = _tune(planted, root, trials=3)
    assert record["study_name"] == name
    states = [t.state for t in _study(root, name).trials]
    assert states == [optuna.trial.TrialState.COMPLETE] * 3  # the second run added only one


def test_tune_objective_falls_back_to_loss(one_class_val: Path, tmp_path: Path) -> None:
    record = _tune(one_class_val, tmp_path, trials=1)
    assert record["objective"] == "loss"
    assert math.isfinite(record["best_value"]) and record["best_value"] < 0  # -val loss
    assert record["trials"]["complete"] == 1


def test_run_rows_from_metrics_json(lstm_run: Path) -> None:
    record = _metrics(lstm_run)
    rows = aggregate.run_rows([record], [{"window_s": 0.01}])
    assert rows["split"].to_list() == ["val", "test"]
    test = rows.row(1, named=True)
    assert test["auprc"] == record["test"]["auprc"] and test["window_s"] == 0.01
    assert test["threshold"] == record["threshold"]["threshold"]


def test_tune_shared_storage_keeps_running_trials(planted: Path, tmp_path: Path) -> None:
    """A configured database may serve several workers: another worker's RUNNING trial is left
    alone (heartbeats find the dead ones), and the study stops at ``trials`` finished trials."""
    url = f"sqlite:///{tmp_path / 'shared.sqlite'}"
    record = _tune(planted, tmp_path, storage=url, trials=1)
    name = record["study_name"]
    other = optuna.load_study(study_name=name, storage=url).ask()  # a live worker's trial
    record = _tune(planted, tmp_path, storage=url, trials=2)
    assert record["study_name"] == name
    assert record["trials"]["running"] == 1 and record["trials"]["fail"] == 0
    assert record["trials"]["complete"] + record["trials"]["pruned"] == 2
    assert optuna.load_study(study_name=name, storage=url).trials[other.number].state.name == (
        "RUNNING"
    )


def test_sampler_seed_differs_per_family() -> None:
    """GRU and LSTM share a search space: their TPE streams must differ, yet be reproducible."""
    from graspstab.learning.tune_model import sampler_seed

    assert sampler_seed(42, "gru") != sampler_seed(42, "lstm")
    assert sampler_seed(42, "gru") == sampler_seed(42, "gru")
    assert sampler_seed(42, "gru") != sampler_seed(43, "gru")
