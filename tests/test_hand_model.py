"""The floating ORCA hand MJCF: structure, limits, wrist convention, both description layouts."""

from __future__ import annotations

import shutil
from pathlib import Path

import mujoco
import numpy as np
import pytest

from graspstab.hand import names
from graspstab.hand.model import build_hand_spec, compile_hand, find_scene, save_hand
from graspstab.hand.params import DEFAULT_PARAMS


@pytest.fixture(scope="module")
def file_spec(hand_assets_dir: Path) -> mujoco.MjSpec:
    return mujoco.MjSpec.from_file(str(find_scene(hand_assets_dir)))


@pytest.fixture(scope="module")
def model(hand_assets_dir: Path) -> mujoco.MjModel:
    return compile_hand(build_hand_spec(hand_assets_dir, DEFAULT_PARAMS))


def _upstream_copy(src: Path, dst: Path, stand_in: str) -> Path:
    """An upstream-like layout: the *.upstream MJCF in place (a local copy's; a download has the
    upstream files already), ``stand_in`` as the full-palm R-Carpals.stl, the two meshes upstream
    declares but no geom uses absent."""
    shutil.copytree(src, dst)
    mjcf = dst / "v2" / "models" / "mjcf"
    for name in ("orcahand_right.mjcf", "orcahand_right_body.xml"):
        if (mjcf / f"{name}.upstream").is_file():
            shutil.copyfile(mjcf / f"{name}.upstream", mjcf / name)
            (mjcf / f"{name}.upstream").unlink()
    right = dst / "v2" / "models" / "assets" / "right"
    shutil.copyfile(right / stand_in, right / "R-Carpals.stl")
    for unused in ("P-Assembly.stl", "T-R-Assembly.stl"):
        (right / unused).unlink(missing_ok=True)
    return dst


def test_names_match_the_file(file_spec: mujoco.MjSpec) -> None:
    bodies = {b.name for b in file_spec.bodies}
    joints = {j.name for j in file_spec.joints}
    assert set(names.FINGERTIP_BODIES.values()) <= bodies
    assert set(names.PROXIMAL_BODIES.values()) <= bodies
    assert {b for links in names.FINGER_LINK_BODIES.values() for b in links} <= bodies
    assert {names.PALM_BODY, *names.DROP_BODIES} <= bodies
    assert set(names.FINGER_JOINTS) | set(names.DROP_JOINTS) == joints
    assert len(names.FINGER_JOINTS) == 16 and names.FINGER_JOINTS[0] == "right_t-cmc"


def test_structure(model: mujoco.MjModel, file_spec: mujoco.MjSpec) -> None:
    assert model.njnt == 17
    wrist = model.joint(names.WRIST_JOINT)
    assert model.jnt_type[wrist.id] == mujoco.mjtJoint.mjJNT_FREE and wrist.qposadr[0] == 0
    assert model.body(names.ROOT_BODY).id == model.jnt_bodyid[wrist.id]
    assert model.body_parentid[model.body(names.ROOT_BODY).id] == 0
    assert np.allclose(model.body_pos[model.body(names.ROOT_BODY).id], 0)
    palm = model.body(names.PALM_BODY).id
    assert model.body_parentid[palm] == model.body(names.ROOT_BODY).id
    assert np.allclose(model.body_pos[palm], 0) and np.allclose(model.body_quat[palm], [1, 0, 0, 0])
    hinges = [model.joint(j).name for j in range(model.njnt) if model.jnt_type[j] == 3]
    assert hinges == list(names.FINGER_JOINTS)  # tree order is the canonical order
    file_range = {j.name: np.array(j.range) for j in file_spec.joints}
    for j in names.FINGER_JOINTS:
        assert np.allclose(model.joint(j).range, file_range[j], atol=1e-9)
    assert model.nu == 16
    for a in range(model.nu):
        assert model.actuator_trntype[a] == mujoco.mjtTrn.mjTRN_JOINT
        joint = model.joint(int(model.actuator_trnid[a, 0])).name
        assert joint == names.FINGER_JOINTS[a]
        assert np.allclose(model.actuator_ctrlrange[a], file_range[joint], atol=1e-9)
        assert model.actuator_gainprm[a, 0] == pytest.approx(2.0)
        assert np.allclose(model.actuator_forcerange[a], [-1, 1])
    body_names = {model.body(i).name for i in range(model.nbody)}
    assert not body_names & {*names.DROP_BODIES, "right_mount"}
    assert "right_wrist" not in {model.joint(j).name for j in range(model.njnt)}
    assert set(names.FINGERTIP_BODIES.values()) <= body_names
    assert model.nlight == 0 and model.ntex == 0
    assert all(model.geom_type[g] == mujoco.mjtGeom.mjGEOM_MESH for g in range(model.ngeom))


def test_excludes_only_kept_bodies(model: mujoco.MjModel) -> None:
    assert model.nexclude == 34  # 69 in the file, minus those with the tower, forearm or top tower
    for e in range(model.nexclude):
        b1, b2 = divmod(int(model.exclude_signature[e]), 1 << 16)
        assert b1 > 1 and b2 > 1  # neither the world nor the root


def test_actuator_params(hand_assets_dir: Path) -> None:
    m = compile_hand(build_hand_spec(hand_assets_dir, {"actuator": {"kp": 3.5, "forcerange": 0.5}}))
    assert np.allclose(m.actuator_gainprm[:, 0], 3.5)
    assert np.allclose(m.actuator_biasprm[:, 1], -3.5)
    assert np.allclose(m.actuator_forcerange, [[-0.5, 0.5]] * 16)


