"""The tests obtain their assets as the workflow does: in a clone with no local copies and no
variables, from a loopback download origin, they fetch, verify and use them; with the origin
down, every test that needs them fails with one message that says what to set."""

from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
from pathlib import Path

import mujoco
import pytest
from asset_archives import serve, workflow_config_line, write_hand_archive, write_ycb_archives
from conftest import ASSET_VARIABLES, REPO, workflow_config

from graspstab.assets.hand import load_manifest
from graspstab.assets.mesh_file import load_object_mesh
from graspstab.hand.model import build_hand_spec, compile_hand, find_scene
from graspstab.hand.params import DEFAULT_PARAMS

# the inner session runs this module's first test alone, in the clone
INNER = "tests/test_assets_clone.py::test_assets_in_use_are_verified_and_usable"


def test_assets_in_use_are_verified_and_usable(
    pytestconfig: pytest.Config, ycb_dir: Path, hand_assets_dir: Path
) -> None:
    """Every configured mesh carries the record of a verified fetch and loads; so does the hand."""
    items = workflow_config(pytestconfig)["objects"]["items"]
    for object_id, entry in items.items():
        record = json.loads((ycb_dir / object_id / "source.json").read_text())
        assert record["verified"] is True and record["sha256"] == entry["sha256"], object_id
        mesh = load_object_mesh(ycb_dir / object_id / "textured.obj", object_id)
        assert 0.005 < max(mesh.extents) < 0.5, object_id  # a hand-held size, in metres
    record = json.loads((hand_assets_dir / "source.json").read_text())
    unchecked = len(record["manifest"]["not_verified_local_patch"])  # a local copy's patched MJCF
    assert record["manifest"]["verified"] == len(load_manifest()) - unchecked
    assert unchecked == (2 if record["method"] == "local" else 0)
    hand = compile_hand(build_hand_spec(hand_assets_dir, DEFAULT_PARAMS))
    assert hand.nu == 16  # the 16 finger servos of the floating hand
    assert mujoco.MjModel.from_xml_path(str(find_scene(hand_assets_dir))).nu == 17


# what a fresh clone lacks, for a checkout that is not a git repository (an unpacked archive)
NOT_IN_A_CLONE = {".git", ".venv", "resources", "results", ".graspstab-cache", ".snakemake", "site"}


def _clone(dest: Path) -> Path:
    """The repository's files as a fresh clone has them (tracked and untracked-unignored)."""
    listed = subprocess.run(
        ["git", "ls-files", "-z", "--cached", "--others", "--exclude-standard"],
        cwd=REPO,
        capture_output=True,
    )
    if listed.returncode == 0:
        files = [REPO / rel for rel in listed.stdout.decode().split("\0") if rel]
    else:
        files = [
            p
            for p in REPO.rglob("*")
            if not NOT_IN_A_CLONE & set(p.relative_to(REPO).parts) and "__pycache__" not in p.parts
        ]
    for src in files:
        if src.is_file():
            rel = src.relative_to(REPO)
            (dest / rel).parent.mkdir(parents=True, exist_ok=True)
            shutil.copy2(src, dest / rel)
    return dest


def _inner_pytest(clone: Path, base_url: str) -> subprocess.CompletedProcess:
    env = {k: v for k, v in os.environ.items() if k not in ASSET_VARIABLES}
    env["PYTHONPATH"] = str(clone / "src")  # the clone's package, not the installed checkout
    cmd = [sys.executable, "-m", "pytest", "-q", "-rN", "-p", "no:cacheprovider", "-n", "0", INNER]
    cmd += ["--workflow-config", workflow_config_line(base_url)]
    return subprocess.run(cmd, cwd=clone, env=env, capture_output=True, text=True, timeout=600)


def test_clone_without_local_copies_downloads_verifies_and_uses_the_assets(
    tmp_path: Path, pytestconfig: pytest.Config, ycb_dir: Path, hand_assets_dir: Path
) -> None:
    clone = _clone(tmp_path / "work" / "graspstab")
    assert not (clone.parent / "shared").exists() and not (clone / "resources" / "ycb").exists()
    items = workflow_config(pytestconfig)["objects"]["items"]
    www = tmp_path / "www"
    write_ycb_archives(ycb_dir, items, www)
    write_hand_archive(hand_assets_dir, www)

    # the origin down (a server that has stopped): one message, what to set, no traceback
    with serve(tmp_path / "nothing_served") as dead_url:
        pass
    down = _inner_pytest(clone, dead_url)
    out = down.stdout + down.stderr
    assert down.returncode == 1, out[-3000:]
    assert "1 error" in out and out.count("could not get them") == 1, out[-3000:]
    assert "GRASPSTAB_YCB_DIR" in out and "GRASPSTAB_HAND_DIR" in out and dead_url in out
    assert "Traceback" not in out and "During handling" not in out, out[-3000:]
    assert not list((clone / "resources").glob("ycb/*/textured.obj"))  # nothing half-written

    with serve(www) as base_url:
        proc = _inner_pytest(clone, base_url)
    out = proc.stdout + proc.stderr
    assert proc.returncode == 0 and "1 passed" in out, out[-3000:]
    for object_id in items:
        record = json.loads((clone / "resources/ycb" / object_id / "source.json").read_text())
        assert record["method"] == "download" and record["url"].startswith(base_url), record
        assert record["verified"] is True
    hand = json.loads((clone / "resources/orcahand_description/source.json").read_text())
    assert hand["method"] == "download" and hand["url"].startswith(base_url)
    assert hand["manifest"]["verified"] == len(load_manifest())  # every pin, the MJCF included
