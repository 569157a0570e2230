"""Bad mesh files: refused at the first job, naming the object and the user's
own file, leaving nothing behind; the SDF node cap; editing the user's mesh reruns its copy."""

from __future__ import annotations

import logging
import os
import re
import shutil
from pathlib import Path

import numpy as np
import pytest
import trimesh
from objects_fixtures import COARSE_COACD, own_object_set

from graspstab.assets import AssetError
from graspstab.assets.mesh_file import MeshFileError, load_object_mesh
from graspstab.assets.ycb import fetch_ycb_object
from graspstab.objects.preprocess_object import preprocess_object
from graspstab.objects.sdf import MAX_NODES, SDFGrid, SDFGridTooLarge, check_grid_size
from tests.toy_workflow import listed_jobs, snakemake_run

FOAM = "061_foam_brick"
MASS = 0.028
PARAMS = {
    "coacd": COARSE_COACD,
    "sdf": {"spacing": 0.003, "margin": 0.02},
    "hull_points": {"count": 200, "seed": 0},
}

# case -> (file name, what the message must also say)
BAD = {
    "empty": ("empty.obj", ["is empty", "OBJ meshes only"]),
    "text": ("notes.obj", ["no triangle mesh could be read", "OBJ meshes only"]),
    "stl": ("brick.stl", ["is not an OBJ file", "OBJ meshes only", "brick.obj"]),
    "millimetres": ("brick_mm.obj", ["in millimetres?", "scale it by 0.001", "metres"]),
    "tiny": ("brick_tiny.obj", ["in metres?", "less than the 5 mm"]),
}


def _brick(brick: Path) -> trimesh.Trimesh:
    return trimesh.load(brick, force="mesh", process=False, skip_materials=True)


def _write_bad(case: str, folder: Path, brick: Path) -> Path:
    """The user's bad mesh of ``case`` in ``folder``, made from the YCB brick at ``brick``."""
    path = folder / BAD[case][0]
    if case == "empty":
        path.write_bytes(b"")
    elif case == "text":  # a text file renamed .obj
        path.write_text("Shopping list\nmilk, eggs, a 5 cm foam brick\n")
    elif case == "stl":
        path.write_bytes(trimesh.exchange.stl.export_stl(_brick(brick)))
    else:  # the YCB brick in millimetres (x1000), or 20 times too small (< 5 mm)
        mesh = _brick(brick)
        mesh.apply_scale(1000.0 if case == "millimetres" else 0.05)
        path.write_text(trimesh.exchange.obj.export_obj(mesh, include_normals=False))
    return path


def _files_under(path: Path) -> list[str]:
    return sorted(p.name for p in path.rglob("*")) if path.exists() else []


def _as_fetched(user_mesh: Path, resources: Path) -> Path:
    """The copy the fetch step leaves in resources/ for a user's mesh."""
    dest = resources / "ycb" / FOAM
    dest.mkdir(parents=True)
    shutil.copyfile(user_mesh, dest / "textured.obj")
    return dest / "textured.obj"


# ---------------------------------------------------------------- the fetch step (first job)


@pytest.mark.parametrize("case", sorted(BAD))
def test_fetch_refuses_bad_user_mesh(tmp_path: Path, case: str, foam_brick_mesh: Path) -> None:
    user = _write_bad(case, tmp_path, foam_brick_mesh)
    dest = tmp_path / "resources" / "ycb" / FOAM
    with pytest.raises(AssetError) as err:
        fetch_ycb_object(FOAM, dest, mesh_override=user)
    msg = str(err.value)
    assert f"object '{FOAM}'" in msg and str(user) in msg
    assert f"config field objects.items.{FOAM}.mesh" in msg
    for words in BAD[case][1]:
        assert words in msg, (words, msg)
    assert not dest.exists() and _files_under(tmp_path / "resources") == []


def test_fetch_accepts_good_user_mesh(tmp_path: Path, foam_brick_mesh: Path) -> None:
    user = tmp_path / "brick.OBJ"  # the suffix is case-insensitive
    shutil.copyfile(foam_brick_mesh, user)
    record = fetch_ycb_object(FOAM, tmp_path / "out", mesh_override=user)
    assert record["method"] == "mesh_override" and record["source"] == str(user.resolve())


# ---------------------------------------------------------------- preprocessing


@pytest.mark.parametrize("case", sorted(BAD))
def test_preprocess_refuses_bad_mesh_naming_object_and_file(
    tmp_path: Path, case: str, foam_brick_mesh: Path
) -> None:
    """A copy fetched before these checks existed still fails first thing, naming the object and
    the file it reads (its declared input), and creates no output folder."""
    user = _write_bad(case, tmp_path, foam_brick_mesh)
    copy = _as_fetched(user, tmp_path / "resources")
    out = tmp_path / "results" / "objects" / FOAM
    with pytest.raises(MeshFileError) as err:
        preprocess_object(FOAM, copy, out, MASS, PARAMS)
    msg = str(err.value)
    assert f"object '{FOAM}'" in msg and str(copy) in msg
    # the copy is always named textured.obj: an STL's content, not its suffix, is what fails here
    stl = ["no triangle mesh could be read", "OBJ meshes only"]
    expected = stl if case == "stl" else BAD[case][1]
    for words in expected:
        assert words in msg, (words, msg)
    assert not out.exists() and not (tmp_path / "results").exists()


