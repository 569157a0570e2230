"""The content-addressed result cache: keys follow content, entries restore exact bytes."""

from __future__ import annotations

import json
import os
import time
from pathlib import Path
from types import SimpleNamespace

import pytest

from graspstab.common.cache import (
    ResultCache,
    content_digest,
    job_key,
    run_cached,
)
from graspstab.common.provenance import module_closure

OLD_NS = 978_307_200 * 10**9  # 2001-01-01T00:00:00Z


class Namedlist(list):
    """What a script job's snakemake.input/output/params offer: a list with named items."""

    def __init__(self, fromdict: dict):
        super().__init__(fromdict.values())
        self._map = dict(fromdict)
        for name, value in fromdict.items():
            setattr(self, name, value)

    def items(self):
        return self._map.items()


def _job(tmp: Path, cache_dir: Path, *, params=None, inputs=None, enabled=True, outdir="out"):
    """A stand-in for the ``snakemake`` object a script job receives."""
    inputs = inputs or [tmp / "in.txt"]
    return SimpleNamespace(
        rule="replay_grasps",
        config={"cache": {"enabled": enabled, "dir": str(cache_dir)}},
        input=Namedlist(fromdict={f"i{k}": str(p) for k, p in enumerate(inputs)}),
        output=Namedlist(
            fromdict={"table": str(tmp / outdir / "t.txt"), "trace": str(tmp / outdir / "r.bin")}
        ),
        params=Namedlist(fromdict={"replay": params or {"steps": 10}}),
        wildcards=Namedlist(fromdict={"object": "014_lemon", "shard": "0"}),
        log=[str(tmp / "logs" / "job.log")],
    )


class _Counter:
    """A compute step that writes outputs derived from its input and counts its calls."""

    def __init__(self, job):
        self.job, self.calls = job, 0

    def __call__(self):
        self.calls += 1
        text = Path(self.job.input[0]).read_text()
        Path(self.job.output.table).parent.mkdir(parents=True, exist_ok=True)
        Path(self.job.output.table).write_text(f"{text}|{self.job.params.replay}|{time.time()}")
        Path(self.job.output.trace).write_bytes(os.urandom(64))


def test_revert_restores_the_first_results_byte_for_byte(tmp_path):
    (tmp_path / "in.txt").write_text("grasps")
    cache = tmp_path / "cache"
    first = _job(tmp_path, cache)
    compute = _Counter(first)
    assert run_cached(first, ["replay"], compute) is False
    original = {k: Path(v).read_bytes() for k, v in first.output.items()}

    changed = _job(tmp_path, cache, params={"steps": 20})
    compute_changed = _Counter(changed)
    assert run_cached(changed, ["replay"], compute_changed) is False
    assert compute_changed.calls == 1
    assert Path(changed.output.table).read_bytes() != original["table"]

    reverted = _job(tmp_path, cache)
    for p in reverted.output:  # Snakemake removes outputs before it runs a job
        Path(p).unlink()
    # the entries' files dated 2001, the input touched just now (as if the revert had rewritten
    # it): a restore that kept the entry's dates would leave outputs older than their input
    stored = [f for f in cache.rglob("*") if f.is_file()]
    assert len(stored) >= 2 * 3  # both entries: two outputs and the record each
    for f in stored:
        os.utime(f, ns=(OLD_NS, OLD_NS))
    now = time.time_ns()
    os.utime(tmp_path / "in.txt", ns=(now, now))
    compute_reverted = _Counter(reverted)
    assert run_cached(reverted, ["replay"], compute_reverted) is True
    assert compute_reverted.calls == 0
    assert {k: Path(v).read_bytes() for k, v in reverted.output.items()} == original
    assert "restored from cache entry" in Path(reverted.log[0]).read_text()
    # the restored files are new to Snakemake: dated at the restore, not the entry's date, so no
    # older than the input (Snakemake would otherwise schedule the job again)
    for out in reverted.output:
        assert Path(out).stat().st_mtime_ns >= now, out
    assert all(f.stat().st_mtime_ns == OLD_NS for f in stored)  # the entries keep theirs


