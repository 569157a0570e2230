"""The hand stage outputs: hand.json, capsules, contact candidates, kinematics and figures."""

from __future__ import annotations

import json
import math
import os
from pathlib import Path

import mujoco
import numpy as np
import pytest
import trimesh
from scipy.spatial import ConvexHull

from graspstab.common.io import read_json
from graspstab.hand import names
from graspstab.hand.build_hand import DEFAULT_PARAMS, OUTPUTS, main
from graspstab.hand.candidates import contact_candidates
from graspstab.hand.capsules import capsule_pairs
from graspstab.hand.figure import plot_candidates, plot_capsules
from graspstab.hand.kinematics import HandKinematics
from graspstab.hand.meshes import body_collision_mesh, collision_geoms, geom_mesh
from graspstab.hand.surface_points import farthest_point_cover, hand_surface_points

IDENTITY = np.array([1.0, 0.0, 0.0, 0.0])


@pytest.fixture(scope="module")
def hand_dir(hand_assets_dir: Path, tmp_path_factory: pytest.TempPathFactory) -> Path:
    """Build once through the CLI, exactly as the workflow rule calls it."""
    out = tmp_path_factory.mktemp("hand")
    rc = main(
        [
            "--description-dir", str(hand_assets_dir),
            "--out-dir", str(out),
            "--params-json", json.dumps(DEFAULT_PARAMS),
            "--log-file", str(out.parent / "hand.log"),
        ]
    )  # fmt: skip
    assert rc == 0
    return out


@pytest.fixture(scope="module")
def model(hand_dir: Path) -> mujoco.MjModel:
    return mujoco.MjModel.from_xml_path(str(hand_dir / "hand.xml"))


@pytest.fixture(scope="module")
def meta(hand_dir: Path) -> dict:
    return read_json(hand_dir / "hand.json")


@pytest.fixture(scope="module")
def caps(hand_dir: Path) -> dict:
    return read_json(hand_dir / "capsules.json")


@pytest.fixture(scope="module")
def cands(hand_dir: Path) -> dict[str, np.ndarray]:
    with np.load(hand_dir / "contact_candidates.npz") as npz:
        return {k: npz[k] for k in npz.files}


def test_outputs_exactly(hand_dir: Path) -> None:
    assert sorted(os.listdir(hand_dir)) == sorted(OUTPUTS)
    assert (hand_dir / "meshes").is_dir() and len(list((hand_dir / "meshes").glob("*.stl"))) == 23


