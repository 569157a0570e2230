"""Replay sensors on an analytic scene: a box squeezed between two position-driven fingertips."""

from __future__ import annotations

import mujoco
import numpy as np
import pytest
from box_scene import two_finger_box

from graspstab.replay.replay_grasps import summarise_replay
from graspstab.replay.run import run_replay
from graspstab.replay.sensors import add_replay_sensors, features, sensor_layout

MASS, HALF, SQUEEZE, G = 0.2, 0.02, 5.0, 9.81
SCENE = two_finger_box(MASS, HALF, SQUEEZE)
TIPS = {"a": "tip_a", "b": "tip_b"}


def _scene(slots: int = 8) -> tuple[mujoco.MjModel, mujoco.MjData]:
    spec = mujoco.MjSpec.from_string(SCENE)
    add_replay_sensors(spec, TIPS, "hand", "object", slots)
    model = spec.compile()
    data = mujoco.MjData(model)
    data.ctrl[:] = 0.05  # both targets 5 cm inwards: deep in the box, so the force saturates
    return model, data


def _direct(model: mujoco.MjModel, data: mujoco.MjData) -> tuple[float, np.ndarray, np.ndarray]:
    """The same quantities from data.contact and mj_contactForce, contact by contact."""
    obj = model.body("object").id
    tips = [model.body(b).id for b in TIPS.values()]
    hand = {model.body(n).id for n in ("hand", "tip_a", "tip_b", "palm")}
    dmin, normal, shear = np.inf, np.zeros(2), np.zeros(2)
    force = np.zeros(6)
    for i in range(data.ncon):
        c = data.contact[i]
        bodies = {model.geom_bodyid[c.geom1], model.geom_bodyid[c.geom2]}
        if obj not in bodies or not (bodies - {obj}) <= hand:
            continue
        dmin = min(dmin, c.dist)
        mujoco.mj_contactForce(model, data, i, force)
        for k, tip in enumerate(tips):
            if tip in bodies:
                normal[k] += abs(force[0])
                shear[k] += np.hypot(force[1], force[2])
    return (np.nan if dmin == np.inf else dmin), normal, shear


def test_sensor_features_equal_contact_by_contact_reference() -> None:
    model, data = _scene()
    layout = sensor_layout(model, tuple(TIPS), 8)
    seen_none = seen_some = False
    for step in range(1500):
        if step == 300:
            model.opt.gravity[:] = (0.0, 0.0, -G)
        mujoco.mj_step(model, data)
        mujoco.mj_forward(model, data)  # sensors and contacts of the same state
        got = features(data.sensordata[None], layout)
        dmin, normal, shear = _direct(model, data)
        if np.isnan(dmin):
            seen_none = True
            assert np.isnan(got["min_distance"][0]), step
        else:
            seen_some = True
            assert got["min_distance"][0] == pytest.approx(dmin, abs=1e-12), step
        np.testing.assert_allclose(got["normal"][0], normal, rtol=1e-9, atol=1e-9)
        np.testing.assert_allclose(got["shear"][0], shear, rtol=1e-9, atol=1e-9)
        assert got["overflow"][0] == 0
    assert seen_none and seen_some  # the fingers start apart, then close on the box


def test_box_held_by_two_fingertips_carries_its_weight() -> None:
    model, data = _scene()
    layout = sensor_layout(model, tuple(TIPS), 8)
    for _ in range(400):  # close the fingers without gravity, then switch it on
        mujoco.mj_step(model, data)
    model.opt.gravity[:] = (0.0, 0.0, -G)
    rows = []
    for _ in range(4000):
        mujoco.mj_step(model, data)
        rows.append(data.sensordata.copy())
    f = features(np.array(rows[-1000:]), layout)  # the last 0.5 s: steady state
    weight = MASS * G
    # the squeeze is horizontal and saturated: each normal is the actuator's force limit
    np.testing.assert_allclose(f["normal"].mean(0), SQUEEZE, rtol=0.02)
    # the contact planes are vertical, so the shear carries the weight, half per fingertip
    assert f["shear"].sum(1).mean() == pytest.approx(weight, rel=0.02)
    np.testing.assert_allclose(f["shear"].mean(0), weight / 2, rtol=0.05)
    # held: the object barely moves
    assert np.abs(f["velocity"]).max() < 1e-3
    assert np.isfinite(f["min_distance"]).all()


