"""A failed workflow job says why once (graspstab.common.jobs, docs/troubleshooting.md).

A graspstab error ends the job with its message alone, a bug with its traceback, a full disk with
the path and the free space; each goes to the job's log (which the profile's show-failed-logs
prints under Snakemake's error block) and, for a job without a log, to stderr. The replay job
checks its traces' largest size against the free space before it simulates.

The workflow scripts run as Snakemake runs them: in-process through ``runpy`` with a
``snakemake`` object of Snakemake's own containers, and once through Snakemake itself.
"""

from __future__ import annotations

import errno
import logging
import os
import re
import runpy
import shutil
import subprocess
import textwrap
from collections import namedtuple
from pathlib import Path
from types import SimpleNamespace
from typing import Any

import mujoco
import numpy as np
import polars as pl
import pyarrow.parquet as pq
import pytest
from snakemake.iocontainers import Namedlist

import graspstab.assets.ycb as ycb
import graspstab.common.cache as cache
import graspstab.replay.replay_grasps as replay_module
from graspstab.assets import AssetError
from graspstab.common.errors import GraspstabError
from graspstab.common.io import save_npz, write_parquet
from graspstab.common.jobs import disk_full_message, format_bytes, job
from graspstab.config import ConfigError
from graspstab.learning.storage import StorageError
from graspstab.replay.run import run_replay
from graspstab.replay.scene import build_replay_scene, place_grasp, to_object_frame
from graspstab.replay.traces import LOAD, WIDTHS, trace_bytes
from tests.toy_workflow import REPO, snakemake_command

SCRIPTS = REPO / "workflow" / "scripts"
FOAM, LEMON, CUBE = "061_foam_brick", "014_lemon", "077_rubiks_cube"
RECORD = re.compile(r"^\d{4}-\d\d-\d\d \d\d:\d\d:\d\d,\d{3} ERROR graspstab\.job: ", re.M)
FREE = re.compile(r" has [\d.]+ [kMGT]?B free of [\d.]+ [kMGT]?B")
Usage = namedtuple("Usage", "total used free")


@pytest.fixture(autouse=True)
def _restore_logging():
    """The scripts' setup_logging replaces the root handlers; give the next test pytest's back."""
    root = logging.getLogger()
    handlers, level = root.handlers[:], root.level
    yield
    root.handlers[:] = handlers
    root.setLevel(level)


def _smk(rule: str, *, log: Path | None, config: dict | None = None, **named: dict) -> Any:
    """A stand-in for the ``snakemake`` object of a script job, built of Snakemake's containers."""
    box = {k: Namedlist(fromdict=named.get(k, {})) for k in ("input", "output", "params")}
    return SimpleNamespace(
        rule=rule,
        wildcards=Namedlist(fromdict=named.get("wildcards", {})),
        log=Namedlist([str(log)] if log else []),
        config=config or {"cache": {"enabled": False}},
        threads=1,
        **box,
    )


def _run(script: str, smk: Any) -> int | None:
    """Run a workflow script as Snakemake does; its exit status (None when it returned)."""
    try:
        runpy.run_path(str(SCRIPTS / script), init_globals={"snakemake": smk}, run_name="__main__")
    except SystemExit as ended:
        return ended.code
    return None


def _records(log: Path) -> list[str]:
    """The job-failure records of a log file, each with the lines that follow it."""
    text = log.read_text()
    starts = [m.start() for m in RECORD.finditer(text)]
    return [text[a:b].rstrip() for a, b in zip(starts, [*starts[1:], len(text)], strict=True)]


# ---------------------------------------------------------------- the error classes


@pytest.mark.parametrize("cls", [AssetError, ConfigError, StorageError])
def test_graspstab_errors_share_a_base_and_keep_theirs(cls: type) -> None:
    historic = {AssetError: RuntimeError, ConfigError: ValueError, StorageError: SystemExit}[cls]
    assert issubclass(cls, GraspstabError) and issubclass(cls, historic)


