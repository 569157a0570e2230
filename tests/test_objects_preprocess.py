"""End-to-end preprocessing of one real YCB mesh (coarse CoACD), plus the objects figure."""

from __future__ import annotations

import json
from pathlib import Path

import mujoco
import numpy as np
import pytest
import trimesh
from objects_fixtures import COARSE_COACD

from graspstab.objects.decompose import inside_any_part
from graspstab.objects.figure import plot_objects
from graspstab.objects.preprocess_object import OUTPUT_FILES, main
from graspstab.objects.sdf import SDFGrid

PARAMS = {
    "repair": {"sliver_max_faces": 16, "sliver_max_area_fraction": 0.01},
    "coacd": COARSE_COACD,
    "sdf": {"spacing": 0.003, "margin": 0.02},
    "hull_points": {"count": 2000, "seed": 0},
    "contact": {"friction": [1.0, 0.005, 0.0001]},
}
MASS = 0.028


@pytest.fixture(scope="module")
def out_dir(tmp_path_factory: pytest.TempPathFactory, foam_brick_mesh: Path) -> Path:
    out = tmp_path_factory.mktemp("foam_brick")
    argv = [
        "--object-id", "061_foam_brick",
        "--mesh", str(foam_brick_mesh),
        "--out-dir", str(out),
        "--mass", str(MASS),
        "--params-json", json.dumps(PARAMS),
        "--log-file", str(out.parent / "preprocess.log"),
    ]  # fmt: skip
    assert main(argv) == 0
    return out


def test_writes_exactly_the_artefacts(out_dir: Path) -> None:
    assert sorted(p.name for p in out_dir.iterdir()) == sorted(OUTPUT_FILES)
    assert "061_foam_brick" in (out_dir.parent / "preprocess.log").read_text()


def test_meta_is_sane(out_dir: Path) -> None:
    meta = json.loads((out_dir / "meta.json").read_text())
    assert meta["object_id"] == "061_foam_brick" and meta["mass"] == MASS
    assert meta["volume"] * 1e6 == pytest.approx(184.9, abs=0.5)  # SOURCES.md
    assert meta["watertight_before"] is True and meta["watertight_after"] is True
    assert sorted(meta["extents"]) == pytest.approx([0.0512, 0.0526, 0.0779], abs=2e-3)
    inertia = meta["inertia"]
    tensor = np.array(inertia["tensor"])
    assert np.allclose(tensor, tensor.T) and np.all(np.array(inertia["principal_moments"]) > 0)
    assert len(inertia["quat_wxyz"]) == 4
    assert 1 <= meta["convex_parts"] <= COARSE_COACD["max_convex_hull"]
    assert not any("timing" in k for k in meta)  # run times: in the log, never in the data
    prov = meta["provenance"]
    assert prov["stage"] == "objects" and prov["params"] == PARAMS
    # the source COM is where the mesh was shifted from
    assert np.allclose(meta["com_offset_applied"], -np.array(meta["com_in_source_frame"]))


def test_artefacts_agree(out_dir: Path) -> None:
    mesh = trimesh.load(out_dir / "mesh.obj", force="mesh", process=False)
    mesh.merge_vertices()
    assert mesh.is_watertight
    assert np.allclose(mesh.center_mass, 0, atol=1e-6)
    hull_points = np.load(out_dir / "hull_points.npy")
    assert hull_points.shape == (2000, 3) and hull_points.dtype == np.float64
    grid = SDFGrid.load(out_dir / "sdf.npz")
    dist, _ = grid.query(hull_points)
    assert np.all(dist > -3e-3)  # hull samples are on or outside the object surface
    with np.load(out_dir / "convex_parts.npz") as data:
        count = int(data["count"])
        parts = [trimesh.Trimesh(data[f"vertices_{i}"], data[f"faces_{i}"]) for i in range(count)]
    assert inside_any_part(parts, np.zeros((1, 3)))[0]  # the COM is inside the brick
    model = mujoco.MjModel.from_xml_path(str(out_dir / "object.xml"))
    assert model.body("object").mass[0] == pytest.approx(MASS)
    assert sum(model.geom_contype == 1) == count


def test_figure(out_dir: Path, tmp_path: Path) -> None:
    png = tmp_path / "objects.png"
    plot_objects([out_dir], png)
    assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    many = tmp_path / "many.png"
    plot_objects([out_dir] * 7, many)
    assert many.stat().st_size > png.stat().st_size / 2