def test_overflow_counts_contacts_beyond_the_slots() -> None:
    model, data = _scene(slots=1)  # box-box contacts come in fours
    layout = sensor_layout(model, tuple(TIPS), 1)
    for _ in range(600):
        mujoco.mj_step(model, data)
    assert features(data.sensordata[None], layout)["overflow"][0] >= 1


# ---------------------------------------------------------------------------------------------
# run_replay on the same scene: held, dropped, chunking and determinism


def _placed(squeeze: float) -> tuple[mujoco.MjModel, mujoco.MjData]:
    model, data = _scene()
    model.actuator_forcerange[:] = (-squeeze, squeeze)
    for _ in range(400):  # close the fingers without gravity (the scene is "placed")
        mujoco.mj_step(model, data)
    model.opt.gravity[:] = (0.0, 0.0, -G)
    return model, data


def test_run_replay_held_and_dropped() -> None:
    model, data = _placed(SQUEEZE)
    layout = sensor_layout(model, tuple(TIPS), 8)
    held = run_replay(model, data, layout, steps=3000, chunk=500, stop_after_loss_steps=400)
    assert held.stop_reason == "completed" and held.steps == 3000
    assert held.traces["normal"].shape == (3000, 2) and held.traces["normal"].dtype == np.float32
    assert np.isfinite(held.traces["min_distance"]).all()
    assert np.linalg.norm(held.traces["velocity"][-500:], axis=1).max() < 1e-3
    # 0.3 N of squeeze and friction 1 hold 0.6 N, not the box's 1.96 N weight: it falls away
    model, data = _placed(0.3)
    dropped = run_replay(model, data, layout, steps=20000, chunk=500, stop_after_loss_steps=400)
    assert dropped.stop_reason == "contact_lost" and dropped.steps < 20000
    assert np.isnan(dropped.traces["min_distance"][-400:]).all()
    assert dropped.traces["position"][-1, 2] < -0.02  # it fell
    assert not dropped.warnings
    # the summaries say so
    kept = summarise_replay(held, held.traces, 0.0005, 200)
    lost = summarise_replay(dropped, dropped.traces, 0.0005, 200)
    assert kept["held_at_end"] and kept["stop_reason"] == "completed" and kept["steps"] == 3000
    assert kept["final_displacement"] < 0.002 and np.isnan(kept["contact_loss_s"])
    assert kept["max_penetration"] > 0 and not kept["diverged"]
    assert not lost["held_at_end"] and lost["stop_reason"] == "contact_lost"
    assert lost["final_displacement"] > 0.02
    # contact ends where the first 0.1 s (200-step) run of undefined d_t starts; brief gaps
    # (contacts flicker while the box slides) do not count
    undefined = np.isnan(dropped.traces["min_distance"]).astype(int)
    window = np.convolve(undefined, np.ones(200, dtype=int), mode="valid")
    first_run = int(np.flatnonzero(window == 200)[0])
    assert lost["contact_loss_s"] == pytest.approx(first_run * 0.0005)


def test_run_replay_chunking_and_determinism() -> None:
    runs = []
    for chunk in (250, 3000, 250):
        model, data = _placed(SQUEEZE)
        layout = sensor_layout(model, tuple(TIPS), 8)
        runs.append(run_replay(model, data, layout, 3000, chunk, 400))
    for c in runs[0].traces:
        np.testing.assert_array_equal(runs[0].traces[c], runs[2].traces[c])  # bit for bit
        np.testing.assert_allclose(runs[0].traces[c], runs[1].traces[c], rtol=0, atol=1e-6)


