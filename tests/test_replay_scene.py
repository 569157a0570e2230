"""The replay scene on the real hand and an object: frames, gravity, determinism."""

from __future__ import annotations

from pathlib import Path

import mujoco
import numpy as np
import pytest
from conftest import CONFIG_DIR

from graspstab.config import compose_config
from graspstab.replay.run import run_replay
from graspstab.replay.scene import (
    build_replay_scene,
    place_grasp,
    squeeze_targets,
    to_object_frame,
)


def _replay(contact: str) -> dict:
    """The shipped replay group with a contact model (config/contact/), no squeeze (3.2)."""
    params = compose_config(CONFIG_DIR, [f"contact={contact}"])["replay"]
    return dict(params, squeeze=dict(params["squeeze"], angle=0.0))


PARAMS, REFERENCE = _replay("strict"), _replay("reference")
G = np.array(PARAMS["gravity"])


@pytest.fixture(scope="module")
def scene(foam_brick_dir: Path, built_hand_dir: Path):
    return build_replay_scene(built_hand_dir, foam_brick_dir, PARAMS)


@pytest.fixture(scope="module")
def reference_scene(foam_brick_dir: Path, built_hand_dir: Path):
    return build_replay_scene(built_hand_dir, foam_brick_dir, REFERENCE)


def test_the_default_contact_model_is_the_reference() -> None:
    assert compose_config(CONFIG_DIR)["replay"]["contact"] == REFERENCE["contact"]
    assert REFERENCE["contact"]["name"] == "reference" and PARAMS["contact"]["name"] == "strict"


def test_reference_contact_model_is_mujocos_defaults(reference_scene, scene) -> None:
    """Every solver option of the reference scene equals a model that sets nothing, except the
    time step (3.2's 5e-4 s) and gravity (off while a grasp is placed, eq. 17 after)."""
    default = mujoco.MjModel.from_xml_string("<mujoco/>").opt
    ours = reference_scene.model.opt
    names = [n for n in dir(default) if not n.startswith("_") and n not in ("timestep", "gravity")]
    assert {"cone", "impratio", "noslip_iterations", "o_solref", "solver", "iterations"} <= set(
        names
    )
    for name in names:
        a, b = getattr(default, name), getattr(ours, name)
        if callable(a):
            continue
        np.testing.assert_array_equal(np.asarray(a), np.asarray(b), err_msg=name)
    assert ours.timestep == 0.0005
    # the strict model does differ, so the comparison can fail
    assert scene.model.opt.cone != default.cone and scene.model.opt.noslip_iterations == 10
    # default geom contact parameters (solref, solimp, condim) on the object's collision geoms
    m = reference_scene.model
    obj = [g for g in range(m.ngeom)
           if m.body(m.geom_bodyid[g]).name.startswith("obj_") and m.geom_contype[g]]  # fmt: skip
    assert obj
    spec = mujoco.MjSpec()
    spec.worldbody.add_geom(size=[0.01, 0, 0])
    plain = spec.compile()
    for g in obj:
        np.testing.assert_array_equal(reference_scene.model.geom_solref[g], plain.geom_solref[0])
        np.testing.assert_array_equal(reference_scene.model.geom_solimp[g], plain.geom_solimp[0])
        assert reference_scene.model.geom_condim[g] == plain.geom_condim[0] == 3


def test_reference_servos_are_the_hand_descriptions(reference_scene, hand_assets_dir) -> None:
    """kp, kv and force range of every finger servo equal the description's own actuators."""
    desc = mujoco.MjModel.from_xml_path(str(hand_assets_dir / "v2" / "scene_right.xml"))
    m = reference_scene.model
    for i in reference_scene.finger_ctrl:
        j = desc.actuator(m.actuator(i).name).id
        np.testing.assert_array_equal(m.actuator_gainprm[i, :3], desc.actuator_gainprm[j, :3])
        np.testing.assert_array_equal(m.actuator_biasprm[i, :3], desc.actuator_biasprm[j, :3])
        np.testing.assert_array_equal(m.actuator_forcerange[i], desc.actuator_forcerange[j])
        # hand.xml stores the limits to 6 significant digits
        np.testing.assert_allclose(m.actuator_ctrlrange[i], desc.actuator_ctrlrange[j], atol=1e-5)


