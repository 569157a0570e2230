"""Friction-ratio proxy (thesis 4.7): last-timestep shear/normal ratio and its ranking metrics."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from graspstab.evaluation.proxy import friction_ratio, proxy_metrics

W, F = 12, 5


def _windows(labels: np.ndarray, rng: np.random.Generator) -> np.ndarray:
    """Raw windows (N, W, 5, 2) with positive normal and shear loads."""
    x = np.empty((labels.size, W, F, 2))
    x[..., 0] = rng.uniform(1.0, 5.0, (labels.size, W, F))
    x[..., 1] = rng.uniform(0.1, 1.0, (labels.size, W, F))
    return x


def _brute_force(windows: np.ndarray, eps: float = 1e-9) -> np.ndarray:
    out = []
    for window in windows:
        normal = sum(float(window[-1, f, 0]) for f in range(window.shape[1]))
        shear = sum(float(window[-1, f, 1]) for f in range(window.shape[1]))
        out.append(shear / max(normal, eps))
    return np.array(out)


def test_ratio_equals_brute_force_loop() -> None:
    rng = np.random.default_rng(0)
    x = _windows(rng.integers(0, 2, 50), rng)
    x[3, -1, :, 0] = 0.0  # no normal load but some shear: large finite score
    x[4, -1] = 0.0  # no load at all: score 0
    scores = friction_ratio(x)
    np.testing.assert_allclose(scores, _brute_force(x), rtol=1e-12)
    assert scores.shape == (50,) and scores.dtype == np.float64
    assert np.isfinite(scores[3]) and scores[3] > 1e8
    assert scores[4] == 0.0


def test_higher_last_step_ratio_for_unstable_gives_auprc_one() -> None:
    rng = np.random.default_rng(1)
    labels = rng.integers(0, 2, 200)
    x = _windows(labels, rng)
    x[:, -1, :, 0] = 2.0
    x[:, -1, :, 1] = np.where(labels[:, None] == 1, 1.5, 0.5) + rng.uniform(0, 0.2, (200, F))
    m = proxy_metrics(friction_ratio(x), labels)
    assert set(m) == {"auprc", "auroc"}
    assert m["auprc"] == 1.0 and m["auroc"] == 1.0


def test_earlier_timesteps_are_ignored_so_auprc_is_chance() -> None:
    rng = np.random.default_rng(2)
    labels = rng.integers(0, 2, 300)
    x = _windows(labels, rng)
    # Earlier steps separate the classes perfectly; the last step is identical for every window.
    x[:, :-1, :, 1] = np.where(labels[:, None, None] == 1, 4.0, 0.1)
    x[:, -1, :, 0] = 2.0
    x[:, -1, :, 1] = 0.3
    m = proxy_metrics(friction_ratio(x), labels)
    assert m["auprc"] == pytest.approx(labels.mean())  # all scores tie: precision = prevalence
    assert m["auroc"] == pytest.approx(0.5)


def test_reads_only_the_last_timestep_of_a_memmap(tmp_path: Path) -> None:
    rng = np.random.default_rng(3)
    x = _windows(rng.integers(0, 2, 20), rng).astype(np.float32)
    expected = friction_ratio(x)
    x[:, :-1] = np.nan  # any use of earlier steps would poison the score
    path = tmp_path / "windows.npy"
    np.save(path, x)
    mm = np.load(path, mmap_mode="r")
    assert isinstance(mm, np.memmap)
    scores = friction_ratio(mm)
    assert np.all(np.isfinite(scores))
    np.testing.assert_allclose(scores, expected, rtol=1e-12)


def test_input_validation_and_one_class() -> None:
    with pytest.raises(ValueError):
        friction_ratio(np.zeros((3, 4, 5)))
    with pytest.raises(ValueError):
        friction_ratio(np.zeros((3, 4, 5, 3)))
    with pytest.raises(ValueError):
        proxy_metrics(np.array([0.1, np.inf]), np.array([0, 1]))
    m = proxy_metrics(np.array([0.1, 0.2]), np.array([1, 1]))
    assert np.isnan(m["auprc"]) and np.isnan(m["auroc"])


def test_evaluate_proxy_gives_still_now_blocks_and_the_persistence_oracle(tmp_path) -> None:
    """The proxy's record adds the still-now and moving-now windows of each split, and the
    persistence oracle: it ranks moving windows above still ones and cannot rank still ones."""
    import json

    from graspstab.evaluation.studies import evaluate_proxy
    from tests.test_learning_train import write_dataset

    data = write_dataset(tmp_path / "ds", {"train": 6, "val": 30, "test": 30})
    out = evaluate_proxy(data, tmp_path / "proxy.json")
    assert json.loads((tmp_path / "proxy.json").read_text())["test_still"]["n"] == 40
    for split in ("val", "test"):
        assert out[f"{split}_still"]["n"] + out[f"{split}_moving"]["n"] == out[split]["n"]
        oracle = out["persistence"]
        assert oracle[split]["n"] == out[split]["n"]
        assert oracle[f"{split}_still"]["auroc"] == pytest.approx(0.5)  # every score is 0
        assert oracle[f"{split}_still"]["auprc"] == pytest.approx(
            oracle[f"{split}_still"]["chance"])  # fmt: skip
