"""Atomic writes and provenance: a failed write leaves nothing; versions track code."""

from __future__ import annotations

import os
import stat

import pytest

from graspstab.common.io import atomic_path, read_json, write_json
from graspstab.common.provenance import code_version, stable_hash


def test_atomic_path_leaves_nothing_on_failure(tmp_path):
    target = tmp_path / "out.txt"
    with pytest.raises(RuntimeError), atomic_path(target) as tmp:
        tmp.write_text("half")
        raise RuntimeError("job killed")
    assert list(tmp_path.iterdir()) == []


def test_atomic_path_keeps_old_file_until_success(tmp_path):
    target = tmp_path / "out.json"
    write_json(target, {"a": 1})
    with pytest.raises(RuntimeError), atomic_path(target) as tmp:
        tmp.write_text("{broken")
        raise RuntimeError
    assert read_json(target) == {"a": 1}


def test_atomic_files_get_umask_permissions(tmp_path):
    write_json(tmp_path / "x.json", {})
    mode = stat.S_IMODE(os.stat(tmp_path / "x.json").st_mode)
    umask = os.umask(0)
    os.umask(umask)
    assert mode == 0o666 & ~umask


def test_stable_hash_ignores_key_order_but_not_values():
    assert stable_hash({"a": 1, "b": [1, 2]}) == stable_hash({"b": [1, 2], "a": 1})
    assert stable_hash({"a": 1}) != stable_hash({"a": 2})


def test_code_version_names_stage():
    assert code_version("objects") != code_version("hand")
    with pytest.raises(ValueError):
        code_version("no_such_stage")


def _truncate(path, keep: float = 0.5) -> None:
    data = path.read_bytes()
    path.write_bytes(data[: int(len(data) * keep)])


def test_corrupt_artefacts_name_their_path_and_the_fix(tmp_path):
    import numpy as np
    import polars as pl

    from graspstab.common.io import (
        UnreadableArtefact,
        load_npy,
        load_npz,
        read_parquet,
        save_npy,
        save_npz,
        write_parquet,
    )
    from graspstab.replay.traces import read_traces, trace_key

    rng = np.random.default_rng(0)
    table, npz, npy, js = (tmp_path / n for n in ("t.parquet", "a.npz", "w.npy", "s.json"))
    write_parquet(table, pl.DataFrame({"x": rng.random(5000)}))
    save_npz(npz, **{trace_key(3, "normal"): rng.random((4000, 5)).astype(np.float32)})
    save_npy(npy, rng.random((100, 4)).astype(np.float32))
    write_json(js, {"a": list(range(100))})
    # intact files read back
    assert read_parquet(table).height == 5000 and load_npy(npy).shape == (100, 4)
    assert read_traces(npz, 3, ("normal",))["normal"].shape == (4000, 5)
    readers = [(table, read_parquet), (npz, load_npz), (npy, load_npy), (js, read_json),
               (npz, lambda p: read_traces(p, 3, ("normal",)))]  # fmt: skip
    for path in {p for p, _ in readers}:
        _truncate(path)
    for path, reader in readers:
        with pytest.raises(UnreadableArtefact) as err:
            reader(path)
        msg = str(err.value)
        assert str(path) in msg and "truncated?" in msg and "Delete it and rerun" in msg
    # a missing file is not "corrupt": it keeps its own error
    with pytest.raises(FileNotFoundError):
        read_parquet(tmp_path / "absent.parquet")


def test_save_figure_is_atomic(tmp_path):
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from graspstab.common.io import save_figure

    fig, ax = plt.subplots()
    ax.plot([0, 1])
    target = tmp_path / "f.png"
    save_figure(target, fig, dpi=50)
    assert target.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    with pytest.raises(ValueError):
        save_figure(tmp_path / "g.png", fig, format="no_such_format")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["f.png"]
    plt.close(fig)


def test_provenance_records_the_compute_platform(monkeypatch, tmp_path):
    """The platform record reads the machine it runs on when first asked (here a faked CPU count,
    BLAS held to one thread), not values fixed at import, and lands in an artefact's strict JSON
    as it was read."""
    from threadpoolctl import threadpool_limits

    from graspstab.common.provenance import compute_platform, provenance

    real = provenance("objects", {"a": 1})["platform"]  # every BLAS the stage uses now loaded
    fake = (real["cpu_count"] or 0) + 3  # not this machine's count
    monkeypatch.setattr(os, "cpu_count", lambda: fake)
    compute_platform.cache_clear()
    try:
        with threadpool_limits(limits=1):
            record = provenance("objects", {"a": 1})["platform"]
        assert record["cpu_count"] == fake and record["machine"] == real["machine"]
        # numpy's BLAS is always loaded: its build and thread count are what reorder reductions,
        # and the count is the one in force when the record was made
        blas = [lib for lib in record["blas"]
                if lib["internal_api"] in {"openblas", "mkl", "blis", "accelerate"}]  # fmt: skip
        assert blas and all(lib["num_threads"] == 1 for lib in blas)
        write_json(tmp_path / "p.json", {"platform": record})
        assert read_json(tmp_path / "p.json")["platform"] == record
    finally:
        compute_platform.cache_clear()  # later artefacts read the real machine again


def test_save_npz_is_byte_reproducible_across_clock_changes(tmp_path, monkeypatch):
    """Same arrays, written an hour apart, give the same bytes (zip members carry a fixed date), so
    a rebuilt hand's or replay's ``.npz`` keeps the hash its downstream cache keys came from."""
    import hashlib
    import time

    import numpy as np

    from graspstab.common.io import load_npz, save_npz

    rng = np.random.default_rng(0)
    arrays = {"points": rng.random((120, 3)), "ids": np.arange(7, dtype=np.int32)}
    save_npz(tmp_path / "a.npz", **arrays)
    later = time.time() + 3600.0
    monkeypatch.setattr(time, "time", lambda: later)
    save_npz(tmp_path / "b.npz", **arrays)
    digest = [hashlib.sha256((tmp_path / f).read_bytes()).hexdigest() for f in ("a.npz", "b.npz")]
    assert digest[0] == digest[1]
    back = load_npz(tmp_path / "b.npz")
    assert sorted(back) == ["ids", "points"]
    np.testing.assert_array_equal(back["points"], arrays["points"])
    assert back["ids"].dtype == np.int32
