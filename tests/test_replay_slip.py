"""Failure anatomy's physics channels on constructed scenes: contact slip against the relative
velocity of the touching material points by finite differences, a box pulled out of a two-finger
grasp slides at both fingertips at its own speed, a servo pushed past its range saturates."""

from __future__ import annotations

import mujoco
import numpy as np
import pytest
from box_scene import two_finger_box

from graspstab.replay.ramp import RampLoad
from graspstab.replay.run import run_replay
from graspstab.replay.sensors import add_replay_sensors, sensor_layout
from graspstab.replay.slip import SlipSampler, body_classes, contact_slip

DT = 0.0005


def scene(force_limit: float = 100.0, palm: bool = False, kp: float = 1000.0):
    """The two-finger box with the replay's sensors, both servos closing (weight 1 / range)."""
    spec = mujoco.MjSpec.from_string(two_finger_box(0.1, 0.02, force_limit, kp=kp, dt=DT,
                                                    palm=palm))  # fmt: skip
    add_replay_sensors(spec, {"a": "tip_a", "b": "tip_b"}, "hand", "object", 8, ["act_a", "act_b"])
    model = spec.compile()
    layout = sensor_layout(model, ("a", "b"), 8, np.full(2, 1.0 / force_limit))
    return model, mujoco.MjData(model), layout


def material_point_slip(model, data, contact: int, h: float = 1e-7) -> float:
    """Tangential relative speed at a contact by finite differences of the two bodies' material
    points at the contact position (independent of cvel)."""
    con = data.contact[contact]
    bodies = model.geom_bodyid[con.geom1], model.geom_bodyid[con.geom2]
    p = con.pos.copy()
    local = [data.xmat[b].reshape(3, 3).T @ (p - data.xpos[b]) for b in bodies]
    qpos = data.qpos.copy()
    mujoco.mj_integratePos(model, qpos, data.qvel, h)
    moved = mujoco.MjData(model)
    moved.qpos[:] = qpos
    mujoco.mj_kinematics(model, moved)
    vel = [(moved.xpos[b] + moved.xmat[b].reshape(3, 3) @ loc - p) / h
           for b, loc in zip(bodies, local, strict=True)]  # fmt: skip
    rel = vel[1] - vel[0]
    n = con.frame[:3]
    return float(np.linalg.norm(rel - rel.dot(n) * n))


@pytest.mark.parametrize("where", ["fingertips", "palm"])
def test_contact_slip_matches_the_material_points_relative_velocity(where: str) -> None:
    """A box moving and spinning against both fingertips, or against the palm link alone: each
    column's slip is the largest finite-difference slip of its contacts, the palm's in the
    non-sensed links' column and nothing elsewhere."""
    model, data, layout = scene(palm=True)
    a = model.jnt_qposadr[model.body("object").jntadr[0]]
    if where == "fingertips":
        data.qpos[:2] = 0.0055  # each fingertip face 0.5 mm into the box at the origin
    else:  # the box 0.5 mm into the palm's -y face (palm at y 0.1, z 0.05, half 10 mm)
        data.qpos[a : a + 3] = [0.0, 0.0705, 0.05]
    data.qpos[a + 3 : a + 7] = [1.0, 0.0, 0.0, 0.0]
    data.qvel[:] = 0.0
    data.qvel[2:8] = [0.01, -0.02, 0.03, 0.5, -0.3, 0.8]  # box linear, then angular velocity
    data.qvel[0] = 0.002
    mujoco.mj_forward(model, data)
    classes = body_classes(model, layout)
    assert classes[model.body("tip_a").id] == 0 and classes[model.body("tip_b").id] == 1
    assert classes[model.body("palm").id] == 2 and classes[model.body("object").id] == -1
    got = contact_slip(model, data, layout.object_body, classes)
    want = np.zeros(3)
    for i in range(data.ncon):
        bodies = model.geom_bodyid[[data.contact[i].geom1, data.contact[i].geom2]]
        other = bodies[bodies != layout.object_body]
        want[classes[other[0]]] = max(want[classes[other[0]]], material_point_slip(model, data, i))
    touched = [0, 1] if where == "fingertips" else [2]
    assert (want[touched] > 1e-3).all() and not np.delete(want, touched).any()
    np.testing.assert_allclose(got, want, rtol=1e-4)


