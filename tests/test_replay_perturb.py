"""The hidden-onset disturbance (replay.protocol perturb): each grasp's delay, rate and direction
come from its own stream, within the configured ranges, reproducibly; the load is open-loop in
time, so neither the object's motion nor a reflex changes it."""

from __future__ import annotations

from types import SimpleNamespace

import mujoco
import numpy as np
import pytest
from box_scene import two_finger_box
from conftest import CONFIG_DIR

from graspstab.config import compose_config
from graspstab.replay.grasp_setup import grasp_load
from graspstab.replay.protocols import creep_free_labels, creep_free_replay, replay_params
from graspstab.replay.run import run_replay
from graspstab.replay.sensors import add_replay_sensors, sensor_layout

DT = 0.0005
GRAVITY = np.array([0.0, -6.0, -7.7611])  # a hand-frame gravity along no hand axis (|g| 9.81)


@pytest.fixture(scope="module")
def params() -> dict:
    cfg = compose_config(CONFIG_DIR, ["contact=strict", "replay.protocol=perturb"])
    return replay_params(cfg["replay"])


def fake_scene(mass: float = 0.2) -> SimpleNamespace:
    """What grasp_load reads of a scene: the object's subtree mass."""
    model = SimpleNamespace(body_subtreemass=np.array([0.0, mass]))
    return SimpleNamespace(model=model, object_body=1)


def test_each_grasp_draws_its_own_delay_rate_and_direction_reproducibly(params) -> None:
    p = params["perturb"]
    loads = [grasp_load(params, fake_scene(), GRAVITY, obj, g)
             for obj in ("a", "b") for g in range(60)]  # fmt: skip
    again = [grasp_load(params, fake_scene(), GRAVITY, obj, g)
             for obj in ("a", "b") for g in range(60)]  # fmt: skip
    for one, two in zip(loads, again, strict=True):
        assert (one.start_s, one.rate) == (two.start_s, two.rate)
        np.testing.assert_array_equal(one.direction, two.direction)
        assert p["delay_s"][0] <= one.start_s <= p["delay_s"][1]
        assert p["rate"][0] <= one.rate <= p["rate"][1]
        assert one.path == "linear" and one.ceiling == p["ceiling"]
    starts = np.array([ld.start_s for ld in loads])
    assert len(np.unique(starts)) == len(loads)  # a stream per grasp and object
    dirs = {tuple(np.round(ld.direction, 6)) for ld in loads}
    gravity = tuple(np.round(GRAVITY / np.linalg.norm(GRAVITY), 6))
    assert gravity in dirs and len(dirs) == 7  # gravity and the six hand axes, all drawn
    # the weight scales the force, not the draw
    heavy = grasp_load(params, fake_scene(1.0), GRAVITY, "a", 0)
    assert heavy.start_s == loads[0].start_s
    assert heavy.weight == pytest.approx(5 * loads[0].weight)


def test_the_load_is_open_loop_in_time(params) -> None:
    """F(t) = m g k (t - t0) from the drawn delay, capped at the ceiling, whatever the object
    does: observing any speeds leaves every later step's force unchanged."""
    load = grasp_load(params, fake_scene(), GRAVITY, "a", 7)
    steps = round((load.start_s + 40.0 / load.rate) / DT)
    before = load.forces(0, steps)
    for first in range(0, steps, 500):
        load.observe(first, np.full(500, 10.0))  # a sliding object
    np.testing.assert_array_equal(load.forces(0, steps), before)
    t = np.arange(steps) * DT
    weight = 0.2 * np.linalg.norm(GRAVITY)
    want = np.clip(weight * load.rate * (t - load.start_s), 0.0, load.ceiling * weight)
    np.testing.assert_allclose(np.linalg.norm(before, axis=1), want, rtol=1e-9, atol=1e-12)
    assert load.chunk_steps(0, 1000) == 1000  # it never asks for the object's speed


def test_a_reflex_does_not_change_the_disturbance() -> None:
    """The two-finger box under a perturbation, once open-loop and once with a controller that
    tightens mid-replay: the recorded load is identical at every step."""
    spec = mujoco.MjSpec.from_string(two_finger_box(0.1, 0.02, 100, kp=1000.0, dt=DT, palm=False))
    add_replay_sensors(spec, {"a": "tip_a", "b": "tip_b"}, "hand", "object", 8)
    model = spec.compile()
    layout = sensor_layout(model, ("a", "b"), 8)
    cfg = compose_config(CONFIG_DIR, ["replay.protocol=perturb"])
    perturb = dict(cfg["replay"]["perturb"], delay_s=[0.1, 0.2], rate=[20.0, 30.0])
    params = dict(cfg["replay"], protocol="perturb", perturb=perturb)

    class Tighten:
        def chunk_steps(self, first: int, default: int) -> int:
            return min(default, 50)

        def targets(self, first: int, n: int, ctrl: np.ndarray) -> np.ndarray:
            return np.repeat((ctrl + (0.002 if first >= 400 else 0.0))[None], n, axis=0)

        def observe(self, first: int, normal: np.ndarray, shear: np.ndarray) -> None:
            pass

    traces = []
    for controller in (None, Tighten()):
        data = mujoco.MjData(model)
        data.ctrl[:] = 0.007
        load = grasp_load(params, SimpleNamespace(model=model, object_body=layout.object_body),
                          np.array([0.0, 0.0, -9.81]), "box", 3)  # fmt: skip
        run = run_replay(model, data, layout, 2000, 500, 10**6, load, layout.object_body,
                         controller=controller)  # fmt: skip
        traces.append(run.traces)
    assert not np.array_equal(traces[0]["normal"], traces[1]["normal"])  # the reflex acted
    n = min(len(traces[0]["load"]), len(traces[1]["load"]))
    assert n > 1000
    np.testing.assert_array_equal(traces[0]["load"][:n], traces[1]["load"][:n])


def test_the_creep_free_benchmark_takes_its_load_and_label_source_by_name() -> None:
    cfg = compose_config(CONFIG_DIR, ["creep_free.load=perturb",
                                      "creep_free.labels_source=displacement"])  # fmt: skip
    replay = creep_free_replay(cfg)
    assert replay["protocol"] == "perturb" and "ramp" not in replay and "perturb" in replay
    assert creep_free_labels(cfg)["source"] == "displacement"
    base = compose_config(CONFIG_DIR)
    ramp = creep_free_replay(base)
    assert ramp["protocol"] == "ramp" and "perturb" not in ramp
    assert creep_free_labels(base) == base["labels"]
    gravity = replay_params(base["replay"])
    assert "ramp" not in gravity and "perturb" not in gravity
