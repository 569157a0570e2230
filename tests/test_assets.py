"""Tests of graspstab.assets: local copies, checksums, downloads from a local server, the CLI."""

from __future__ import annotations

import functools
import hashlib
import http.server
import io
import json
import logging
import shutil
import socket
import subprocess
import sys
import tarfile
import threading
from collections.abc import Iterator
from pathlib import Path

import pytest
import yaml
from conftest import CONFIG_DIR

from graspstab.assets import YCB_IDS, AssetError, is_known_ycb_id
from graspstab.assets.cli import main
from graspstab.assets.hand import (
    ABSENT_LOCALLY_OK,
    HAND_COMMIT,
    UPSTREAM_MJCF,
    build_manifest,
    fetch_hand_description,
    load_manifest,
    read_manifest,
)
from graspstab.assets.ycb import fetch_ycb_object
from tests.toy_workflow import listed_jobs, snakemake_run

FOAM = "061_foam_brick"
FOAM_SHA = "04a5b79997a874638c3ad71044b1ed50fae16148f9bd29629fe37caab3a71d86"
OBJ_BYTES = b"v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n"
# a user's own mesh must be a hand-held size (5 mm to 0.5 m; tests/test_objects_mesh_file.py)
# a closed tetrahedron: the fetch step refuses a flat mesh (a lone triangle)
OWN_OBJ_BYTES = b"v 0 0 0\nv 0.1 0 0\nv 0 0.1 0\nv 0 0 0.1\nf 1 3 2\nf 1 2 4\nf 1 4 3\nf 2 3 4\n"
STL = "v2/models/assets/right/A.stl"


def sha(data: bytes) -> str:
    return hashlib.sha256(data).hexdigest()


def files_under(path: Path) -> list[str]:
    """Every file and folder under ``path`` (hidden temp files included)."""
    return sorted(p.relative_to(path).as_posix() for p in path.rglob("*")) if path.exists() else []


def make_tgz(path: Path, members: dict[str, bytes]) -> Path:
    path.parent.mkdir(parents=True, exist_ok=True)
    with tarfile.open(path, "w:gz") as tf:
        for name, data in members.items():
            info = tarfile.TarInfo(name)
            info.size = len(data)
            tf.addfile(info, io.BytesIO(data))
    return path


class _QuietHandler(http.server.SimpleHTTPRequestHandler):
    def log_message(self, format: str, *args: object) -> None:  # noqa: A002
        pass


@pytest.fixture
def server(tmp_path: Path) -> Iterator[tuple[str, Path]]:
    """An HTTP server on 127.0.0.1 (free port) serving a tmp folder; yields (base URL, folder)."""
    root = tmp_path / "www"
    root.mkdir()
    handler = functools.partial(_QuietHandler, directory=str(root))
    httpd = http.server.ThreadingHTTPServer(("127.0.0.1", 0), handler)
    thread = threading.Thread(target=httpd.serve_forever, daemon=True)
    thread.start()
    try:
        yield f"http://127.0.0.1:{httpd.server_address[1]}", root
    finally:
        httpd.shutdown()
        httpd.server_close()
        thread.join(timeout=5)


# ---------------------------------------------------------------- catalogue


def test_catalogue() -> None:
    for object_id in ("002_master_chef_can", "065-j_cups", "073-m_lego_duplo", "077_rubiks_cube"):
        assert is_known_ycb_id(object_id)
    for object_id in ("061_foam", "020_nothing", "063-g_marbles", ""):
        assert not is_known_ycb_id(object_id)
    assert isinstance(YCB_IDS, frozenset) and len(YCB_IDS) > 90


def test_catalogue_knows_every_configured_object() -> None:
    """Every id of every committed object set is in the catalogue (a YCB download exists)."""
    sets = sorted((CONFIG_DIR / "objects").glob("*.yaml"))
    assert sets
    for path in sets:
        items = yaml.safe_load(path.read_text())["items"]
        unknown = [
            i for i, entry in items.items() if not entry.get("mesh") and not is_known_ycb_id(i)
        ]
        assert not unknown, (path.name, unknown)


# ---------------------------------------------------------------- YCB, local and override


