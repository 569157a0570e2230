"""benchmarks/compare_outputs.py, the check that a refactor left every output alone: it must see
through a code-version change in provenance, and nothing else."""

from __future__ import annotations

import json
import subprocess
import sys
import zipfile
from pathlib import Path

import polars as pl
import pytest

from tests.conftest import REPO

TOOL = REPO / "benchmarks" / "compare_outputs.py"


def _tree(root: Path, version: str, value: float = 1.0, log: str = "a") -> Path:
    res = root / "results"
    (res / "datasets").mkdir(parents=True)
    (res / "logs").mkdir()
    (res / "logs" / "job.log").write_text(log)
    (res / "datasets" / "summary.json").write_text(
        json.dumps({"windows": 3, "provenance": {"code_version": version}})
    )
    table = pl.DataFrame({"x": [value, 2.0], "undefined": [float("nan"), 1.0]}).to_arrow()
    table = table.replace_schema_metadata({"provenance": json.dumps({"code_version": version})})
    import pyarrow.parquet as pq

    pq.write_table(table, res / "datasets" / "index.parquet")
    with zipfile.ZipFile(res / "datasets" / "model.pt", "w") as z:
        z.writestr("extra/provenance.json", json.dumps({"code_version": version}))
        z.writestr("data/0", b"weights")
        # a TorchScript archive's random save id, and its debug table naming the checkout
        z.writestr("archive/.data/serialization_id", str(abs(hash(str(root)))))
        z.writestr("archive/code/m.py.debug_pkl", f"{root.resolve()}/src/graspstab/m.py:1")
    (res / "datasets" / "train.timing.json").write_text(json.dumps({"s": value}))
    return res


def _run(old: Path, new: Path) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, str(TOOL), str(old), str(new)],
                          capture_output=True, text=True, timeout=60)  # fmt: skip


def test_a_code_version_change_alone_is_the_same(tmp_path: Path) -> None:
    old = _tree(tmp_path / "a", "0.3.0+0123456789ab")
    new = _tree(tmp_path / "b", "0.3.0+ba9876543210", log="another log")
    proc = _run(old, new)
    assert proc.returncode == 0, proc.stdout + proc.stderr
    assert proc.stdout.strip().endswith("same but code version: 3")


@pytest.mark.parametrize("change", ["value", "missing"])
def test_a_changed_or_missing_output_is_named(tmp_path: Path, change: str) -> None:
    old = _tree(tmp_path / "a", "0.3.0+0123456789ab")
    new = _tree(tmp_path / "b", "0.3.0+0123456789ab", value=1.5)
    if change == "missing":
        new = _tree(tmp_path / "c", "0.3.0+0123456789ab")
        (new / "datasets" / "summary.json").unlink()
    proc = _run(old, new)
    assert proc.returncode == 1
    expected = ("differs: datasets/index.parquet" if change == "value"
                else f"only in {old}: datasets/summary.json")  # fmt: skip
    assert expected in proc.stdout.splitlines()
    assert "timing" not in proc.stdout  # the timing sidecar differs too, and is not data