def test_key_follows_input_content_not_paths(tmp_path):
    a, b = tmp_path / "a.txt", tmp_path / "elsewhere" / "b.txt"
    b.parent.mkdir()
    a.write_text("same bytes")
    b.write_text("same bytes")
    key = lambda p, **kw: job_key("r", ["objects"], kw.get("params", {"x": 1}), {}, [p])[0]  # noqa: E731
    assert key(a) == key(b)
    assert key(a, params={"x": 2}) != key(a)
    b.write_text("other bytes")
    assert key(a) != key(b)
    # key order of the params does not matter, their values do
    k1 = job_key("r", ["objects"], {"x": 1, "y": 2}, {}, [a])[0]
    k2 = job_key("r", ["objects"], {"y": 2, "x": 1}, {}, [a])[0]
    assert k1 == k2
    # a different rule, wildcard or stage code is a different result
    assert job_key("q", ["objects"], {"x": 1}, {}, [a])[0] != key(a)
    assert job_key("r", ["objects"], {"x": 1}, {"shard": "1"}, [a])[0] != key(a)
    assert job_key("r", ["synthesis"], {"x": 1}, {}, [a])[0] != key(a)


def test_another_workflow_directory_shares_the_cache(tmp_path):
    cache = tmp_path / "shared-cache"
    for d in ("wf1", "wf2"):
        (tmp_path / d).mkdir()
        (tmp_path / d / "in.txt").write_text("grasps")
    one = _job(tmp_path / "wf1", cache)
    run_cached(one, ["replay"], _Counter(one))
    two = _job(tmp_path / "wf2", cache)
    compute = _Counter(two)
    assert run_cached(two, ["replay"], compute) is True and compute.calls == 0
    assert Path(two.output.trace).read_bytes() == Path(one.output.trace).read_bytes()


def test_failed_compute_stores_nothing(tmp_path):
    (tmp_path / "in.txt").write_text("grasps")
    cache = tmp_path / "cache"
    job = _job(tmp_path, cache)

    def boom():
        raise RuntimeError("replay diverged")

    with pytest.raises(RuntimeError):
        run_cached(job, ["replay"], boom)
    assert not list(cache.rglob("entry.json"))
    compute = _Counter(job)
    assert run_cached(job, ["replay"], compute) is False and compute.calls == 1


def test_disabled_cache_always_computes_and_stores_nothing(tmp_path):
    (tmp_path / "in.txt").write_text("grasps")
    cache = tmp_path / "cache"
    job = _job(tmp_path, cache, enabled=False)
    compute = _Counter(job)
    run_cached(job, ["replay"], compute)
    run_cached(job, ["replay"], compute)
    assert compute.calls == 2 and not cache.exists()


def test_incomplete_entry_is_ignored_and_concurrent_store_keeps_one(tmp_path):
    src = tmp_path / "f.txt"
    src.write_text("x")
    cache = ResultCache(tmp_path / "cache")
    # a half-built entry (no entry.json, e.g. a job killed while storing) is not a hit, and it
    # is removed so that the job's store puts a complete one in its place
    (cache.entry("r", "k")).mkdir(parents=True)
    (cache.entry("r", "k") / "f").write_text("partial")
    assert cache.restore("r", "k", {"f": tmp_path / "out.txt"}) is False
    assert not (tmp_path / "out.txt").exists()
    assert not cache.entry("r", "k").exists()
    cache.store("r", "k", {"f": src}, {"rule": "r"})
    src2 = tmp_path / "g.txt"
    src2.write_text("y")
    cache.store("r", "k", {"f": src2}, {"rule": "r"})  # the same key again: first entry stays
    assert (cache.entry("r", "k") / "f").read_text() == "x"
    assert json.loads((cache.entry("r", "k") / "entry.json").read_text())["key"] == "k"
    assert not [p for p in cache.entry("r", "k").parent.iterdir() if p.name.startswith(".")]