def test_ycb_local_copy_verified(tmp_path: Path, ycb_dir: Path) -> None:
    dest = tmp_path / "resources" / "ycb" / FOAM
    record = fetch_ycb_object(FOAM, dest, local_dir=ycb_dir, sha256=FOAM_SHA)
    mesh = dest / "textured.obj"
    assert mesh.is_file() and not mesh.is_symlink()
    assert mesh.read_bytes() == (ycb_dir / FOAM / "textured.obj").read_bytes()
    assert files_under(dest) == ["source.json", "textured.obj"]
    saved = json.loads((dest / "source.json").read_text())
    assert saved == record
    assert saved["method"] == "local" and saved["verified"] is True
    assert saved["sha256"] == FOAM_SHA and saved["object_id"] == FOAM
    assert saved["fetched_at"]


def _local_ycb(tmp_path: Path, data: bytes = OBJ_BYTES) -> Path:
    local = tmp_path / "local_ycb"
    (local / FOAM).mkdir(parents=True)
    (local / FOAM / "textured.obj").write_bytes(data)
    return local


@pytest.mark.parametrize("dest_exists", [True, False])
def test_ycb_local_checksum_mismatch_leaves_nothing(tmp_path: Path, dest_exists: bool) -> None:
    local = _local_ycb(tmp_path)
    dest = tmp_path / "out" / FOAM
    if dest_exists:
        dest.mkdir(parents=True)
    with pytest.raises(AssetError) as err:
        fetch_ycb_object(FOAM, dest, local_dir=local, sha256=FOAM_SHA)
    msg = str(err.value)
    assert FOAM in msg and "checksum" in msg and "textured.obj" in msg
    assert FOAM_SHA in msg and sha(OBJ_BYTES) in msg
    assert "sha256" in msg and "mesh" in msg  # says what to do
    assert files_under(dest) == []
    assert dest.exists() == dest_exists


def test_ycb_local_missing_file(tmp_path: Path) -> None:
    local = tmp_path / "empty"
    local.mkdir()
    dest = tmp_path / "out" / FOAM
    with pytest.raises(AssetError) as err:
        fetch_ycb_object(FOAM, dest, local_dir=local, sha256=FOAM_SHA)
    msg = str(err.value)
    assert FOAM in msg
    assert str(local / FOAM / "textured.obj") in msg
    assert "assets.ycb_dir" in msg and "GRASPSTAB_YCB_DIR" in msg
    assert not dest.exists()


def test_ycb_mesh_override(tmp_path: Path) -> None:
    own = tmp_path / "my_mesh.obj"
    own.write_bytes(OWN_OBJ_BYTES)
    dest = tmp_path / "out" / FOAM
    record = fetch_ycb_object(
        FOAM, dest, local_dir=tmp_path / "unused", sha256=sha(OWN_OBJ_BYTES), mesh_override=own
    )
    assert (dest / "textured.obj").read_bytes() == OWN_OBJ_BYTES
    assert record["method"] == "mesh_override" and record["sha256"] == sha(OWN_OBJ_BYTES)
    assert record["source"] == str(own.resolve()) and record["verified"] is True

    with pytest.raises(AssetError, match="checksum") as err:
        fetch_ycb_object(FOAM, tmp_path / "out2", sha256=FOAM_SHA, mesh_override=own)
    assert "'mesh'" in str(err.value)
    assert not (tmp_path / "out2").exists()

    with pytest.raises(AssetError, match="no such file"):
        fetch_ycb_object(FOAM, tmp_path / "out3", mesh_override=tmp_path / "nope.obj")


def test_ycb_without_sha_is_recorded_and_warned(
    tmp_path: Path, caplog: pytest.LogCaptureFixture
) -> None:
    local = _local_ycb(tmp_path)
    with caplog.at_level(logging.WARNING, logger="graspstab.assets"):
        record = fetch_ycb_object(FOAM, tmp_path / "out", local_dir=local)
    assert record["verified"] is False and record["expected_sha256"] is None
    assert record["sha256"] == sha(OBJ_BYTES)
    assert any("NOT verified" in r.getMessage() for r in caplog.records)