def test_squeeze_moves_targets_in_the_closing_direction_within_limits(scene) -> None:
    rng = np.random.default_rng(0)
    lo, hi = scene.ctrl_range[:, 0], scene.ctrl_range[:, 1]
    closing = scene.closing.astype(bool)
    assert closing.sum() == 10  # every finger's mcp and pip
    for angle in (0.0, 0.05, 0.3, 3.0):
        for _ in range(50):
            joints = rng.uniform(lo, hi)
            at_limit = rng.random(16) < 0.2
            joints[at_limit] = hi[at_limit]
            t = squeeze_targets(joints, scene.closing, angle, scene.ctrl_range)
            assert np.all(t[~closing] == joints[~closing])  # the other joints are held
            assert np.all(t[closing] >= joints[closing])  # never opened
            assert np.all(t <= hi + 1e-12)  # never past a joint limit
            expect = np.minimum(joints[closing] + angle, hi[closing])
            np.testing.assert_allclose(t[closing], expect)
    with pytest.raises(ValueError, match="squeeze.angle"):
        squeeze_targets(np.zeros(16), scene.closing, -0.1, scene.ctrl_range)


def test_closing_joints_move_the_fingertips_towards_the_grasp_focus(built_hand_dir) -> None:
    """Increasing each squeezed joint brings its finger's tip geometry closer to the palm's grasp
    focus (in the open posture and a curled one), so "closing" means what it says."""
    import json

    hand = json.loads((built_hand_dir / "hand.json").read_text())
    spec = mujoco.MjSpec.from_file(str(built_hand_dir / "hand.xml"))
    spec.delete(spec.joint(hand["wrist_joint"]))
    m = spec.compile()
    d = mujoco.MjData(m)
    qadr = [m.joint(j).qposadr[0] for j in hand["joint_names"]]
    focus = np.asarray(hand["grasp_focus"])
    tip_geom = {}
    for f in hand["fingers"]:
        body = m.body(hand["fingertips"][f]).id
        tip_geom[f] = next(
            g for g in range(m.ngeom) if m.geom_bodyid[g] == body and m.geom_contype[g]
        )

    def dist(q: np.ndarray, finger: str) -> float:
        d.qpos[:] = 0
        d.qpos[qadr] = q
        mujoco.mj_kinematics(m, d)
        return float(np.linalg.norm(d.geom_xpos[tip_geom[finger]] - focus))

    open_pose = np.asarray(compose_config(CONFIG_DIR)["synthesis"]["pregrasp"]["open_joints"])
    curled = np.array([0.3, 0.6, 0.5, 0.8] + [0.0, 0.8, 0.8] * 4)
    finger_of = {"t": "thumb", "i": "index", "m": "middle", "r": "ring", "p": "little"}
    for joint in PARAMS["squeeze"]["joints"]:
        k = hand["joint_names"].index(joint)
        finger = finger_of[joint.split("_")[1][0]]
        for pose in (open_pose, curled):
            moved = pose.copy()
            moved[k] += 0.1
            assert dist(moved, finger) < dist(pose, finger) - 1e-4, (joint, pose)


def test_place_grasp_applies_the_squeeze(foam_brick_dir, built_hand_dir) -> None:
    params = dict(PARAMS, squeeze=dict(PARAMS["squeeze"], angle=0.2))
    sq = build_replay_scene(built_hand_dir, foam_brick_dir, params)
    data = mujoco.MjData(sq.model)
    joints = np.clip(GRASP_JOINTS, sq.ctrl_range[:, 0], sq.ctrl_range[:, 1])
    place_grasp(sq, data, GRASP_POS, GRASP_QUAT / np.linalg.norm(GRASP_QUAT), joints, G)
    np.testing.assert_allclose(data.qpos[sq.finger_qpos], joints)
    np.testing.assert_allclose(
        data.ctrl[sq.finger_ctrl], squeeze_targets(joints, sq.closing, 0.2, sq.ctrl_range)
    )
    assert (data.ctrl[sq.finger_ctrl] > joints + 1e-9).sum() >= 8
    bad = dict(PARAMS, squeeze={"angle": 0.1, "joints": ["right_x-mcp"]})
    with pytest.raises(ValueError, match="right_x-mcp"):
        build_replay_scene(built_hand_dir, foam_brick_dir, bad)