def test_directory_digest_and_stage_closure(tmp_path):
    d = tmp_path / "hand"
    (d / "meshes").mkdir(parents=True)
    (d / "meshes" / "a.stl").write_bytes(b"1")
    first = content_digest(d)
    (d / "meshes" / "a.stl").write_bytes(b"2")
    assert content_digest(d) != first
    # learning reads datasets through the dataset format's module, and traces (the sensing
    # study) through replay's trace module: a change there must reach the key; the labelling
    # entry point (its effect is in the dataset's content), replay's engine and another stage's
    # figure must not
    learning = set(module_closure(["learning"]))
    assert {"labels/dataset.py", "labels/trace_windows.py", "replay/traces.py",
            "common/io.py", "learning/train.py", "__init__.py"} <= learning  # fmt: skip
    assert not {"labels/label_windows.py", "replay/scene.py", "replay/figure.py",
                "hand/figure.py"} & learning  # fmt: skip
    assert not any(f.startswith("labels/") for f in module_closure(["replay"]))
    objects = module_closure(["objects"])
    assert all(f.startswith(("objects/", "assets/", "common/", "__init__")) for f in objects)


def test_module_closure_follows_function_level_and_relative_imports():
    # labels.figure imports replay.figure at module level; replay.figure's own closure reaches
    # hand.names (FINGERS) but nothing of labels
    assert "hand/names.py" in module_closure(["replay/figure"])
    assert "replay/figure.py" in module_closure(["labels/figure"])
    with pytest.raises(ValueError, match="no graspstab sub-package"):
        module_closure(["no_such_stage"])