def test_ycb_bad_sha_format(tmp_path: Path) -> None:
    with pytest.raises(AssetError, match="64 hexadecimal"):
        fetch_ycb_object(FOAM, tmp_path / "out", local_dir=tmp_path, sha256="abc")


# ---------------------------------------------------------------- YCB, download


def _serve_ycb(root: Path, data: bytes = OBJ_BYTES, object_id: str = FOAM) -> None:
    make_tgz(
        root / f"{object_id}_google_16k.tgz",
        {
            f"{object_id}/google_16k/textured.obj": data,
            f"{object_id}/google_16k/texture_map.png": b"png",
            f"{object_id}/google_16k/textured.mtl": b"mtl",
        },
    )


def test_ycb_download_verified(tmp_path: Path, server: tuple[str, Path]) -> None:
    base, root = server
    _serve_ycb(root)
    dest = tmp_path / "out" / FOAM
    template = base + "/{id}_google_16k.tgz"
    record = fetch_ycb_object(FOAM, dest, url_template=template, sha256=sha(OBJ_BYTES))
    assert (dest / "textured.obj").read_bytes() == OBJ_BYTES
    assert files_under(dest) == ["source.json", "textured.obj"]
    saved = json.loads((dest / "source.json").read_text())
    assert saved["url"] == f"{base}/{FOAM}_google_16k.tgz"
    assert saved["method"] == "download" and saved["verified"] is True
    assert saved["archive_member"] == f"{FOAM}/google_16k/textured.obj"
    assert record == saved


def test_ycb_download_bad_checksum(tmp_path: Path, server: tuple[str, Path]) -> None:
    base, root = server
    _serve_ycb(root)
    dest = tmp_path / "out" / FOAM
    dest.mkdir(parents=True)
    with pytest.raises(AssetError) as err:
        fetch_ycb_object(FOAM, dest, url_template=base + "/{id}_google_16k.tgz", sha256=FOAM_SHA)
    msg = str(err.value)
    assert "checksum" in msg and FOAM in msg and FOAM_SHA in msg and sha(OBJ_BYTES) in msg
    assert "retry" in msg and "assets.ycb_dir" in msg
    assert files_under(dest) == []


def test_ycb_download_404(tmp_path: Path, server: tuple[str, Path]) -> None:
    base, _root = server
    dest = tmp_path / "out" / FOAM
    with pytest.raises(AssetError) as err:
        fetch_ycb_object(FOAM, dest, url_template=base + "/{id}_google_16k.tgz", sha256=FOAM_SHA)
    msg = str(err.value)
    assert f"{base}/{FOAM}_google_16k.tgz" in msg and "404" in msg
    assert "assets.ycb_dir" in msg and "GRASPSTAB_YCB_DIR" in msg
    assert not dest.exists()


def test_ycb_download_member_missing(tmp_path: Path, server: tuple[str, Path]) -> None:
    base, root = server
    make_tgz(root / f"{FOAM}_google_16k.tgz", {f"{FOAM}/google_512k/textured.obj": OBJ_BYTES})
    dest = tmp_path / "out" / FOAM
    with pytest.raises(AssetError, match="google_16k/textured.obj"):
        fetch_ycb_object(FOAM, dest, url_template=base + "/{id}_google_16k.tgz")
    assert not dest.exists()


def test_ycb_download_refuses_path_traversal(tmp_path: Path, server: tuple[str, Path]) -> None:
    base, root = server
    make_tgz(
        root / f"{FOAM}_google_16k.tgz",
        {f"{FOAM}/google_16k/textured.obj": OBJ_BYTES, "../../evil.txt": b"x"},
    )
    dest = tmp_path / "out" / FOAM
    with pytest.raises(AssetError, match="unsafe"):
        fetch_ycb_object(FOAM, dest, url_template=base + "/{id}_google_16k.tgz")
    assert not dest.exists()
    assert not list(tmp_path.rglob("evil.txt"))


