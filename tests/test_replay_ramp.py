"""The load-ramp protocol against analytic cases: a squeezed box slides when the ramp exceeds its
friction capacity, a free body accelerates by F/m, and the recorded load is F(t)."""

from __future__ import annotations

from pathlib import Path

import mujoco
import mujoco.rollout
import numpy as np
import pytest
from conftest import CONFIG_DIR

from graspstab.config import compose_config
from graspstab.replay.creep import BOX_MASS, squeezed_box
from graspstab.replay.grasp_setup import grasp_load
from graspstab.replay.ramp import (
    CONTROL_SPEC,
    RampLoad,
    control_rows,
    ramp_direction,
    ramp_magnitude,
)
from graspstab.replay.run import run_replay
from graspstab.replay.scene import build_replay_scene, place_grasp, to_object_frame

DT = 0.0005
G = 9.81


def _strict_box(squeeze: float) -> tuple[mujoco.MjModel, mujoco.MjData]:
    """creep.py's box between two pads pressing with ``squeeze`` [N] each, under the strict
    model (elliptic, impratio 10, noslip 10), gravity on."""
    strict = {"cone": "elliptic", "impratio": 10.0, "noslip_iterations": 10}
    return squeezed_box(strict, squeeze, DT)


@pytest.mark.parametrize(("squeeze", "rate"), [(5.0, 2.0), (3.0, 1.0)])
def test_squeezed_box_slides_when_the_ramp_exceeds_its_friction_capacity(squeeze, rate):
    model, data = _strict_box(squeeze)
    weight, t0 = BOX_MASS * G, 0.5
    # weight + m g k (t - t0) = 2 mu N (mu = 1, MuJoCo's default sliding friction)
    predicted = t0 + (2 * 1.0 * squeeze / weight - 1.0) / rate
    steps = round((predicted + 0.6) / DT)
    force = ramp_magnitude(steps, DT, t0, rate, 10.0, weight)
    load = np.zeros((steps, 3))
    load[:, 2] = -force  # along gravity
    body = model.body("object").id
    spec = mujoco.mjtState.mjSTATE_FULLPHYSICS
    state = np.empty(mujoco.mj_stateSize(model, spec))
    mujoco.mj_getState(model, data, state, spec)
    out, _ = mujoco.rollout.rollout(model, data, state[None], control_rows(model, data.ctrl, body,
                                    load), control_spec=int(CONTROL_SPEC), nstep=steps)  # fmt: skip
    dof = model.jnt_dofadr[model.body("object").jntadr[0]]
    vz = out[0, :, 1 + model.nq + dof + 2]  # state = (time, qpos, qvel, ...)
    moving = np.flatnonzero(np.abs(vz) >= 0.0012)  # eq. 23's threshold
    assert len(moving), "the box never slid"
    onset = moving[0] * DT
    assert abs(onset - predicted) < 0.03 * predicted, (onset, predicted)
    # before the load reaches the capacity it is held: no creep under the strict model
    assert np.abs(vz[: round((predicted - 0.1) / DT)]).max() < 1e-4


def test_ramp_magnitude_and_directions():
    f = ramp_magnitude(6000, DT, 0.5, 2.0, 3.0, 1.5)
    t = np.arange(6000) * DT
    np.testing.assert_allclose(f, np.clip(1.5 * 2.0 * (t - 0.5), 0.0, 4.5))
    assert f[999] == 0.0 and f[-1] == 4.5
    rng = np.random.default_rng(0)
    np.testing.assert_allclose(ramp_direction("gravity", np.array([0, 0, -9.81]), rng), [0, 0, -1])
    axes = {tuple(ramp_direction("hand_axes", np.zeros(3), rng)) for _ in range(200)}
    assert len(axes) == 6 and all(sorted(np.abs(a)) == [0, 0, 1] for a in axes)
    v = np.array([ramp_direction("sphere", np.zeros(3), rng) for _ in range(2000)])
    np.testing.assert_allclose(np.linalg.norm(v, axis=1), 1.0)
    assert np.abs(v.mean(axis=0)).max() < 0.06  # no preferred direction
    with pytest.raises(ValueError, match="hand_axes"):
        ramp_direction("up", np.zeros(3), rng)


def _replay_params(**ramp) -> dict:
    params = compose_config(CONFIG_DIR, ["contact=strict"])["replay"]
    return dict(params, protocol="ramp", ramp=dict(params["ramp"], **ramp))


