"""A user's own mesh (objects.items.<id>.mesh) and a local YCB folder (assets.ycb_dir), issue 49:
an edit that keeps the old mtime still reruns the copy; a flat or zero-volume mesh is refused at
the fetch step, naming the file and what was measured, leaving nothing in resources/; a local
folder is looked at only for the objects the run covers."""

from __future__ import annotations

import os
import shutil
import subprocess
from pathlib import Path

import numpy as np
import pytest
import trimesh
import yaml
from objects_fixtures import own_object_set

from graspstab.assets import AssetError
from graspstab.assets.local_ycb import check_local_ycb_dir
from graspstab.assets.mesh_file import MIN_THICKNESS_M, MIN_VOLUME_FRACTION
from graspstab.assets.ycb import fetch_ycb_object, user_mesh_sha256
from tests.toy_workflow import REPO, listed_jobs, snakemake_command, snakemake_run

OWN = "900_own_brick"  # an id of the YCB pattern that is no YCB object: only a mesh: entry has it
FOAM = "061_foam_brick"


def _write(mesh: trimesh.Trimesh, path: Path) -> Path:
    path.write_text(trimesh.exchange.obj.export_obj(mesh, include_normals=False))
    return path


def _flat_square() -> trimesh.Trimesh:
    """A 10 cm square of two triangles, tilted so that no coordinate extent is zero."""
    square = trimesh.Trimesh(
        [[0, 0, 0], [0.1, 0, 0], [0.1, 0.1, 0], [0, 0.1, 0]], [[0, 1, 2], [0, 2, 3]], process=False
    )
    square.apply_transform(trimesh.transformations.rotation_matrix(0.6, [1, 1, 0]))
    return square


def _foil_angle(wall: float = 1e-5, arm: float = 0.05) -> trimesh.Trimesh:
    """A closed L-shaped angle of ``wall`` m thick walls, ``arm`` m long and high: 36 mm thick in
    its thinnest direction, yet it encloses almost nothing (a sheet folded onto itself)."""
    outline = [(0, 0), (arm, 0), (arm, wall), (wall, wall), (wall, arm), (0, arm)]
    n = len(outline)
    vertices = [(x, y, z) for z in (0.0, arm) for x, y in outline]
    faces = [(0, i + 1, i) for i in range(1, n - 1)]  # bottom: a fan from the corner (0, 0)
    faces += [(n, n + i, n + i + 1) for i in range(1, n - 1)]  # top
    for i in range(n):  # the walls
        j = (i + 1) % n
        faces += [(i, j, n + j), (i, n + j, n + i)]
    mesh = trimesh.Trimesh(vertices, faces, process=False)
    trimesh.repair.fix_normals(mesh)
    return mesh


# ---------------------------------------------------------------- flat and zero-volume meshes


@pytest.mark.parametrize(
    "shape",
    ["square of two triangles", "box of zero height"],
)
def test_fetch_refuses_a_flat_user_mesh(tmp_path: Path, shape: str) -> None:
    if shape == "box of zero height":
        mesh = trimesh.creation.box((0.08, 0.05, 0.0))  # closed, watertight, volume 0
    else:
        mesh = _flat_square()
    user = _write(mesh, tmp_path / "plate.obj")
    resources = tmp_path / "resources"
    with pytest.raises(AssetError) as err:
        fetch_ycb_object(OWN, resources / "ycb" / OWN, mesh_override=user)
    msg = str(err.value)
    assert msg.startswith(
        f"object '{OWN}': your mesh {user} (config field objects.items.{OWN}.mesh)"
    )
    assert "is flat: 0.00 mm thick in its thinnest direction" in msg, msg
    assert f"less than the {MIN_THICKNESS_M * 1e3:g} mm a solid object needs" in msg
    assert "resources" not in msg  # the user's file, not a copy
    assert not resources.exists()


def test_fetch_refuses_a_closed_mesh_that_encloses_almost_nothing(tmp_path: Path) -> None:
    mesh = _foil_angle()
    assert mesh.is_watertight and mesh.is_winding_consistent  # closed: only its volume is wrong
    user = _write(mesh, tmp_path / "foil.obj")
    resources = tmp_path / "resources"
    with pytest.raises(AssetError) as err:
        fetch_ycb_object(OWN, resources / "ycb" / OWN, mesh_override=user)
    msg = str(err.value)
    assert f"your mesh {user} (config field objects.items.{OWN}.mesh)" in msg
    volume = 2 * 0.05 * 0.05 * 1e-5  # the two walls
    assert f"encloses almost no volume: {volume:.3g} m^3" in msg, msg
    assert f"less than the {100 * MIN_VOLUME_FRACTION:g} % a solid object encloses" in msg
    assert "mm thick in its thinnest direction" in msg and "is flat" not in msg
    assert not resources.exists()