def test_download_unreachable_host(tmp_path: Path) -> None:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        port = s.getsockname()[1]
    url = f"http://127.0.0.1:{port}/" + "{id}.tgz"
    with pytest.raises(AssetError) as err:
        fetch_ycb_object(FOAM, tmp_path / "out", url_template=url, timeout=5)
    assert f"127.0.0.1:{port}/{FOAM}.tgz" in str(err.value)
    assert "GRASPSTAB_YCB_DIR" in str(err.value)
    assert not (tmp_path / "out").exists()


# ---------------------------------------------------------------- hand, local


def test_committed_manifest_matches_the_hand_in_use(hand_assets_dir: Path) -> None:
    """Every pinned file hashes to its pin in the copy the tests use (a local copy's patched MJCF
    through its *.upstream twin); a local copy lacks only the three documented meshes."""
    manifest = load_manifest()
    built = build_manifest(hand_assets_dir)
    assert {rel: built[rel] for rel in manifest} == manifest
    assert set(built) - set(manifest) <= ABSENT_LOCALLY_OK
    assert all(p.endswith(".stl") for p in manifest if p not in UPSTREAM_MJCF)
    assert set(UPSTREAM_MJCF) <= set(manifest)


def test_hand_local_copy_verified(tmp_path: Path, hand_assets_dir: Path) -> None:
    dest = tmp_path / "resources" / "orcahand_description"
    record = fetch_hand_description(dest, local_dir=hand_assets_dir)
    assert (dest / "v2" / "scene_right.xml").is_file() and (dest / "LICENSE").is_file()
    # a local copy's SOURCES.md (the documented patch) travels with it; a download has none
    assert (dest / "SOURCES.md").is_file() == (hand_assets_dir / "SOURCES.md").is_file()
    saved = json.loads((dest / "source.json").read_text())
    assert saved == record and saved["method"] == "local"
    assert saved["upstream_commit"] == HAND_COMMIT
    assert sorted(saved["manifest"]["not_verified_local_patch"]) == sorted(UPSTREAM_MJCF)
    assert saved["manifest"]["verified"] == len(load_manifest()) - 2
    assert [p.name for p in (tmp_path / "resources").iterdir()] == ["orcahand_description"]


def test_hand_local_corrupted_stl(tmp_path: Path, hand_assets_dir: Path) -> None:
    local = tmp_path / "hand_copy"
    shutil.copytree(hand_assets_dir, local)
    victim = local / "v2/models/assets/right/T-DP.stl"
    victim.write_bytes(victim.read_bytes()[:-10] + b"0123456789")
    out = tmp_path / "resources"
    with pytest.raises(AssetError) as err:
        fetch_hand_description(out / "orcahand_description", local_dir=local)
    msg = str(err.value)
    assert "v2/models/assets/right/T-DP.stl" in msg and "expected sha256" in msg
    assert "assets.hand_dir" in msg
    assert files_under(out) == []


def _fake_hand(stl: bytes = b"solid a\nendsolid a\n") -> dict[str, bytes]:
    return {
        "LICENSE": b"MIT\n",
        "v2/scene_right.xml": b"<mujoco/>\n",
        STL: stl,
        "v2/models/mjcf/orcahand_right.mjcf": b"<mujoco model='upstream'/>\n",
    }


def _write_tree(root: Path, files: dict[str, bytes]) -> Path:
    for rel, data in files.items():
        (root / rel).parent.mkdir(parents=True, exist_ok=True)
        (root / rel).write_bytes(data)
    return root


def test_hand_local_missing_files(tmp_path: Path) -> None:
    files = _fake_hand()
    local = _write_tree(tmp_path / "local", files)
    absent_ok = "v2/models/assets/right/R-Carpals.stl"
    manifest = {
        STL: sha(files[STL]),
        absent_ok: "0" * 64,
        # a patched local MJCF is not checked on the local path
        "v2/models/mjcf/orcahand_right.mjcf": "1" * 64,
    }
    record = fetch_hand_description(tmp_path / "out" / "hand", local_dir=local, manifest=manifest)
    assert record["manifest"]["absent_locally"] == [absent_ok]
    assert record["manifest"]["verified"] == 1

    manifest["v2/models/assets/right/B.stl"] = "2" * 64
    with pytest.raises(AssetError) as err:
        fetch_hand_description(tmp_path / "out2" / "hand", local_dir=local, manifest=manifest)
    assert "v2/models/assets/right/B.stl: missing" in str(err.value)
    assert files_under(tmp_path / "out2") == []

    shutil.rmtree(local / "v2")
    with pytest.raises(AssetError, match="v2"):
        fetch_hand_description(tmp_path / "out3" / "hand", local_dir=local, manifest=manifest)


