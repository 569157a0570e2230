"""The replay scene on the real hand and an object: frames, gravity, determinism."""

from __future__ import annotations

from pathlib import Path

import mujoco
import numpy as np
import pytest
import yaml
from conftest import CONFIG_DIR

from graspstab.replay.run import run_replay
from graspstab.replay.scene import build_replay_scene, place_grasp, to_object_frame

PARAMS = yaml.safe_load((CONFIG_DIR / "replay" / "default.yaml").read_text())
G = np.array(PARAMS["gravity"])


@pytest.fixture(scope="module")
def scene(foam_brick_dir: Path, built_hand_dir: Path):
    return build_replay_scene(built_hand_dir, foam_brick_dir, PARAMS)


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