def test_loads_from_another_directory(
    hand_dir: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.chdir(tmp_path)
    m = mujoco.MjModel.from_xml_path(str(hand_dir / "hand.xml"))
    data = mujoco.MjData(m)
    data.qpos[3] = 1.0
    mujoco.mj_step(m, data)
    assert np.all(np.isfinite(data.qpos))


def test_hand_json(meta: dict, model: mujoco.MjModel) -> None:
    assert meta["root_body"] == names.ROOT_BODY and meta["wrist_joint"] == names.WRIST_JOINT
    assert meta["wrist_qpos_index"] == list(range(7))
    assert meta["joint_names"] == list(names.FINGER_JOINTS)
    for i, j in enumerate(meta["joint_names"]):
        assert [meta["joint_lower"][i], meta["joint_upper"][i]] == list(model.joint(j).range)
        assert meta["joint_qpos_index"][j] == 7 + i
        assert meta["joint_ctrl_index"][j] == i
        assert model.actuator(meta["actuator_names"][i]).trnid[0] == model.joint(j).id
    assert meta["fingertips"] == names.FINGERTIP_BODIES
    assert meta["proximal_bodies"] == names.PROXIMAL_BODIES
    assert meta["finger_links"] == {f: list(b) for f, b in names.FINGER_LINK_BODIES.items()}
    assert meta["palm_body"] == names.PALM_BODY
    assert meta["total_mass"] == pytest.approx(model.body_mass.sum())
    assert meta["provenance"]["stage"] == "hand"
    assert meta["provenance"]["params"]["capsules"]["coverage"] == 0.95
    # palm normal: unit, towards the side the fingers close; focus in front of the palm surface
    n = np.asarray(meta["palm_normal"])
    assert np.linalg.norm(n) == pytest.approx(1.0)
    palm_v = body_collision_mesh(model, names.PALM_BODY).vertices
    height = np.asarray(meta["grasp_focus"]) @ n - (palm_v @ n).max()
    assert height == pytest.approx(DEFAULT_PARAMS["grasp_focus_offset"], abs=1e-9)
    data = mujoco.MjData(model)
    mujoco.mj_kinematics(model, data)  # wrist at the origin: world frame = palm frame
    thumb_tip = data.xpos[model.body(names.FINGERTIP_BODIES["thumb"]).id]
    assert (thumb_tip - palm_v.mean(0)) @ n > 0.03  # the thumb opposes on the palm side


def _segment_distance_brute(points: np.ndarray, p0: np.ndarray, p1: np.ndarray) -> np.ndarray:
    """Distance to the segment by brute force (independent of the library): the nearest of 401
    samples along it, then the nearest of 401 samples between that sample's neighbours."""
    n = 401
    s = np.linspace(0.0, 1.0, n)
    d = np.linalg.norm(points[:, None, :] - (p0 + s[:, None] * (p1 - p0))[None], axis=2)
    k = np.argmin(d, axis=1)
    lo, hi = s[np.maximum(k - 1, 0)], s[np.minimum(k + 1, n - 1)]
    fine = lo[:, None] + (hi - lo)[:, None] * np.linspace(0.0, 1.0, n)[None, :]
    q = p0[None, None, :] + fine[:, :, None] * (p1 - p0)[None, None, :]
    return np.linalg.norm(points[:, None, :] - q, axis=2).min(axis=1)


def test_capsules_cover_their_links(caps: dict, model: mujoco.MjModel) -> None:
    capsules = caps["capsules"]
    assert len(capsules) == 16
    assert [c["body"] for c in capsules] == [
        b for f in names.FINGERS for b in names.FINGER_LINK_BODIES[f]
    ]
    coverage = DEFAULT_PARAMS["capsules"]["coverage"]
    for c in capsules:
        verts = body_collision_mesh(model, c["body"]).vertices
        p0, p1, r = np.asarray(c["p0"]), np.asarray(c["p1"]), c["radius"]
        d = _segment_distance_brute(verts, p0, p1)
        assert np.mean(d <= r + 1e-7) >= coverage, c["name"]
        r_min = np.sort(d)[math.ceil(coverage * len(d)) - 1]
        assert r <= r_min + DEFAULT_PARAMS["capsules"]["max_slack"], c["name"]
        assert 0.004 < r < 0.02 and np.linalg.norm(p1 - p0) < 0.05, c["name"]


def test_palm_box_encloses_palm(caps: dict, model: mujoco.MjModel) -> None:
    box = caps["palm_box"]
    assert box["body"] == names.PALM_BODY
    rot = np.asarray(box["rotation"])
    assert np.allclose(rot.T @ rot, np.eye(3)) and np.linalg.det(rot) == pytest.approx(1.0)
    local = (body_collision_mesh(model, names.PALM_BODY).vertices - box["center"]) @ rot
    assert np.all(np.abs(local) <= np.asarray(box["half_extents"]) + 1e-9)


def test_pairs_skip_same_finger(caps: dict) -> None:
    capsules = caps["capsules"]
    pairs = capsule_pairs(capsules)
    assert [list(p) for p in pairs] == caps["pairs"]
    assert len(pairs) == 56
    for i, j in pairs:
        assert capsules[i]["finger"] != capsules[j]["finger"]
        for c in (capsules[i], capsules[j]):
            assert c["finger"] == "thumb" or c["link_index"] > 0  # long-finger AP links excluded
    pp_pairs = {(capsules[i]["name"], capsules[j]["name"]) for i, j in pairs}
    assert ("index_pp", "middle_pp") in pp_pairs and ("thumb_dp", "index_dp") in pp_pairs


def test_candidate_set_shape(cands: dict[str, np.ndarray]) -> None:
    assert cands["points"].shape == (120, 3) and cands["normals"].shape == (120, 3)
    assert np.array_equal(np.bincount(cands["region"]), [12] * 10)
    assert list(cands["region_body"]) == [
        b for f in names.FINGERS for b in (names.PROXIMAL_BODIES[f], names.FINGERTIP_BODIES[f])
    ]
    for r in range(10):
        sel = cands["region"] == r
        assert set(cands["body"][sel]) == {cands["region_body"][r]}
        assert set(cands["finger"][sel]) == {cands["region_finger"][r]}
        pts = cands["points"][sel]
        gaps = np.linalg.norm(pts[:, None] - pts[None], axis=2) + np.eye(12)
        assert gaps.min() > 0.002  # farthest-point sampling spreads the points
    assert np.allclose(np.linalg.norm(cands["normals"], axis=1), 1.0)


def test_candidates_on_surface_and_outward(
    cands: dict[str, np.ndarray], model: mujoco.MjModel
) -> None:
    for body in np.unique(cands["body"]):
        sel = cands["body"] == body
        m = body_collision_mesh(model, str(body))
        mesh = trimesh.Trimesh(m.vertices, m.faces, process=False)
        _, dist, _ = trimesh.proximity.closest_point(mesh, cands["points"][sel])
        assert dist.max() < 1e-3, body
        outside = cands["points"][sel] + 2e-5 * cands["normals"][sel]
        inside = cands["points"][sel] - 2e-5 * cands["normals"][sel]
        assert mesh.contains(inside).mean() >= 0.9 and not mesh.contains(outside).any(), body


def test_candidates_palm_facing(
    cands: dict[str, np.ndarray], model: mujoco.MjModel, meta: dict, hand_dir: Path
) -> None:
    # (1) normal within the patch cone around the link's flexion direction, recomputed here
    min_cos = DEFAULT_PARAMS["candidates"]["palm_facing_min_cos"]
    for r, body in enumerate(cands["region_body"]):
        jnt = [j for j in range(model.njnt) if model.jnt_bodyid[j] == model.body(str(body)).id][0]
        centroid = body_collision_mesh(model, str(body)).vertices.mean(axis=0)
        d = np.cross(model.jnt_axis[jnt], centroid - model.jnt_pos[jnt])
        d /= np.linalg.norm(d)
        assert np.all(cands["normals"][cands["region"] == r] @ d >= min_cos - 1e-9)
    # (2) open hand: the long fingers' candidates face the way the palm faces
    kin = HandKinematics(hand_dir)
    long_fingers = cands["finger"] != "thumb"
    _, normals = kin.candidates_world(np.zeros(3), IDENTITY, np.zeros(16), with_normals=True)
    assert np.mean(normals[long_fingers] @ np.asarray(meta["palm_normal"])) > 0.6
    # (3) flexed hand: the long fingers' candidates face back towards the palm / grasp focus
    flexed = np.array([0.6 if j.endswith(("mcp", "pip")) else 0.0 for j in names.FINGER_JOINTS])
    pts, normals = kin.candidates_world(np.zeros(3), IDENTITY, flexed, with_normals=True)
    to_focus = np.asarray(meta["grasp_focus"]) - pts
    assert np.mean(np.sum(normals * to_focus, axis=1)[long_fingers] > 0) >= 0.9


def test_candidates_deterministic(cands: dict[str, np.ndarray], model: mujoco.MjModel) -> None:
    again = contact_candidates(model, DEFAULT_PARAMS)
    assert np.array_equal(again["points"], cands["points"])
    other = contact_candidates(model, {**DEFAULT_PARAMS, "candidates": {
        **DEFAULT_PARAMS["candidates"], "seed": 1}})  # fmt: skip
    assert not np.array_equal(other["points"], cands["points"])


def test_surface_points_cover_every_colliding_hull(hand_dir: Path, model: mujoco.MjModel) -> None:
    with np.load(hand_dir / "surface_points.npz") as npz:
        points, bodies = npz["points"], npz["body"].astype(str)
    radius = DEFAULT_PARAMS["surface_points"]["cover_radius"]
    colliding = {model.body(b).name for b in range(1, model.nbody) if collision_geoms(
        model, model.body(b).name)}  # fmt: skip
    assert set(bodies) == colliding and len(colliding) == 17
    for body in colliding:
        own = points[bodies == body]
        verts = [geom_mesh(model, g)[0] for g in collision_geoms(model, body)]
        # every point lies on the surface of one of the body's geom hulls: the largest of the
        # hull's half-space values n.x + b is 0 there (negative inside, positive outside)
        halfspaces = [ConvexHull(v).equations for v in verts]
        on_hull = np.min([np.abs((own @ e[:, :3].T + e[:, 3]).max(1)) for e in halfspaces], 0)
        assert on_hull.max() < 1e-9, body
        hulls = [trimesh.convex.convex_hull(v) for v in verts]
        # an independent sample of the hulls lies within the cover radius of a kept point, up
        # to the spacing of the dense sample the cover was thinned from (50 per cm^2: ~1.4 mm)
        for h in hulls:
            probe = trimesh.sample.sample_surface(h, 2000, seed=7)[0]
            gap = np.linalg.norm(probe[:, None] - own[None], axis=2).min(1)
            assert gap.max() <= radius + 0.001, body
    again = hand_surface_points(model, DEFAULT_PARAMS["surface_points"])
    assert np.array_equal(again["points"], points)


def test_farthest_point_cover() -> None:
    line = np.c_[np.linspace(0, 1, 101), np.zeros(101), np.zeros(101)]
    keep = farthest_point_cover(line, 0.1)
    gaps = np.abs(line[:, :1] - line[keep, 0][None]).min(1)
    # by hand: after 0, 1, 0.5, 0.25, 0.75 the gaps are 0.125 > 0.1, so the four eighths follow
    assert keep.tolist() == [0, 100, 50, 25, 75, 12, 37, 62, 87]
    assert gaps.max() <= 0.1
    assert len(farthest_point_cover(line, 2.0)) == 1


def test_kinematics(hand_dir: Path, cands: dict[str, np.ndarray]) -> None:
    kin = HandKinematics(hand_dir)
    rng = np.random.default_rng(1)
    pos, quat = rng.normal(size=3), rng.normal(size=4)
    quat /= np.linalg.norm(quat)
    joints = rng.uniform(kin.model.jnt_range[1:, 0], kin.model.jnt_range[1:, 1])
    poses = kin.link_poses(pos, quat, joints)
    mat = np.zeros(9)
    mujoco.mju_quat2Mat(mat, quat)
    assert np.allclose(poses[names.PALM_BODY][0], pos)
    assert np.allclose(poses[names.PALM_BODY][1], mat.reshape(3, 3))
    world = kin.candidates_world(pos, quat, joints)
    for i in (0, 57, 119):
        p, r = poses[str(cands["body"][i])]
        assert np.allclose(world[i], p + r @ cands["points"][i])
    with pytest.raises(ValueError, match="shape"):
        kin.link_poses(pos, quat, np.zeros(17))


def test_figures(hand_dir: Path, tmp_path: Path) -> None:
    plot_candidates(hand_dir, tmp_path / "candidates.png")
    plot_capsules(hand_dir, tmp_path / "capsules.png")
    for name in ("candidates.png", "capsules.png"):
        data = (tmp_path / name).read_bytes()
        assert data.startswith(b"\x89PNG") and len(data) > 20_000
    assert sorted(p.name for p in tmp_path.iterdir()) == ["candidates.png", "capsules.png"]