# ---------------------------------------------------------------- (a) a graspstab error


def _fetch_job(tmp_path: Path, mesh: Path, *, log: bool) -> Any:
    out = tmp_path / "resources" / "ycb" / FOAM
    return _smk(
        "fetch_ycb_object",
        log=tmp_path / "fetch.log" if log else None,
        output={"mesh": str(out / "textured.obj"), "source": str(out / "source.json")},
        params={"local_dir": None, "url": "http://127.0.0.1:9/{id}", "sha256": None,
                "mesh_override": str(mesh)},
        wildcards={"object": FOAM},
    )  # fmt: skip


@pytest.fixture
def not_a_mesh(tmp_path: Path) -> tuple[Path, str]:
    """A user's 'mesh' that is text, and the message the fetch refuses it with."""
    bad = tmp_path / "notes.obj"
    bad.write_text("just some notes, no vertices or faces\n")
    with pytest.raises(AssetError) as refused:
        ycb.fetch_ycb_object(FOAM, tmp_path / "probe", mesh_override=bad)
    return bad, str(refused.value)


def test_graspstab_error_is_one_record_in_the_log(
    tmp_path: Path, not_a_mesh: tuple[Path, str], capsys: pytest.CaptureFixture[str]
) -> None:
    bad, message = not_a_mesh
    smk = _fetch_job(tmp_path, bad, log=True)
    assert _run("fetch_ycb_object.py", smk) == 1
    err = capsys.readouterr().err
    log = Path(smk.log[0]).read_text()
    # the log holds it once, as one record naming the job; no traceback anywhere
    [record] = _records(Path(smk.log[0]))
    assert record.endswith(f"fetch_ycb_object (object={FOAM}) failed: {message}")
    assert log.count(message) == 1 and str(bad) in message
    assert "Traceback" not in log + err and "During handling" not in log + err
    # the terminal gets it from the log (show-failed-logs), so not a second time from stderr
    assert message not in err
    assert not (tmp_path / "resources" / "ycb" / FOAM / "textured.obj").exists()