def test_a_thin_but_solid_user_mesh_passes(tmp_path: Path) -> None:
    """The limits are not too tight: a 2 mm plate, tilted, and the same angle with 2 mm walls."""
    plate = trimesh.creation.box((0.1, 0.06, 0.002))
    plate.apply_transform(trimesh.transformations.rotation_matrix(0.7, [1, 0.3, 0.2]))
    for name, mesh in (("plate", plate), ("angle", _foil_angle(wall=0.002))):
        user = _write(mesh, tmp_path / f"{name}.obj")
        record = fetch_ycb_object(OWN, tmp_path / name / "ycb" / OWN, mesh_override=user)
        assert record["method"] == "mesh_override"
        copy = tmp_path / name / "ycb" / OWN / "textured.obj"
        assert copy.read_bytes() == user.read_bytes()


# ---------------------------------------------------------------- the local YCB folder


def _ycb12_items() -> dict:
    return yaml.safe_load((REPO / "config" / "objects" / "ycb12.yaml").read_text())["items"]


def _partial_ycb_dir(tmp_path: Path, ycb_dir: Path, keep: list[str]) -> Path:
    folder = tmp_path / "partial_ycb"
    folder.mkdir()
    for object_id in keep:
        (folder / object_id).symlink_to(ycb_dir / object_id, target_is_directory=True)
    return folder


def test_local_ycb_dir_is_checked_for_the_selected_objects_only(
    tmp_path: Path, ycb_dir: Path
) -> None:
    items = _ycb12_items()
    keep = [FOAM, "077_rubiks_cube"]
    folder = _partial_ycb_dir(tmp_path, ycb_dir, keep)
    check_local_ycb_dir(items, folder, keep)  # the other ten are left out: not looked at
    check_local_ycb_dir(items, None, None)  # no local folder: downloads, nothing to check
    own = {**items, "009_gelatin_box": {**items["009_gelatin_box"], "mesh": "/some/own.obj"}}
    check_local_ycb_dir(own, folder, [*keep, "009_gelatin_box"])  # an own mesh needs no YCB file

    with pytest.raises(AssetError) as err:
        check_local_ycb_dir(items, folder, [*keep, "009_gelatin_box"])
    msg = str(err.value)
    assert f"the local YCB directory {folder} (config key assets.ycb_dir" in msg
    assert "GRASPSTAB_YCB_DIR" in msg
    assert f"object '009_gelatin_box': no {folder / '009_gelatin_box' / 'textured.obj'}" in msg
    assert f"only_objects (e.g. --config 'only_objects=[{FOAM},077_rubiks_cube]'" in msg
    assert "config field objects.items.009_gelatin_box.mesh" in msg
    assert "field 'mesh'" not in msg  # the entry has no such field to blame

    with pytest.raises(AssetError) as err:  # the whole set: every missing one, in one message
        check_local_ycb_dir(items, folder, None)
    msg = str(err.value)
    assert "10 objects of this run: no <dir>/<id>/textured.obj for " in msg
    assert all(o in msg for o in items if o not in keep), msg

    with pytest.raises(AssetError, match="does not exist"):
        check_local_ycb_dir(items, tmp_path / "no_such_dir", keep)


def test_fetch_from_a_local_dir_without_the_object(tmp_path: Path, ycb_dir: Path) -> None:
    folder = _partial_ycb_dir(tmp_path, ycb_dir, ["077_rubiks_cube"])
    resources = tmp_path / "resources"
    with pytest.raises(AssetError) as err:
        fetch_ycb_object(FOAM, resources / "ycb" / FOAM, local_dir=folder)
    msg = str(err.value)
    assert f"object '{FOAM}': no {folder / FOAM / 'textured.obj'}" in msg
    assert "only_objects" in msg and f"objects.items.{FOAM}.mesh" in msg
    assert not resources.exists()


# ---------------------------------------------------------------- the content hash


def test_user_mesh_sha256_is_the_content_hash_cached_per_file(tmp_path: Path) -> None:
    import hashlib

    user = tmp_path / "own.obj"
    user.write_text("v 0 0 0\n")
    assert user_mesh_sha256(user) == hashlib.sha256(b"v 0 0 0\n").hexdigest()
    user.write_text("v 1 1 1\n")  # same process: the first hash stands (one per workflow load)
    assert user_mesh_sha256(str(user)) == hashlib.sha256(b"v 0 0 0\n").hexdigest()
    assert user_mesh_sha256(None) is None and user_mesh_sha256(tmp_path / "missing.obj") is None