def _truncate(path: Path) -> None:
    path.write_bytes(path.read_bytes()[: path.stat().st_size // 2])


def _flip_byte(path: Path) -> None:
    """One bit of the middle byte changed: the size stays, only the digest can tell."""
    data = bytearray(path.read_bytes())
    data[len(data) // 2] ^= 0x01
    path.write_bytes(bytes(data))


DAMAGE = {"truncated": _truncate, "deleted": Path.unlink, "byte flipped": _flip_byte}


@pytest.mark.parametrize("damage", sorted(DAMAGE))
def test_damaged_entry_is_removed_recomputed_and_stored_whole(tmp_path, caplog, damage):
    """A truncated, missing or changed file in an entry: the restore refuses it with a warning
    naming the entry, the job recomputes, and the entry it stores verifies again."""
    (tmp_path / "in.txt").write_text("grasps")
    cache_dir = tmp_path / "cache"
    first = _job(tmp_path, cache_dir)
    run_cached(first, ["replay"], _Counter(first))
    (entry,) = [p.parent for p in cache_dir.rglob("entry.json")]
    DAMAGE[damage](entry / "1")  # the trace file, output 1
    for p in first.output:
        Path(p).unlink()

    job = _job(tmp_path, cache_dir)
    compute = _Counter(job)
    with caplog.at_level("WARNING", logger="graspstab.common.cache"):
        assert run_cached(job, ["replay"], compute) is False
    assert compute.calls == 1
    assert f"cache entry {entry} is damaged" in caplog.text
    assert f"stored a whole entry at {entry}" in Path(job.log[0]).read_text()
    # the stored entry is whole and holds what the job computed
    cache = ResultCache(cache_dir)
    cache.verify(entry, ["0", "1"])
    assert (entry / "1").read_bytes() == Path(job.output.trace).read_bytes()
    # and a third run restores it, unchanged
    for p in job.output:
        Path(p).unlink()
    again = _job(tmp_path, cache_dir)
    compute = _Counter(again)
    assert run_cached(again, ["replay"], compute) is True and compute.calls == 0
    assert Path(again.output.trace).read_bytes() == (entry / "1").read_bytes()
    assert not [p for p in entry.parent.iterdir() if p.name.startswith(".")]  # no debris


def test_entry_without_checksums_is_not_trusted(tmp_path):
    """An entry whose record lists no files (one stored before records had checksums, or a
    record edited by hand) is replaced rather than restored unverified."""
    src = tmp_path / "f.txt"
    src.write_text("x")
    cache = ResultCache(tmp_path / "cache")
    cache.store("r", "k", {"f": src}, {"rule": "r"})
    record = json.loads((cache.entry("r", "k") / "entry.json").read_text())
    assert record["files"]["f"] == {"size": 1, "sha256": content_digest(src)}
    del record["files"]
    (cache.entry("r", "k") / "entry.json").write_text(json.dumps(record))
    assert cache.restore("r", "k", {"f": tmp_path / "out.txt"}) is False
    assert not cache.entry("r", "k").exists()


def test_store_replaces_a_damaged_entry_of_the_same_key(tmp_path):
    """A half entry (one file lost after it was stored) used to stay forever, since a store
    returned as soon as the record existed: now the store puts a complete entry in its place."""
    a, b = tmp_path / "a.txt", tmp_path / "b.txt"
    a.write_text("alpha")
    b.write_text("beta")
    cache = ResultCache(tmp_path / "cache")
    entry = cache.store("r", "k", {"a": a, "b": b}, {"rule": "r"})
    (entry / "b").unlink()
    assert cache.store("r", "k", {"a": a, "b": b}, {"rule": "r"}) == entry
    cache.verify(entry, ["a", "b"])
    assert (entry / "b").read_text() == "beta"


@pytest.mark.parametrize("changed_after_restore", [False, True])
def test_unreadable_file_names_the_cache_entry_it_came_from(tmp_path, changed_after_restore):
    """A corrupt input that a restore placed: the advice names the entry, and says whether the
    entry holds the same bytes (delete it too) or the file changed after the restore."""
    from graspstab.common.io import cache_origin, unreadable

    src = tmp_path / "t.parquet"
    src.write_bytes(b"not a parquet file")  # stored as computed: a corrupt entry
    cache = ResultCache(tmp_path / "cache")
    entry = cache.store("r", "k", {"t": src}, {"rule": "r"})
    out = tmp_path / "results" / "t.parquet"
    assert cache.restore("r", "k", {"t": out})
    assert cache_origin(out) == entry.resolve()
    if changed_after_restore:
        _flip_byte(out)
    message = str(unreadable(out, ValueError("bad magic")))
    assert str(entry.resolve()) in message
    if changed_after_restore:
        assert "changed since" in message and "restores the entry's verified copy" in message
    else:
        assert "holds the same bytes: delete that folder and this file" in message
    # a file the job wrote itself carries no origin, and gets the plain advice
    plain = tmp_path / "results" / "own.parquet"
    plain.write_bytes(b"x")
    assert cache_origin(plain) is None
    assert str(unreadable(plain, ValueError("bad"))).endswith("the workflow rebuilds it.")


def test_each_cached_script_keys_the_code_it_runs():
    """A cached job's key covers the closure of the modules its script names for run_cached; every
    graspstab module the script imports must be inside it (else editing that module would
    restore stale results), while code it never runs (its stage's figures) stays out."""
    import ast

    from tests.conftest import REPO

    src = REPO / "src" / "graspstab"
    checked = 0
    for script in sorted((REPO / "workflow" / "scripts").glob("*.py")):
        tree = ast.parse(script.read_text())
        if not any(isinstance(n, ast.Name) and n.id == "run_cached" for n in ast.walk(tree)):
            continue
        # the code names given to run_cached: string constants naming a module or package
        named = {c.value for c in ast.walk(tree) if isinstance(c, ast.Constant)
                 and isinstance(c.value, str) and c.value.isidentifier() is False
                 and (src / c.value).with_suffix(".py").is_file()}  # fmt: skip
        named |= {c.value for c in ast.walk(tree) if isinstance(c, ast.Constant)
                  and isinstance(c.value, str) and c.value.isidentifier()
                  and (src / c.value / "__init__.py").is_file()}  # fmt: skip
        assert named, f"{script.name}: no module named for its cache key"
        closure = set(module_closure(sorted(named)))
        for node in ast.walk(tree):
            if isinstance(node, ast.ImportFrom) and (node.module or "").startswith("graspstab."):
                rel = node.module.removeprefix("graspstab.").replace(".", "/")
                if rel.startswith("common"):
                    continue
                assert f"{rel}.py" in closure or f"{rel}/__init__.py" in closure, (
                    f"{script.name} imports {node.module}, outside its cache key {sorted(named)}"
                )
        checked += 1
    assert checked == 10
    replay = set(module_closure(["replay/replay_grasps"]))
    assert "replay/figure.py" not in replay and "replay/replay_grasps.py" in replay