def test_hand_refetch_replaces_and_failure_keeps_old(tmp_path: Path) -> None:
    files = _fake_hand()
    local = _write_tree(tmp_path / "local", files)
    dest = tmp_path / "out" / "hand"
    _write_tree(dest, {"stale.txt": b"old"})
    manifest = {STL: sha(files[STL])}
    fetch_hand_description(dest, local_dir=local, manifest=manifest)
    assert not (dest / "stale.txt").exists() and (dest / STL).is_file()
    before = files_under(dest)
    with pytest.raises(AssetError):
        fetch_hand_description(dest, local_dir=local, manifest={STL: "3" * 64})
    assert files_under(dest) == before
    assert [p.name for p in (tmp_path / "out").iterdir()] == ["hand"]
    with pytest.raises(AssetError, match="destination"):
        fetch_hand_description(local, local_dir=local, manifest=manifest)


# ---------------------------------------------------------------- hand, download


def _serve_hand(root: Path, commit: str, files: dict[str, bytes]) -> None:
    top = f"orcahand_description-{commit}"
    members = {f"{top}/{rel}": data for rel, data in files.items()}
    members[f"{top}/README.md"] = b"readme"
    members[f"{top}/v1/models/old.stl"] = b"v1"
    make_tgz(root / f"{commit}.tar.gz", members)


def test_hand_download_verified(tmp_path: Path, server: tuple[str, Path]) -> None:
    base, root = server
    commit = "abc123"
    files = _fake_hand()
    _serve_hand(root, commit, files)
    manifest = {rel: sha(data) for rel, data in files.items() if rel != "LICENSE"}
    dest = tmp_path / "out" / "orcahand_description"
    record = fetch_hand_description(
        dest, url_template=base + "/{commit}.tar.gz", commit=commit, manifest=manifest
    )
    assert sorted(files_under(dest)) == sorted(
        [
            "LICENSE",
            "source.json",
            "v2",
            "v2/models",
            "v2/models/assets",
            "v2/models/assets/right",
            STL,
            "v2/models/mjcf",
            "v2/models/mjcf/orcahand_right.mjcf",
            "v2/scene_right.xml",
        ]
    )
    saved = json.loads((dest / "source.json").read_text())
    assert saved == record
    assert saved["url"] == f"{base}/{commit}.tar.gz" and saved["method"] == "download"
    assert saved["manifest"]["verified"] == len(manifest)  # MJCF verified on this path
    assert saved["files"][STL] == sha(files[STL])
    assert [p.name for p in (tmp_path / "out").iterdir()] == ["orcahand_description"]


def test_hand_download_bad_checksum(tmp_path: Path, server: tuple[str, Path]) -> None:
    base, root = server
    commit = "abc123"
    files = _fake_hand()
    _serve_hand(root, commit, files)
    manifest = {STL: sha(files[STL]), "v2/models/mjcf/orcahand_right.mjcf": "4" * 64}
    out = tmp_path / "out"
    with pytest.raises(AssetError) as err:
        fetch_hand_description(
            out / "orcahand_description",
            url_template=base + "/{commit}.tar.gz",
            commit=commit,
            manifest=manifest,
        )
    msg = str(err.value)
    assert "checksum" in msg and "v2/models/mjcf/orcahand_right.mjcf" in msg and "4" * 64 in msg
    assert "Retry" in msg and "assets.hand_dir" in msg
    assert files_under(out) == []


def test_hand_download_404(tmp_path: Path, server: tuple[str, Path]) -> None:
    base, _root = server
    out = tmp_path / "out"
    with pytest.raises(AssetError) as err:
        fetch_hand_description(out / "orcahand_description", url_template=base + "/{commit}.tar.gz")
    msg = str(err.value)
    assert f"{base}/{HAND_COMMIT}.tar.gz" in msg and "404" in msg
    assert "assets.hand_dir" in msg and "GRASPSTAB_HAND_DIR" in msg
    assert files_under(out) == []