def test_a_box_pulled_out_of_a_two_finger_grasp_slides_at_both_fingertips() -> None:
    """Held by 2 N a side (friction 1), a load along -z rising at 10 N/s tears it out after
    ~0.4 s: while loaded below capacity neither fingertip slides; once the box moves, each
    fingertip's slip equals the box's speed (the slides cannot move along z), no servo saturates
    and no other link touches it."""
    model, data, layout = scene()
    data.ctrl[:] = 0.007  # faces meet the box 5 mm in; 2 mm past it: 2 N a side
    for _ in range(600):
        mujoco.mj_step(model, data)
    load = RampLoad(np.array([0.0, 0.0, -1.0]), weight=1.0, dt=DT, start_s=0.0, rate=10.0,
                    ceiling=20.0, path="linear")  # fmt: skip
    run = run_replay(model, data, layout, 2000, 100, 10**6, load, layout.object_body,
                     slip=SlipSampler(model, layout, 4))  # fmt: skip
    tr = run.traces
    speed = np.linalg.norm(tr["velocity"], axis=1)
    tip = tr["tip_slip"]
    assert tip.shape == (len(speed), 2) and tr["link_slip"].shape == (len(speed),)
    quiet = np.flatnonzero(np.linalg.norm(tr["load"], axis=1) < 2.0)  # well below 4 N capacity
    assert tip[quiet].max() < 1e-3
    moving = np.flatnonzero((speed > 0.05) & np.isfinite(tr["min_distance"]))
    assert len(moving) > 50, "the box should slide out while still touching"
    # a sample holds for 4 rows: compare at the sampled rows, which read the same state
    sampled = moving[moving % 4 == 0]
    np.testing.assert_allclose(tip[sampled, 0], speed[sampled], rtol=0.02)
    np.testing.assert_allclose(tip[sampled, 1], speed[sampled], rtol=0.02)
    assert not tr["link_slip"].any()
    assert tr["servo_load"].max() < 0.1  # 2 N of a 100 N range
    assert tr["spin"].max() < 0.5


def test_a_servo_pushed_past_its_range_saturates() -> None:
    """Targets 10 mm past the faces at kp 1000 ask ~10 N of a 1 N range: servo_load reads 1
    while pressing; 0.5 mm past asks kp (target - q) < 1 N at rest, which it reads exactly."""
    for past in (0.010, 0.0005):
        model, data, layout = scene(force_limit=1.0)
        data.ctrl[:] = 0.005 + past
        run = run_replay(model, data, layout, 1000, 500, 10**6)
        load = run.traces["servo_load"][-100:]
        if past > 0.001:
            assert load == pytest.approx(1.0, abs=1e-6)
        else:
            asked = 1000.0 * (data.ctrl - data.qpos[:2])  # statics of the servo at rest
            assert 0.1 < asked.max() < 0.9
            assert load == pytest.approx(asked.max(), rel=1e-3)


def test_the_sampler_holds_each_sample_and_starts_on_the_global_grid() -> None:
    """Rows between samples repeat the last sample, across chunk boundaries; a sample is taken
    at every row whose global index is a multiple of ``every``."""
    model, data, layout = scene()
    sampler = SlipSampler(model, layout, 5)
    calls: list[int] = []
    sampler.sample = lambda state: (calls.append(int(state[0])), np.full(3, state[0]))[1]
    states = np.arange(1.0, 13.0)[:, None] * np.ones((1, 4))  # state after row i is i + 1
    rows = sampler.rows(3, np.zeros(4), states)  # rows 3..14: samples at rows 5 and 10
    assert calls == [2, 7]  # the state before row 5 is the one after row 4 (index 1)
    np.testing.assert_array_equal(rows[:, 0], [0, 0, 2, 2, 2, 2, 2, 7, 7, 7, 7, 7])
    more = sampler.rows(15, np.full(4, 100.0), states[:3])  # rows 15..17: sample at 15
    assert calls[-1] == 100 and (more[:, 0] == 100).all()
