"""The grip reflex: it fires on the monitor's warning only, honours its delay to the step, and
tightening a held box between two fingers raises its friction capacity as physics predicts."""

from __future__ import annotations

import mujoco
import numpy as np
import pytest
from box_scene import two_finger_box

from graspstab.closedloop.reflex import GripReflex, ReflexParams, delay_steps
from graspstab.monitor.constants import MonitorConstants
from graspstab.monitor.stream import StreamingMonitor
from graspstab.replay.ramp import RampLoad
from graspstab.replay.run import REFLEX, run_replay
from graspstab.replay.sensors import add_replay_sensors, sensor_layout

DT = 0.0005
NU = 16
CLOSING = np.r_[np.ones(10), np.zeros(6)]


class Planted:
    """A scorer that calls a window unstable when fingertip 0's normal force in its last frame
    exceeds 1 N (probability 1, else 0)."""

    def __init__(self, window: int = 4) -> None:
        self.constants = MonitorConstants(np.zeros((5, 2)), np.ones((5, 2)), 0.5, window)

    def score_one(self, window: np.ndarray) -> float:
        return float(window[-1, 0, 0] > 1.0)

    def __call__(self, windows: np.ndarray) -> np.ndarray:
        return (windows[:, -1, 0, 0] > 1.0).astype(np.float64)


def planted(frames: int, unstable: list[tuple[int, int]]) -> tuple[np.ndarray, np.ndarray]:
    """Normal and shear (frames, 5): fingertip 0 at 2 N over the ``unstable`` [lo, hi) spans."""
    normal, shear = np.full((frames, 5), 0.5), np.zeros((frames, 5))
    for lo, hi in unstable:
        normal[lo:hi, 0] = 2.0
    return normal, shear


def drive(reflex: GripReflex, normal: np.ndarray, shear: np.ndarray, default: int) -> np.ndarray:
    """Run the reflex the way ``run_replay`` does (its chunking, targets then forces); return
    each step's offset along the closing joints."""
    ctrl, out, first = np.zeros(NU), [], 0
    while first < len(normal):
        n = min(reflex.chunk_steps(first, default), len(normal) - first)
        targets = reflex.targets(first, n, ctrl)
        assert np.all(targets[:, CLOSING == 0] == 0)  # the other joints are never moved
        out.append(targets[:, 0])
        reflex.observe(first, normal[first : first + n], shear[first : first + n])
        first += n
    return np.concatenate(out)


def reflex(monitor=None, fire_at=None, **params) -> GripReflex:  # noqa: ANN001
    p = {"amount": 0.2, "rate": 4.0, "delay_s": 0.01} | params
    return GripReflex(ReflexParams(**p), CLOSING, np.full(NU, 10.0), DT, monitor=monitor,
                      latency_s=0.0003, fire_at=fire_at)  # fmt: skip


def monitor(debounce: int = 1) -> StreamingMonitor:
    return StreamingMonitor.from_scorer(Planted(), stride=10, debounce=debounce)


def expected(steps: int, on: int, amount: float = 0.2, rate: float = 4.0) -> np.ndarray:
    """The offset a tightening from step ``on`` gives, step by step (brute force)."""
    out = np.zeros(steps)
    for t in range(on, steps):
        out[t] = min(amount, rate * DT * (t - on + 1))
    return out


def test_delay_is_whole_steps_and_never_zero_steps_late() -> None:
    assert delay_steps(0.01, 0.0003, DT) == 21  # 20.6 steps rounds up
    assert delay_steps(0.01, 0.0, DT) == 20
    assert delay_steps(0.0, 0.0, DT) == 0  # acts on the next step


@pytest.mark.parametrize("default", [1, 7, 1000])
def test_reflex_acts_delay_steps_after_the_warning_frame(default: int) -> None:
    # window 4, stride 10: scored frames 3, 13, ..., 133, 143; the plant starts at frame 137,
    # so the first unstable score is frame 143 and the grip moves from 143 + 1 + 21 = 165
    r = reflex(monitor())
    normal, shear = planted(600, [(137, 600)])
    got = drive(r, normal, shear, default)
    assert r.warn_frames == [143] and r.on_steps == [165]
    np.testing.assert_allclose(got, expected(600, 165), atol=1e-12)
    assert got[164] == 0 and got[165] == pytest.approx(4.0 * DT)
    assert got[165 + 99] == pytest.approx(0.2)  # 0.2 rad at 4 rad/s: 50 ms = 100 steps


