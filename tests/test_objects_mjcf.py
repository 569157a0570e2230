"""MJCF fragment: loads, exact mass/inertia, attachable into another spec, convex parts collide."""

from __future__ import annotations

from pathlib import Path

import mujoco
import numpy as np
import pytest
import trimesh
from objects_fixtures import COARSE_COACD, mug_like
from scipy.spatial.transform import Rotation

from graspstab.objects.decompose import convex_decomposition
from graspstab.objects.frame import to_upright_com_frame
from graspstab.objects.inertia import compute_inertia
from graspstab.objects.mjcf import write_object_mjcf

MASS = 0.118


@pytest.fixture(scope="module")
def fragment(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, np.ndarray, int]:
    # an asymmetric concave object (cup plus an off-axis lug) so the tensor is not diagonal
    cup = mug_like()
    lug = trimesh.creation.box([0.02, 0.01, 0.03])
    lug.apply_translation([0.045, 0.0, 0.05])
    body = trimesh.boolean.union([cup, lug], engine="manifold")
    tf = np.eye(4)
    tf[:3, :3] = Rotation.from_euler("z", 30, degrees=True).as_matrix()
    body.apply_transform(tf)
    body, _, _ = to_upright_com_frame(body)
    inertia = compute_inertia(body, MASS)
    parts = convex_decomposition(body, COARSE_COACD)
    path = tmp_path_factory.mktemp("mjcf") / "object.xml"
    write_object_mjcf(path, "toy_mug", body, parts, inertia, {"friction": [0.8, 0.01, 0.001]})
    return path, inertia.tensor, len(parts)


def _full_inertia(model: mujoco.MjModel, body: int) -> np.ndarray:
    w, x, y, z = model.body_iquat[body]
    rot = Rotation.from_quat([x, y, z, w]).as_matrix()
    return rot @ np.diag(model.body_inertia[body]) @ rot.T


def test_fragment_loads_with_exact_inertia(fragment: tuple[Path, np.ndarray, int]) -> None:
    path, tensor, n_parts = fragment
    model = mujoco.MjModel.from_xml_path(str(path))
    body = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, "object")
    assert model.body_mass[body] == pytest.approx(MASS, rel=1e-9)
    assert np.allclose(model.body_ipos[body], 0, atol=1e-12)
    assert np.allclose(_full_inertia(model, body), tensor, rtol=1e-6, atol=1e-12)
    assert abs(tensor[0, 1]) > 1e-8  # the test object really has off-diagonal terms
    assert model.njnt == 1 and model.jnt_type[0] == mujoco.mjtJoint.mjJNT_FREE
    assert model.joint("object_free").id == 0
    colliding = [g for g in range(model.ngeom) if model.geom_contype[g] == 1]
    assert len(colliding) == n_parts
    for g in colliding:
        assert model.geom_group[g] == 3 and model.geom_condim[g] == 3
        assert model.geom_conaffinity[g] == 1
        assert np.allclose(model.geom_friction[g], [0.8, 0.01, 0.001])
    visual = model.geom("object_visual")
    assert visual.contype[0] == 0 and visual.conaffinity[0] == 0 and visual.group[0] == 2


def test_fragment_attaches_and_collides(fragment: tuple[Path, np.ndarray, int]) -> None:
    path, tensor, n_parts = fragment
    world = mujoco.MjSpec()
    world.worldbody.add_geom(type=mujoco.mjtGeom.mjGEOM_PLANE, size=[1, 1, 0.1])
    frame = world.worldbody.add_frame(pos=[0, 0, 0.1])
    child = mujoco.MjSpec.from_file(str(path))
    frame.attach_body(child.body("object"), "obj_", "")
    model = world.compile()
    body = model.body("obj_object").id
    assert model.body_mass[body] == pytest.approx(MASS)
    assert np.allclose(_full_inertia(model, body), tensor, rtol=1e-6, atol=1e-12)
    data = mujoco.MjData(model)
    for _ in range(1000):  # 2 s: fall onto the plane and settle
        mujoco.mj_step(model, data)
    assert data.ncon > 0
    floor_contacts = [c for c in data.contact[: data.ncon] if 0 in (c.geom1, c.geom2)]
    assert floor_contacts
    z = data.xpos[body][2]
    assert 0.0 < z < 0.1 and np.linalg.norm(data.qvel[:3]) < 1e-2