# ---------------------------------------------------------------- the workflow


@pytest.mark.workflow
def test_edit_keeping_the_mtime_reruns_the_copy_and_a_flat_edit_fails_there(
    tmp_path: Path, asset_env: dict[str, str], foam_brick_mesh: Path
) -> None:
    user = tmp_path / "own.obj"
    shutil.copyfile(foam_brick_mesh, user)
    stamp = (user.stat().st_atime_ns, user.stat().st_mtime_ns)
    config = own_object_set(tmp_path, OWN, user, 0.03)
    work = tmp_path / "wd"
    target = f"resources/ycb/{OWN}/textured.obj"
    copy = work / target
    proc = snakemake_run(work, target, *config, env=asset_env)
    assert proc.returncode == 0, proc.stdout[-3000:] + proc.stderr[-3000:]
    assert copy.read_bytes() == user.read_bytes()

    # the edit of `cp -p`, `rsync -a` or an unpacked archive: new content, the old mtime
    brick = trimesh.load(foam_brick_mesh, force="mesh", process=False, skip_materials=True)
    brick.apply_scale(1.2)
    _write(brick, user)
    os.utime(user, ns=stamp)
    assert user.stat().st_mtime_ns == stamp[1] < copy.stat().st_mtime_ns
    dry = snakemake_run(work, target, "-n", *config, env=asset_env)
    out = dry.stdout + dry.stderr
    assert dry.returncode == 0, out[-3000:]
    assert [j["rule"] for j in listed_jobs(out)] == ["fetch_ycb_object"], out[-3000:]
    proc = snakemake_run(work, target, *config, env=asset_env)
    assert proc.returncode == 0, proc.stdout[-3000:] + proc.stderr[-3000:]
    assert copy.read_bytes() == user.read_bytes()
    assert np.allclose(trimesh.load(copy, force="mesh").extents, brick.extents)
    dry = snakemake_run(work, target, "-n", *config, env=asset_env)
    assert "Nothing to be done" in dry.stdout + dry.stderr  # and it settles

    # a flat edit, again keeping the mtime: the fetch job fails naming the user's file and what
    # it measured, and leaves nothing in resources/ (the old copy is gone too)
    _write(_flat_square(), user)
    os.utime(user, ns=stamp)
    proc = snakemake_run(work, target, *config, env=asset_env)
    out = proc.stdout + proc.stderr
    assert proc.returncode != 0
    assert "Error in rule fetch_ycb_object" in out, out[-3000:]
    assert f"your mesh {user} (config field objects.items.{OWN}.mesh) is flat: 0.00 mm" in out
    assert [p for p in (work / "resources").rglob("*") if not p.is_dir()] == []


@pytest.mark.workflow
def test_dry_run_with_a_partial_local_ycb_dir(tmp_path: Path, ycb_dir: Path, bare_env) -> None:
    """A local YCB folder that lacks objects only_objects leaves out loads (dry run); one that
    lacks a selected object stops at load time naming it, the folder and the fixes."""
    folder = _partial_ycb_dir(tmp_path, ycb_dir, [FOAM, "077_rubiks_cube"])
    env = dict(bare_env, GRASPSTAB_YCB_DIR=str(folder))
    target = f"results/objects/{FOAM}/meta.json"

    def dry(only: str) -> subprocess.CompletedProcess:
        cmd = snakemake_command(
            tmp_path / "wd", "-n", "--config", f"only_objects={only}", "--", target
        )
        return subprocess.run(cmd, capture_output=True, text=True, env=env, timeout=300)

    ok = dry(f"[{FOAM}]")
    assert ok.returncode == 0, ok.stdout[-3000:] + ok.stderr[-3000:]
    assert "fetch_ycb_object" in ok.stdout
    bad = dry(f"[{FOAM},009_gelatin_box]")
    out = bad.stdout + bad.stderr
    assert bad.returncode != 0
    assert (
        "graspstab configuration error: object set 'ycb12' (config/objects/ycb12.yaml): the local "
        f"YCB directory {folder} (config key assets.ycb_dir or env var GRASPSTAB_YCB_DIR) lacks "
        f"the mesh of object '009_gelatin_box': no {folder}/009_gelatin_box/textured.obj" in out
    ), out[-3000:]
    assert (
        f"--config 'only_objects=[{FOAM}]'" in out and "objects.items.009_gelatin_box.mesh" in out
    )
    assert "field 'mesh'" not in out