def test_reflex_fires_only_on_a_warning() -> None:
    normal, shear = planted(800, [])  # always stable
    r = reflex(monitor())
    assert not drive(r, normal, shear, 1000).any() and not r.on_steps
    # one unstable score (frames 137-149 cover the scored frame 143 only) under debounce 2:
    # no warning, no reflex; two consecutive unstable scores (143, 153): it fires after 153
    normal, shear = planted(800, [(137, 150)])
    r = reflex(monitor(debounce=2))
    assert not drive(r, normal, shear, 1000).any() and not r.warn_frames
    normal, shear = planted(800, [(137, 160)])
    r = reflex(monitor(debounce=2))
    got = drive(r, normal, shear, 1000)
    assert r.warn_frames == [153] and r.on_steps == [153 + 22]
    np.testing.assert_allclose(got, expected(800, 175), atol=1e-12)


def test_warnings_before_the_arm_step_are_ignored() -> None:
    normal, shear = planted(800, [(137, 800)])
    r = reflex(monitor())
    r.arm_step = 300  # a warning already up when the reflex arms counts as raised there
    got = drive(r, normal, shear, 1000)
    assert r.warn_frames == [300] and r.on_steps == [322]
    np.testing.assert_allclose(got, expected(800, 322), atol=1e-12)


def test_a_fresh_reflex_ignores_a_warning_up_at_arming_until_it_drops_and_rises() -> None:
    """Armed at 300 inside an unstable span [137, 400): the warning up at arming never fires;
    it drops (stable scores from 403), and the span from 597 raises a new one at 603, which
    fires 22 steps later. A warning that rises only after arming fires at once."""
    normal, shear = planted(1000, [(137, 400), (597, 1000)])
    r = GripReflex(ReflexParams(0.2, 4.0, 0.01), CLOSING, np.full(NU, 10.0), DT,
                   monitor=monitor(), latency_s=0.0003, arm_step=300, fresh=True)  # fmt: skip
    got = drive(r, normal, shear, 1000)
    assert r.warn_frames == [603] and r.on_steps == [625]
    np.testing.assert_allclose(got, expected(1000, 625), atol=1e-12)
    normal, shear = planted(1000, [(597, 1000)])  # nothing up at arming: the first rise fires
    r = GripReflex(ReflexParams(0.2, 4.0, 0.01), CLOSING, np.full(NU, 10.0), DT,
                   monitor=monitor(), latency_s=0.0003, arm_step=300, fresh=True)  # fmt: skip
    drive(r, normal, shear, 1000)
    assert r.warn_frames == [603] and r.on_steps == [625]
    # a warning down exactly at arming counts as down: the next rise fires
    normal, shear = planted(1000, [(137, 290), (597, 1000)])
    r = GripReflex(ReflexParams(0.2, 4.0, 0.01), CLOSING, np.full(NU, 10.0), DT,
                   monitor=monitor(), latency_s=0.0003, arm_step=300, fresh=True)  # fmt: skip
    drive(r, normal, shear, 1000)
    assert r.warn_frames == [603]


def test_calm_release_returns_the_grip_and_a_new_warning_tightens_again() -> None:
    # unstable scores at 143 .. 293, stable from 303 on: down 20 frames (0.01 s) at 322, so the
    # release acts from 322 + 1 + 21 = 344; a second plant from 600 warns at 603, acts at 625
    r = reflex(monitor(), release="calm", release_s=0.01)
    normal, shear = planted(1000, [(137, 300), (597, 1000)])
    got = drive(r, normal, shear, 1000)
    assert r.warn_frames == [143, 603] and r.on_steps == [165, 625] and r.off_steps == [344]
    ref = expected(1000, 165)
    ref[344:] = np.clip(0.2 - 4.0 * DT * np.arange(1, 1000 - 344 + 1), 0, None)
    ref[625:] = expected(1000, 625)[625:]
    np.testing.assert_allclose(got, ref, atol=1e-12)


def test_fixed_schedule_and_limits() -> None:
    normal, shear = planted(300, [])
    r = reflex(fire_at=50)  # the "always" and "oracle" policies: no monitor, a fixed step
    assert r.chunk_steps(0, 1000) == 1000  # nothing to decide: open-loop chunks
    np.testing.assert_allclose(drive(r, normal, shear, 1000), expected(300, 50), atol=1e-12)
    # a target is never moved past its joint's upper limit, nor pulled back if beyond it
    r = GripReflex(ReflexParams(0.2, 4.0, 0.0), CLOSING, np.full(NU, 0.05), DT, fire_at=0)
    ctrl = np.zeros(NU)
    ctrl[1] = 0.5  # beyond its limit already
    targets = r.targets(0, 200, ctrl)
    assert targets[:, 0].max() == pytest.approx(0.05) and np.all(targets[:, 1] == 0.5)
    with pytest.raises(ValueError, match="closed_loop.reflex.rate"):
        ReflexParams(0.2, 0.0, 0.01)
    with pytest.raises(ValueError, match="release must be one of never, calm"):
        ReflexParams(0.2, 1.0, 0.01, release="sometimes")