def test_a_log_that_cannot_be_written_leaves_the_message_on_stderr(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    """The log gone by the time the job fails (here a folder in its place, as good as a full
    disk for appending): the message goes to stderr instead, once."""
    smk = _fetch_job(tmp_path, tmp_path / "unused.obj", log=True)

    def fetch_then_fail(*args: Any, **kwargs: Any) -> None:
        Path(smk.log[0]).unlink()
        Path(smk.log[0]).mkdir()
        raise AssetError("YCB object '061_foam_brick': the planted failure")

    monkeypatch.setattr(ycb, "fetch_ycb_object", fetch_then_fail)
    assert _run("fetch_ycb_object.py", smk) == 1
    err = capsys.readouterr().err
    assert err.count("the planted failure") == 1 and "Traceback" not in err
    assert f"fetch_ycb_object (object={FOAM}) failed: YCB object '{FOAM}'" in err


# ---------------------------------------------------------------- (b) a bug


def _divide_by_zero(*args: Any, **kwargs: Any) -> None:
    raise ZeroDivisionError("division by zero")


def test_bug_keeps_its_traceback_in_the_log(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    monkeypatch.setattr(ycb, "fetch_ycb_object", _divide_by_zero)
    smk = _fetch_job(tmp_path, tmp_path / "unused.obj", log=True)
    assert _run("fetch_ycb_object.py", smk) == 1
    err = capsys.readouterr().err
    [record] = _records(Path(smk.log[0]))
    assert record.count("Traceback (most recent call last):") == 1
    assert "in _divide_by_zero" in record and record.endswith("ZeroDivisionError: division by zero")
    assert f"fetch_ycb_object (object={FOAM}) failed on an unexpected error, a bug" in record
    assert "Traceback" not in err  # once: in the log, which Snakemake prints, not on stderr too


@pytest.mark.parametrize(
    "error", [AssetError("the planted failure"), ZeroDivisionError("planted bug")]
)
def test_a_job_without_a_log_reports_on_stderr(
    error: Exception, capsys: pytest.CaptureFixture[str]
) -> None:
    smk = _smk("write_report", log=None)
    with pytest.raises(SystemExit) as ended, job(smk):
        raise error
    assert ended.value.code == 1
    err = capsys.readouterr().err
    assert err.startswith("write_report failed")
    assert err.count("Traceback") == (0 if isinstance(error, GraspstabError) else 1)
    assert err.count(str(error)) == 1


# ---------------------------------------------------------------- (c) a full disk


def _grasps(path: Path, n: int) -> Path:
    write_parquet(path, pl.DataFrame({"grasp_id": list(range(n)), "shard": [0] * n}))
    return path


def _replay_job(tmp_path: Path, *, steps: int = 2000, grasps: int = 4, cache_on: bool = False):
    out = tmp_path / "results" / "replay" / LEMON
    return _smk(
        "replay_grasps",
        log=tmp_path / "replay.log",
        config={"cache": {"enabled": cache_on, "dir": str(tmp_path / "cache")}},
        input={"object_xml": str(tmp_path / "objects" / LEMON / "object.xml"),
               "hand": str(tmp_path / "hand" / "hand.xml"),
               "grasps": str(_grasps(tmp_path / "shard_0.parquet", grasps))},
        output={"traces": str(out / "traces_0.npz"), "summary": str(out / "replays_0.parquet"),
                "timing": str(out / "timing_0.json")},
        params={"replay": {"steps": steps, "protocol": "gravity"}},
        wildcards={"object": LEMON, "shard": "0"},
    )  # fmt: skip


def _write_outputs(object_id, object_dir, hand_dir, grasp_table, traces, summary, **kw) -> None:
    """A replay that writes its files through graspstab's writers (no simulation)."""
    save_npz(traces, g0_position=np.zeros((10, 3), np.float32))
    write_parquet(summary, pl.DataFrame({"grasp_id": [0]}))


def _full_on_npz(fh: Any, **arrays: Any) -> None:
    """A write that hits a full disk, naming the file it writes (the atomic writer's temporary)."""
    raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC), fh.name)


def _full_on_parquet(table: Any, where: Any, **kwargs: Any) -> None:
    """pyarrow's form: the errno in the text only, and no file name."""
    raise OSError("[Errno 28] Error writing bytes to file. Detail: [errno 28] No space left on "
                  "device")  # fmt: skip


@pytest.mark.parametrize(
    ("target", "writer", "named"),
    [(np, "savez_compressed", ["traces"]), (pq, "write_table", ["traces", "summary", "timing"])],
    ids=["npz_names_its_file", "parquet_names_the_outputs"],
)
def test_full_disk_names_the_output_and_the_free_space(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str],
    target: Any, writer: str, named: list[str],
) -> None:  # fmt: skip
    smk = _replay_job(tmp_path)
    monkeypatch.setattr(replay_module, "replay_grasps", _write_outputs)
    monkeypatch.setattr(target, writer, _full_on_npz if target is np else _full_on_parquet)
    usage = Usage(total=50_000_000_000, used=49_876_543_211, free=123_456_789)
    monkeypatch.setattr(shutil, "disk_usage", lambda path: usage)
    assert _run("replay_grasps.py", smk) == 1
    err = capsys.readouterr().err
    [record] = _records(Path(smk.log[0]))
    out_dir = Path(smk.output.traces).parent
    assert "replay_grasps (object=014_lemon, shard=0) failed: the disk is full" in record
    for name, path in smk.output.items():  # the output(s) it wrote, not a temporary file
        assert (path in record) is (name in named), name
        assert f".{Path(path).name}." not in record
    assert f"{out_dir} has 123 MB free of 50 GB" in record and FREE.search(record)
    assert "Free space there" in record and "GRASPSTAB_CACHE_DIR" in record
    assert "Traceback" not in record + err and record.count("No space left on device") == 1
    left = ["traces_0.npz"] if writer == "write_table" else []  # Snakemake deletes it
    assert sorted(p.name for p in out_dir.iterdir()) == left