# ---------------------------------------------------------------------------------------------
# creep under the configured contact settings (issue: < 1/10 of 1.2 mm/s when held)


def _contact(model: str) -> dict:
    from conftest import CONFIG_DIR

    from graspstab.config import compose_config

    return compose_config(CONFIG_DIR, [f"contact={model}"])["replay"]["contact"]


def test_strict_contacts_hold_without_creep_and_failing_grasps_still_slide() -> None:
    """graspstab.replay.creep.box_creep (the report's creep figure) under the strict model: the
    box held with 5 N per side (10 N of friction against 1.96 N) barely moves."""
    from graspstab.replay.creep import box_creep

    assert box_creep(_contact("strict"), SQUEEZE, 3.0) < 0.1 * 0.0012  # [m/s]
    assert box_creep(_contact("strict"), 0.3, 0.5) > 0.1  # squeezed too weakly: it falls


def test_reference_contacts_creep_at_the_order_of_the_instability_threshold() -> None:
    """MuJoCo's defaults (the reference model): the same squeezed box creeps above 1.2 mm/s
    (eq. 23) itself, so under this model creep is part of what "unstable" means."""
    from graspstab.replay.creep import box_creep

    c = _contact("reference")
    assert (c["cone"], c["impratio"], c["noslip_iterations"]) == ("pyramidal", 1.0, 0)
    assert box_creep(c, SQUEEZE, 3.0) > 0.0012
    assert box_creep(c, 0.3, 0.5) > 0.1


# ---------------------------------------------------------------------------------------------
# the shear's two fingertip-frame components (the input audit's 15-input set)


def _world_tangential(model: mujoco.MjModel, data: mujoco.MjData, tip: int) -> np.ndarray:
    """Brute force: each contact's force from mj_contactForce, rotated to the world by the
    contact's frame, the fingertip's force on the object, its normal part removed; summed."""
    obj = model.body("object").id
    total, force = np.zeros(3), np.zeros(6)
    for i in range(data.ncon):
        c = data.contact[i]
        b1, b2 = model.geom_bodyid[c.geom1], model.geom_bodyid[c.geom2]
        if {b1, b2} != {obj, tip}:
            continue
        mujoco.mj_contactForce(model, data, i, force)
        frame = c.frame.reshape(3, 3)  # rows: normal (geom1 to geom2), tangents
        on_geom2 = frame.T @ force[:3]
        f = on_geom2 if b1 == tip else -on_geom2
        total += f - (f @ frame[0]) * frame[0]
    return total


def _tilted_scene(anchor: str, gravity: np.ndarray) -> tuple[mujoco.MjModel, mujoco.MjData]:
    """The squeezed box with joint anchors that set the fingertips' long axis (their centre of
    mass minus the anchor), under a given gravity."""
    xml = SCENE.replace('axis="1 0 0"', f'axis="1 0 0" pos="{anchor}"').replace(
        'axis="-1 0 0"', f'axis="-1 0 0" pos="{anchor}"'
    )
    spec = mujoco.MjSpec.from_string(xml)
    add_replay_sensors(spec, TIPS, "hand", "object", 8)
    model = spec.compile()
    data = mujoco.MjData(model)
    data.ctrl[:] = 0.05
    for _ in range(400):
        mujoco.mj_step(model, data)
    model.opt.gravity[:] = gravity
    return model, data


