"""benchmarks/label_source_models.py: each labelling's rules, the test figures of every scorer
against direct computations on a planted dataset, and its table."""

from __future__ import annotations

import importlib.util
from pathlib import Path

import numpy as np
import polars as pl
import pytest

from graspstab.evaluation.detection import ORACLE, ranked, still_now, unstable_share
from graspstab.evaluation.proxy import friction_ratio
from tests.conftest import REPO
from tests.test_learning_train import write_dataset

spec = importlib.util.spec_from_file_location(
    "label_source_models", REPO / "benchmarks" / "label_source_models.py"
)
lsm = importlib.util.module_from_spec(spec)
spec.loader.exec_module(lsm)


def test_each_labelling_replaces_source_and_form_of_the_protocols_rules() -> None:
    cfg = lsm.run_config(["creep_free={enabled: true, load: perturb, labels_source: "
                          "displacement}"])  # fmt: skip
    ref = lsm.labels_for(cfg, "reference", "contact_slip", "event")
    assert ref == {**cfg["labels"], "source": "contact_slip", "form": "event"}
    cf = lsm.labels_for(cfg, "creep_free", "object_speed", "share")
    assert cf["source"] == "object_speed" and cf["form"] == "share"
    assert cf["v_slip"] == cfg["labels"]["v_slip"]


def test_replay_pairs_match_tables_to_their_traces(tmp_path: Path) -> None:
    root = tmp_path / "results" / "creep_free" / "replay" / "obj"
    root.mkdir(parents=True)
    for k in (1, 0):
        (root / f"replays_{k}.parquet").touch()
        (root / f"traces_{k}.npz").touch()
    pairs = lsm.replay_pairs(tmp_path, "creep_free")
    assert [(t.name, r.name) for t, r in pairs] == [("replays_0.parquet", "traces_0.npz"),
                                                    ("replays_1.parquet", "traces_1.npz")]
    assert lsm.replay_pairs(tmp_path, "reference") == []


def test_scorer_rows_are_the_direct_computation_on_the_test_windows(tmp_path: Path) -> None:
    data = write_dataset(tmp_path / "d", {"train": 6, "val": 6, "test": 30})
    index = pl.read_parquet(data / "index.parquet")
    test = np.flatnonzero(index["split"].to_numpy() == "test")
    y = index["label"].to_numpy()[test]
    motion = np.load(data / "motion.npy")[test]
    windows = np.load(data / "windows.npy")[test]
    noisy = y + np.random.default_rng(0).normal(0, 0.8, len(y))
    rows = lsm.scorer_rows(data, {"gru": noisy})
    still = still_now(motion)
    assert rows["all"]["n"] == len(y) and rows["still"]["n"] == int(still.sum())
    for name, s in (("gru", noisy), ("proxy", friction_ratio(windows)),
                    (ORACLE, unstable_share(motion))):  # fmt: skip
        for part, keep in (("all", np.ones(len(y), bool)), ("still", still)):
            want = ranked(s[keep], y[keep])
            got = rows[name][part]
            assert (got["n"], got["n_unstable"]) == (want["n"], want["n_unstable"])
            assert got["auprc"] == pytest.approx(want["auprc"], nan_ok=True)
    table = lsm.render("reference", {("displacement", "share"): rows}, ["gru", "proxy", ORACLE])
    assert table.startswith("### reference") and "| displacement | share |" in table
    assert table.count("\n") == 4