def test_replay_applies_and_records_the_ramp(foam_brick_dir: Path, built_hand_dir: Path):
    """The hand far from the object (no contact): the object falls under gravity plus the ramp,
    so its velocity is g t + (1/m) integral of F, and the recorded load is F(t)."""
    params = _replay_params(start_s=0.1, rate=20.0, ceiling=3.0, directions="hand_axes",
                            path="linear")
    scene = build_replay_scene(built_hand_dir, foam_brick_dir, params)
    data = mujoco.MjData(scene.model)
    quat = np.array([0.9, 0.2, -0.3, 0.25])
    pos, quat = np.array([0.3, -0.1, 0.05]), quat / np.linalg.norm(quat)
    place_grasp(scene, data, pos, quat, np.zeros(16), np.array(params["gravity"]))
    steps = 800
    ramp = grasp_load(params, scene, scene.model.opt.gravity.copy(), "061_foam_brick", 3)
    load = ramp.forces(0, steps)
    assert load.shape == (steps, 3)
    run = run_replay(scene.model, data, scene.layout, steps, 300, 10_000, ramp, scene.object_body)
    np.testing.assert_allclose(run.traces["load"], load, rtol=1e-6, atol=1e-6)
    mass = float(scene.model.body_subtreemass[scene.object_body])
    weight = mass * G
    t = np.arange(steps) * DT
    magnitude = np.clip(weight * 20.0 * (t - 0.1), 0.0, 3.0 * weight)
    np.testing.assert_allclose(np.linalg.norm(load, axis=1), magnitude, rtol=1e-9, atol=1e-12)
    # row t is the state before step t: v_t = sum over earlier steps of (g + F/m) dt
    accel = scene.model.opt.gravity[None] + load / mass
    expected = np.concatenate([np.zeros((1, 3)), np.cumsum(accel[:-1] * DT, axis=0)])
    np.testing.assert_allclose(run.traces["velocity"], expected, rtol=2e-3, atol=2e-4)
    # in the object frame the load is rotated like the velocity
    frame = to_object_frame(run.traces, pos, quat)
    np.testing.assert_allclose(np.linalg.norm(frame["load"], axis=1), magnitude, atol=1e-4)
    # the gravity protocol applies no load and records none
    assert grasp_load(dict(params, protocol="gravity"), scene, np.zeros(3), "x", 0) is None


def _box_run(load: RampLoad, steps: int, squeeze: float) -> tuple[np.ndarray, np.ndarray]:
    """Roll the strict squeezed box out chunk by chunk as run_replay does (chunk lengths from the
    load, speeds fed back after each chunk); its z velocity and the applied |F| per step."""
    model, data = _strict_box(squeeze)
    body = model.body("object").id
    dof = model.jnt_dofadr[model.body("object").jntadr[0]]
    spec = mujoco.mjtState.mjSTATE_FULLPHYSICS
    state = np.empty(mujoco.mj_stateSize(model, spec))
    vz, applied, done = [], [], 0
    while done < steps:
        n = load.chunk_steps(done, min(1000, steps - done))
        forces = load.forces(done, n)
        mujoco.mj_getState(model, data, state, spec)
        control = control_rows(model, data.ctrl, body, forces)
        out, _ = mujoco.rollout.rollout(model, data, state[None], control, nstep=n,
                                        control_spec=int(CONTROL_SPEC),
                                        initial_warmstart=data.qacc_warmstart.copy()[None])
        vz.append(out[0, :, 1 + model.nq + dof + 2])  # state = (time, qpos, qvel, ...)
        load.observe(done, np.abs(vz[-1]))
        applied.append(np.linalg.norm(forces, axis=1))
        done += n
    return np.concatenate(vz), np.concatenate(applied)


@pytest.mark.parametrize("fraction", [1.0, 0.9])
def test_hold_path_stops_rising_when_the_box_slides(fraction):
    """Path ``hold``: the load rises until the box slides (at the predicted load, within the
    feedback step), then stays at ``fraction`` of it; backed off below the capacity the box
    sticks again."""
    squeeze, rate, t0 = 3.0, 1.0, 0.5
    weight = BOX_MASS * G
    capacity = 2 * 1.0 * squeeze - weight  # the extra load the two pads can carry
    load = RampLoad(np.array([0.0, 0.0, -1.0]), weight, DT, t0, rate, 10.0, path="hold",
                    slip_speed=0.0012, hold_fraction=fraction, feedback_steps=20)  # fmt: skip
    steps = round((t0 + capacity / weight / rate + 1.0) / DT)
    vz, applied = _box_run(load, steps, squeeze)
    assert load.slip_step is not None, "the box never slid"
    assert abs(load.held / fraction - capacity) < 0.03 * capacity, (load.held, capacity)
    after = applied[load.slip_step + 2 * 20 :]
    np.testing.assert_allclose(after, load.held)  # held, not rising
    assert applied.max() <= load.held / fraction + weight * rate * 2 * 20 * DT  # overshoot bound
    if fraction < 1.0:
        # below the capacity again: the box sticks within 0.2 s of the slip
        assert np.abs(vz[load.slip_step + round(0.2 / DT) :]).max() < 1e-3


def test_servo_path_keeps_the_sliding_box_near_the_target_speed():
    """Path ``servo``: after the first slide the load is servoed on the speed, so the box keeps
    sliding near ``slip_speed`` instead of accelerating away (as under path ``linear``)."""
    squeeze, rate, t0, target = 3.0, 1.0, 0.5, 0.005
    weight = BOX_MASS * G
    capacity = 2 * 1.0 * squeeze - weight
    steps = round((t0 + capacity / weight / rate + 2.0) / DT)
    speeds = {}
    for path in ("servo", "linear"):
        load = RampLoad(np.array([0.0, 0.0, -1.0]), weight, DT, t0, rate, 10.0, path=path,
                        slip_speed=target, feedback_steps=20)  # fmt: skip
        vz, applied = _box_run(load, steps, squeeze)
        speeds[path] = np.abs(vz)
        if path == "servo":
            assert load.slip_step is not None
            late = np.abs(vz[-round(1.0 / DT) :])  # the last second, well after the slide
            assert 0.2 * target < late.mean() < 3 * target, late.mean()
            # the load hovers around the friction capacity, below the ceiling
            assert abs(applied[-round(1.0 / DT) :].mean() - capacity) < 0.05 * capacity
    assert speeds["linear"][-1] > 10 * speeds["servo"][-1]  # the linear ramp tears it away