def _far_pose() -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The hand 30 cm to the side, tilted: no contact, so the object falls freely."""
    quat = np.array([0.9, 0.2, -0.3, 0.25])
    return np.array([0.3, -0.1, 0.05]), quat / np.linalg.norm(quat), np.zeros(16)


def test_free_fall_in_the_object_frame(scene, built_hand_dir: Path) -> None:
    data = mujoco.MjData(scene.model)
    pos, quat, joints = _far_pose()
    place_grasp(scene, data, pos, quat, joints, G)
    assert data.ncon == 0
    run = run_replay(scene.model, data, scene.layout, steps=600, chunk=200,
                     stop_after_loss_steps=10_000)  # fmt: skip
    traces = to_object_frame(run.traces, pos, quat)
    # row t is the state before step t: the object starts at the object frame's origin and falls
    # straight down under eq. 17's gravity, whatever the hand's orientation
    np.testing.assert_allclose(traces["position"][0], 0.0, atol=1e-6)
    t = np.arange(600) * PARAMS["timestep"]
    np.testing.assert_allclose(traces["velocity"][:, :2], 0.0, atol=1e-5)
    np.testing.assert_allclose(traces["velocity"][:, 2], G[2] * t, rtol=1e-3, atol=1e-4)
    assert np.isnan(traces["min_distance"]).all() and (traces["normal"] == 0).all()
    # the fingers hold their targets
    np.testing.assert_allclose(data.qpos[scene.finger_qpos], joints, atol=1e-3)


# a foam-brick grasp of the quick profile (annealed with the default config), rounded
GRASP_POS = np.array([-0.048636, -0.066074, -0.010980])
GRASP_QUAT = np.array([0.602683, -0.500769, -0.247765, -0.569750])
GRASP_JOINTS = np.array(
    [0.576, 0.95, -0.436, 1.36, 0.434, 0.694, 0.195, 0.347, -0.296, 0.622, -0.413, 0.835, 0.758,
     0.424, 0.297, 1.858]
)  # fmt: skip


def test_replay_of_a_grasp_is_bit_for_bit_deterministic(scene) -> None:
    runs = []
    for _ in range(2):
        data = mujoco.MjData(scene.model)
        quat = GRASP_QUAT / np.linalg.norm(GRASP_QUAT)
        place_grasp(scene, data, GRASP_POS, quat, GRASP_JOINTS, G)
        runs.append(run_replay(scene.model, data, scene.layout, 1000, 300, 10_000))
    assert np.isfinite(runs[0].traces["min_distance"]).mean() > 0.9  # the hand touches it
    assert runs[0].traces["normal"].max() > 0.0
    for c in runs[0].traces:
        np.testing.assert_array_equal(runs[0].traces[c], runs[1].traces[c])


def test_a_grasp_that_holds_stays_held(scene) -> None:
    """The grasp above, replayed for 6 s with the configured gains and contacts: the object stays
    in the hand, barely moving, and the summary says so."""
    from graspstab.replay.replay_grasps import summarise_replay

    data = mujoco.MjData(scene.model)
    quat = GRASP_QUAT / np.linalg.norm(GRASP_QUAT)
    place_grasp(scene, data, GRASP_POS, quat, GRASP_JOINTS, G)
    dt = PARAMS["timestep"]
    run = run_replay(scene.model, data, scene.layout, round(6.0 / dt), 1000, 400)
    traces = to_object_frame(run.traces, GRASP_POS, quat)
    summary = summarise_replay(run, traces, dt, round(PARAMS["contact_loss_s"] / dt))
    assert summary["stop_reason"] == "completed" and summary["held_at_end"]
    assert summary["final_displacement"] < 0.01 and np.isnan(summary["contact_loss_s"])
    speed = np.linalg.norm(traces["velocity"][-round(1.0 / dt) :], axis=1)
    assert np.median(speed) < 0.1 * 0.0012  # creeps less than a tenth of 1.2 mm/s
    assert traces["normal"][-1].sum() > 0.5  # fingertips still press on it