# ---------------------------------------------------------------------------------------------
# physics: a box between two position-servoed fingertips, loaded by a slowly rising force

KP, MU = 1000.0, 1.0
BOX = two_finger_box(0.1, 0.02, 100, kp=KP, mu=MU, dt=DT, palm=False)
# each fingertip's face meets the box 5 mm in; the targets sit 2 mm past it: 2 N a side
CONTACT, PRESS, EXTRA = 0.005, 0.002, 0.002


def slip_load(extra: float) -> tuple[float, dict[str, np.ndarray], np.ndarray]:
    """Close on the box unloaded with a reflex that tightens both fingertips by ``extra`` [m]
    from step 0 (0.3 s through ``run_replay``), then ramp a load along -z at 5 N/s from there (a
    second replay holding the tightened targets). Returns the load [N] at which the box first
    slides, the unloaded replay's traces and the fingertips' joint positions at its end."""
    spec = mujoco.MjSpec.from_string(BOX)
    add_replay_sensors(spec, {"a": "tip_a", "b": "tip_b"}, "hand", "object", 8)
    model = spec.compile()
    data = mujoco.MjData(model)
    data.ctrl[:] = CONTACT + PRESS
    for _ in range(600):  # close on the box, unloaded
        mujoco.mj_step(model, data)
    layout = sensor_layout(model, ("a", "b"), 8)
    grip = GripReflex(ReflexParams(amount=extra, rate=0.1, delay_s=0.0), np.ones(2),
                      np.full(2, np.inf), DT, fire_at=0)  # fmt: skip
    unloaded = run_replay(model, data, layout, 600, 1000, 10**6, controller=grip)
    q = data.qpos[:2].copy()
    assert data.ctrl == pytest.approx(CONTACT + PRESS + extra)  # rollout leaves the last targets
    data.ctrl[:] = CONTACT + PRESS  # the open-loop targets again; the reflex adds its offset
    held = GripReflex(ReflexParams(amount=extra, rate=1e9, delay_s=0.0), np.ones(2),
                      np.full(2, np.inf), DT, fire_at=0)  # fmt: skip
    load = RampLoad(np.array([0.0, 0.0, -1.0]), weight=1.0, dt=DT, start_s=0.0, rate=5.0,
                    ceiling=20.0, path="hold", slip_speed=0.005, feedback_steps=10)  # fmt: skip
    loaded = run_replay(model, data, layout, 6000, 1000, 10**6, load, model.body("object").id,
                        controller=held)  # fmt: skip
    assert load.slip_step is not None, "the box never slid"
    return float(np.linalg.norm(loaded.traces["load"][load.slip_step])), unloaded.traces, q


def test_tightening_a_held_box_raises_its_friction_capacity_as_predicted() -> None:
    plain, before, q0 = slip_load(0.0)
    tight, after, q1 = slip_load(EXTRA)
    # the reflex's trace channel: the offset reaches 2 mm within 20 ms and stays
    assert after[REFLEX][200:].min() == pytest.approx(EXTRA, rel=1e-6)
    assert not before[REFLEX].any()
    # statics of a position servo at rest: each side presses kp (target - q); the fingertips
    # sink a little further into the soft contact, so the rise is below kp x extra
    n0, n1 = before["normal"][-100:].mean(0), after["normal"][-100:].mean(0)
    np.testing.assert_allclose(n0, KP * (CONTACT + PRESS - q0), rtol=0.02)
    np.testing.assert_allclose(n1, KP * (CONTACT + PRESS + EXTRA - q1), rtol=0.02)
    assert np.all(n1 - n0 > 0.8 * KP * EXTRA)
    # Coulomb: two contacts of friction mu carry 2 mu N, so the slip load rises by 2 mu dN
    assert plain == pytest.approx(2 * MU * n0.mean(), rel=0.1)
    assert tight - plain == pytest.approx(2 * MU * (n1 - n0).mean(), rel=0.1)
