"""Tests of the synthesis figures (thesis figs. 3.4 and 3.6, energy histograms): valid, non-trivial
PNGs from hand-built pre-grasps and grasp tables, the gallery's choice of grasps, input errors."""

from __future__ import annotations

from pathlib import Path

import matplotlib.image as mpimg
import mujoco
import numpy as np
import polars as pl
import pytest
import trimesh

from graspstab.common.io import read_json
from graspstab.synthesis import figure, figure_data, figure_meshes

INFLATION = 0.08  # [m], thesis 3.1.3
STANDOFF = 0.08  # [m], inside the 0.06-0.10 m range of 3.1.3


def _rotation_to(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """The rotation taking unit vector a onto unit vector b (Rodrigues; a != -b)."""
    a, b = a / np.linalg.norm(a), b / np.linalg.norm(b)
    v, c = np.cross(a, b), float(a @ b)
    k = np.array([[0, -v[2], v[1]], [v[2], 0, -v[0]], [-v[1], v[0], 0]])
    return np.eye(3) + k + k @ k / (1.0 + c)


def _quat(rot: np.ndarray) -> np.ndarray:
    q = np.zeros(4)
    mujoco.mju_mat2Quat(q, rot.reshape(-1))
    return q


@pytest.fixture(scope="module")
def brick_mesh(foam_brick_dir: Path) -> trimesh.Trimesh:
    return trimesh.load(foam_brick_dir / "mesh.obj", force="mesh", process=False)


@pytest.fixture(scope="module")
def inflated_hull(brick_mesh: trimesh.Trimesh) -> trimesh.Trimesh:
    """The convex hull with every vertex moved INFLATION away from the centroid (3.1.3)."""
    hull = brick_mesh.convex_hull
    v = hull.vertices - brick_mesh.centroid
    v += INFLATION * v / np.linalg.norm(v, axis=1, keepdims=True)
    return trimesh.Trimesh(brick_mesh.centroid + v, hull.faces)


@pytest.fixture(scope="module")
def pregrasp(built_hand_dir: Path, brick_mesh: trimesh.Trimesh) -> dict[str, np.ndarray]:
    """Two pre-grasps: the palm facing the brick from +x (entry 0) and from -y (entry 1), open
    joints (zeros clipped to the limits), anchors INFLATION out from the surface point."""
    hand = read_json(built_hand_dir / "hand.json")
    palm_normal, focus = np.asarray(hand["palm_normal"]), np.asarray(hand["grasp_focus"])
    joints = np.clip(np.zeros(16), hand["joint_lower"], hand["joint_upper"])
    out: dict[str, list[np.ndarray]] = {k: [] for k in figure_data.PREGRASP_KEYS}
    for outward, jitter in (([1.0, 0, 0], [0, 0.2, -0.1]), ([0, -1.0, 0], [0.1, 0, -0.2])):
        outward = np.asarray(outward)
        surface = brick_mesh.nearest.on_surface((0.2 * outward)[None])[0][0]
        anchor = surface + INFLATION * outward
        direction_raw = -outward
        direction = -outward + np.asarray(jitter)
        direction /= np.linalg.norm(direction)
        rot = _rotation_to(palm_normal, direction)
        wrist = surface - STANDOFF * direction - rot @ focus
        values = [wrist, _quat(rot), joints, anchor, surface, direction, direction_raw]
        for key, value in zip(figure_data.PREGRASP_KEYS, [*values, STANDOFF, 0.0], strict=True):
            out[key].append(np.asarray(value, dtype=float))
    return {k: np.stack(v) for k, v in out.items()}


@pytest.fixture(scope="module")
def grasps(pregrasp: dict[str, np.ndarray]) -> pl.DataFrame:
    """A grasp table for two 'objects' (both the brick) with known energies, 3 rows each."""
    rng = np.random.default_rng(0)
    rows = []
    energies = {"brick_a": [5.0, 1.5, 3.0], "brick_b": [0.0, 9.0, 2.0]}
    gid = 0
    for obj, values in energies.items():
        for k, energy in enumerate(values):
            i = k % 2
            wrist = pregrasp["wrist_pos"][i] + 0.04 * pregrasp["direction"][i]  # closer in
            joints = pregrasp["joints"][i] + rng.uniform(0.0, 0.4, 16)
            row = {"grasp_id": gid, "object": obj, "shard": 0, "seed": 7}
            row |= dict(zip(figure_data.WRIST_COLUMNS, wrist, strict=True))
            row |= {f"rot6d_{j}": float(j == 0 or j == 4) for j in range(6)}
            row |= dict(zip(figure_data.QUAT_COLUMNS, pregrasp["quat"][i], strict=True))
            row |= dict(zip(figure_data.JOINT_COLUMNS, joints, strict=True))
            row |= {f"e_{t}": energy / 5 for t in ("dis", "fc", "pen", "spen", "joint")}
            row |= {"energy": energy, "energy_start": 40.0 + 10 * k, "acceptance_rate": 0.3}
            rows.append(row)
            gid += 1
    return pl.DataFrame(rows).with_columns(
        pl.col("grasp_id").cast(pl.Int64), pl.col("shard").cast(pl.Int32)
    )


def _assert_figure(path: Path, min_side: int = 300) -> np.ndarray:
    """A readable PNG of reasonable size with varied content, and no temporary file beside it."""
    assert path.is_file()
    image = mpimg.imread(path)
    assert image.ndim == 3 and min(image.shape[:2]) >= min_side
    rgb = image[..., :3]
    assert rgb.std() > 0.05
    assert len(np.unique((rgb * 255).astype(np.uint8).reshape(-1, 3), axis=0)) > 100
    assert not [p for p in path.parent.iterdir() if p.name.endswith(".tmp")]
    return rgb


def _teal_pixels(rgb: np.ndarray) -> int:
    """Pixels with the hand's hue (green and blue well above red)."""
    r, g, b = rgb[..., 0], rgb[..., 1], rgb[..., 2]
    return int(np.sum((g - r > 0.2) & (b - r > 0.2) & (np.abs(g - b) < 0.15)))


def test_plot_pregrasp_draws_hand_hull_and_points(
    tmp_path: Path,
    brick_mesh: trimesh.Trimesh,
    inflated_hull: trimesh.Trimesh,
    pregrasp: dict[str, np.ndarray],
    built_hand_dir: Path,
) -> None:
    out = figure.plot_pregrasp(
        tmp_path / "fig" / "pregrasp.png",
        brick_mesh,
        inflated_hull,
        pregrasp,
        built_hand_dir,
        index=1,
        object_id="061_foam_brick",
    )
    assert out == tmp_path / "fig" / "pregrasp.png"
    rgb = _assert_figure(out, min_side=500)
    assert _teal_pixels(rgb) > 2000  # the open hand is drawn
    r, g, b = rgb[..., 0], rgb[..., 1], rgb[..., 2]
    assert np.sum((r > 0.9) & (g > 0.4) & (g < 0.7) & (b < 0.2)) > 20  # orange anchor
    assert np.sum((r > 0.85) & (g < 0.3) & (b > 0.85)) > 20  # magenta approach arrows


def test_plot_pregrasp_rejects_incomplete_batches(
    tmp_path: Path,
    brick_mesh: trimesh.Trimesh,
    inflated_hull: trimesh.Trimesh,
    pregrasp: dict[str, np.ndarray],
    built_hand_dir: Path,
) -> None:
    partial = {k: v for k, v in pregrasp.items() if k != "surface_point"}
    with pytest.raises(figure.FigureInputError, match="surface_point"):
        figure.plot_pregrasp(tmp_path / "p.png", brick_mesh, inflated_hull, partial, built_hand_dir)
    bad = dict(pregrasp, joints=pregrasp["joints"][:, :15])
    with pytest.raises(figure.FigureInputError, match="joints"):
        figure.plot_pregrasp(tmp_path / "p.png", brick_mesh, inflated_hull, bad, built_hand_dir)
    with pytest.raises(IndexError):
        figure.plot_pregrasp(
            tmp_path / "p.png", brick_mesh, inflated_hull, pregrasp, built_hand_dir, index=2
        )
    assert not (tmp_path / "p.png").exists()


def test_grasp_arrays_round_trip_the_columns(grasps: pl.DataFrame) -> None:
    pos, quat, joints = figure_data.grasp_arrays(grasps)
    assert pos.shape == (6, 3) and quat.shape == (6, 4) and joints.shape == (6, 16)
    assert pos.dtype == quat.dtype == joints.dtype == np.float64
    np.testing.assert_array_equal(pos[:, 2], grasps["wrist_z"].to_numpy())
    np.testing.assert_array_equal(quat[:, 0], grasps["quat_w"].to_numpy())
    np.testing.assert_array_equal(quat[:, 3], grasps["quat_z"].to_numpy())
    np.testing.assert_array_equal(joints[:, 0], grasps["theta_00"].to_numpy())
    np.testing.assert_array_equal(joints[:, 15], grasps["theta_15"].to_numpy())
    one = figure_data.grasp_arrays(grasps.row(4, named=True))
    for a, b in zip(one, (pos, quat, joints), strict=True):
        np.testing.assert_array_equal(a, b[4:5])


def test_grasp_arrays_names_missing_columns(grasps: pl.DataFrame) -> None:
    with pytest.raises(figure.FigureInputError, match="'theta_07'.*'quat_x'|'quat_x'.*'theta_07'"):
        figure_data.grasp_arrays(grasps.drop("theta_07", "quat_x"))


def test_select_gallery_grasps_takes_the_lowest_energies(grasps: pl.DataFrame) -> None:
    chosen = figure_data.select_gallery_grasps(grasps, per_object=2, max_objects=6)
    assert chosen["object"].to_list() == ["brick_a", "brick_a", "brick_b", "brick_b"]
    assert chosen["energy"].to_list() == [1.5, 3.0, 0.0, 2.0]
    first = figure_data.select_gallery_grasps(grasps, per_object=1, max_objects=1)
    assert first["grasp_id"].to_list() == [1]
    # Non-finite energies never make it into the gallery.
    nan_best = grasps.with_columns(
        energy=pl.when(pl.col("grasp_id") == 3).then(float("nan")).otherwise(pl.col("energy"))
    )
    assert 3 not in figure_data.select_gallery_grasps(nan_best, 3, 6)["grasp_id"].to_list()
    # A random pick is a seeded subset of the object's grasps.
    a = figure_data.select_gallery_grasps(grasps, 2, 6, seed=3, choose="random")
    b = figure_data.select_gallery_grasps(grasps, 2, 6, seed=3, choose="random")
    assert a.equals(b) and a.height == 4
    assert set(a["grasp_id"].to_list()) <= set(grasps["grasp_id"].to_list())
    with pytest.raises(figure.FigureInputError, match="energy"):
        figure_data.select_gallery_grasps(grasps.drop("energy"), 2, 6)
    with pytest.raises(ValueError, match="choose"):
        figure_data.select_gallery_grasps(grasps, 2, 6, choose="worst")  # type: ignore[arg-type]


def test_plot_grasp_gallery(
    tmp_path: Path, grasps: pl.DataFrame, foam_brick_dir: Path, built_hand_dir: Path
) -> None:
    dirs = {"brick_a": foam_brick_dir, "brick_b": foam_brick_dir}
    out = figure.plot_grasp_gallery(
        tmp_path / "gallery.png", grasps, dirs, built_hand_dir, per_object=1, max_objects=2
    )
    rgb = _assert_figure(out)
    assert rgb.shape[1] > rgb.shape[0]  # two panels side by side
    assert _teal_pixels(rgb) > 1000
    with pytest.raises(figure.FigureInputError, match="brick_b"):
        figure.plot_grasp_gallery(
            tmp_path / "g2.png", grasps, {"brick_a": foam_brick_dir}, built_hand_dir
        )
    with pytest.raises(figure.FigureInputError, match="'wrist_y'"):
        figure.plot_grasp_gallery(tmp_path / "g2.png", grasps.drop("wrist_y"), dirs, built_hand_dir)
    assert not (tmp_path / "g2.png").exists()


def test_plot_energy_histograms(tmp_path: Path, grasps: pl.DataFrame) -> None:
    rng = np.random.default_rng(1)
    many = pl.concat([grasps] * 30).with_columns(
        energy=pl.col("energy") * pl.Series(rng.lognormal(0.0, 0.5, 180)),
        energy_start=pl.col("energy_start") * pl.Series(rng.lognormal(0.0, 0.3, 180)),
    )  # brick_b keeps 30 zero energies: they must be drawn, not crash the log axis
    out = figure.plot_energy_histograms(tmp_path / "hist.png", many)
    rgb = _assert_figure(out, min_side=200)  # one row of two panels
    r, b = rgb[..., 0], rgb[..., 2]
    assert np.sum((b - r > 0.2) & (b > 0.6)) > 500  # the blue final-energy bars
    assert figure_data.energy_floor(np.array([0.0, 0.4, 2.0])) == pytest.approx(0.2)
    assert figure_data.energy_floor(np.array([0.0, np.nan])) == pytest.approx(1e-6)
    with pytest.raises(figure.FigureInputError, match="'energy_start'"):
        figure.plot_energy_histograms(tmp_path / "h2.png", grasps.drop("energy_start"))
    assert not (tmp_path / "h2.png").exists()


def test_decimate_keeps_winding_and_shrinks(brick_mesh: trimesh.Trimesh) -> None:
    tris, normals = figure_meshes.mesh_surface(brick_mesh, 1500)
    assert len(tris) < len(brick_mesh.faces) and len(tris) > 300

    def outward(t: np.ndarray, n: np.ndarray) -> float:
        """Area fraction whose normal points away from the centre (< 1: the brick's holes)."""
        area = np.linalg.norm(np.cross(t[:, 1] - t[:, 0], t[:, 2] - t[:, 0]), axis=1)
        away = np.sum(n * (t.mean(axis=1) - brick_mesh.centroid), axis=1) > 0
        return float(np.sum(area * away) / np.sum(area))

    # Shading normals follow the outward surface as well as the full mesh's own normals do.
    full = brick_mesh.vertices[brick_mesh.faces]
    assert outward(tris, normals) > outward(full, brick_mesh.face_normals) - 0.01 > 0.9
    vertices, faces = figure_meshes.decimate(brick_mesh.vertices, brick_mesh.faces, 0.005)
    assert faces.max() < len(vertices) and len(faces) < len(brick_mesh.faces)