def test_load_without_a_user_file_names_the_file(tmp_path: Path, foam_brick_mesh: Path) -> None:
    bad = _write_bad("millimetres", tmp_path, foam_brick_mesh)
    with pytest.raises(MeshFileError, match=rf"object '{FOAM}': mesh {re.escape(str(bad))} is "):
        load_object_mesh(bad, FOAM)


def test_sdf_node_cap_fails_before_the_slow_steps(
    tmp_path: Path, caplog: pytest.LogCaptureFixture, foam_brick_mesh: Path
) -> None:
    user = tmp_path / "own.obj"
    shutil.copyfile(foam_brick_mesh, user)
    copy = _as_fetched(user, tmp_path / "resources")
    out = tmp_path / "results" / "objects" / FOAM
    fine = {**PARAMS, "sdf": {"spacing": 0.0002, "margin": 0.05}}  # ~5e8 nodes
    with caplog.at_level(logging.INFO, logger="graspstab.objects"):
        with pytest.raises(SDFGridTooLarge) as err:
            preprocess_object(FOAM, copy, out, MASS, fine)
    msg = str(err.value)
    assert f"object '{FOAM}'" in msg and str(copy) in msg
    need = re.search(r"would need (\d+) x (\d+) x (\d+) = ([\d,]+) nodes", msg)
    assert need, msg
    nodes = int(need.group(1)) * int(need.group(2)) * int(need.group(3))
    assert int(need.group(4).replace(",", "")) == nodes > MAX_NODES
    assert f"{MAX_NODES:,}" in msg and "preprocess.sdf.spacing = 0.0002 m" in msg
    suggested = float(re.search(r"Raise preprocess\.sdf\.spacing to at least ([\d.]+) m", msg)[1])
    assert 0.0002 < suggested <= 0.01
    steps = [r.getMessage() for r in caplog.records]
    assert not any("decompose" in s for s in steps), steps  # CoACD never started
    assert not out.exists()


def test_sdf_grid_refuses_mesh_in_millimetres_without_allocating(foam_brick_mesh: Path) -> None:
    mesh = _brick(foam_brick_mesh)
    mesh.apply_scale(1000.0)  # the 271 TiB grid of issue 14
    with pytest.raises(SDFGridTooLarge, match=r"is the mesh in metres\? Rescale it") as err:
        SDFGrid.build(mesh, spacing=0.0015, margin=0.05, what=f"object '{FOAM}'")
    assert str(err.value).startswith(f"object '{FOAM}': its signed-distance grid would need")


def test_grid_shape_unchanged_under_the_cap(foam_brick_mesh: Path) -> None:
    bounds = np.asarray(_brick(foam_brick_mesh).bounds)
    for spacing, margin in ((0.0015, 0.05), (0.003, 0.02), (0.001, 0.0)):
        lo = bounds[0] - margin
        before = np.ceil((bounds[1] + margin - lo) / spacing).astype(int) + 1  # the old formula
        assert check_grid_size(bounds, spacing, margin) == tuple(before)


# ---------------------------------------------------------------- the workflow


@pytest.mark.workflow
def test_editing_users_mesh_reruns_fetch_and_a_bad_edit_fails_there(
    tmp_path: Path, asset_env: dict[str, str], foam_brick_mesh: Path
) -> None:
    env = asset_env
    user = tmp_path / "own.obj"
    shutil.copyfile(foam_brick_mesh, user)
    config = own_object_set(tmp_path, FOAM, user, MASS)
    work = tmp_path / "wd"
    target = f"resources/ycb/{FOAM}/textured.obj"
    proc = snakemake_run(work, target, *config, env=env)
    assert proc.returncode == 0, proc.stdout[-3000:] + proc.stderr[-3000:]
    copy = work / target
    assert copy.read_bytes() == user.read_bytes()

    dry = snakemake_run(work, target, "-n", *config, env=env)
    assert dry.returncode == 0 and "Nothing to be done" in dry.stdout + dry.stderr

    # edit in place (later mtime than the copy): the copy is out of date
    user.write_text(user.read_text() + "# edited in place\n")
    later = copy.stat().st_mtime + 10
    os.utime(user, (later, later))
    dry = snakemake_run(work, target, "-n", *config, env=env)
    out = dry.stdout + dry.stderr
    assert dry.returncode == 0, out[-3000:]
    assert [j["rule"] for j in listed_jobs(out)] == ["fetch_ycb_object"], out[-3000:]
    assert f"Updated input files: {user}" in out

    # a bad edit (the mesh saved in millimetres) fails at that first job, naming object and file
    bad = _brick(foam_brick_mesh)
    bad.apply_scale(1000.0)
    user.write_text(trimesh.exchange.obj.export_obj(bad, include_normals=False))
    os.utime(user, (later + 10, later + 10))
    proc = snakemake_run(work, f"results/objects/{FOAM}/meta.json", *config, env=env)
    out = proc.stdout + proc.stderr
    assert proc.returncode != 0
    assert "Error in rule fetch_ycb_object" in out, out[-3000:]
    assert f"object '{FOAM}'" in out and str(user) in out and "in millimetres?" in out
    assert _files_under(work / "resources" / "ycb" / FOAM) == []
    assert not (work / "results" / "objects").exists()