def test_full_disk_in_a_copy_names_the_target(tmp_path: Path) -> None:
    """shutil's copy reports ENOSPC with the source as filename and the target as filename2
    (the result cache storing an output): the message names the target and its disk."""
    out, entry = tmp_path / "out.npz", tmp_path / "cache" / "rule" / "key" / "0"
    smk = _smk("replay_grasps", log=None, output={"traces": str(out)})
    error = OSError(errno.ENOSPC, os.strerror(errno.ENOSPC), str(out), None, str(entry))
    message = disk_full_message(smk, error)
    assert f"while writing {entry}. {tmp_path} has " in message and str(out) not in message


# ---------------------------------------------------------------- (d) the replay's check first


@pytest.mark.parametrize(
    ("free_mb", "cache_on", "fails"),
    [(100, False, True), (800, True, True), (800, False, False)],
    ids=["too_little", "too_little_for_the_cache_copy", "enough"],
)
def test_replay_checks_free_space_before_it_simulates(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, free_mb: int, cache_on: bool, fails: bool
) -> None:
    calls: list[str] = []
    monkeypatch.setattr(replay_module, "replay_grasps", lambda *a, **k: calls.append("replay"))
    real_run_cached = cache.run_cached
    monkeypatch.setattr(cache, "run_cached",
                        lambda *a: calls.append("run_cached") or real_run_cached(*a))  # fmt: skip
    usage = Usage(total=50_000_000_000, used=0, free=free_mb * 1_000_000)
    monkeypatch.setattr(shutil, "disk_usage", lambda path: usage)
    smk = _replay_job(tmp_path, steps=40_000, grasps=128, cache_on=cache_on)
    need = trace_bytes(128, 40_000, load=False)  # the thesis shard: 128 grasps x 20 s
    assert 100e6 < need < 800e6 < 2 * need
    status = _run("replay_grasps.py", smk)
    if not fails:
        assert status is None and calls == ["run_cached", "replay"]
        return
    assert status == 1 and calls == []  # nothing computed, nothing restored
    [record] = _records(Path(smk.log[0]))
    total = 2 * need if cache_on else need
    assert "not enough free disk space for this shard's replay traces" in record
    assert smk.output.traces in record and f"up to {format_bytes(total)}" in record
    assert f"has {free_mb} MB free of 50 GB" in record
    assert ("(the result cache's copy)" in record) is cache_on


def test_trace_bound_holds_a_real_replay(
    foam_brick_dir: Path, built_hand_dir: Path, tmp_path: Path
) -> None:
    """Every channel the replay records has the width the bound counts, and a saved shard is
    no larger than the bound (ramp protocol: the load channel too)."""
    from test_replay_ramp import _replay_params

    params = _replay_params(start_s=0.01, rate=20.0, ceiling=3.0, directions="gravity",
                            path="linear")  # fmt: skip
    scene = build_replay_scene(built_hand_dir, foam_brick_dir, params)
    data = mujoco.MjData(scene.model)
    pos, quat = np.array([0.3, -0.1, 0.05]), np.array([1.0, 0.0, 0.0, 0.0])
    place_grasp(scene, data, pos, quat, np.zeros(16), np.array(params["gravity"]))
    steps = 200
    load = replay_module.grasp_load(params, scene, scene.model.opt.gravity.copy(), FOAM, 0)
    result = run_replay(scene.model, data, scene.layout, steps, 100, 10_000, load,
                        scene.object_body)  # fmt: skip
    traces = {c: v for c, v in to_object_frame(result.traces, pos, quat).items() if c in WIDTHS}
    assert set(traces) == set(WIDTHS) and LOAD in traces
    for channel, values in traces.items():
        assert values.dtype == np.float32 and len(values) == steps, channel
        assert (values.shape[1] if values.ndim == 2 else 1) == WIDTHS[channel], channel
    path = tmp_path / "traces_0.npz"
    save_npz(path, **{f"g0_{c}": v for c, v in traces.items()})
    assert path.stat().st_size <= trace_bytes(1, steps, load=True)
    assert sum(v.nbytes for v in traces.values()) <= trace_bytes(1, steps, load=True)