# ---------------------------------------------------------------- CLI


def test_cli_error_exit_code(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    empty = tmp_path / "empty"
    empty.mkdir()
    argv = ["ycb", "--object-id", FOAM, "--dest", str(tmp_path / "out"), "--local-dir", str(empty)]
    assert main(argv) == 1
    err = capsys.readouterr().err
    assert err.startswith("error: ") and FOAM in err and "Traceback" not in err


def test_cli_ok_and_module_entry(tmp_path: Path) -> None:
    local = _local_ycb(tmp_path)
    out = tmp_path / "out"
    args = ["ycb", "--object-id", FOAM, "--dest", str(out), "--local-dir", str(local)]
    assert main([*args, "--sha256", sha(OBJ_BYTES)]) == 0
    assert (out / "textured.obj").is_file()
    proc = subprocess.run(
        [sys.executable, "-m", "graspstab.assets", *args, "--sha256", FOAM_SHA],
        capture_output=True,
        text=True,
        timeout=60,
    )
    assert proc.returncode == 1
    assert "checksum" in proc.stderr and "Traceback" not in proc.stderr


# ---------------------------------------------------------------- hand, the user's manifest


def test_hand_manifest_file_pins_another_commit(tmp_path: Path, server: tuple[str, Path]) -> None:
    """assets.hand_manifest: a commit the shipped manifest does not pin, verified by the user's."""
    base, root = server
    commit = "f" * 40
    files = _fake_hand()
    _serve_hand(root, commit, files)
    path = tmp_path / "manifest.json"
    path.write_text(json.dumps({STL: sha(files[STL]).upper()}))  # case is not significant
    manifest = read_manifest(path)
    assert manifest == {STL: sha(files[STL])}
    dest = tmp_path / "out" / "orcahand_description"
    record = fetch_hand_description(
        dest, url_template=base + "/{commit}.tar.gz", commit=commit, manifest=manifest
    )
    assert record["upstream_commit"] == commit and record["manifest"]["verified"] == 1
    path.write_text(json.dumps({STL: "5" * 64}))
    with pytest.raises(AssetError, match="checksum check failed"):
        fetch_hand_description(
            tmp_path / "out2" / "hand",
            url_template=base + "/{commit}.tar.gz",
            commit=commit,
            manifest=read_manifest(path),
        )


@pytest.mark.parametrize(
    ("text", "words"),
    [
        (None, "no such file"),
        ("{not json", "not readable JSON"),
        ("[]", "non-empty JSON object"),
        ('{"v2/a.stl": "abc"}', "not 64 hexadecimal digits"),
    ],
)
def test_hand_manifest_file_errors_name_the_file_and_key(
    tmp_path: Path, text: str | None, words: str
) -> None:
    path = tmp_path / "manifest.json"
    if text is not None:
        path.write_text(text)
    with pytest.raises(AssetError) as err:
        read_manifest(path)
    msg = str(err.value)
    assert words in msg and str(path) in msg and "assets.hand_manifest" in msg


def test_hand_manifest_is_the_fetch_rules_declared_input(
    tmp_path: Path, bare_env: dict[str, str]
) -> None:
    """A dry run (no assets needed): the manifest file is an input, so editing it refetches."""
    path = tmp_path / "manifest.json"
    path.write_text(json.dumps({STL: "6" * 64}))
    work = tmp_path / "wd"
    config = ["--config", f"assets={{hand_manifest: {path}}}"]
    proc = snakemake_run(work, "resources/orcahand_description", "-n", *config, env=bare_env)
    out = proc.stdout + proc.stderr
    assert proc.returncode == 0, out[-3000:]
    [job] = listed_jobs(out)
    assert job["rule"] == "fetch_hand_description" and job["input"] == [str(path)], job
    proc = snakemake_run(work, "resources/orcahand_description", "-n", env=bare_env)
    assert proc.returncode == 0 and listed_jobs(proc.stdout)[0]["input"] == []