def test_shear_components_equal_the_brute_force_tangential_force() -> None:
    gravity = np.array([0.0, 3.0, -G])  # weight down and sideways: both components nonzero
    model, data = _tilted_scene("0 0.004 -0.01", gravity)
    layout = sensor_layout(model, tuple(TIPS), 8)
    for step in range(1200):
        mujoco.mj_step(model, data)
        if step % 100:
            continue
        mujoco.mj_forward(model, data)
        got = features(data.sensordata[None], layout)
        for k, body in enumerate(TIPS.values()):
            tip = model.body(body).id
            t = _world_tangential(model, data, tip)
            nrm = np.zeros(3)  # force-weighted mean normal from the contacts themselves
            force = np.zeros(6)
            for i in range(data.ncon):
                c = data.contact[i]
                if tip in (model.geom_bodyid[c.geom1], model.geom_bodyid[c.geom2]):
                    mujoco.mj_contactForce(model, data, i, force)
                    sign = 1.0 if model.geom_bodyid[c.geom1] == tip else -1.0
                    nrm += abs(force[0]) * sign * c.frame[:3]
            nrm /= np.linalg.norm(nrm)
            axis = data.xmat[tip].reshape(3, 3) @ layout.distal[k]
            e1 = axis - (axis @ nrm) * nrm
            e1 /= np.linalg.norm(e1)
            want = [t @ e1, t @ np.cross(nrm, e1)]
            have = [got["shear_distal"][0, k], got["shear_lateral"][0, k]]
            np.testing.assert_allclose(have, want, rtol=1e-9, atol=1e-9)
            # one contact plane: the vector's length is eq. 18's sum of magnitudes
            assert np.hypot(*have) == pytest.approx(got["shear"][0, k], rel=1e-6, abs=1e-9)


def test_shear_components_of_a_held_box_carry_its_weight_along_the_finger() -> None:
    """Fingertips whose long axis points up (anchor below the centre of mass): the weight is
    carried distally, half per fingertip, nothing laterally; a sideways pull shows laterally."""
    model, data = _tilted_scene("0 0 -0.01", np.array([0.0, 0.0, -G]))
    layout = sensor_layout(model, tuple(TIPS), 8)
    np.testing.assert_allclose(layout.distal, [[0, 0, 1], [0, 0, 1]], atol=1e-12)
    rows = []
    for _ in range(3000):
        mujoco.mj_step(model, data)
        rows.append(data.sensordata.copy())
    f = features(np.array(rows[-1000:]), layout)
    np.testing.assert_allclose(f["shear_distal"].mean(0), MASS * G / 2, rtol=0.05)
    np.testing.assert_allclose(f["shear_lateral"].mean(0), 0.0, atol=1e-3)
    # the same box pulled along +y as well, so the fingertips push it along -y: tip a's lateral
    # axis is n x distal = x x z = -y, tip b's (-x) x z = +y
    model.opt.gravity[:] = (0.0, 2.0, -G)
    rows = []
    for _ in range(3000):
        mujoco.mj_step(model, data)
        rows.append(data.sensordata.copy())
    f = features(np.array(rows[-1000:]), layout)
    lateral = f["shear_lateral"].mean(0)
    assert lateral[0] == pytest.approx(MASS * 2.0 / 2, rel=0.1)
    assert lateral[1] == pytest.approx(-MASS * 2.0 / 2, rel=0.1)


def test_shear_components_are_zero_without_contact_and_use_the_spare_axis_end_on() -> None:
    model, data = _tilted_scene("0 0 0", np.array([0.0, 0.0, -G]))  # long axis = body x = normal
    layout = sensor_layout(model, tuple(TIPS), 8)
    free = features(np.zeros((1, model.nsensordata)), layout)
    assert not free["shear_distal"].any() and not free["shear_lateral"].any()
    rows = []
    for _ in range(3000):
        mujoco.mj_step(model, data)
        rows.append(data.sensordata.copy())
    f = features(np.array(rows[-1000:]), layout)
    # the long axis is end-on (parallel to the normal): the spare axis (x cross y = z) takes its
    # place, so the weight still shows, and the components keep eq. 18's magnitude
    np.testing.assert_allclose(np.abs(f["shear_distal"]).mean(0), MASS * G / 2, rtol=0.05)
    np.testing.assert_allclose(
        np.hypot(f["shear_distal"], f["shear_lateral"]), f["shear"], rtol=1e-6, atol=1e-9
    )