# ---------------------------------------------------------------- through Snakemake


SITECUSTOMIZE = """
import errno, os
from pathlib import Path
import graspstab.assets.ycb as ycb
from graspstab.common.io import atomic_path

_real = ycb.fetch_ycb_object

def fetch(object_id, dest_dir, **kwargs):
    if object_id == "{lemon}":  # a bug
        return 1 / 0
    if object_id == "{cube}":  # a full disk while writing the mesh
        with atomic_path(Path(dest_dir) / "textured.obj") as tmp, open(tmp, "wb") as fh:
            raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))
    return _real(object_id, dest_dir, **kwargs)

ycb.fetch_ycb_object = fetch
"""


@pytest.mark.workflow
def test_what_the_terminal_shows_for_each_failure(
    tmp_path: Path, asset_env: dict[str, str], not_a_mesh: tuple[Path, str]
) -> None:
    """Three fetch jobs fail in one run (--keep-going): the foam brick's mesh is not a mesh
    (a graspstab error), the lemon's fetch divides by zero (a bug), the cube's disk is full. The
    terminal shows each failure once, under Snakemake's block for the job, from its log."""
    bad, message = not_a_mesh
    conf = tmp_path / "conf" / "objects"
    conf.mkdir(parents=True)
    (conf / "own.yaml").write_text(
        textwrap.dedent(f"""\
        name: own
        items:
          {FOAM}: {{split: train, mass: 0.028, sha256: null, mesh: {bad}}}
          {LEMON}: {{split: val, mass: 0.029, sha256: null}}
          {CUBE}: {{split: test, mass: 0.094, sha256: null}}
        """)
    )
    hooks = tmp_path / "hooks"
    hooks.mkdir()
    (hooks / "sitecustomize.py").write_text(SITECUSTOMIZE.format(lemon=LEMON, cube=CUBE))
    env = dict(
        asset_env,
        PYTHONPATH=os.pathsep.join(filter(None, [str(hooks), asset_env.get("PYTHONPATH")])),
    )
    work = tmp_path / "wd"
    targets = [f"resources/ycb/{o}/textured.obj" for o in (FOAM, LEMON, CUBE)]
    searchpath = f'"hydra.searchpath=[file://{tmp_path / "conf"}]"'
    cmd = snakemake_command(work, "--cores", "3", "--keep-going", *targets,
                            "--config", f"overrides=[{searchpath}]", "objects=own")  # fmt: skip
    proc = subprocess.run(cmd, capture_output=True, text=True, env=env, timeout=120)
    out = proc.stdout + proc.stderr
    assert proc.returncode == 1, out[-4000:]
    for rule_object in (FOAM, LEMON, CUBE):
        assert out.count(f"Logfile results/logs/fetch_ycb_object/{rule_object}.log:") == 1
    # (a) the message once, no traceback for it
    assert out.count(message) == 1 and out.count(f"(object={FOAM}) failed") == 1
    # (b) the bug's traceback once, in its log's block
    assert out.count("Traceback (most recent call last):") == 1
    assert out.count("ZeroDivisionError: division by zero") == 1
    # (c) the full disk: the outputs, the free space, the fix; once
    [full] = [line for line in out.splitlines() if f"(object={CUBE}) failed" in line]
    assert "the disk is full (No space left on device) while writing " in full
    assert f"resources/ycb/{CUBE}/textured.obj" in full and FREE.search(full)
    assert "Free space there" in full and "During handling" not in out
    for o in (FOAM, LEMON, CUBE):  # the logs hold what the terminal showed; no outputs left
        [record] = _records(work / f"results/logs/fetch_ycb_object/{o}.log")
        assert record.splitlines()[0] in out
        assert not (work / f"resources/ycb/{o}/textured.obj").exists()