@pytest.mark.parametrize(
    ("key", "value"),
    [
        ("palm_body", "right_Palm_typo"),
        ("drop_bodies", ["right_tower", "right_typo"]),
        ("drop_joints", ["right_wristt"]),
    ],
)
def test_missing_name_lists_valid_names(hand_assets_dir: Path, key: str, value: object) -> None:
    with pytest.raises(names.HandNameError, match="valid names") as err:
        build_hand_spec(hand_assets_dir, {key: value})
    assert "typo" in str(err.value) or "wristt" in str(err.value)


def test_bad_fingertip_name(hand_assets_dir: Path) -> None:
    tips = {**names.FINGERTIP_BODIES, "ring": "right_Ring_tip"}
    with pytest.raises(names.HandNameError, match=names.FINGERTIP_BODIES["thumb"]):
        build_hand_spec(hand_assets_dir, {"fingertips": tips})


def test_wrist_pose_moves_palm(model: mujoco.MjModel) -> None:
    data = mujoco.MjData(model)
    rng = np.random.default_rng(0)
    for _ in range(3):
        pos = rng.normal(size=3)
        quat = rng.normal(size=4)
        quat /= np.linalg.norm(quat)
        data.qpos[:] = 0
        data.qpos[0:3], data.qpos[3:7] = pos, quat
        data.qpos[7:] = rng.uniform(model.jnt_range[1:, 0], model.jnt_range[1:, 1])
        mujoco.mj_kinematics(model, data)
        palm = model.body(names.PALM_BODY).id
        mat = np.zeros(9)
        mujoco.mju_quat2Mat(mat, quat)
        assert np.allclose(data.xpos[palm], pos)
        assert np.allclose(data.xmat[palm], mat)


@pytest.mark.parametrize("stand_in", ["R-Carpals_CORE.stl", "R-Carpals_Skin.stl"])
def test_both_layouts_same_model(
    hand_assets_dir: Path, model: mujoco.MjModel, tmp_path: Path, stand_in: str
) -> None:
    """Upstream layout (full R-Carpals.stl present, unused meshes declared but absent) gives the
    same hand; the second stand-in differs from the core, so using it would change the palm."""
    upstream = _upstream_copy(hand_assets_dir, tmp_path / "orcahand_description", stand_in)
    text = (upstream / "v2/models/mjcf/orcahand_right.mjcf").read_text()
    assert "P-Assembly" in text and "R-Carpals.stl" in text
    other = compile_hand(build_hand_spec(upstream, DEFAULT_PARAMS))

    def names_of(m: mujoco.MjModel, obj: mujoco.mjtObj, n: int) -> list[str]:
        return [mujoco.mj_id2name(m, obj, i) for i in range(n)]

    for obj, n in [
        (mujoco.mjtObj.mjOBJ_BODY, "nbody"),
        (mujoco.mjtObj.mjOBJ_JOINT, "njnt"),
        (mujoco.mjtObj.mjOBJ_ACTUATOR, "nu"),
        (mujoco.mjtObj.mjOBJ_MESH, "nmesh"),
    ]:
        assert names_of(model, obj, getattr(model, n)) == names_of(other, obj, getattr(other, n))
    for field in [
        "jnt_range", "jnt_axis", "jnt_pos", "body_pos", "body_quat", "body_mass", "body_inertia",
        "geom_contype", "geom_margin", "geom_friction", "mesh_vertnum", "mesh_facenum",
        "actuator_gainprm", "actuator_forcerange", "exclude_signature",
    ]:  # fmt: skip
        assert np.array_equal(getattr(model, field), getattr(other, field)), field
    palm_mesh = model.geom_dataid[[g for g in range(model.ngeom) if model.geom_bodyid[g] == 2][0]]
    assert model.mesh(palm_mesh).name == "right_R-Carpals"
    assert model.mesh_vertnum[palm_mesh] == other.mesh_vertnum[palm_mesh]
    assert model.body_mass[2] == pytest.approx(0.0444, abs=1e-3)  # core palm mass (SOURCES.md)


def test_save_hand_is_self_contained(
    hand_assets_dir: Path, model: mujoco.MjModel, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    out = tmp_path / "hand"
    xml = save_hand(build_hand_spec(hand_assets_dir, DEFAULT_PARAMS), out)
    text = xml.read_text()
    assert str(hand_assets_dir) not in text and "orcahand_description" not in text
    assert sorted(p.name for p in (out / "meshes").iterdir()) == sorted(
        {Path(model.mesh(i).name).name.removeprefix("right_") + ".stl" for i in range(model.nmesh)}
        - {"R-Carpals.stl"}
        | {"R-Carpals_CORE.stl"}
    )
    moved = tmp_path / "elsewhere"
    shutil.copytree(out, moved)
    monkeypatch.chdir(tmp_path.parent)
    loaded = mujoco.MjModel.from_xml_path(str(moved / "hand.xml"))
    assert loaded.nbody == model.nbody and loaded.nq == 23 and loaded.nu == 16
    assert np.allclose(loaded.body_mass, model.body_mass, rtol=1e-5)
    assert np.allclose(loaded.jnt_range, model.jnt_range, atol=1e-5)
